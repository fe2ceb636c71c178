"""Checks of configuration values, for the ``__post_init__`` of every configuration dataclass.

Each check raises ``ValueError`` naming the field, the allowed values and the value given, e.g.
``EncoderConfig.hidden must be an integer >= 1 (got 0)``. Booleans are not numbers here: a spec's
``hidden = true`` is an error, not 1.
"""
from __future__ import annotations

import math
from numbers import Integral, Real
from typing import Any, Collection


def require_number(name: str, value: Any, integer: bool = False, low: float | None = None,
                   high: float | None = None, open_low: bool = False,
                   open_high: bool = False) -> None:
    """Raise unless ``value`` is a finite number (an integer with ``integer``) within the bounds.

    Args:
        name: what the message calls the value, e.g. ``"OptimConfig.learning_rate"``.
        value: the value to check.
        integer: require an integer (``numbers.Integral``, not ``bool``).
        low: lower bound, inclusive unless ``open_low``; None = unbounded.
        high: upper bound, inclusive unless ``open_high``; None = unbounded.
        open_low: exclude ``low`` itself.
        open_high: exclude ``high`` itself.
    """
    kind = Integral if integer else Real
    ok = isinstance(value, kind) and not isinstance(value, bool) and math.isfinite(value)
    if ok and low is not None:
        ok = value > low if open_low else value >= low
    if ok and high is not None:
        ok = value < high if open_high else value <= high
    if not ok:
        what = "an integer" if integer else "a finite number"
        raise ValueError(f"{name} must be {what}{_range(low, high, open_low, open_high)} "
                         f"(got {value!r})")


def require_choice(name: str, value: Any, choices: Collection) -> None:
    """Raise ``ValueError`` unless ``value`` is one of ``choices``.

    Args:
        name: what the message calls the value, e.g. ``"OptimConfig.unit"``.
        value: the value to check; a bool is never a choice (``True == 1``), nor is a value
            that cannot be looked up among them (a TOML table or array, unhashable).
        choices: the allowed values, listed in the message.
    """
    try:
        known = not isinstance(value, bool) and value in choices
    except TypeError:
        known = False
    if not known:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, choices))} (got {value!r})")


def require_bool(name: str, value: Any) -> None:
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false (got {value!r})")


def _range(low, high, open_low: bool, open_high: bool) -> str:
    if low is not None and high is not None:
        return f" in {'(' if open_low else '['}{low:g}, {high:g}{')' if open_high else ']'}"
    if low is not None:
        return f" {'>' if open_low else '>='} {low:g}"
    if high is not None:
        return f" {'<' if open_high else '<='} {high:g}"
    return ""

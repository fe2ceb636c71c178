"""Range-checked ``type=`` functions for numeric command-line options.

Each turns the option's text into a number or rejects it with an ``ArgumentTypeError`` naming the
allowed range, which argparse prints as ``prog: error: argument --hidden: expected an integer >= 1,
got '0'`` (exit 2) before any work starts::

    parser.add_argument("--hidden", type=positive_int, default=1024, help="...")
    parser.add_argument("--keep-prob", type=probability, default=0.5, help="...")

The configuration dataclasses validate their fields again, for callers that bypass the command
line.
"""
from __future__ import annotations

import argparse
import math
from typing import Callable

from ..cores import usable_cores


def int_range(low: int, high: int | None = None) -> Callable[[str], int]:
    """A type accepting integers in ``low..high`` (inclusive; ``high`` None = unbounded)."""
    allowed = f"an integer >= {low}" if high is None else f"an integer in {low}..{high}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}")
        return value

    parse.__name__ = f"int_range({low}, {high})"
    return parse


def float_range(low: float = -math.inf, high: float = math.inf, *, low_open: bool = False,
                high_open: bool = False) -> Callable[[str], float]:
    """A type accepting finite floats between ``low`` and ``high``. NaN and infinities are
    always rejected.

    Args:
        low: the smallest value allowed; -inf = no lower bound.
        high: the largest value allowed; inf = no upper bound.
        low_open: exclude ``low`` itself.
        high_open: exclude ``high`` itself.

    Returns:
        An argparse ``type``: text -> float, raising ``argparse.ArgumentTypeError`` that names
        the allowed range and the text.
    """
    allowed = _describe(low, high, low_open, high_open)

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        too_low = value <= low if low_open else value < low
        too_high = value >= high if high_open else value > high
        if not math.isfinite(value) or too_low or too_high:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}")
        return value

    parse.__name__ = f"float_range({allowed})"
    return parse


def _describe(low: float, high: float, low_open: bool, high_open: bool) -> str:
    if math.isinf(low) and math.isinf(high):
        return "a finite number"
    if math.isinf(high):
        return f"a finite number {'>' if low_open else '>='} {low:g}"
    if math.isinf(low):
        return f"a finite number {'<' if high_open else '<='} {high:g}"
    return (f"a number in {'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}")


def int_list(item: Callable[[str], int]) -> Callable[[str], tuple[int, ...]]:
    """A type for comma-separated integers, each checked by ``item`` (e.g. ``positive_int``)."""

    def parse(text: str) -> tuple[int, ...]:
        parts = [p.strip() for p in text.split(",")]
        if not all(parts):
            raise argparse.ArgumentTypeError(f"expected comma-separated integers, got {text!r}")
        return tuple(item(p) for p in parts)

    parse.__name__ = "int_list"
    return parse


#: Counts: layers, epochs, batch size, workers ...
positive_int = int_range(1)
#: Seeds, thread counts with 0 = all, epochs before a decay ...
non_negative_int = int_range(0)


def thread_count(text: str) -> int:
    """Cores for a process: 0 (= all of them) up to those this process may use
    (``jigsaws_tools.cores.usable_cores``)."""
    value = non_negative_int(text)
    cores = usable_cores()
    if value > cores:
        raise argparse.ArgumentTypeError(f"expected at most the {cores} core"
                                         f"{'s' if cores > 1 else ''} this process may use, "
                                         f"got {text!r}")
    return value


#: Learning rates, clipping norms, initial weight ranges ...
positive_float = float_range(0.0, low_open=True)
#: Weights such as GradNorm's alpha.
non_negative_float = float_range(0.0)
#: Any finite number.
finite_float = float_range()
#: Keep probabilities and other fractions that may be 1 but not 0.
probability = float_range(0.0, 1.0, low_open=True)
#: Momentum: 0 (none) up to, not including, 1.
momentum = float_range(0.0, 1.0, high_open=True)
#: Comma-separated positive integers (evaluation points).
positive_int_list = int_list(positive_int)

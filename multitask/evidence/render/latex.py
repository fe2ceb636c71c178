"""Pieces of paste-ready LaTeX tables: numbers with true minus signs, escaped text, the comment
naming the packages a table needs, and a check of what a table asks for.

Every table this package writes starts with ``% Requires: \\usepackage{booktabs}`` (one line per
package), so that a user (and ``tests/test_latex.py``) knows the preamble it compiles with.
"""
from __future__ import annotations

import math
import re

#: ``\usepackage`` commands named in a table's leading comment.
_REQUIRED = re.compile(r"^% Requires: (\\usepackage(?:\[[^\]]*\])?\{[^}]+\})", re.MULTILINE)


def requires(*packages: str) -> str:
    """The leading comment lines of a table needing ``packages`` (e.g. ``"booktabs"``)."""
    return "".join(f"% Requires: \\usepackage{{{p}}}\n" for p in packages)


def required_packages(tex: str) -> list[str]:
    """The ``\\usepackage`` lines a table's leading comment names."""
    return _REQUIRED.findall(tex)


def number(value: float | None, digits: int = 1, signed: bool = False) -> str:
    """``value`` as LaTeX with a true minus sign (``$-$``); a value that rounds to zero has no
    sign; ``--`` if missing.

    Args:
        value: the number, in the table's unit (e.g. percent); None or NaN = missing.
        digits: decimals shown.
        signed: put ``$+$`` in front of positive values (differences).
    """
    if value is None or math.isnan(value):
        return "--"
    text = f"{abs(value):.{digits}f}"
    if float(text) == 0:
        return text
    if value < 0:
        return f"$-${text}"
    return f"$+${text}" if signed else text


def mean_std(mean: float | None, std: float | None, digits: int = 1) -> str:
    """``mean (std)`` as LaTeX (``number``), or the mean alone when there is no std; ``--``
    without a mean.

    Args:
        mean: the mean, in the table's unit; None or NaN = missing.
        std: its standard deviation, same unit; None or NaN = none.
        digits: decimals shown of both.
    """
    if mean is None or math.isnan(mean):
        return "--"
    if std is None or math.isnan(std):
        return number(mean, digits)
    return f"{number(mean, digits)} ({number(std, digits)})"


def bold(text: str) -> str:
    return rf"\textbf{{{text}}}"


def escape(text: str) -> str:
    """Plain text for LaTeX: the special characters ``\\ & % $ # _ { } ~ ^`` escaped."""
    special = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#",
               "_": r"\_", "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}",
               "^": r"\textasciicircum{}"}
    return "".join(special.get(c, c) for c in text)

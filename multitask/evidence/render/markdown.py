"""Markdown tables, as the READMEs under ``results/`` quote them."""
from __future__ import annotations


def markdown_table(header: list[str], rows: list[list]) -> list[str]:
    """The lines of a Markdown table: ``header``, the rule under it, one line per row (cells
    written with ``str``)."""
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(map(str, cells)) + " |" for cells in rows])

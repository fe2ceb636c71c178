"""What ``multitask-tables`` is making, said while it works (a minute for ``--curves`` at the
paper's size): the slow steps (the claims' power simulations) and every figure saved
(``figures.save``) are named on standard output, as the grid's and training's progress is
(standard error stays for warnings and errors): a transient status line on a terminal
(``rich``), a plain line per figure elsewhere (a file, a pipe, a batch job's log). Only within
``shown`` (the command's); library calls draw silently.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator


class _Reporter:
    def __init__(self, prog: str):
        from rich.console import Console

        self.prog, self.count = prog, 0
        self.console = Console()
        self.status = (self.console.status("drawing figures") if self.console.is_terminal
                       else None)

    def say(self, message: str) -> None:
        if self.status is not None:
            self.status.update(f"{self.prog}: {message}")
        else:
            print(f"{self.prog}: {message}", flush=True)


_reporter: _Reporter | None = None


@contextmanager
def shown(prog: str) -> Iterator[None]:
    """For the block, say each figure drawn (see the module), as ``prog``."""
    global _reporter
    _reporter = _Reporter(prog)
    if _reporter.status is not None:
        _reporter.status.start()
    try:
        yield
    finally:
        if _reporter.status is not None:
            _reporter.status.stop()
        _reporter = None


def say(message: str) -> None:
    """Say ``message`` (e.g. ``drawing 22 training-curve figures``) within ``shown``."""
    if _reporter is not None:
        _reporter.say(message)


def drew(name: str) -> None:
    """Say that the figure ``name`` was drawn, and how many so far, within ``shown``."""
    if _reporter is not None:
        _reporter.count += 1
        _reporter.say(f"figure {_reporter.count}: {name}")

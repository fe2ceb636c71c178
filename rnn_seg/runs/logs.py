"""A run's per-unit CSV logs (``history.csv``, ``gradnorm.csv``): a row appended at each progress
line under a header written once, with every column the run can ever fill (an empty cell where
a value is not computed, e.g. training scores without ``monitor_train``), so output settings may
change between launches.

At resume a log is checked against the run's columns and cut back to its checkpoint
(``resume_log``): a torn last row (cut short by a kill or a full disk) is dropped with a warning;
a log of an older version without some of the columns gets them, empty; anything else (an empty
log of a run with a checkpoint, other columns, a malformed row or sweep count) is a
``RunFolderError`` naming the file and the line. Rows are kept as written, byte for byte.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Sequence

import pandas as pd

from jigsaws_tools.files import NotRegularFileError, read_regular

from .folder import RunFolderError, write_atomic


def append_csv_row(path: Path, row: dict, columns: Sequence[str] | None = None) -> None:
    """Append one row to a CSV log, writing the header ``columns`` (default: the row's keys)
    first when the file is new. A row key outside the header is a ``ValueError``; a column the
    row lacks is an empty cell."""
    path = Path(path)
    new = not path.exists()
    with open(path, "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(columns or row))
        if new:
            writer.writeheader()
        writer.writerow(row)


def resume_log(path: Path, last_sweep: int, columns: Sequence[str] | None = None) -> list[str]:
    """Make the log ``path`` fit a run resuming after ``last_sweep`` sweeps: drop its rows past
    that sweep and a torn last row, add ``columns`` it lacks (empty); returns warnings to show.

    Args:
        path: the log (nothing happens when it does not exist).
        last_sweep: the sweep count of the checkpoint the run continues from (0 = the start).
        columns: the run's columns, None = whatever the log's header says.

    Raises:
        RunFolderError: naming the file (and line) when the log cannot be repaired: empty while
            the run has a checkpoint, a header of other columns, no ``sweep`` column, a malformed
            row before the last.
    """
    path = Path(path)
    if not path.is_file():
        return []
    lines = _lines(path)
    warnings = []
    if lines and (not lines[-1].endswith("\n") or _fields(lines[-1]) is None
                  or (len(lines) > 1 and len(_fields(lines[-1])) != len(_fields(lines[0]) or []))):
        warnings.append(f"{path}: dropped its last line, cut short by an interrupted write "
                        f"({lines[-1].strip()[:60]!r})")
        lines = lines[:-1]
    if not lines:
        if last_sweep:
            raise RunFolderError(f"{path}: empty, though the run has a checkpoint after sweep "
                                 f"{last_sweep}: its rows up to there are lost; restart the run "
                                 "(e.g. --restart)")
        path.unlink()
        return warnings + [f"{path}: removed (empty); it is written again from the start"]
    header = _fields(lines[0])
    if header is None:
        raise RunFolderError(f"{path}: line 1: not a CSV header ({lines[0].strip()[:60]!r}); "
                             "restart the run (e.g. --restart)")
    kept = [lines[0]] + [line for number, line in enumerate(lines[1:], start=2)
                         if _sweep(path, number, header, line) <= last_sweep]
    if columns is not None and header != list(columns):
        kept = _widened(path, header, list(columns), kept)
        added = ", ".join(c for c in columns if c not in header)
        warnings.append(f"{path}: added the columns {added} (empty) of this version")
    if kept != lines or warnings:
        write_atomic(path, "".join(kept))
    return warnings


def read_log(path: Path) -> pd.DataFrame:
    """A CSV log as a table; one that cannot be parsed is a ``RunFolderError`` naming the file
    and pandas' reason (e.g. the line with too many fields)."""
    try:
        return pd.read_csv(io.BytesIO(read_regular(path)))
    except (OSError, UnicodeDecodeError, ValueError) as error:    # ParserError, EmptyDataError
        reason = str(error).strip().splitlines()[0] if str(error).strip() else "empty"
        raise RunFolderError(f"{path}: unreadable CSV log ({reason})") from None


def _lines(path: Path) -> list[str]:
    try:
        return read_regular(path).decode("utf-8").splitlines(keepends=True)
    except (OSError, UnicodeDecodeError, NotRegularFileError) as error:
        raise RunFolderError(f"{path}: unreadable CSV log ({error})") from None


def _fields(line: str) -> list[str] | None:
    """The cells of one CSV line, None when it is not one (e.g. NUL bytes of a torn write)."""
    try:
        return next(csv.reader([line]), [])
    except csv.Error:
        return None


def _sweep(path: Path, number: int, header: list[str], line: str) -> int:
    """The ``sweep`` cell of line ``number`` (1-based) as an integer."""
    if "sweep" not in header:
        raise RunFolderError(f"{path}: line 1: no 'sweep' column (columns: {', '.join(header)})")
    fields = _fields(line)
    if fields is None or len(fields) != len(header):
        raise RunFolderError(f"{path}: line {number}: {len(fields or [])} fields where the "
                             f"header has {len(header)} ({line.strip()[:60]!r})")
    value = fields[header.index("sweep")]
    try:
        return int(value)
    except ValueError:
        raise RunFolderError(f"{path}: line {number}: sweep is not a sweep count "
                             f"(value: {value!r})") from None


def _widened(path: Path, header: list[str], columns: list[str], lines: list[str]) -> list[str]:
    """``lines`` rewritten under ``columns``, when ``header`` is ``columns`` less some (a log of
    an older version); a ``RunFolderError`` naming the file otherwise."""
    foreign = [c for c in header if c not in columns]
    if foreign or [c for c in columns if c in header] != header:
        raise RunFolderError(
            f"{path}: its columns are not this run's: "
            + (f"unknown column {foreign[0]!r}" if foreign else "another column order")
            + f" (expected {', '.join(columns)}); restart the run (e.g. --restart)")
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=columns)
    writer.writeheader()
    for line in lines[1:]:
        writer.writerow(dict(zip(header, _fields(line))))
    return out.getvalue().splitlines(keepends=True)

"""A grid's scores archive: its evidence, small enough to commit and carried from machine to machine.

An archive is itself a grid folder: the grid's record (``grid.json``) and, for every finished
run, the files that say what the run was and what it scored: ``config.json`` (its settings and
settings hash), ``metrics.json``, ``finished.json``, ``timing.json`` and its top-level logs
(``history.csv``, ``gradnorm.csv``). It leaves out what is heavy or holds the data's values:
checkpoints (the weights), ``eval/`` (per-trial predictions, which carry the release's labels),
``train.log`` and lock files. So

- ``multitask-tables ARCHIVE`` tabulates it like the grid (the example-trial figures need
  predictions and are left out, saying so);
- a grid continues from it on another machine: ``cp -r ARCHIVE runs/grid``, then the same
  ``multitask-grid --out runs/grid``; its finished runs count as finished, and every launch still
  checks each run's ``config.json`` against the spec (``grid_record.prepare_grid``), so an
  archived run of other settings is never taken for one of the spec's.

``archive.json`` marks a folder as an archive (what was archived from where, and when); only such a
folder, or a new or empty one, is (re)written.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path

from rnn_seg.provenance import now
from rnn_seg.rundir import CONFIG, FINISHED, RunFolderError, is_finished, write_json

from .grid_folder import GRID_RECORD, read_record

ARCHIVE_RECORD = "archive.json"
#: A finished run's files an archive keeps, besides its top-level ``*.csv`` logs.
RUN_FILES = (CONFIG, "metrics.json", FINISHED, "timing.json")


def archive_grid(grid_dir: Path | str, dest: Path | str) -> tuple[int, int]:
    """Write the scores archive of ``grid_dir`` to ``dest``, replacing an earlier archive there.

    The new archive is written beside ``dest`` and put in its place at the end: an interrupted
    call leaves the earlier archive as it was.

    Args:
        grid_dir: a grid folder (``multitask-grid --out``) with its ``grid.json``.
        dest: a new or empty folder, or an archive (``archive.json``) to replace.

    Returns:
        ``(finished runs archived, runs the grid records)``.

    Raises:
        RunFolderError: ``grid_dir`` has no grid record, or ``dest`` holds something else.
    """
    source, dest = Path(grid_dir), Path(dest)
    record = read_record(source)
    if record is None:
        raise RunFolderError(f"{source}: no {GRID_RECORD}: not a grid folder to archive")
    _check_destination(dest)
    finished = [run for run in record["runs"] if is_finished(source / run)]
    staging = dest.parent / f".{dest.name}.archiving"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    shutil.copy2(source / GRID_RECORD, staging / GRID_RECORD)
    for run in finished:
        _copy_run(source / run, staging / run)
    write_json(staging / ARCHIVE_RECORD, {"source": str(source.resolve()), "archived": now(),
                                          "runs_finished": len(finished),
                                          "runs_recorded": len(record["runs"]),
                                          "run_files": [*RUN_FILES, "*.csv"]})
    _replace(staging, dest)
    return len(finished), len(record["runs"])


def _check_destination(dest: Path) -> None:
    """``dest`` may be written: absent, an empty folder, or an earlier archive."""
    if dest.exists() and not dest.is_dir():
        raise RunFolderError(f"{dest}: not a folder; archive a grid into a folder")
    if dest.is_dir() and any(dest.iterdir()) and not (dest / ARCHIVE_RECORD).is_file():
        raise RunFolderError(f"{dest}: not empty and not a scores archive (no {ARCHIVE_RECORD}); "
                             "nothing written. Archive into a new folder.")


def _copy_run(run_dir: Path, to: Path) -> None:
    """The archived files of one finished run."""
    to.mkdir(parents=True)
    for name in RUN_FILES:
        if (run_dir / name).is_file():
            shutil.copy2(run_dir / name, to / name)
    for log in sorted(run_dir.glob("*.csv")):
        shutil.copy2(log, to / log.name)


def _replace(staging: Path, dest: Path) -> None:
    """Put the finished archive ``staging`` in the place of ``dest`` (an old archive, if any,
    is removed only once the new one is complete)."""
    old = dest.parent / f".{dest.name}.replaced"
    shutil.rmtree(old, ignore_errors=True)
    if dest.exists():
        os.replace(dest, old)
    os.replace(staging, dest)
    shutil.rmtree(old, ignore_errors=True)

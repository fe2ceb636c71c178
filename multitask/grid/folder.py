"""A grid folder's record, ``grid.json``: its file name and its reader, without TensorFlow.

``record.prepare_grid`` writes the record when a grid is launched (the spec, the path of
every run under ``runs/``, provenance); ``multitask-tables`` (``multitask.evidence.collect``)
reads its run list to tell missing runs and stray folders apart. Both go through this module.
"""
from __future__ import annotations

from pathlib import Path, PurePosixPath

from rnn_seg.runs.folder import RunFolderError, read_json
from rnn_seg.runs.outputs import GRID_RECORD  # noqa: F401 (re-exported)


def read_record(grid_dir: Path | str) -> dict | None:
    """The parsed ``grid.json`` of the grid in ``grid_dir``, None when there is none.

    Raises ``RunFolderError`` naming the file when it is not valid JSON or holds no ``runs``
    list of run paths (``runs/...`` strings, none leading outside ``runs/``).
    """
    path = Path(grid_dir) / GRID_RECORD
    if not path.is_file():
        return None
    record = read_json(path)
    runs = record.get("runs") if isinstance(record, dict) else None
    if not isinstance(runs, list) or not all(isinstance(run, str) for run in runs):
        raise RunFolderError(f"{path}: not a grid record: no 'runs' list of run folders "
                             f"(value: {str(runs)[:80]!r})")
    outside = next((run for run in runs if not _under_runs(run)), None)
    if outside is not None:
        raise RunFolderError(f"{path}: runs: {outside!r} is not a folder under runs/ of the "
                             "grid (a relative path without '..')")
    return record


def _under_runs(run: str) -> bool:
    """Whether ``run`` names a folder below the grid's ``runs/`` (so that nothing read or
    written for it lies outside the grid, or outside an archive of it)."""
    parts = PurePosixPath(run).parts
    return len(parts) > 1 and parts[0] == "runs" and ".." not in parts


def record_runs(grid_dir: Path | str) -> list[str] | None:
    """The run paths (``runs/...``, relative to ``grid_dir``) its record lists, None without
    a record."""
    record = read_record(grid_dir)
    return None if record is None else record["runs"]

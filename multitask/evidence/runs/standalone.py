"""Runs trained one by one (``multitask-train``, ``baseline-train``), tabulated without a grid.

A folder without ``grid.json`` that is a run folder, or holds run folders at any depth, gets
what a grid's runs get where no spec is needed: one row per run (``runs.csv``, with the run's
folder), the mean over seeds per fold and over folds per configuration. A grid knows each run's
configuration, seed and held-out user from the run's place; here they come from the run's
``config.json`` (a ``baseline-train`` run is model A with fixed weights). The paper's tables and
the claims pair configurations over the folds and seeds a grid spec guarantees, so they are left
to a grid (``multitask-grid``).

Problems are reported as a grid's are (``collect.run_rows``): a run not finished or unreadable,
a grid folder among the runs (tabulate it on its own), two runs of the same settings, seed and
fold (which would both count as that fold's run; with ``--allow-incomplete`` the first in path
order is tabulated and each other one is named as left out).
"""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import pandas as pd

from rnn_seg.runs.outputs import GRID_RECORD, folder_kind, folders_below

from .collect import KEY_COLUMNS, LEFT_OUT, IncompleteEvidence, finished_record, run_metrics
from .pooling import pool, record_key

#: The column of ``standalone_rows``' table naming each run's folder (relative to the folder
#: tabulated; ``.`` when it is the run).
RUN_COLUMN = "run"


def is_run_collection(folder: Path) -> bool:
    """Whether ``folder`` is tabulated as runs trained one by one: no ``grid.json``, and a run
    folder itself or a folder holding one."""
    folder = Path(folder)
    if (folder / GRID_RECORD).is_file() or not folder.is_dir():
        return False
    return folder_kind(folder) == "run folder" or any(
        kind == "run folder" for _, kind in folders_below(folder))


def standalone_rows(folder: Path, allow_incomplete: bool = False,
                    seeds: tuple[int, ...] | None = None) -> tuple[pd.DataFrame, list[str]]:
    """One row per usable run below ``folder`` (``RUN_COLUMN``, the key columns, the metrics),
    and the problems found: ``IncompleteEvidence`` naming them unless ``allow_incomplete``.

    Args:
        folder: a run folder, or a folder holding run folders.
        allow_incomplete: return the usable runs and the problems instead of refusing.
        seeds: only the runs of these seeds (None: every run).
    """
    folder = Path(folder)
    found = ([(folder, "run folder")] if folder_kind(folder) == "run folder"
             else list(folders_below(folder)))
    problems = [f"{path} is a grid folder: tabulate it on its own (multitask-tables paper {path})"
                for path, kind in found if kind == "grid folder"]
    rows, records = [], {}
    for run_dir, _ in (item for item in found if item[1] == "run folder"):
        record = finished_record(run_dir, problems)
        if record is None or (seeds is not None and record_key(record).seed not in seeds):
            continue
        metrics = run_metrics(run_dir, record, problems)
        if metrics is not None:
            name = run_dir.relative_to(folder).as_posix()
            rows.append({RUN_COLUMN: name, **asdict(record_key(record)), **metrics})
            records[Path(name)] = record
    pool(records, folder)
    rows = _without_duplicates(folder, rows, problems)
    if problems and not allow_incomplete:
        raise IncompleteEvidence(f"{folder}: incomplete evidence, no tables written:\n  "
                                 + "\n  ".join(problems)
                                 + "\nFinish or remove those runs, or pass --allow-incomplete "
                                   "to tabulate the others.")
    if not rows:
        raise IncompleteEvidence(f"{folder}: no finished run to tabulate")
    return pd.DataFrame(rows), problems


def _without_duplicates(folder: Path, rows: list[dict], problems: list[str]) -> list[dict]:
    """``rows`` less the second and further runs of one configuration, seed and fold (each would
    count as that fold's run), each named in a problem with the run kept; after ``pool``, such
    runs agree on every setting: they are two runs of one fold."""
    kept: dict[tuple, dict] = {}
    for row in rows:
        key = tuple(row[column] for column in KEY_COLUMNS)
        if key in kept:
            problems.append(f"{LEFT_OUT} {folder / row[RUN_COLUMN]}: a second run of the same "
                            f"settings, seed and fold as {folder / kept[key][RUN_COLUMN]} "
                            "(tabulated)")
        else:
            kept[key] = row
    return list(kept.values())

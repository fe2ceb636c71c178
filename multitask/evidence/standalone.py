"""Runs trained one by one (``multitask-train``, ``baseline-train``), tabulated without a grid.

A folder without ``grid.json`` that is a run folder, or holds run folders at any depth, gets
what a grid's runs get where no spec is needed: one row per run (``runs.csv``, with the run's
folder), the mean over seeds per fold and over folds per configuration. A grid knows each run's
configuration, seed and held-out user from the run's place; here they come from the run's
``config.json`` (a ``baseline-train`` run is model A with fixed weights). The paper's tables and
the claims pair configurations over the folds and seeds a grid spec guarantees, so they are left
to a grid (``multitask-grid``).

Problems are reported as a grid's are (``collect.run_rows``): a run not finished or unreadable,
two runs of one configuration, seed and fold (which would both count as that fold's run), a grid
folder among the runs (tabulate it on its own).
"""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import CONFIG, RunFolderError, read_json
from rnn_seg.runs.outputs import GRID_RECORD, folder_kind, folders_below

from ..grid.spec import RunKey
from .collect import IncompleteEvidence, run_metrics

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


def key_from_config(run_dir: Path) -> RunKey:
    """The configuration, seed and held-out user a run's ``config.json`` records.

    Raises:
        RunFolderError: naming the file and the missing or malformed field.
    """
    path = Path(run_dir) / CONFIG
    saved = read_json(path)
    try:
        run = saved["run"]
        fold = run["test_user"]
        if not isinstance(fold, str):
            raise ValueError(f"test_user {fold!r}: no held-out user to score")
        return RunKey(annotations=run["data"]["annotations"],
                      direction="bidirectional" if run["encoder"]["bidirectional"] else "forward",
                      variant=saved.get("variant", "A"), weighting=saved.get("weighting", "fixed"),
                      seed=int(run["train"]["seed"]), fold=fold)
    except KeyError as error:
        raise RunFolderError(f"{path}: not a run's configuration (no {error.args[0]!r})") from None
    except (TypeError, ValueError) as error:
        raise RunFolderError(f"{path}: not a run's configuration ({error})") from None


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
    problems = [f"{path} is a grid folder: tabulate it on its own (multitask-tables {path})"
                for path, kind in found if kind == "grid folder"]
    rows, places = [], {}
    for run_dir, _ in (item for item in found if item[1] == "run folder"):
        try:
            key = key_from_config(run_dir)
        except RunFolderError as error:
            problems.append(f"unreadable configuration: {error}")
            continue
        if seeds is not None and key.seed not in seeds:
            continue
        if key in places:
            problems.append(f"two runs of {key.path()}: {places[key]} and {run_dir}")
            continue
        places[key] = run_dir
        metrics = run_metrics(run_dir, problems)
        if metrics is not None:
            rows.append({RUN_COLUMN: run_dir.relative_to(folder).as_posix(), **asdict(key),
                         **metrics})
    if problems and not allow_incomplete:
        raise IncompleteEvidence(f"{folder}: incomplete evidence, no tables written:\n  "
                                 + "\n  ".join(problems)
                                 + "\nFinish or remove those runs, or pass --allow-incomplete "
                                   "to tabulate the others.")
    if not rows:
        raise IncompleteEvidence(f"{folder}: no finished run to tabulate")
    return pd.DataFrame(rows), problems

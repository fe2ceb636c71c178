"""The run folders a grid's tables may use: each checked the way the grid checks it.

``multitask-grid`` checks every run folder's ``config.json`` against its spec before any work
(``multitask.grid.record``); ``multitask-tables`` reads the spec grid.json records and asks the
same check of every recorded folder (``record.recorded_mismatches``): the settings of the run the
spec puts at the folder's place (its variant, weighting, seed and fold included) against those the
folder records. A folder retrained by hand with other settings, or a run copied into another's
folder, is so never tabulated as the spec's. The data is not read: the fingerprint is the one
the folder records (the tables may be made where the data is not).
"""
from __future__ import annotations

import logging
from pathlib import Path

from jigsaws_tools.cli.common import import_tensorflow
from multitask.grid.folder import GRID_RECORD, read_record
from multitask.grid.spec import RunKey, spec_from_dict

log = logging.getLogger(__name__)

#: First words of the problem line of a run folder of other settings than the grid's.
OTHER_SETTINGS = "other settings than the grid's spec:"


def other_settings(root: Path, keys: dict[Path, RunKey]) -> dict[Path, str]:
    """``{run: what differs}`` for the run folders of ``keys`` (run path relative to ``root`` ->
    its key) whose ``config.json`` does not record the run grid.json's spec puts there; empty
    when grid.json records no spec (an older grid: nothing to check against) or when its spec's
    task definition file is not on this machine (a grid of the user's own task tabulated
    elsewhere: a warning says the check was skipped; each run's config.json still records the
    definition it trained with).

    Raises:
        ValueError: naming grid.json, when its spec cannot be read back.
    """
    record = read_record(root)
    if not record or not isinstance(record.get("spec"), dict):
        return {}
    task = record["spec"].get("task")
    if isinstance(task, str) and task.endswith(".toml") and not Path(task).is_file():
        log.warning("%s: the spec's task file %s is not here: the runs' settings are not checked "
                    "against the spec", Path(root) / GRID_RECORD, task)
        return {}
    spec = spec_from_dict(record["spec"], source=f"{Path(root) / GRID_RECORD}: spec")
    import_tensorflow()                          # quietly: the grid's check builds the runs'
    from multitask.grid.record import recorded_mismatches

    runs = {key: run for run, key in keys.items()}
    return {runs[key]: details
            for key, details in recorded_mismatches(Path(root), spec, list(runs)).items()}

"""The run folders a grid's tables may use: each checked the way the grid checks it.

``multitask-grid`` checks every run folder's ``config.json`` against its spec before any work
(``multitask.grid.record``); ``multitask-tables`` reads the spec grid.json records and asks the
same of every recorded folder (``other_settings``): the settings of the run the spec puts at the
folder's place (its variant, weighting, seed and fold included, ``models.run_record``) against
those the folder records. A folder retrained by hand with other settings, or a run copied into
another's folder, is so never tabulated as the spec's. Only recorded settings are read: the
fingerprint is the one the folder records, and neither the data (the tables may be made where the
data is not), nor a synthetic release, nor TensorFlow is needed.

A grid.json without a spec (written by hand, or by an early version) leaves nothing to check
against: a warning says so, and the runs are still checked against their own config.json, their
place and each other (``pooling``).
"""
from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from jigsaws_tools.errors import JigsawsError
from multitask.grid.folder import GRID_RECORD, read_record
from multitask.grid.spec import (GridSpec, RunKey, expand, fold_users, run_arguments,
                                 spec_from_dict)
from multitask.models.run_record import variant_record
from rnn_seg.runs.folder import CONFIG, RunFolderError, read_json
from rnn_seg.runs.settings import SettingsMismatchError, check_run_dir

log = logging.getLogger(__name__)

#: First words of the problem line of a run folder of other settings than the grid's.
OTHER_SETTINGS = "other settings than the grid's spec:"
#: What a record check expects of a fingerprint the run folder does not record.
NOT_RECORDED = "(not recorded)"


def other_settings(root: Path, keys: dict[Path, RunKey]) -> dict[Path, str]:
    """``{run: what differs}`` for the run folders of ``keys`` (run path relative to ``root`` ->
    its key) that are no run of grid.json's spec, or whose ``config.json`` does not record the
    run the spec puts there, or cannot be read; a folder without config.json is not checked (it holds no finished run). Empty when
    grid.json records no spec (an older grid: a warning says the runs are unchecked against one)
    or when its spec's task definition or recording format file is not on this machine (a grid
    of the user's own task or recordings tabulated elsewhere: a warning says the check was
    skipped; each run's config.json still records the definition and format it trained with).

    Raises:
        ValueError: naming grid.json, when its spec cannot be read back.
    """
    record = read_record(root)
    if not record:
        return {}
    if "spec" not in record:
        log.warning("%s records no spec (a grid of an early version): its runs are checked against "
                    "their own config.json and each other, unchecked against a spec",
                    Path(root) / GRID_RECORD)
        return {}
    for key in ("task", "format"):
        name = record["spec"].get(key)
        if isinstance(name, str) and name.endswith(".toml") and not Path(name).is_file():
            log.warning("%s: the spec's %s file %s is not here: the runs' settings are not "
                        "checked against the spec", Path(root) / GRID_RECORD, key, name)
            return {}
    spec = spec_from_dict(record["spec"], source=f"{Path(root) / GRID_RECORD}: spec")
    spec = replace(spec, data_dir=".")              # where the data is: not a setting
    planned = _planned(spec, keys)
    mismatched = {}
    for run, key in keys.items():
        details = (_mismatch(Path(root) / run, spec, key) if key in planned
                   else "no run of the grid's spec: its experiments, seeds and folds do not "
                        "hold this configuration, seed and fold")
        if details:
            mismatched[run] = details
    return mismatched


def _planned(spec: GridSpec, keys: dict[Path, RunKey]) -> set[RunKey]:
    """The runs of ``spec`` among the folds of ``keys`` (the data, and so the release's users,
    unknown here): its LOUO folds; for inner runs (``inner_validation``), every inner fold of
    ``keys`` whose outer fold is the spec's (which users follow it in the release is not
    checked). Which runs a spec holds does not depend on its ``fold_settings`` (checked against
    the release's users when the grid was launched), so they are not checked here."""
    spec = replace(spec, fold_settings=None)
    folds = tuple(sorted({key.fold for key in keys.values()}))
    if spec.inner_validation is None:
        return set(expand(spec, spec.test_users or folds))
    inner = tuple(fold for fold in folds if fold_users(fold)[1] and (
        not spec.test_users or fold_users(fold)[1][0] in spec.test_users))
    return set(expand(replace(spec, inner_validation=None, test_users=()), inner))


def _mismatch(run_dir: Path, spec: GridSpec, key: RunKey) -> str | None:
    """What differs between the run folder's config.json and the run ``spec`` puts at ``key``
    (the fingerprints as the folder records them); None when they agree or the folder holds no
    config.json."""
    path = run_dir / CONFIG
    if not path.is_file():
        return None
    try:
        saved = read_json(path)
        saved = saved if isinstance(saved, dict) else {}
        chosen = saved.get("selection")
        args = run_arguments(spec, key, (chosen.get("common_fingerprint") if isinstance(
            chosen, dict) else None) or NOT_RECORDED)
        check_run_dir(run_dir, variant_record(args["variant"], key.weighting, args["config"],
                                              spec.gradnorm, spec.heads,
                                              saved.get("data_fingerprint") or NOT_RECORDED,
                                              args["selection"]))
    except SettingsMismatchError as error:
        return error.details
    except (RunFolderError, ValueError, JigsawsError) as error:   # config.json, the task file
        return str(error).splitlines()[0]
    return None

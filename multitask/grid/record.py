"""A grid folder's own record, ``grid.json``, and the check of its run folders against a spec.

``grid.json`` holds the spec (budget, data, folds, seeds, experiments), the path of every run and
the provenance of the launch that wrote it. It is written once and never rewritten with another
spec: launching a spec whose values or runs differ stops before any work, naming each difference,
unless the launch restarts (``--restart``); the data's folder may change (``LOCATION_KEYS``), so
may how the runs compute and what figures they draw (``EXECUTION_KEYS``: the LSTM's loops,
``plots``), and so may the order of the spec's experiments and of the recorded runs (the order
they run in, not what they are). Run paths do not encode the budget; the record does, and every
run's config.json records that run's settings (``rnn_seg.runs.settings``): a spec with another
width or length never finds runs "already finished".

``multitask-tables`` reads the record's run list to tell missing runs and stray folders, and
checks each run folder as the grid does (``multitask.evidence.runs.checks``, without the data or
TensorFlow); the record's file name and reader are ``folder``'s, which imports no TensorFlow.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

from rnn_seg.runs.lock import hold_folder
from rnn_seg.runs.provenance import now, provenance
from rnn_seg.runs.folder import clear_run_dir, write_json
from rnn_seg.runs.settings import SettingsMismatchError, check_run_dir, differences

from ..models.run_record import variant_configs
from .folder import GRID_RECORD, comparable_spec, read_record, record_runs
from .spec import GridSpec, RunKey, run_arguments, spec_payload

SHOWN = 5           # mismatching runs named in full in an error


def plan_launch(out: Path, spec: GridSpec, keys: list[RunKey], restart: bool = False
                ) -> tuple[list[RunKey], dict]:
    """What launching ``spec`` over ``out`` does to its record and run folders, decided without
    writing anything (``prepare_grid`` then does it; ``multitask-grid --dry-run`` says it):
    the runs whose folders hold other settings, cleared and trained afresh (with ``restart``),
    and the grid record the folder then holds (``spec``, ``runs``).

    Raises:
        SettingsMismatchError: without ``restart``, ``out``'s record is of another spec, or run
            folders hold runs of other settings; naming every difference.
    """
    out = Path(out)
    runs = [str(key.path()) for key in keys]
    kept = (out / GRID_RECORD).is_file() and not restart
    if kept:
        _check_record(out, spec, runs)
    mismatched = _mismatched_runs(out, spec, keys)
    if mismatched and not restart:
        shown = "\n".join(details for _, details in mismatched[:SHOWN])
        more = f"\n... and {len(mismatched) - SHOWN} more" if len(mismatched) > SHOWN else ""
        raise SettingsMismatchError(
            f"{out}: {len(mismatched)} run folder(s) hold runs with other settings:\n{shown}{more}",
            "Use another --out, or --restart to train those runs afresh.")
    record = read_record(out) if kept else {"spec": spec_payload(spec), "runs": runs}
    return [key for key, _ in mismatched], record


def prepare_grid(out: Path, spec: GridSpec, keys: list[RunKey], restart: bool = False,
                 log: Callable[[str], None] = print) -> None:
    """Check (or with ``restart``, replace) ``out``'s record and run folders for ``spec``'s runs,
    before any work (``plan_launch``); raise ``SettingsMismatchError`` naming every difference.

    Args:
        out: the grid's folder.
        spec: the grid's budget, data and experiments.
        keys: the grid's runs (``spec.expand``).
        restart: make ``spec`` the grid's record and clear run folders of other settings.
        log: where the notes of a restart go.
    """
    out = Path(out)
    cleared, record = plan_launch(out, spec, keys, restart)
    for key in cleared:
        with hold_folder(out / key.path()):
            clear_run_dir(out / key.path())
    if cleared:
        log(f"[grid] restart: cleared {len(cleared)} run folder(s) of other settings")
    if restart or not (out / GRID_RECORD).is_file():
        old = set(record_runs(out) or ())
        write_json(out / GRID_RECORD, {**record, "provenance": {**provenance(), "started": now()}})
        dropped = old - set(record["runs"])
        if dropped:
            log(f"[grid] {len(dropped)} run folder(s) of the previous record are not runs of this "
                "spec; multitask-tables reports them until they are removed")


def _check_record(out: Path, spec: GridSpec, runs: list[str]) -> None:
    recorded = read_record(out)
    changed = differences({"spec": comparable_spec(recorded.get("spec") or {})},
                          {"spec": comparable_spec(spec_payload(spec))})
    old_runs = recorded["runs"]
    if set(old_runs) != set(runs):                  # the order of the runs is not the grid's
        changed.append(f"runs: {len(old_runs)} -> {len(runs)} ({len(set(runs) - set(old_runs))} "
                       f"new, {len(set(old_runs) - set(runs))} no longer in the grid)")
    if changed:
        raise SettingsMismatchError(
            f"{out / GRID_RECORD} records another grid (recorded -> requested):\n  "
            + "\n  ".join(changed),
            "Use another --out, or --restart to make this spec the grid's (runs of other "
            "settings are trained afresh; finished runs of the same settings are kept).")


def _mismatched_runs(out: Path, spec: GridSpec, keys: list[RunKey]
                     ) -> list[tuple[RunKey, str]]:
    """``(key, message)`` of every run folder holding a run of other settings than ``spec``'s."""
    fingerprints: dict = {}       # one data fingerprint per data configuration
    mismatched = []
    for key in keys:
        args = run_arguments(spec, key)
        data = args["config"].data
        configs = variant_configs(**args, fingerprint=fingerprints.get(data))
        fingerprints[data] = configs["data_fingerprint"]
        details = _mismatch(out / key.path(), configs)
        if details:
            mismatched.append((key, details))
    return mismatched


def _mismatch(run_dir: Path, configs: dict) -> str | None:
    """``check_run_dir``'s details for ``run_dir`` against ``configs``; None when it matches."""
    try:
        check_run_dir(run_dir, configs)
    except SettingsMismatchError as error:
        return error.details
    return None

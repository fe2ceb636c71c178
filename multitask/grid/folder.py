"""A grid folder's record, ``grid.json``: its file name and its reader, without TensorFlow.

``record.prepare_grid`` writes the record when a grid is launched (the spec, the path of
every run under ``runs/``, provenance); ``multitask-tables`` (``multitask.evidence.runs.collect``)
reads its run list to tell missing runs and stray folders apart. Both go through this module.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from baseline.config import DIRECTIONS
from jigsaws_tools.annotations import ANNOTATION_VERSIONS
from rnn_seg.runs.folder import RunFolderError, read_json
from rnn_seg.runs.outputs import GRID_RECORD  # noqa: F401 (re-exported)

from ..models.config import WEIGHTINGS
from ..models.variants import VARIANTS
from .spec import RunKey
#: Spec keys saying where the data is, not what it holds: not compared with grid.json's, since
#: every run folder's check compares the data fingerprint (a grid may resume on moved data).
LOCATION_KEYS = ("data_dir",)
#: Spec keys that say how the runs compute or what they write besides their scores, not what they
#: compute: a grid may resume with other values.
EXECUTION_KEYS = ("loops", "plots")
#: Spec keys added after grid.json was first written -> the value their absence meant.
IMPLIED_BY_OLDER_RECORDS = {"schedule_factors": {}, "encoder": "lstm", "resample_factor": None,
                            "kernel": None, "format": "jigsaws", "lowpass": None,
                            "normalise": None, "feature_set": None, "padding": None,
                            "head_init": None, "inner_validation": None, "fold_settings": None}


def read_record(grid_dir: Path | str) -> dict | None:
    """The parsed ``grid.json`` of the grid in ``grid_dir``, None when there is none.

    Raises ``RunFolderError`` naming the file when it is not valid JSON or holds no ``runs``
    list of run paths (``runs/...`` strings, none leading outside ``runs/``), naming the entry
    when a path is not a run's place (``run_key``) or is listed twice, and naming ``spec`` when
    it is there but not a table of settings.
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
    seen = set()
    for run in runs:
        try:
            run_key(run)
        except ValueError as error:
            raise RunFolderError(f"{path}: runs: {error}") from None
        if run in seen:
            raise RunFolderError(f"{path}: runs: {run!r} is listed twice")
        seen.add(run)
    if "spec" in record and not isinstance(record["spec"], dict):
        raise RunFolderError(f"{path}: spec: not a grid spec (value: {str(record['spec'])[:60]!r})")
    return record


def run_key(run: str) -> RunKey:
    """The run a grid puts at ``run``,
    ``runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>`` (``RunKey.path``);
    a ``ValueError`` naming ``run`` and what is wrong with it."""
    parts = PurePosixPath(run).parts
    shape = "runs/<annotations>/<direction>/<variant>-<weighting>/seed<k>/<fold>"
    if len(parts) != 6 or parts[0] != "runs":
        raise ValueError(f"{run!r} is not a run's place, {shape}")
    _, annotations, direction, config, seed, fold = parts
    variant, _, weighting = config.rpartition("-")
    for value, allowed, what in ((annotations, ANNOTATION_VERSIONS, "annotation version"),
                                 (direction, DIRECTIONS, "direction"),
                                 (variant, VARIANTS, "variant"),
                                 (weighting, WEIGHTINGS, "weighting")):
        if value not in allowed:
            raise ValueError(f"{run!r}: {value!r} is no {what} ({', '.join(allowed)}), so this "
                             f"is not a run's place, {shape}")
    if not seed.startswith("seed") or not seed[4:].isdigit() or not seed[4:].isascii():
        raise ValueError(f"{run!r}: {seed!r} is not seed<k>, so this is not a run's place, "
                         f"{shape}")
    key = RunKey(annotations, direction, variant, weighting, int(seed[4:]), fold)
    if key.path().as_posix() != run:
        raise ValueError(f"{run!r} is not written as a run's place is, "
                         f"{key.path().as_posix()!r}")
    return key


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


def comparable_spec(spec: dict) -> dict:
    """A grid.json spec as two grids of the same runs record it alike: the keys its (older)
    writer did not know set to what that writer implied, less its ``LOCATION_KEYS`` and
    ``EXECUTION_KEYS``, its experiments in a fixed order (where the data lies, how the runs
    compute, the figures they draw and the order the experiments run in are not what the
    grid's runs are)."""
    kept = {key: value for key, value in {**IMPLIED_BY_OLDER_RECORDS, **spec}.items()
            if key not in LOCATION_KEYS + EXECUTION_KEYS}
    if isinstance(kept.get("experiments"), list):
        kept["experiments"] = sorted(kept["experiments"],
                                     key=lambda experiment: json.dumps(experiment, sort_keys=True))
    return kept



@dataclass(frozen=True)
class GridRelease:
    """Where a grid's data lies and what it holds: the release ``folder``, its ``task`` and
    recording ``format`` (names or definition files, as the spec records them), the test users
    (``folds``) and ``annotations`` versions of the grid's runs, sorted."""

    folder: Path
    task: str
    format: str | None
    folds: list[str]
    annotations: list[str]


def grid_release(record: dict, data_dir: Path | str | None = None) -> GridRelease:
    """The release of the grid whose record is ``record``: ``data_dir`` when given, else the
    folder its spec records; its spec's task (Suturing when it records none) and recording
    format (None when it records none: the release's).

    Raises:
        OSError: no folder is given and the spec records none, or names the synthetic release
            (which nothing reading a grid writes in its place).
    """
    spec = record.get("spec") or {}
    recorded = spec.get("data_dir")
    if data_dir is None and (not recorded or recorded == "synthetic"):
        raise OSError(f"the grid records no release folder ({recorded or 'none'})")
    keys = [run_key(run) for run in record.get("runs", [])]
    return GridRelease(Path(data_dir if data_dir is not None else recorded),
                       spec.get("task") or "Suturing", spec.get("format"),
                       sorted({key.fold for key in keys}),
                       sorted({key.annotations for key in keys}))

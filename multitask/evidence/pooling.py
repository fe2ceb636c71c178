"""The one rule for what a table may pool: which runs are runs of one configuration.

A configuration is every setting that changes a result: all that a run's ``config.json`` records
(``rnn_seg.runs.settings``: variant and weighting, GradNorm's alpha and rates, the progress
head's loss, the encoder's width, layers, direction and precision, the schedule and evaluation
points, the batch size, and the data: task definition, annotations, features, preprocessing,
recording format and the fingerprint of the release's files) except the seed and the held-out
user, which tables pool over (``POOLED``), and what only says what a run writes or where its data
lay (the output fields). Every table reads its runs through ``pool``: a grid's tables, claims
and figures, ``--compare``, the width study and the tables of runs trained one by one, whether
or not a grid's spec vouches for the runs.

* A run is placed by what its config.json records (``record_key``): in a grid, a folder whose
  config.json records another configuration, seed or fold than its place is named
  (``misplaced``) and never tabulated as the folder's;
* the runs a table puts in one row (one annotation version, direction, variant and weighting)
  must agree on every other setting, or the table is refused with the list of the settings
  that differ and the runs of each value (``MixedSettings``), with or without
  ``--allow-incomplete``: there is no row to put them in. Runs that differ so are never taken for
  two runs of one fold (duplicates).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from rnn_seg.runs.settings import settings_of

from ..grid.spec import RunKey
from ..models.run_record import RunRecord

#: The settings the runs of one configuration differ in: a table pools over them.
POOLED = ("run.train.seed", "run.test_user")
#: Runs named per value in a difference, the rest counted.
SHOWN = 3


class MixedSettings(ValueError):
    """Runs a table would put in one row differ in settings that change results."""


def record_key(record: RunRecord) -> RunKey:
    """The configuration, seed and held-out user the run's config.json records."""
    config = record.config
    return RunKey(annotations=config.data.annotations,
                  direction="bidirectional" if config.encoder.bidirectional else "forward",
                  variant=record.variant, weighting=record.weighting, seed=config.train.seed,
                  fold=config.test_user)


def configuration(record: RunRecord) -> dict[str, Any]:
    """The settings that identify the run's configuration (``{"run.encoder.hidden": 128, ...}``):
    every setting of its record but ``POOLED``."""
    return {k: v for k, v in settings_of(record.configs()).items() if k not in POOLED}


def misplaced(record: RunRecord, place: RunKey) -> str | None:
    """What the run's config.json records that its place in a grid (``place``) does not say,
    e.g. ``variant: APc, not A``; None when they agree."""
    recorded = record_key(record)
    differing = [f"{name}: {getattr(recorded, name)}, not {getattr(place, name)}"
                 for name in RunKey.__dataclass_fields__
                 if getattr(recorded, name) != getattr(place, name)]
    return "; ".join(differing) or None


def pool(records: dict[Path, RunRecord], where: Path | str, varying: tuple[str, ...] = ()
         ) -> None:
    """Check that the runs of each row agree on every setting of ``configuration``.

    Args:
        records: run folder (as it is to be named) -> its record; every run a table holds.
        where: the folder of the runs, named first in the error.
        varying: settings the table states per run and so may differ, e.g. the width study's
            width and schedule (none for a table whose rows are configurations).

    Raises:
        MixedSettings: naming, per row whose runs differ, each setting that differs and the runs
            of each of its values.
    """
    rows: dict[tuple, dict[Path, dict]] = {}
    for run, record in records.items():
        key = record_key(record)
        label = (key.annotations, key.direction, key.config_name)
        rows.setdefault(label, {})[run] = {name: value for name, value
                                           in configuration(record).items()
                                           if name not in varying}
    mixed = [f"{'/'.join(label)}: {_differences(runs)}" for label, runs in sorted(rows.items())
             if len({repr(sorted(s.items())) for s in runs.values()}) > 1]
    if mixed:
        raise MixedSettings(
            f"{where}: runs of one configuration differ in settings that change results, so no table "
            "pools them (" + "; ".join(mixed) + "). Tabulate runs of other settings from a "
            "folder of their own.")


def _differences(runs: dict[Path, dict]) -> str:
    """``run.encoder.hidden 8 (a, b) / 16 (c)``, a clause per setting that differs among
    ``runs``."""
    names = sorted({name for settings in runs.values() for name in settings})
    clauses = []
    for name in names:
        by_value: dict[str, list[str]] = {}
        for run, settings in runs.items():
            by_value.setdefault(_shown(settings.get(name, "(not recorded)")), []).append(str(run))
        if len(by_value) > 1:
            clauses.append(f"{name} " + " / ".join(f"{value} ({_runs(folders)})"
                                                   for value, folders in by_value.items()))
    return ", ".join(clauses)


def _shown(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _runs(folders: list[str]) -> str:
    shown = ", ".join(folders[:SHOWN])
    return shown + (f" and {len(folders) - SHOWN} more" if len(folders) > SHOWN else "")

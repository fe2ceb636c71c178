"""The one rule for what a table may pool: which runs are runs of one configuration.

A configuration is every setting that changes a result: all that a run's ``config.json`` records
(``rnn_seg.runs.settings``: variant and weighting, GradNorm's alpha and rates, the progress
head's loss, the encoder's width, layers, direction and precision, the schedule and evaluation
points, the batch size, and the data: task definition, annotations, features, preprocessing,
recording format and the fingerprint of the release's files) except the seed and the held-out
user, which tables pool over (``POOLED``), and what only says what a run writes or where its data
lay (the output fields). Every table reads its runs through ``pool``: a grid's tables, claims
and figures, ``multitask-tables pair``, the width study and the tables of runs trained one by
one, whether or not a grid's spec vouches for the runs.

* A run is placed by what its config.json records (``record_key``): in a grid, a folder whose
  config.json records another configuration, seed or fold than its place is named
  (``misplaced``) and never tabulated as the folder's;
* the runs a table puts in one row (one annotation version, direction, variant and weighting)
  must agree on every other setting, or the table is refused with the list of the settings
  that differ and the runs of each value (``MixedSettings``), with or without
  ``--allow-incomplete``: there is no row to put them in. Runs that differ so are never taken for
  two runs of one fold (duplicates). Runs of several encoders (the LSTM, ED-TCN, MS-TCN, a
  user's own: each import path and source hash one encoder, ``encoder_identity``) are refused
  in one table even in different rows: its rows would compare them as one model's
  configurations;
* runs of different architectures (``architecture``: the LSTM at each width, ED-TCN, MS-TCN, a
  user's encoder by its import path)
  are kept apart: a table of several architectures reads one grid per architecture, each
  pooled by the rule above, tags each run with its grid's architecture and pairs nothing across
  them (``apart``); two grids of one architecture, a grid of several, or grids on other data are
  refused (``MixedArchitectures``);
* an inner run (a validation user's, inside an outer fold's training users: its config.json
  records ``held_out_users``; ``multitask.grid.spec``, ``inner_validation``) is pooled only by a
  table made for inner runs (``INNER_SETTING`` among ``pool``'s ``varying``), and never with
  outer runs: the folds of the paper's tables are test users, not validation users;
* the runs of a nested selection (settings chosen per outer fold on its training users: their
  config.json records the selection, ``SelectionConfig``; ``multitask.grid.spec``,
  ``fold_settings``) are one configuration, the procedure: they may differ across folds in the
  settings it selects, and in the data fingerprint where those change the data, and must agree
  on everything else and on the selection itself; each run must hold the settings the
  selection gives its outer fold (``selected_mismatch``), and runs on the same data (its
  selection's common setting counted as data too) one data fingerprint
  (``one_fingerprint_per_data``). Where a table compares data, a run of a selection counts
  with its data at the selection's common setting (``_data``).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from jigsaws_tools.dataset import DataConfig
from rnn_seg.encoders.config import ENCODERS
from rnn_seg.encoders.import_path import is_import_path
from rnn_seg.runs.settings import settings_of

from ...grid.spec import RunKey, inner_fold
from ...models.run_record import RunRecord

#: The settings the runs of one configuration differ in: a table pools over them.
POOLED = ("run.train.seed", "run.test_user")
#: The setting that marks an inner run (``RunConfig.held_out_users``: its outer fold's user).
INNER_SETTING = "run.held_out_users"
#: Runs named per value in a difference, the rest counted.
SHOWN = 3
#: What ``configuration`` holds for a setting that a run's nested selection chooses per fold.
CHOSEN = "(chosen per fold)"


class MixedSettings(ValueError):
    """Runs a table would put in one row differ in settings that change results."""


class MixedArchitectures(ValueError):
    """Grids a table of several architectures reads are not one architecture each, on one
    data."""


def architecture(record: RunRecord) -> str:
    """The run's architecture: ``lstm-<units per direction>`` (e.g. ``lstm-128``), ``ed-tcn``,
    ``ms-tcn`` (``rnn_seg.encoders``), or a user's encoder's import path
    (``package.module:name``)."""
    encoder = record.config.encoder
    if encoder.kind == "custom":
        return encoder.path
    return f"lstm-{encoder.hidden}" if encoder.kind == "lstm" else encoder.kind


def encoder_identity(record: RunRecord) -> str:
    """What one encoder is: its kind, or for a user's encoder its import path and source hash
    (``package.module:name (sha256 0123456789ab)``)."""
    encoder = record.config.encoder
    return encoder.describe() if encoder.kind == "custom" else encoder.kind


def architecture_name(key: str) -> str:
    """How tables name an architecture: ``LSTM-128``, ``ED-TCN``, ``MS-TCN``, a user's encoder
    by its import path as given."""
    return key if is_import_path(key) else key.upper()


def is_architecture(text: str) -> bool:
    """Whether ``text`` is what ``architecture`` returns for some run (``lstm-1024``,
    ``package.module:name``)."""
    if is_import_path(text):
        return True
    kind, _, width = text.partition("-") if text.startswith("lstm-") else (text, "", "")
    return kind in ENCODERS and (kind != "lstm" or width.isdigit()) and text != "lstm"


def apart(grids: dict[Path, dict[Path, RunRecord]]) -> dict[Path, str]:
    """Check that each grid holds one architecture, no two grids the same one, and every grid the
    same data (every recorded data setting but where the data lay, and the data's fingerprint,
    per annotation version); the architecture of each.

    Args:
        grids: grid folder -> run folder -> its record; the runs each grid contributes (each
            grid already pooled by ``pool``).

    Raises:
        MixedArchitectures: one line naming the grids (and runs) at fault.
    """
    found: dict[Path, str] = {}
    for grid, records in grids.items():
        kinds: dict[str, list[Path]] = {}
        for run, record in records.items():
            kinds.setdefault(architecture(record), []).append(run)
        if len(kinds) > 1:
            raise MixedArchitectures(f"{grid}: runs of several architectures in one grid ("
                                     + " / ".join(f"{kind} ({_runs([str(r) for r in runs])})"
                                                  for kind, runs in sorted(kinds.items()))
                                     + "); one grid per architecture")
        if not kinds:
            raise MixedArchitectures(f"{grid}: no run to read its architecture from")
        found[grid] = next(iter(kinds))
    seen: dict[str, Path] = {}
    for grid, kind in found.items():
        if kind in seen:
            raise MixedArchitectures(f"{seen[kind]} and {grid} are both {kind} grids; give one "
                                     "grid per architecture (their runs are never pooled)")
        seen[kind] = grid
    seen_data: dict[str, tuple[Path, dict[str, Any]]] = {}    # annotations -> first grid's
    for grid, records in grids.items():
        for labels, settings in _data_by_annotations(records).items():
            first, known = seen_data.setdefault(labels, (grid, settings))
            differing = sorted(k for k in settings.keys() | known.keys()
                               if settings.get(k) != known.get(k))
            if differing:
                raise MixedArchitectures(f"{first} and {grid} differ in their data "
                                         f"({', '.join(differing)}; {labels} labels): "
                                         "architectures are compared on one data set only")
    return found


def _data_by_annotations(records: dict[Path, RunRecord]) -> dict[str, dict[str, Any]]:
    """Annotation version -> the data settings of the first of ``records`` with it (``_data``;
    the data fingerprint covers the labels, so it differs between versions)."""
    first: dict[str, RunRecord] = {}
    for record in records.values():
        first.setdefault(record.config.data.annotations, record)
    return {annotations: _data(record) for annotations, record in first.items()}


def _data(record: RunRecord) -> dict[str, Any]:
    """The run's data settings but where the data lay and its labels, and its data fingerprint;
    for a run of a nested selection, those at the selection's common setting
    (``SelectionConfig``)."""
    return {name: value for name, value in _run_data(record, record.selection is not None).items()
            if name != "run.data.annotations"}


def _run_data(record: RunRecord, common: bool = False) -> dict[str, Any]:
    """The run's data settings (its labels included) but where the data lay, and its data
    fingerprint; with ``common``, those at its nested selection's common setting."""
    settings, fingerprint = settings_of(record.configs()), record.fingerprint
    if common:
        chosen = record.selection.common           # None: a default the record leaves out
        settings = {name: value for name, value in {**settings, **chosen}.items()
                    if name not in chosen or value is not None}
        fingerprint = record.selection.common_fingerprint
    return {**{name: value for name, value in settings.items()
               if name.startswith("run.data.")
               and name.removeprefix("run.data.") not in DataConfig.output_fields},
            "data_fingerprint": fingerprint}


def outer_fold(record: RunRecord) -> str:
    """The run's outer fold: its held-out user for an inner run, else its test user."""
    held_out = record.config.held_out_users
    return held_out[0] if held_out else record.config.test_user


def selected_mismatch(record: RunRecord) -> str | None:
    """Where a run of a nested selection does not hold the settings its selection gives its
    outer fold, e.g. ``run.encoder.kernel 15, its selection's 25 on fold B``; None when it does
    (or the run is of none)."""
    if record.selection is None:
        return None
    fold = outer_fold(record)
    settings = settings_of(record.configs())
    wrong = [f"{name} {settings.get(name)!r}, its selection's {value!r} on fold {fold}"
             for name, value in record.selection.expected(fold).items()
             if settings.get(name) != value]
    return "; ".join(wrong) or None


def one_fingerprint_per_data(records: dict[Path, RunRecord], where: Path | str) -> None:
    """Check that the runs of nested selections among ``records`` record one data fingerprint
    per data (``_run_data``'s settings), a selection's common setting counted as data too
    (``SelectionConfig.common_fingerprint``): the fingerprint hashes the data, and
    ``configuration`` leaves it out for these runs, whose folds' data may differ.

    Raises:
        MixedSettings: naming, per data with several fingerprints, each and what records it.
    """
    found: dict[str, dict[str, list[str]]] = {}     # data -> fingerprint -> what records it
    for run, record in records.items():
        if record.selection is None:
            continue
        for data, source in ((_run_data(record), str(run)),
                             (_run_data(record, common=True), f"{run}'s selection")):
            fingerprint = str(data.pop("data_fingerprint"))
            found.setdefault(repr(sorted(data.items())), {}).setdefault(fingerprint,
                                                                         []).append(source)
    mixed = [" / ".join(f"{fingerprint} ({_runs(sources)})"
                        for fingerprint, sources in by_fingerprint.items())
             for by_fingerprint in found.values() if len(by_fingerprint) > 1]
    if mixed:
        raise MixedSettings(f"{where}: runs of a nested selection record other data "
                            f"fingerprints for the same data (data_fingerprint "
                            f"{'; '.join(mixed)}), so no table pools them")


def record_key(record: RunRecord) -> RunKey:
    """The configuration, seed and held-out user the run's config.json records."""
    config = record.config
    fold = config.test_user
    if len(config.held_out_users) == 1:
        fold = inner_fold(config.held_out_users[0], config.test_user)
    return RunKey(annotations=config.data.annotations,
                  direction="bidirectional" if config.encoder.bidirectional else "forward",
                  variant=record.variant, weighting=record.weighting, seed=config.train.seed,
                  fold=fold)


def configuration(record: RunRecord) -> dict[str, Any]:
    """The settings that identify the run's configuration (``{"run.encoder.hidden": 128, ...}``):
    every setting of its record but ``POOLED``; for a run of a nested selection, the settings it
    selects and the data fingerprint read ``CHOSEN``: its recorded selection stands for them."""
    settings = {k: v for k, v in settings_of(record.configs()).items() if k not in POOLED}
    if record.selection is not None:
        settings |= {name: CHOSEN for name in (*record.selection.common, "data_fingerprint")}
    return settings


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
        MixedSettings: runs of several encoders (an LSTM, ED-TCN, MS-TCN, a user's encoder of
            another import path or source: a table of one grid would pair them as one model's
            configurations), naming each; inner runs in a table not made for them
            (``INNER_SETTING`` not in ``varying``), or with outer runs; runs of a nested
            selection not holding their fold's settings (``selected_mismatch``) or recording
            other fingerprints for the same data (``one_fingerprint_per_data``); or, naming,
            per row whose runs differ, each setting that differs and the runs of each of its
            values.
    """
    _check_inner(records, where, INNER_SETTING in varying)
    wrong = [f"{run}: {problem}" for run, problem
             in ((run, selected_mismatch(record)) for run, record in records.items()) if problem]
    if wrong:
        raise MixedSettings(f"{where}: runs of a nested selection that do not hold the settings "
                            f"it gives their fold ({'; '.join(wrong[:SHOWN])}"
                            + (f"; and {len(wrong) - SHOWN} more" if len(wrong) > SHOWN else "")
                            + "), so no table pools them")
    one_fingerprint_per_data(records, where)
    encoders: dict[str, list[str]] = {}
    for run, record in records.items():
        encoders.setdefault(encoder_identity(record), []).append(str(run))
    if len(encoders) > 1:
        raise MixedSettings(
            f"{where}: runs of several encoders ("
            + " / ".join(f"{kind} ({_runs(runs)})" for kind, runs in sorted(encoders.items()))
            + "), so no table pools or pairs them. Tabulate each encoder's runs from a folder "
            "of their own; multitask-tables architectures puts grids of several side by side.")
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


def _check_inner(records: dict[Path, RunRecord], where: Path | str, wanted: bool) -> None:
    """Refuse inner runs where they are not ``wanted`` and, where they are, outer runs beside
    them (``pool``)."""
    inner = [str(run) for run, record in records.items() if record.config.held_out_users]
    outer = [str(run) for run, record in records.items() if not record.config.held_out_users]
    if inner and not wanted:
        raise MixedSettings(
            f"{where}: inner runs, scored on a validation user with their outer fold's user held "
            f"out ({_runs(inner)}): their folds are not test users, so this table does not pool "
            "them; multitask-tables factors reads them.")
    if inner and outer:
        raise MixedSettings(f"{where}: inner runs ({_runs(inner)}) beside outer runs "
                            f"({_runs(outer)}); no table pools the two.")


def _differences(runs: dict[Path, dict]) -> str:
    """``run.encoder.hidden 8 (a, b) / 16 (c)``, a clause per setting that differs among
    ``runs``."""
    names = sorted({name for settings in runs.values() for name in settings})
    clauses = []
    for name in names:
        values: dict[str, Any] = {}                 # repr of each value -> the value
        folders: dict[str, list[str]] = {}          # repr of each value -> its runs
        for run, settings in runs.items():
            value = settings.get(name, "(not recorded)")
            values.setdefault(repr(value), value)
            folders.setdefault(repr(value), []).append(str(run))
        if len(values) > 1:
            shown = {key: _shown(value) for key, value in values.items()}
            if len(set(shown.values())) < len(shown):       # 5 and "5", or alike once cut
                shown = {key: key for key in values}
            clauses.append(f"{name} " + " / ".join(f"{shown[key]} ({_runs(folders[key])})"
                                                   for key in values))
    return ", ".join(clauses)


def _shown(value: Any) -> str:
    text = str(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _runs(folders: list[str]) -> str:
    shown = ", ".join(folders[:SHOWN])
    return shown + (f" and {len(folders) - SHOWN} more" if len(folders) > SHOWN else "")

"""The factor study of ``results/tcn/PLAN_factors.md``: each level's validation scores against the
baseline's, per outer fold, and each fold's choice of setting (its section D).

Input: one grid of *inner* runs per level (its spec sets ``inner_validation``; every run scored
on a validation user, its outer fold's user held out: ``multitask.grid.spec``), the baseline's
first. Every run of a grid must be finished and usable (``collect.run_records``; inner runs
pooled over their outer folds, never with outer runs: ``pooling.INNER_SETTING``), a grid holds
one configuration, and a level's spec differs from the baseline's only in the keys of the plan's
factors (``FACTORS``; a key left out counts as its default), in its outer folds
(``test_users``, a subset of the baseline's) and in its validation users per fold
(``inner_validation``, at most the baseline's: the first of them); anything else is refused,
naming the grid and the keys. A level's factors are the factors of the keys it changes (several:
a combination).

A level's **validation score on outer fold u** is the mean over u's inner runs (its validation
users, and seeds if several) of each run's score, per metric (``METRICS``: gesture accuracy,
edit, F1@10, each run's the mean over its evaluation points) and for ``mean``, each run's mean
of the three (section B). The baseline's score it is set against is the same mean over the
baseline's runs of the level's validation users.

Output (``write_factors``), in percentage points:

* ``factors.csv`` (section D.1): per level, its factors, the spec keys it changes, whether it
  runs at the model's rate (5 Hz), its folds, and per metric (``accuracy``, ``edit``, ``f1@10``,
  ``mean``) the mean over its folds of level minus baseline (``<metric>_diff``) and how many folds
  favour the level (``<metric>_favouring``: a difference above 0);
* ``factors_per_fold.csv``: level, outer fold, metric, the level's score, the baseline's and the
  difference (the per-fold differences of D.1);
* ``factors_choice.csv`` (D.2, first step): per outer fold and factor a fold's setting can
  take (not S: ``_SELECTABLE_FACTORS``), among the levels of that factor alone at the model's
  rate, those *eligible* (mean difference at least ``ELIGIBLE`` points), the one taken (the
  eligible level of the highest score; ``baseline`` when none) and its difference;
* ``factors_settings.csv`` (D.2, second step, and D.3): per outer fold the combination of the
  taken levels; when it combines two factors or more, the combination's grid (``combinations``,
  a grid whose spec changes exactly the taken levels' keys and holds the fold) and its
  difference; the fold's setting: ``baseline``, the single taken level, the combination, or the
  best single taken level when the combination's score is more than ``COMBINATION_MARGIN``
  below it, or ``pending`` while the combination has not run; and, for D.3, the best level of
  factor T at another rate than the model's, its difference and whether it is eligible;
* ``combination-<folds>.toml``: for each combination still pending, the spec that runs it on
  the folds that chose it (the baseline's spec, the taken levels' keys, ``test_users``): run it
  with ``multitask-grid`` and give its grid with ``--combination``;
* ``fold_settings.toml``, once no fold's setting is pending: each fold's setting as the
  ``fold_settings`` tables of a grid spec (``multitask.grid.spec``; a fold at the baseline's
  setting has none), to add to the specs that train with the chosen settings.
"""
from __future__ import annotations

import json
from functools import cached_property
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import pandas as pd

from jigsaws_tools.dataset import DataConfig
from jigsaws_tools.preprocessing import PreprocessConfig
from rnn_seg.encoders.config import EDTCNConfig
from rnn_seg.runs.folder import write_atomic

from ...grid.folder import GRID_RECORD, comparable_spec, read_record
from ...grid.spec import SELECTABLE, GridSpec, fold_users, spec_from_dict, spec_payload
from ..runs.collect import CONFIG_COLUMNS, run_records
from ..runs.pooling import INNER_SETTING

#: The plan's metrics (section B) -> their names in the tables; ``mean`` is the three's mean.
METRICS = {"gesture_accuracy": "accuracy", "gesture_edit": "edit", "gesture_f1@10": "f1@10"}
MEAN = "mean"
#: The plan's factors (section C) -> the spec keys each changes; ``S``, the schedule's length,
#: was added after the plan (exploratory: ``results/tcn/FINDINGS.md``, section 6).
FACTORS = {"T": ("resample_factor", "kernel"), "L": ("lowpass",), "N": ("normalise",),
           "F": ("feature_set",), "P": ("padding",), "H": ("head_init",), "S": ("epochs",)}
#: What a factor key left out of a spec means (``epochs``: the preset's schedule).
DEFAULTS = {"resample_factor": PreprocessConfig.resample_factor, "kernel": EDTCNConfig.kernel,
            "lowpass": PreprocessConfig.lowpass, "normalise": PreprocessConfig.normalise,
            "feature_set": DataConfig.feature_set, "padding": EDTCNConfig.padding,
            "head_init": EDTCNConfig.head_init, "epochs": None}
#: The factors a fold's setting may take (D.2): those whose keys ``fold_settings`` can set (not
#: S: a grid's schedule is one for all its folds).
_SELECTABLE_FACTORS = tuple(f for f, keys in FACTORS.items() if set(keys) <= set(SELECTABLE))
#: Spec keys a level may set otherwise than the baseline: its folds, and fewer validation users
#: per fold (the first of the baseline's: the runs a level holds are then among the baseline's).
FOLD_KEYS = ("test_users", "inner_validation")
#: Points above the baseline's validation score on a fold that make a level eligible (D.2).
ELIGIBLE = 1.0
#: Points below the best single taken level's score that make a fold drop the combination.
COMBINATION_MARGIN = 0.5
BASELINE = "baseline"
PENDING = "pending"
#: The settled settings as a grid spec's ``fold_settings`` tables.
FOLD_SETTINGS = "fold_settings.toml"


@dataclass(frozen=True)
class Level:
    """One grid of inner runs: its name (the folder's), spec, the factor keys it changes from
    the baseline's (key -> value) and its runs' validation scores (``fold``, e.g. ``B-val-C``;
    ``outer``; ``METRICS``' columns and ``MEAN``; a row per run)."""

    name: str
    spec: GridSpec
    changes: dict[str, Any]
    runs: pd.DataFrame

    @cached_property
    def scores(self) -> pd.DataFrame:
        """Its validation score per outer fold (index) and metric (columns: ``METRICS``' names
        and ``MEAN``): the mean of the fold's runs."""
        return _scores(self.runs)

    @property
    def factors(self) -> tuple[str, ...]:
        return tuple(f for f, keys in FACTORS.items() if set(keys) & set(self.changes))

    @property
    def at_model_rate(self) -> bool:
        """Whether it runs at the model's 5 Hz (the baseline's rate)."""
        return self.changes.get("resample_factor", DEFAULTS["resample_factor"]) == \
            DEFAULTS["resample_factor"]

    def describe(self) -> str:
        """E.g. ``resample_factor 10, kernel 15``; ``baseline`` for no change."""
        return ", ".join(f"{k} {_toml_value(v)}" for k, v in self.changes.items()) or BASELINE


def read_level(grid: Path, baseline: GridSpec | None = None) -> Level:
    """The level of ``grid`` (module docstring); ``baseline``: the baseline's spec (None: this
    grid is the baseline).

    Raises:
        ValueError: one line naming the grid: no spec, not inner runs, several configurations,
            other changes than the factors' keys, folds the baseline lacks;
            ``collect.IncompleteEvidence`` for runs missing or unfinished.
    """
    record = read_record(grid)
    if not record or "spec" not in record:
        raise ValueError(f"{grid}: no {GRID_RECORD} with a spec: not a grid of the factor study")
    spec = spec_from_dict(record["spec"], source=f"{grid / GRID_RECORD}: spec")
    if spec.inner_validation is None:
        raise ValueError(f"{grid}: its spec sets no inner_validation: not a grid of inner runs "
                         "(the factor study reads validation scores only, never a test user's)")
    rows, _, _ = run_records(grid, varying=(INNER_SETTING,))
    configs = rows[CONFIG_COLUMNS].drop_duplicates()
    if len(configs) != 1:
        raise ValueError(f"{grid}: {len(configs)} configurations; a level's grid holds one")
    changes = {} if baseline is None else _changes(grid, spec, baseline)
    rows = rows.assign(outer=[fold_users(fold)[1][0] for fold in rows.fold])
    rows[MEAN] = rows[list(METRICS)].mean(axis=1)
    level = Level(grid.name, spec, changes, rows[["fold", "outer", *METRICS, MEAN]])
    if baseline is not None and not set(level.scores.index) <= set(_folds(baseline,
                                                                         level.scores)):
        raise ValueError(f"{grid}: outer folds {', '.join(sorted(level.scores.index))} not all "
                         "among the baseline's")
    return level


def _scores(rows: pd.DataFrame) -> pd.DataFrame:
    """Per outer fold, the mean of its runs' scores (``Level.scores``), metrics renamed."""
    return rows.groupby("outer")[[*METRICS, MEAN]].mean().rename(columns=METRICS)


def _folds(baseline: GridSpec, scores: pd.DataFrame) -> tuple[str, ...]:
    return baseline.test_users or tuple(scores.index)


def _changes(grid: Path, spec: GridSpec, baseline: GridSpec) -> dict[str, Any]:
    """The factor keys ``spec`` sets otherwise than ``baseline`` (module docstring)."""
    mine, theirs = (_effective(s) for s in (spec, baseline))
    differ = [k for k in mine.keys() | theirs.keys()
              if mine.get(k) != theirs.get(k) and k not in FOLD_KEYS]
    if (spec.inner_validation or 0) > (baseline.inner_validation or 0):
        raise ValueError(f"{grid}: inner_validation {spec.inner_validation} is more than the "
                         f"baseline's {baseline.inner_validation}: its runs are not all among "
                         "the baseline's")
    other = sorted(k for k in differ if k not in DEFAULTS)
    if other:
        raise ValueError(f"{grid}: its spec differs from the baseline's in {', '.join(other)}, "
                         f"not only in the factors' keys ({', '.join(DEFAULTS)})")
    return {k: mine[k] for k in DEFAULTS if k in differ}


def _effective(spec: GridSpec) -> dict[str, Any]:
    """``spec`` as grid.json records compare (``comparable_spec``), factor keys left out at
    their defaults."""
    data = comparable_spec(spec_payload(spec))
    return {k: (DEFAULTS[k] if k in DEFAULTS and v is None else v) for k, v in data.items()}


def write_factors(baseline: Path, levels: list[Path], combinations: list[Path], out: Path
                  ) -> tuple[list[Path], list[str]]:
    """The tables and pending specs of the module docstring into ``out``: their paths, and
    notes for the user (each combination still to run, the folds' settings)."""
    base = read_level(Path(baseline))
    read = [read_level(Path(grid), base.spec) for grid in levels]
    names = [level.name for level in [base, *read]]
    if len(set(names)) < len(names):
        raise ValueError(f"two grids of one name among {', '.join(names)}: a level is named by "
                         "its grid's folder")
    singles = [level for level in read if len(level.factors) == 1]
    combos = [read_level(Path(grid), base.spec) for grid in combinations]
    tables = {"factors": effects(base, read), "factors_per_fold": per_fold(base, read)}
    tables["factors_choice"] = choice(base, singles)
    tables["factors_settings"] = settings(base, singles, combos, tables["factors_choice"])
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, table in tables.items():
        path = out / f"{name}.csv"
        write_atomic(path, table.to_csv(index=False, float_format="%.4f"))
        written.append(path)
    pending = tables["factors_settings"][tables["factors_settings"].setting == PENDING]
    notes = []
    for combination, rows in pending.groupby("combination", sort=False):
        folds = tuple(rows.fold)
        path = out / f"combination-{'-'.join(folds)}.toml"
        taken = [level for level in singles if level.name in combination.split(" + ")]
        write_atomic(path, combination_spec(base.spec, taken, folds))
        written.append(path)
        notes.append(f"folds {', '.join(folds)} chose {combination}: run {path.name} "
                     "(multitask-grid) and give its grid with --combination")
    final = set(tables["factors_settings"].setting)
    if PENDING not in final:
        path = out / FOLD_SETTINGS
        write_atomic(path, fold_settings_toml(tables["factors_settings"], singles))
        written.append(path)
        notes.append("every fold's setting: " + ("the same, " if len(final) == 1 else
                                                 "not the same (a nested selection), ")
                     + "; ".join(f"{f} {s}" for f, s in zip(tables["factors_settings"].fold,
                                                            tables["factors_settings"].setting)))
    return written, notes


def _baseline(base: Level, level: Level) -> pd.DataFrame:
    """The baseline's scores on the level's runs: per outer fold of the level, the mean over
    the baseline's runs of the validation users the level has (all of them, unless the level
    sets fewer)."""
    return _scores(base.runs[base.runs.fold.isin(set(level.runs.fold))])


def _differences(base: Level, level: Level) -> pd.DataFrame:
    """Level minus baseline per outer fold of the level (rows) and metric (columns), on the
    level's validation users."""
    return level.scores - _baseline(base, level).loc[level.scores.index]


def effects(base: Level, levels: list[Level]) -> pd.DataFrame:
    """``factors.csv`` (module docstring)."""
    rows = []
    for level in levels:
        diff = _differences(base, level)
        row = {"level": level.name, "factors": "+".join(level.factors),
               "changes": level.describe(), "model_rate": level.at_model_rate,
               "folds": len(diff)}
        for metric in diff.columns:
            row[f"{metric}_diff"] = diff[metric].mean()
            row[f"{metric}_favouring"] = int((diff[metric] > 0).sum())
        rows.append(row)
    return pd.DataFrame(rows, columns=["level", "factors", "changes", "model_rate", "folds",
                                       *(f"{m}_{k}" for m in [*METRICS.values(), MEAN]
                                         for k in ("diff", "favouring"))])


def per_fold(base: Level, levels: list[Level]) -> pd.DataFrame:
    """``factors_per_fold.csv`` (module docstring)."""
    rows = [{"level": level.name, "fold": fold, "metric": metric,
             "level_score": level.scores.at[fold, metric],
             "baseline_score": baseline.at[fold, metric],
             "difference": level.scores.at[fold, metric] - baseline.at[fold, metric]}
            for level, baseline in ((level, _baseline(base, level)) for level in levels)
            for fold in level.scores.index for metric in level.scores.columns]
    return pd.DataFrame(rows, columns=["level", "fold", "metric", "level_score",
                                       "baseline_score", "difference"])


def choice(base: Level, singles: list[Level]) -> pd.DataFrame:
    """``factors_choice.csv``: per outer fold and factor, the eligible levels at the model's rate
    and the one taken (module docstring)."""
    rows = []
    for fold in base.scores.index:
        for factor in _SELECTABLE_FACTORS:
            diffs = {level.name: _differences(base, level).at[fold, MEAN]
                     for level in singles if level.factors == (factor,) and level.at_model_rate
                     and fold in level.scores.index}
            if not diffs:
                continue
            eligible = {name: d for name, d in diffs.items() if d >= ELIGIBLE}
            taken = max(eligible, key=eligible.get) if eligible else BASELINE
            rows.append({"fold": fold, "factor": factor, "levels": " ".join(diffs),
                         "eligible": " ".join(eligible), "taken": taken,
                         "taken_diff": eligible.get(taken, 0.0)})
    return pd.DataFrame(rows, columns=["fold", "factor", "levels", "eligible", "taken",
                                       "taken_diff"])


def settings(base: Level, singles: list[Level], combos: list[Level], chosen: pd.DataFrame
             ) -> pd.DataFrame:
    """``factors_settings.csv``: per outer fold, its combination and setting (module
    docstring)."""
    rows = []
    for fold in base.scores.index:
        taken = chosen[(chosen.fold == fold) & (chosen.taken != BASELINE)]
        combination = " + ".join(taken.taken) or BASELINE
        row = {"fold": fold, "combination": combination, "combination_grid": "",
               "combination_diff": float("nan")}
        if len(taken) < 2:
            row["setting"] = combination
        else:
            wanted = _merged([level for level in singles if level.name in set(taken.taken)])
            grid = next((c for c in combos if c.changes == wanted and fold in c.scores.index),
                        None)
            best = taken.loc[taken.taken_diff.idxmax()]
            if grid is None:
                row["setting"] = PENDING
            else:
                diff = _differences(base, grid).at[fold, MEAN]
                row.update(combination_grid=grid.name, combination_diff=diff)
                row["setting"] = (best.taken if diff < best.taken_diff - COMBINATION_MARGIN
                                  else combination)
        row.update(_other_rate(base, singles, fold))
        rows.append(row)
    return pd.DataFrame(rows, columns=["fold", "combination", "combination_grid",
                                       "combination_diff", "setting", "other_rate_best",
                                       "other_rate_diff", "other_rate_eligible"])


def _merged(levels: list[Level]) -> dict[str, Any]:
    """The changes of ``levels`` together, in ``DEFAULTS``' key order."""
    merged = {k: v for level in levels for k, v in level.changes.items()}
    return {k: merged[k] for k in DEFAULTS if k in merged}


def _other_rate(base: Level, singles: list[Level], fold: str) -> dict[str, Any]:
    """D.3: the best level of factor T at another rate than the model's on ``fold``."""
    diffs = {level.name: _differences(base, level).at[fold, MEAN] for level in singles
             if level.factors == ("T",) and not level.at_model_rate
             and fold in level.scores.index}
    if not diffs:
        return {"other_rate_best": "", "other_rate_diff": float("nan"),
                "other_rate_eligible": False}
    best = max(diffs, key=diffs.get)
    return {"other_rate_best": best, "other_rate_diff": diffs[best],
            "other_rate_eligible": bool(diffs[best] >= ELIGIBLE)}


def fold_settings_toml(chosen: pd.DataFrame, singles: list[Level]) -> str:
    """``fold_settings.toml`` (module docstring) from ``factors_settings.csv``'s table
    (``chosen``) and the single levels its settings name."""
    by_name = {level.name: level for level in singles}
    lines = ["# Each outer fold's setting of results/tcn/PLAN_factors.md (section D.2), chosen "
             "on its inner runs",
             "# only: written by multitask-tables factors. A fold not listed keeps the "
             "baseline's. Add to a",
             "# grid spec (multitask.grid.spec, fold_settings)."]
    for fold, setting in zip(chosen.fold, chosen.setting):
        if setting == BASELINE:
            continue
        changes = _merged([by_name[name] for name in setting.split(" + ")])
        lines += ["", f"[fold_settings.{fold}]  # {setting}"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in changes.items()]
    return "\n".join(lines) + "\n"


def combination_spec(baseline: GridSpec, taken: list[Level], folds: tuple[str, ...]) -> str:
    """The TOML spec of the combination of ``taken`` on the outer ``folds``: the baseline's
    spec (where its data lay and how its loops ran left out), every key the levels change, and
    ``test_users``; keys at ``GridSpec``'s defaults are not written."""
    data = {k: v for k, v in spec_payload(baseline).items() if k not in ("data_dir", "loops")}
    data.update(_merged(taken), test_users=list(folds))
    defaults = {f.name: f.default for f in fields(GridSpec)}
    lines = [f"# The combination {' + '.join(level.name for level in taken)} of "
             "results/tcn/PLAN_factors.md (section D.2) on outer folds "
             f"{', '.join(folds)}: written by multitask-tables factors.", ""]
    for key, value in data.items():
        if key == "experiments" or value is None:
            continue
        if key in defaults and _jsonable(defaults[key]) == value:
            continue
        lines.append(f"{key} = {_toml_value(value)}")
    for experiment in data["experiments"]:
        lines += ["", "[[experiments]]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in experiment.items() if v is not None]
    return "\n".join(lines) + "\n"


def _jsonable(value: Any) -> Any:
    return json.loads(json.dumps(list(value) if isinstance(value, tuple) else value))


def _toml_value(value: Any) -> str:
    """A spec value (string, number, boolean, list, table) as TOML."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)

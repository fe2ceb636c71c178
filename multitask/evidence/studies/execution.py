"""Does an execution path change what a grid says? A grid against its reference, paired by fold.

An execution path computes the same model with other roundings: the fused C++ loops
(``loops = "fused"``, ``rnn_seg.kernels``), bfloat16 products (``precision = "bf16"``). The
option's grid repeats configurations of a reference grid (e.g. the committed float32 grid
``results/grid``) on another path; this module says, per configuration and score, by how much the
path moves the scores, and whether a model comparison reads the same (``results/precision/PLAN.md``
is the plan it runs).

Evidence: every run the option's grid records must have finished (no interim look) and be usable
(``collect.run_records``: readable, in its place, finite scores); the reference must hold a
finished, usable run of each of the option's runs (configuration, seed and fold; the refusal names
the first it lacks and why). The reference's other runs are not the comparison's: they may be
unfinished, or of other configurations or seeds. The runs of both grids must agree on every
setting that changes a result but the precision (``pooling.pool`` with ``varying=EXECUTION``);
the loops, which are not such a setting, are those each run's ``config.json`` says it started on
(``RunRecord.loops``: its provenance's, so ``auto`` and a fallback read as what ran) and must be one
path per grid. Nothing else may differ:
a reference of another width, schedule or data is refused with the list of what differs.

Per configuration and metric, each side's per-fold mean over the seeds, and the option minus the
reference per fold, tested as ``claims.csv`` tests a claim (``paired.paired_sides``: exact
two-sided sign-flip test over the folds, the 95 % interval that inverts it). Outcome against the
equivalence ``margin`` (percentage points):

* ``equivalent``: the whole interval lies within (-margin, +margin);
* ``different``: the whole interval lies beyond +margin or below -margin;
* ``inconclusive``: otherwise.

An *equivalent* endpoint whose test rejects "no difference" (p <= alpha) is noted ``a shift
smaller than the margin`` (column ``note``; empty otherwise): the path moves the score, by less
than the margin.

Beside it, every other configuration minus ``A-fixed`` of its labels and direction
(``baseline_of``: ``original/APoc-gradnorm - original/A-fixed``) on each metric in each grid (the
comparison a user makes), with the verdict by ``claims.csv``'s rule (p <= alpha: ``X above A`` or
``X below A``; else ``no difference detected``), and the difference of the two contrasts
(option's minus reference's, paired by fold). A configuration whose ``A-fixed`` the option's grid
lacks has no contrast (a grid of ``APoc-gradnorm`` alone: a table of the header alone). The
progress-only models (``Pr``, ``Pc``, ``Poc``) have no gesture scores: they are left out, with a
note.

Output (``write_execution``): ``execution.csv`` (configuration, metric, folds, seeds, option and
reference path, option_mean, reference_mean (means over folds of the per-fold seed means), diff,
ci_low, ci_high, p_value, margin, outcome, note), ``execution_contrasts.csv`` (contrast, metric,
each grid's diff, interval, p and verdict, same_reading, and the difference of the contrasts with
its interval and p) and ``execution_per_fold.csv`` (configuration, metric, fold, option,
reference, difference).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rnn_seg.runs.folder import is_finished

from ...grid.folder import GRID_RECORD
from ...grid.spec import RunKey
from ...models.run_record import RunRecord
from ...models.variants import get_variant
from ..runs.collect import recorded_runs, run_records
from ..runs.pooling import pool, record_key
from ..statistics.paired import (ConfigId, Contrast, PairedResult, StatsConfig, config_labels,
                                 paired, paired_sides, seed_values)

#: The settings an execution path may change among those that change results (``pooling``).
EXECUTION = ("run.encoder.precision",)
METRICS = ("gesture_accuracy", "gesture_edit", "gesture_f1@10")
#: The configuration every other one is compared with (of its labels and direction:
#: ``baseline_of``).
BASELINE = ConfigId("A", "fixed")
#: The columns of ``execution_contrasts.csv``.
CONTRAST_COLUMNS = ["contrast", "metric",
                    *(f"{side}_{name}" for side in ("option", "reference")
                      for name in ("diff", "ci_low", "ci_high", "p", "verdict")),
                    "same_reading", "diff_of_diffs", "dd_ci_low", "dd_ci_high", "dd_p"]
OUTCOMES = ("equivalent", "different", "inconclusive")
#: The note of an *equivalent* endpoint whose test rejects "no difference" (``shift_note``).
SMALL_SHIFT = "a shift smaller than the margin"


@dataclass(frozen=True)
class GridPart:
    """One grid's side: its runs (``collect.run_rows``' columns), their path and records."""

    grid: Path
    runs: pd.DataFrame
    path: str                              # e.g. "fused loops, bf16"
    records: dict[Path, RunRecord]

    def configs(self) -> list[ConfigId]:
        """Its configurations with gesture scores (not the progress-only ``P*``), A first."""
        keys = self.runs[["variant", "weighting", "annotations", "direction"]].drop_duplicates()
        return sorted((c for c in (ConfigId(*key) for key in keys.itertuples(index=False))
                       if "gesture" in get_variant(c.variant).task_names),
                      key=lambda c: (c != BASELINE, c.label))

    def unscored(self) -> list[str]:
        """The labels of its configurations without gesture scores, which ``configs`` leaves
        out."""
        return sorted(set(config_labels(self.runs)) - {c.label for c in self.configs()})


def option_part(grid: Path) -> GridPart:
    """The option's grid: every run it records, all finished and usable (``ValueError`` naming
    what is not, one line)."""
    recorded = _recorded(grid)
    done = sum(is_finished(grid / run) for run in recorded)
    if done < len(recorded):
        raise ValueError(f"{grid}: {done} of its {len(recorded)} runs have finished: the "
                         "comparison waits for all of them (no interim look)")
    runs, problems, records = run_records(grid, allow_incomplete=True)
    if problems:
        more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
        raise ValueError(f"{grid}: {problems[0]}{more}")
    return GridPart(grid, runs, _path(grid, records), records)


def reference_part(grid: Path, option: GridPart) -> GridPart:
    """The reference's runs of the option's configurations, seeds and folds (``ValueError``
    naming a run the reference lacks and why, one line); problems of its other runs (unfinished,
    unreadable) do not matter here."""
    _recorded(grid)
    runs, problems, records = run_records(grid, seeds=tuple(sorted(option.runs.seed.unique())),
                                          allow_incomplete=True)
    wanted = {record_key(record) for record in option.records.values()}
    chosen = {run: record for run, record in records.items() if record_key(record) in wanted}
    missing = sorted(wanted - {record_key(record) for record in chosen.values()},
                     key=lambda key: str(key.path()))
    if missing:
        key = missing[0]
        label = ConfigId(key.variant, key.weighting, key.annotations, key.direction).label
        raise ValueError(f"{grid}: no usable run of {label}, seed {key.seed}, fold {key.fold}: "
                         f"{_why(grid, key, problems)} ({len(missing)} of the option's "
                         f"{len(wanted)} runs lack their reference)")
    keep = runs[[_row_key(row) in wanted for row in runs.itertuples(index=False)]]
    return GridPart(grid, keep.reset_index(drop=True), _path(grid, chosen), chosen)


def _recorded(grid: Path) -> list[Path]:
    """The runs ``grid``'s grid.json records (``ValueError`` when it has none: not a grid)."""
    recorded, unknown = recorded_runs(grid)
    if unknown:
        raise ValueError(f"{grid}: not a grid: {unknown[0]}")
    return recorded


def _why(grid: Path, key: RunKey, problems: list[str]) -> str:
    """Why the reference ``grid`` has no usable run of ``key``: the problem ``run_records``
    found with it, or that its grid.json does not record it."""
    place = re.compile(re.escape(str(grid / key.path())) + "(/|:|$)")
    return next((problem for problem in problems if place.search(problem)),
                f"{grid / GRID_RECORD} does not record it")


def _row_key(row) -> RunKey:
    """The ``RunKey`` of a row of ``collect.run_rows`` (``pooling.record_key`` of its run)."""
    return RunKey(row.annotations, row.direction, row.variant, row.weighting, int(row.seed),
                  str(row.fold))


def _path(grid: Path, records: dict[Path, RunRecord]) -> str:
    """``"<loops> loops, <precision>"`` of every run of ``grid`` (``ValueError`` if they differ,
    or a run's sessions ran on different loops: e.g. a fused run resumed on the graph loops)."""
    paths = {f"{r.loops()} loops, {r.config.encoder.precision}"
             for r in records.values()}
    mixed = sorted(str(run) for run, r in records.items() if r.loops().startswith("mixed"))
    if mixed:
        raise ValueError(f"{grid}: {len(mixed)} run(s) ran on more than one execution path, its "
                         f"sessions on different loops (first: {mixed[0]}, "
                         f"{records[Path(mixed[0])].loops()}): one path per grid")
    if len(paths) != 1:
        raise ValueError(f"{grid}: its runs ran on more than one execution path "
                         f"({', '.join(sorted(paths))}): one path per grid")
    return paths.pop()


def outcome(result: PairedResult, margin: float) -> str:
    """``equivalent``, ``different`` or ``inconclusive`` (module docstring)."""
    if -margin < result.ci_low and result.ci_high < margin:
        return "equivalent"
    if result.ci_low > margin or result.ci_high < -margin:
        return "different"
    return "inconclusive"


def shift_note(result: PairedResult, margin: float, alpha: float) -> str:
    """``SMALL_SHIFT`` when ``result`` is *equivalent* at ``margin`` and its p <= ``alpha``;
    "" otherwise."""
    return SMALL_SHIFT if (outcome(result, margin) == "equivalent"
                           and result.p_value <= alpha) else ""


def baseline_of(x: ConfigId) -> ConfigId:
    """``A-fixed`` of ``x``'s labels and direction: the configuration ``x`` is compared with."""
    return ConfigId(BASELINE.variant, BASELINE.weighting, x.annotations, x.direction)


def reading(result: PairedResult, x: ConfigId, alpha: float) -> str:
    """``claims.csv``'s rule for ``x - A`` (``baseline_of``): ``<x> above <A>``, ``<x> below
    <A>`` or ``no difference detected``."""
    if not result.p_value <= alpha:
        return "no difference detected"
    return f"{x.label} {'above' if result.mean > 0 else 'below'} {baseline_of(x).label}"


def execution_tables(option: GridPart, reference: GridPart, margin: float,
                     config: StatsConfig = StatsConfig()
                     ) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """``execution.csv``, ``execution_contrasts.csv`` and ``execution_per_fold.csv`` (module
    docstring) of ``option`` against ``reference`` at ``margin`` points."""
    rows, contrasts, folds = [], [], []
    configs = option.configs()
    for config_id in configs:
        for metric in METRICS:
            sides = {"option": seed_values(option.runs, config_id, metric),
                     "reference": seed_values(reference.runs, config_id, metric)}
            result = paired_sides(f"{option.path} - {reference.path}: {config_id.label}", metric,
                                  {"option": (1, sides["option"]),
                                   "reference": (-1, sides["reference"])}, config)
            means = {name: float(np.mean([values[f].mean() for f in result.folds]))
                     for name, values in sides.items()}
            rows.append({"configuration": config_id.label, "metric": metric,
                         "folds": result.pairs, "seeds": _seeds(option.runs, config_id),
                         "option": option.path, "reference": reference.path,
                         "option_mean": means["option"], "reference_mean": means["reference"],
                         "diff": result.mean, "ci_low": result.ci_low,
                         "ci_high": result.ci_high, "p_value": result.p_value,
                         "margin": margin, "outcome": outcome(result, margin),
                         "note": shift_note(result, margin, config.alpha)})
            folds += [{"configuration": config_id.label, "metric": metric, "fold": fold,
                       "option": sides["option"][fold].mean(),
                       "reference": sides["reference"][fold].mean(), "difference": d}
                      for fold, d in zip(result.folds, result.differences)]
            if config_id != baseline_of(config_id) and baseline_of(config_id) in configs:
                contrasts.append(_contrast(option, reference, config_id, metric, config))
    return (pd.DataFrame(rows), pd.DataFrame(contrasts, columns=CONTRAST_COLUMNS),
            pd.DataFrame(folds))


def _contrast(option: GridPart, reference: GridPart, x: ConfigId, metric: str,
              config: StatsConfig) -> dict:
    """One row of ``execution_contrasts.csv``: ``x - A`` (``baseline_of``) in each grid, and
    their difference."""
    baseline = baseline_of(x)
    contrast = Contrast(x, baseline)
    row = {"contrast": contrast.label, "metric": metric}
    readings = {}
    for name, part in (("option", option), ("reference", reference)):
        result = paired(part.runs, contrast, metric, config)
        readings[name] = reading(result, x, config.alpha)
        row |= {f"{name}_diff": result.mean, f"{name}_ci_low": result.ci_low,
                f"{name}_ci_high": result.ci_high, f"{name}_p": result.p_value,
                f"{name}_verdict": readings[name]}
    both = paired_sides(
        f"({contrast.label}) option - reference", metric,
        {"option x": (1, seed_values(option.runs, x, metric)),
         "option A": (-1, seed_values(option.runs, baseline, metric)),
         "reference x": (-1, seed_values(reference.runs, x, metric)),
         "reference A": (1, seed_values(reference.runs, baseline, metric))}, config)
    return row | {"same_reading": readings["option"] == readings["reference"],
                  "diff_of_diffs": both.mean, "dd_ci_low": both.ci_low,
                  "dd_ci_high": both.ci_high, "dd_p": both.p_value}


def _seeds(runs: pd.DataFrame, config_id: ConfigId) -> str:
    return " ".join(map(str, sorted(config_id.select(runs).seed.unique())))


def write_execution(option_grid: Path, reference_grid: Path, margin: float, out: Path
                    ) -> tuple[list[Path], list[str]]:
    """The three CSVs of ``option_grid`` against ``reference_grid`` into ``out``: their paths,
    and notes for the user (configurations left out: no gesture scores).

    Raises:
        ValueError: one line: a margin not a finite number above 0, an unfinished option grid,
            a reference lacking a run the option has, a grid of two paths, runs differing in a
            setting other than the path (``pooling.MixedSettings``), no configuration with
            gesture scores.
    """
    if not 0 < margin < math.inf:
        raise ValueError(f"--margin must be a finite number of points above 0 (value: {margin})")
    option = option_part(Path(option_grid))
    if not option.configs():
        raise ValueError(f"{option_grid}: no configuration with gesture scores (it holds "
                         f"{', '.join(option.unscored())}): nothing to compare")
    reference = reference_part(Path(reference_grid), option)
    pool(option.records | reference.records, f"{option_grid} against {reference_grid}",
         varying=EXECUTION)
    if option.path == reference.path:
        raise ValueError(f"{option_grid} and {reference_grid} ran on the same execution path "
                         f"({option.path}): nothing to compare")
    tables = execution_tables(option, reference, margin)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, table in zip(("execution", "execution_contrasts", "execution_per_fold"), tables):
        path = out / f"{name}.csv"
        table.to_csv(path, index=False, float_format="%.4f")
        written.append(path)
    notes = [f"{label}: no gesture scores (a progress-only model), left out"
             for label in option.unscored()]
    return written, notes + _too_few_folds(tables[0])


def _too_few_folds(table: pd.DataFrame, config: StatsConfig = StatsConfig()) -> list[str]:
    """A note when some intervals of ``execution.csv`` are infinite: too few folds for the
    exact test to reach its level (``paired.SignFlip``)."""
    infinite = table[~np.isfinite(table.ci_low) | ~np.isfinite(table.ci_high)]
    if infinite.empty:
        return []
    folds = int(infinite.folds.max())
    return [f"{len(infinite)} of {len(table)} endpoints have {folds} or fewer paired folds: the "
            f"exact sign-flip test cannot reach p <= {config.alpha:.2g} there (smallest p "
            f"{2 / 2 ** folds:.4f}), so their intervals are infinite and their outcomes "
            "inconclusive"]

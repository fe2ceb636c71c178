"""A pre-registered confirmatory analysis, run exactly as its plan says (``results/confirm/``).

The plan is a TOML file (``plan.toml`` beside the plan's text): parts, each a grid and the seeds
the test pools; each part holds families of endpoints (``X - Y`` on a metric, with the paper's
gain). Every endpoint is tested as ``claims.csv`` tests a claim: per fold, each side's mean over
the part's seeds, then the exact two-sided sign-flip test over the folds and the 95 % interval
that inverts it (``paired.paired``); Holm's correction runs within each family over its declared
size (``paired.holm``). A primary endpoint gets an outcome by the part's decision rule:

* a part **without** ``rule_out_below`` (a claim of the paper): *reproduced* (Holm-adjusted
  p <= alpha, mean > 0), *contradicted* (adjusted p <= alpha, mean < 0), else *inconclusive*;
  ``rule_out`` is true when the interval's upper end lies below the paper's gain ("the paper's
  gain is excluded"), whatever the outcome;
* a part **with** ``rule_out_below`` (a replication): *replicated* (adjusted p <= alpha,
  mean > 0), else *not replicated* when the interval's upper end lies below ``rule_out_below``
  (*not replicated (reversed)* when significantly negative), else *inconclusive*.

Beside the planned analysis (``analysis`` = ``planned``), every endpoint is also given for each
seed alone (``seed <k>``) and, where the plan names ``sensitivity_seeds``, for those seeds pooled
(``sensitivity``); these rows are descriptive (no outcome, no correction).

**No interim analysis**: a part is analysed only when every run its grid records for the part's
seeds has finished; otherwise the part is reported as not analysed, with how many runs are done,
and gets no rows.

Output, in ``--out``: ``confirm.csv`` (one row per part, family, endpoint and analysis) and
``confirm_per_fold.csv`` (the fold differences behind each row).
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .collect import IncompleteEvidence, key_from_path, recorded_runs, run_rows
from .paired import ConfigId, Contrast, StatsConfig, holm, paired

ROLES = ("primary", "secondary")
COLUMNS = ["part", "family", "role", "analysis", "seeds", "comparison", "metric", "folds",
           "diff", "ci_low", "ci_high", "p_value", "p_holm", "paper_gain", "paper_in_ci",
           "rule_out", "outcome", "folds_favouring"]


class PlanError(ValueError):
    """A plan file that cannot be read as a plan; the message names the file and the key."""


@dataclass(frozen=True)
class Endpoint:
    """``x - y`` on ``metric``, and the paper's gain on it (percentage points)."""

    x: str
    y: str
    metric: str
    paper_gain: float

    @property
    def contrast(self) -> Contrast:
        return Contrast(ConfigId.parse(self.x), ConfigId.parse(self.y))


@dataclass(frozen=True)
class Family:
    name: str
    role: str
    endpoints: tuple[Endpoint, ...]


@dataclass(frozen=True)
class Part:
    """One confirmatory test: a grid, the seeds pooled, its families and its decision rule."""

    name: str
    title: str
    grid: Path
    seeds: tuple[int, ...]
    families: tuple[Family, ...]
    outcomes: tuple[str, str, str]
    sensitivity_seeds: tuple[int, ...] = ()
    rule_out_below: float | None = None


@dataclass(frozen=True)
class Plan:
    path: Path
    confidence: float
    parts: tuple[Part, ...]


def read_plan(path: Path) -> Plan:
    """The plan in ``path``; a part's ``grid`` is found relative to the plan's folder or the
    nearest folder above it that holds it (a repository's root).

    Raises:
        PlanError: a missing or mistyped key, an unknown role.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise PlanError(f"{path}: cannot read the plan: {error}") from None
    confidence = _get(data, "confidence", float, path, "")
    parts = tuple(_part(entry, path, f"parts[{i}]")
                  for i, entry in enumerate(_get(data, "parts", list, path, "")))
    return Plan(path, confidence, parts)


def _get(table: dict, key: str, kind: type, path: Path, where: str):
    value = table.get(key)
    ok = isinstance(value, kind) or (kind is float and isinstance(value, int))
    if value is None or not ok or isinstance(value, bool):
        name = f"{where}.{key}" if where else key
        raise PlanError(f"{path}: {name} must be a {kind.__name__} (value: {value!r})")
    return float(value) if kind is float else value


def _part(entry: dict, path: Path, where: str) -> Part:
    families = tuple(_family(f, path, f"{where}.families[{i}]")
                     for i, f in enumerate(_get(entry, "families", list, path, where)))
    outcomes = tuple(_get(entry, "outcomes", list, path, where))
    if len(outcomes) != 3:
        raise PlanError(f"{path}: {where}.outcomes must name 3 outcomes (value: {outcomes})")
    rule_out = entry.get("rule_out_below")
    return Part(name=_get(entry, "name", str, path, where),
                title=_get(entry, "title", str, path, where),
                grid=_locate(path, _get(entry, "grid", str, path, where)),
                seeds=tuple(_get(entry, "seeds", list, path, where)),
                families=families, outcomes=outcomes,
                sensitivity_seeds=tuple(entry.get("sensitivity_seeds", ())),
                rule_out_below=None if rule_out is None
                else _get(entry, "rule_out_below", float, path, where))


def _family(entry: dict, path: Path, where: str) -> Family:
    role = _get(entry, "role", str, path, where)
    if role not in ROLES:
        raise PlanError(f"{path}: {where}.role must be one of {', '.join(ROLES)} "
                        f"(value: {role!r})")
    endpoints = tuple(
        Endpoint(*(_get(e, key, str, path, f"{where}.endpoints[{i}]")
                   for key in ("x", "y", "metric")),
                 _get(e, "paper_gain", float, path, f"{where}.endpoints[{i}]"))
        for i, e in enumerate(_get(entry, "endpoints", list, path, where)))
    return Family(_get(entry, "name", str, path, where), role, endpoints)


def _locate(plan: Path, grid: str) -> Path:
    """``grid`` in the plan's folder or the nearest folder above that holds it; if none does
    (not run yet), as named, relative to the plan's folder."""
    for folder in (plan.parent, *plan.parent.resolve().parents):
        if (folder / grid).is_dir():
            return folder / grid
    return Path(grid)


def analyse(plan: Plan) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """``confirm.csv``'s and ``confirm_per_fold.csv``'s tables, and one line per part not
    analysed (its grid not complete for the part's seeds)."""
    config = StatsConfig(confidence=plan.confidence)
    rows, per_fold, skipped = [], [], []
    for part in plan.parts:
        runs = _complete_runs(part, skipped)
        if runs is None:
            continue
        analyses = {"planned": part.seeds}
        if part.sensitivity_seeds:
            analyses["sensitivity"] = part.sensitivity_seeds
        analyses |= {f"seed {seed}": (seed,) for seed in part.seeds}
        for analysis, seeds in analyses.items():
            chosen = runs[runs.seed.isin(seeds)]
            for family in part.families:
                results = [paired(chosen, e.contrast, e.metric, config)
                           for e in family.endpoints]
                adjusted = (holm([r.p_value for r in results])
                            if analysis == "planned" else [np.nan] * len(results))
                for endpoint, result, p_holm in zip(family.endpoints, results, adjusted):
                    row = _row(part, family, analysis, seeds, endpoint, result, p_holm, config)
                    rows.append(row)
                    per_fold += [{"part": part.name, "analysis": analysis,
                                  "comparison": row["comparison"], "metric": endpoint.metric,
                                  "fold": fold, "difference": d}
                                 for fold, d in zip(result.folds, result.differences)]
    return pd.DataFrame(rows, columns=COLUMNS), pd.DataFrame(per_fold), skipped


def _complete_runs(part: Part, skipped: list[str]) -> pd.DataFrame | None:
    """The part's runs, every seed of it finished on every fold of both sides; None (and a line
    in ``skipped``) otherwise."""
    if not part.grid.is_dir():
        skipped.append(f"{part.name}: not analysed, its grid {part.grid} does not exist (yet)")
        return None
    recorded, _ = recorded_runs(part.grid)
    wanted = [run for run in recorded if key_from_path(part.grid / run, part.grid).seed
              in part.seeds]
    done = sum((part.grid / run / "finished.json").is_file() for run in wanted)
    try:
        runs, _ = run_rows(part.grid, seeds=part.seeds)
    except IncompleteEvidence:
        skipped.append(f"{part.name}: not analysed, {done} of {len(wanted)} runs of seeds "
                       f"{' '.join(map(str, part.seeds))} in {part.grid} finished (the plan "
                       "analyses complete grids only)")
        return None
    for endpoint in (e for family in part.families for e in family.endpoints):
        for side in endpoint.contrast.configs:
            of_side = runs[(runs.variant == side.variant) & (runs.weighting == side.weighting)
                           & (runs.annotations == side.annotations)
                           & (runs.direction == side.direction)]
            seeds = of_side.groupby("fold").seed.apply(lambda s: tuple(sorted(s)))
            if of_side.empty or set(seeds) != {tuple(sorted(part.seeds))}:
                raise IncompleteEvidence(
                    f"{part.grid}: {side.label} does not have seeds "
                    f"{' '.join(map(str, part.seeds))} on every fold (part {part.name})")
    return runs


def _row(part: Part, family: Family, analysis: str, seeds: tuple[int, ...], endpoint: Endpoint,
         result, p_holm: float, config: StatsConfig) -> dict:
    low, high = result.ci
    planned_primary = analysis == "planned" and family.role == "primary"
    return {"part": part.name, "family": family.name, "role": family.role, "analysis": analysis,
            "seeds": " ".join(map(str, seeds)), "comparison": result.contrast,
            "metric": endpoint.metric, "folds": result.pairs, "diff": result.mean,
            "ci_low": low, "ci_high": high, "p_value": result.p_value, "p_holm": p_holm,
            "paper_gain": endpoint.paper_gain,
            "paper_in_ci": bool(low <= endpoint.paper_gain <= high),
            "rule_out": bool(high < (part.rule_out_below if part.rule_out_below is not None
                                     else endpoint.paper_gain)) if planned_primary else None,
            "outcome": (outcome(part, result.mean, p_holm, high, config.alpha)
                        if planned_primary else None),
            "folds_favouring": f"{int((np.asarray(result.differences) > 0).sum())}/"
                               f"{result.pairs}"}


def outcome(part: Part, mean: float, p_holm: float, ci_high: float, alpha: float) -> str:
    """The part's decision rule (module docstring) for one primary endpoint."""
    first, second, third = part.outcomes
    if part.rule_out_below is None:
        if p_holm <= alpha:
            return first if mean > 0 else second
        return third
    if p_holm <= alpha and mean > 0:
        return first
    if ci_high < part.rule_out_below:
        return f"{second} (reversed)" if p_holm <= alpha else second
    return third


def write_confirm(plan_path: Path, out: Path) -> tuple[list[Path], list[str]]:
    """``confirm.csv`` and ``confirm_per_fold.csv`` in ``out`` (the paths), and the parts not
    analysed."""
    from rnn_seg.runs.folder import write_atomic

    table, per_fold, skipped = analyse(read_plan(plan_path))
    written = []
    for name, frame in (("confirm.csv", table), ("confirm_per_fold.csv", per_fold)):
        write_atomic(out / name, frame.to_csv(index=False, float_format="%.4f"))
        written.append(out / name)
    return written, skipped

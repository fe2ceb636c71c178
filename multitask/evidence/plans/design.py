"""What a confirmatory plan's design could detect, and what more seeds or more folds would
change: for each primary endpoint of each part of a plan (``confirm``), the variance of its
per-fold differences split into the seeds' part and the folds' part, each with its interval, and
the sign-flip test's power at the paper's gain, alone and under the plan's Holm correction, as
seeds and folds grow (``statistics.design`` states the model and the methods).

Exploratory: it reads the runs the plan's test read (a part whose grid is not complete is left
out, with the line ``confirm`` gives), or, with ``grid``, the same endpoints on another grid's
runs (e.g. ``results/grid`` at 128 units, with no check of the plan's width).

Output, in ``--out``: ``design.csv``, one row per part and primary endpoint:

* ``part``, ``family``, ``family_size`` (Holm's ``m``), ``comparison``, ``metric``, ``grid``,
  ``seeds`` (pooled within each fold), ``folds``, ``diff`` (the mean fold difference),
  ``paper_gain``;
* ``sd`` (of the per-fold differences) and its 95 % interval ``sd_low``, ``sd_high``;
  ``seed_variance`` (``S``) and its degrees of freedom ``seed_df``; ``seed_ratio`` (``S / V``,
  unclipped), ``seed_share`` (clipped to 1, ``claims.csv``'s) and its interval ``share_low``,
  ``share_high``; ``fold_sd`` (``tau``, the floor of ``sd`` as seeds grow);
* ``power``: the test's power at the paper's gain at the runs' design, before any correction
  (``claims.csv``'s ``power_at_paper_effect``); ``power_holm``: at Holm's first-step level
  ``alpha / family_size``, the least it can be under the plan's correction; ``power_low``,
  ``power_high``: ``power`` at the ends of the ``sd`` interval;
* ``ceiling``, ``ceiling_holm``: the same two as seeds grow without bound (``sd`` = ``fold_sd``);
  ``ceiling_low``, ``ceiling_high``: ``ceiling`` at the ends of the seed share's interval.

``design_power.csv``: per part and endpoint, for ``folds`` in the runs' number and ``MORE_FOLDS``
and ``seeds`` per side in ``SEEDS`` (``inf``: the ceiling), ``sd`` and the two powers (at
``MORE_FOLDS`` from ``MORE_FOLDS_SAMPLES`` simulated vectors).
"""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pandas as pd

from rnn_seg.runs.folder import write_atomic

from ..statistics.design import detection_power, holm_config, variance_split
from ..statistics.paired import StatsConfig
from .confirm import Part, Plan, PlanError, as_named, complete_runs, read_plan

#: Seeds per side and fold of the power table (``math.inf``: the ceiling).
SEEDS = (1, 2, 3, 5, 10, math.inf)
#: Folds (test users) of the power table beyond the runs' own, and the standard normal vectors
#: simulated for them (2^(n-1) splits each: a tenth of the default keeps 12 folds to about a
#: minute; Monte-Carlo error at most 0.0016).
MORE_FOLDS = (10, 12)
MORE_FOLDS_SAMPLES = 100_000
#: The files written, in order.
FILES = ("design.csv", "design_power.csv")


def write_design(plan_path: Path, out: Path, part_name: str | None = None,
                 grid: Path | None = None, seeds: tuple[int, ...] | None = None,
                 config: StatsConfig | None = None) -> tuple[list[Path], list[str]]:
    """``design.csv`` and ``design_power.csv`` in ``out`` for the plan's parts (or the one named
    ``part_name``), on each part's grid and seeds or on ``grid`` and ``seeds``. Returns the paths
    written and one line per part left out.

    Raises:
        confirm.PlanError: the plan cannot be read, or names no part ``part_name``; ``grid``
            without ``part_name`` in a plan of several parts.
    """
    plan = read_plan(plan_path)
    parts = _chosen_parts(plan, plan_path, part_name, grid, seeds)
    config = config or StatsConfig(confidence=plan.confidence)
    rows, table, skipped = [], [], []
    for part in parts:
        found = complete_runs(part, skipped)
        if found is not None:
            _part_rows(part, found[0], config, rows, table)
    written = []
    for name, frame in zip(FILES, (pd.DataFrame(rows), pd.DataFrame(table))):
        write_atomic(out / name, frame.to_csv(index=False, float_format="%.4f"))
        written.append(out / name)
    return written, skipped


def _chosen_parts(plan: Plan, plan_path: Path, part_name: str | None, grid: Path | None,
                  seeds: tuple[int, ...] | None) -> list[Part]:
    """The plan's parts to read, ``grid`` (with the width unchecked) and ``seeds`` put in."""
    parts = [p for p in plan.parts if part_name in (None, p.name)]
    if not parts:
        raise PlanError(f"{plan_path}: no part named {part_name!r} (parts: "
                        f"{', '.join(p.name for p in plan.parts)})")
    if grid is not None and len(parts) > 1:
        raise PlanError(f"{plan_path}: another grid replaces one part's: name the part "
                        f"({', '.join(p.name for p in parts)})")
    if grid is not None:
        parts = [replace(parts[0], grid=grid, grid_name=str(grid), hidden=None)]
    return [replace(p, seeds=seeds) if seeds else p for p in parts]


def _part_rows(part: Part, runs: pd.DataFrame, config: StatsConfig, rows: list[dict],
               table: list[dict]) -> None:
    """Append the rows of ``part``'s primary endpoints to ``rows`` (``design.csv``) and
    ``table`` (``design_power.csv``)."""
    for family in (f for f in part.families if f.role == "primary"):
        holm = holm_config(config, len(family.endpoints))
        for endpoint in family.endpoints:
            split = variance_split(runs, endpoint.contrast, endpoint.metric, config)
            result, gain = split.result, endpoint.paper_gain
            folds = result.pairs
            sd_low, sd_high = split.sd_interval(config.confidence)
            share_low, share_high = split.share_interval(config.confidence)
            ceiling = split.sd_with(math.inf)
            key = {"part": part.name, "comparison": result.contrast, "metric": result.metric}
            rows.append({
                **key, "family": family.name, "family_size": len(family.endpoints),
                "grid": part.grid_name or str(part.grid),
                "seeds": " ".join(map(str, part.seeds)), "folds": folds, "diff": result.mean,
                "paper_gain": gain, "sd": result.sd, "sd_low": sd_low, "sd_high": sd_high,
                "seed_variance": split.seed, "seed_df": split.seed_df,
                "seed_ratio": split.ratio, "seed_share": split.share,
                "share_low": share_low, "share_high": share_high,
                "fold_sd": ceiling,
                "power": detection_power(folds, gain, result.sd, config),
                "power_holm": detection_power(folds, gain, result.sd, holm),
                "power_low": detection_power(folds, gain, sd_high, config),
                "power_high": detection_power(folds, gain, sd_low, config),
                "ceiling": detection_power(folds, gain, ceiling, config),
                "ceiling_holm": detection_power(folds, gain, ceiling, holm),
                "ceiling_low": detection_power(folds, gain, split.sd_with(math.inf, share_low),
                                               config),
                "ceiling_high": detection_power(folds, gain,
                                                split.sd_with(math.inf, share_high), config)})
            for n in (folds, *MORE_FOLDS):
                alone, corrected = (config, holm) if n == folds else (
                    replace(c, power_samples=MORE_FOLDS_SAMPLES) for c in (config, holm))
                for k in SEEDS:
                    sd = split.sd_with(k)
                    table.append({**key, "paper_gain": gain, "folds": n,
                                  "seeds": "inf" if math.isinf(k) else k, "sd": sd,
                                  "power": detection_power(n, gain, sd, alone),
                                  "power_holm": detection_power(n, gain, sd, corrected)})

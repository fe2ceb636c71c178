"""The exploratory analyses a confirmatory plan's text names beside its tests, never part of them.

``results/confirm/PLAN.md`` (part 2) names one: "labelled exploratory, the same analysis with
seed 0 pooled (seeds 0-5; A's seed 0 from ``results/width/h512-a180/``, APoc's from
``results/width/h512/``)". The plan file (``plan.toml``) cannot hold it, so an
``exploratory.toml`` beside it does: per analysis, the plan's part it repeats and, per side
(configuration), the runs of another grid pooled into it::

    [[analyses]]
    part = "replication-512"
    name = "seed 0 pooled"
    borrowed = [{config = "A-fixed", grid = "results/width/h512-a180", seeds = [0]},
                {config = "APoc-gradnorm", grid = "results/width/h512", seeds = [0]}]

Each analysis repeats every endpoint of its part on the part's runs plus the borrowed ones,
seeds averaged within each fold as the plan's test does, and is written to ``exploratory.csv``
(``confirm.csv``'s columns; ``analysis`` = ``exploratory: <name>``; no Holm, no outcome, no
rule-out) and ``exploratory_per_fold.csv``: the planned rows are never touched. An analysis is
computed only for a part the plan analysed (no interim look), and only when every borrowed run
is finished and usable, of the settings of the part's runs of its configuration
(``pooling.pool``), on every fold the part has and of seeds the part does not hold; otherwise a
line says why it was not.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from ..runs.collect import LEFT_OUT, IncompleteEvidence, run_records
from ..runs.pooling import MixedSettings, pool, record_key
from ..statistics.paired import ConfigId, StatsConfig
from .confirm import (Plan, PlanError, as_named, check_keys, complete_runs, endpoint_rows,
                      fold_seed_gaps, locate_grid, plan_config, plan_list, plan_seeds,
                      plan_value, read_plan_file, run_commit, tables)

#: The exploratory analyses' file, beside the plan's.
EXPLORATORY_FILE = "exploratory.toml"
KINDS = {"exploratory": {"analyses"}, "analysis": {"part", "name", "borrowed"},
         "borrowed": {"config", "grid", "seeds"}}


@dataclass(frozen=True)
class Borrowed:
    """Runs of ``config`` (a side's label, e.g. ``A-fixed``) in another ``grid``, of ``seeds``."""

    config: ConfigId
    grid: Path
    seeds: tuple[int, ...]
    grid_name: str = ""                 # ``grid`` as the file names it ("": as found)


@dataclass(frozen=True)
class Exploratory:
    """A part's endpoints again, with ``borrowed`` runs pooled into their sides."""

    part: str
    name: str
    borrowed: tuple[Borrowed, ...]


def read_exploratory(path: Path, plan: Plan) -> tuple[Exploratory, ...]:
    """The analyses in ``path`` (none when there is no such file); grids are found as the plan's.
    The file is checked as the plan is (``confirm``): a folder, a FIFO or a dangling link of its
    name is refused, not taken for no file.

    Raises:
        PlanError: a file that is no exploratory file; a missing, mistyped or unknown key, a
            part the plan does not have, two analyses of one name in a part, a run borrowed
            twice.
    """
    if not (path.exists() or path.is_symlink()):
        return ()
    data = read_plan_file(path, "plan's exploratory")
    check_keys(data, "exploratory", path, "", KINDS)
    parts = {part.name for part in plan.parts}
    found = []
    for i, entry in enumerate(plan_value(data, "analyses", list, path, "")):
        where = f"analyses[{i}]"
        check_keys(entry, "analysis", path, where, KINDS)
        part = plan_value(entry, "part", str, path, where)
        if part not in parts:
            raise PlanError(f"{path}: {where}.part: {part!r} is not a part of {plan.path} "
                            f"({', '.join(sorted(parts))})")
        name = plan_value(entry, "name", str, path, where)
        if any((a.part, a.name) == (part, name) for a in found):
            raise PlanError(f"{path}: {where}.name: part {part} has an analysis {name!r} "
                            "already")
        borrowed = []
        for j, side in enumerate(plan_list(entry, "borrowed", path, where)):
            at = f"{where}.borrowed[{j}]"
            check_keys(side, "borrowed", path, at, KINDS)
            config = plan_config(side, "config", path, at)
            named = plan_value(side, "grid", str, path, at)
            seeds = plan_seeds(side, "seeds", path, at)
            twice = [b for b in borrowed if b.config == config and set(b.seeds) & set(seeds)]
            if twice:
                raise PlanError(f"{path}: {at}: {config.label}'s seeds "
                                f"{' '.join(map(str, sorted(set(twice[0].seeds) & set(seeds))))}"
                                " are borrowed already")
            borrowed.append(Borrowed(config, locate_grid(path, named), seeds, named))
        found.append(Exploratory(part, name, tuple(borrowed)))
    return tuple(found)


def analyse_exploratory(plan: Plan, analyses: tuple[Exploratory, ...]
                        ) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """``exploratory.csv``'s and ``exploratory_per_fold.csv``'s tables, and one line per
    analysis not computed (its part not analysed, or its borrowed runs unusable)."""
    config = StatsConfig(confidence=plan.confidence)
    rows, per_fold, notes = [], [], []
    for analysis in analyses:
        part = next(p for p in plan.parts if p.name == analysis.part)
        found = complete_runs(part, [])
        label = f"exploratory: {analysis.name}"
        if found is None:
            notes.append(f"{part.name}, {label}: not computed, the part is not analysed")
            continue
        runs, records = found
        try:
            borrowed = [_borrowed_runs(b, part.seeds, sorted(set(runs.fold)), runs, records)
                        for b in analysis.borrowed]
        except (IncompleteEvidence, MixedSettings) as error:
            note = f"{part.name}, {label}: not computed: {' '.join(str(error).split())}"
            for grid, name in [(part.grid, part.grid_name),
                               *((b.grid, b.grid_name) for b in analysis.borrowed)]:
                note = as_named(note, grid, name)
            notes.append(note)
            continue
        pooled = pd.concat([runs, *borrowed], ignore_index=True)
        seeds = tuple(sorted(set(pooled.seed)))
        endpoint_rows(part, label, seeds, pooled, config, rows, per_fold)
    return tables(rows, per_fold) + (notes,)


def _borrowed_runs(borrowed: Borrowed, part_seeds: tuple[int, ...], folds: list[str],
                   runs: pd.DataFrame, records: dict) -> pd.DataFrame:
    """The borrowed runs of ``borrowed.config`` (with their ``commit``), checked: finished and
    usable, of seeds the part does not hold, one per seed on each of ``folds``, of the settings
    of the part's runs of that configuration (``records``).

    Raises:
        IncompleteEvidence: naming what is missing or wrong.
        MixedSettings: the borrowed runs' settings differ from the part's.
    """
    side = borrowed.config
    where = f"{borrowed.grid} ({side.label}, seeds {' '.join(map(str, borrowed.seeds))})"
    if set(borrowed.seeds) & set(part_seeds):
        raise IncompleteEvidence(f"{where}: seeds the part holds already")
    if not borrowed.grid.is_dir():
        raise IncompleteEvidence(f"{where}: no such grid")
    found, problems, found_records = run_records(borrowed.grid, allow_incomplete=True,
                                                 seeds=borrowed.seeds)
    problems = [line for line in problems if not line.startswith(LEFT_OUT)]
    if problems:
        raise IncompleteEvidence(f"{where}: {problems[0]}")
    found = found.assign(commit=[run_commit(r) for r in found_records.values()])
    gaps = fold_seed_gaps(found, side, folds, borrowed.seeds)
    if gaps:
        raise IncompleteEvidence(f"{where}: not one run per seed on each of the folds "
                                 f"{' '.join(folds)}: seeds on {', '.join(gaps)}")
    pool({**_of(side, records), **_of(side, found_records)}, where)
    return side.select(found)


def _of(side: ConfigId, records: dict) -> dict:
    """The ``records`` (run folder -> record) of runs of the configuration ``side``."""
    def config(record) -> tuple[str, ...]:
        key = record_key(record)
        return key.variant, key.weighting, key.annotations, key.direction
    wanted = (side.variant, side.weighting, side.annotations, side.direction)
    return {run: record for run, record in records.items() if config(record) == wanted}

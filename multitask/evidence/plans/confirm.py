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

An interval end is compared with a paper's gain (``rule_out``, ``paper_in_ci``, the replication's
threshold) at two decimals, the gain at its published digit, as the plan says "so a reader can
see on which side they lie" (``shown``).

Beside the planned analysis (``analysis`` = ``planned``), every endpoint is also given for each
seed alone (``seed <k>``) and, where the plan names ``sensitivity_seeds``, for those seeds pooled
(``sensitivity``); these rows are descriptive (no outcome, no correction).

**No interim analysis**: a part is analysed only when every run its grid records for the part's
seeds has finished and is usable (finite scores, the grid's settings, one setting per
configuration), at the plan's width (``hidden``), and every side of every endpoint has exactly
the part's seeds on every fold; otherwise the part is reported as not analysed, with how many
runs are done and what is wrong, and gets no rows (the other parts are still analysed). Seeds
the grid holds beyond the part's are left out.

The plan is checked as strictly as a grid spec, each problem a one-line ``PlanError`` naming the
file and the key: a missing, mistyped or unknown key; a number that is not finite (``inf``,
``nan``: a gain or threshold no interval can be compared with) or out of range (``confidence``
in (0, 1), ``hidden`` >= 1, seeds >= 0); a name, title, outcome or configuration that is empty
or not one line of text; ``outcomes`` not three distinct words (as a reader tells them: case
and spacing aside); a configuration that is none (``APoc-gradnrom``: an unknown variant or
weighting) or a metric the runs have not; an endpoint comparing a configuration with itself, or
tested twice in a part, in one family or two (``x - y`` and ``y - x`` alike: it would enter
Holm's correction twice). The file is read by the project's one TOML
reader (``jigsaws_tools.toml_files.read_toml``), which refuses a folder, a FIFO, a file too large
or nested too deeply at once.

Output, in ``--out``: ``confirm.csv`` (one row per part, family, endpoint and analysis, with
``commits``: the commits whose code trained the runs behind it, for the reader to hold against
the commits the plan names) and ``confirm_per_fold.csv`` (the fold differences behind each row),
written with the report ``confirm.md`` by ``confirm_report``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.errors import DefinitionError
from jigsaws_tools.toml_files import read_toml
from rnn_seg.runs.folder import FINISHED, RunFolderError, read_json

from ...models.run_record import RunRecord
from ...models.variants import check_weighting, get_variant
from ..runs.collect import (LEFT_OUT, METRICS, IncompleteEvidence, key_from_path, per_class,
                            recorded_runs, run_records)
from ..runs.pooling import MixedSettings, architecture
from ..statistics.paired import (TIES, ConfigId, Contrast, StatsConfig, config_labels, holm,
                                 paired)

ROLES = ("primary", "secondary")
COLUMNS = ["part", "family", "role", "analysis", "seeds", "comparison", "metric", "folds",
           "diff", "ci_low", "ci_high", "p_value", "p_holm", "paper_gain", "paper_in_ci",
           "rule_out", "outcome", "folds_favouring", "commits"]
PER_FOLD_COLUMNS = ["part", "analysis", "comparison", "metric", "fold", "difference"]
#: Problems a line of a part not analysed names (the rest are counted).
SHOWN_PROBLEMS = 3
#: Decimals of an interval end when it is compared with a paper's gain (PLAN.md, ``shown``).
DECIMALS = 2
#: The tasks whose per-class scores a metric may name (``gesture_f1_G2``).
TASKS = ("gesture", "progress")


#: The keys a plan's tables may hold; any other is refused (a misspelt key is not ignored).
KEYS = {"plan": {"confidence", "parts"},
        "part": {"name", "title", "grid", "hidden", "seeds", "sensitivity_seeds", "outcomes",
                 "rule_out_below", "families"},
        "family": {"name", "role", "endpoints"},
        "endpoint": {"x", "y", "metric", "paper_gain"}}


#: What a plan's value of each type is called in a message.
TYPE_NAMES = {float: "a float", int: "an integer", str: "a string", list: "a list"}


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
    hidden: int | None = None           # LSTM units per direction of every run; None: unchecked
    grid_name: str = ""                 # ``grid`` as the plan names it ("": as found)


@dataclass(frozen=True)
class Plan:
    path: Path
    confidence: float
    parts: tuple[Part, ...]


def read_plan(path: Path) -> Plan:
    """The plan in ``path``; a part's ``grid`` is found relative to the plan's folder or the
    nearest folder above it that holds it (a repository's root).

    Raises:
        PlanError: a file that is no plan, a missing, mistyped, unknown or out-of-range key
            (module docstring).
    """
    path = Path(path)
    data = read_plan_file(path, "plan")
    check_keys(data, "plan", path, "")
    confidence = plan_value(data, "confidence", float, path, "")
    if not 0 < confidence < 1:
        raise PlanError(f"{path}: confidence must be in (0, 1), e.g. 0.95 "
                        f"(value: {confidence!r})")
    parts = tuple(_part(entry, path, f"parts[{i}]")
                  for i, entry in enumerate(plan_list(data, "parts", path, "")))
    names = [part.name for part in parts]
    if len(set(names)) != len(names):
        raise PlanError(f"{path}: parts: two parts of one name (names: {', '.join(names)})")
    return Plan(path, confidence, parts)


def read_plan_file(path: Path, what: str) -> dict:
    """The tables of the TOML file ``path`` (``toml_files.read_toml``: a folder, a FIFO, a file
    too large, not UTF-8, not TOML or nested too deeply is refused at once); a ``PlanError``
    naming it otherwise."""
    try:
        return read_toml(path, what)
    except DefinitionError as error:
        raise PlanError(str(error)) from None


def plan_value(table: dict, key: str, kind: type, path: Path, where: str):
    """``table[key]``, of ``kind`` (an int where a float is asked is read as one): a float
    finite, a str one non-empty line of printable text."""
    value = table.get(key)
    ok = isinstance(value, kind) or (kind is float and isinstance(value, int))
    name = f"{where}.{key}" if where else key
    if value is None or not ok or isinstance(value, bool):
        raise PlanError(f"{path}: {name} must be {TYPE_NAMES[kind]} (value: {value!r})")
    if kind is float and not math.isfinite(value):
        raise PlanError(f"{path}: {name} must be a finite number (value: {value!r})")
    if kind is str:
        plan_text(value, path, name)
    return float(value) if kind is float else value


def plan_text(value: str, path: Path, name: str) -> str:
    """``value`` when it is one non-empty line of printable text (a name, a title, an outcome:
    words the report and the CSVs print on one line)."""
    if not value.strip() or not value.isprintable():
        raise PlanError(f"{path}: {name} must be one non-empty line of text (value: {value!r})")
    return value


def plan_list(table: dict, key: str, path: Path, where: str) -> list:
    """``table[key]``, a non-empty list (a part without families, a family without endpoints
    tests nothing)."""
    entries = plan_value(table, key, list, path, where)
    if not entries:
        raise PlanError(f"{path}: {where + '.' if where else ''}{key} must not be empty")
    return entries


def check_keys(table, kind: str, path: Path, where: str, keys: dict[str, set[str]] = KEYS
               ) -> None:
    """Raise unless ``table`` is a table whose keys are all ``keys[kind]``."""
    if not isinstance(table, dict):
        raise PlanError(f"{path}: {where or 'the file'} must be a table (value: {table!r})")
    unknown = sorted(set(table) - keys[kind])
    if unknown:
        raise PlanError(f"{path}: {where + '.' if where else ''}{unknown[0]}: not a key of a "
                        f"plan's {kind} (known: {', '.join(sorted(keys[kind]))})")


def plan_seeds(entry: dict, key: str, path: Path, where: str, required: bool = True
               ) -> tuple[int, ...]:
    """``entry[key]``, a non-empty list of distinct seeds (integers); () when not required and
    absent."""
    if key not in entry and not required:
        return ()
    seeds = plan_value(entry, key, list, path, where)
    if not seeds or not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0
                            for s in seeds) or len(set(seeds)) != len(seeds):
        raise PlanError(f"{path}: {where}.{key} must be a list of distinct integer seeds >= 0 "
                        f"(value: {seeds!r})")
    return tuple(seeds)


def plan_config(entry: dict, key: str, path: Path, where: str) -> ConfigId:
    """``entry[key]``, a configuration of a grid (``paired.ConfigId``) whose variant and
    weighting exist: a misspelt one is named here, not reported later as runs missing."""
    text = plan_value(entry, key, str, path, where)
    try:
        config = ConfigId.parse(text)
        check_weighting(get_variant(config.variant), config.weighting)
    except ValueError as error:
        raise PlanError(f"{path}: {where}.{key}: {text!r} is not a configuration: {error}"
                        ) from None
    return config


def _part(entry: dict, path: Path, where: str) -> Part:
    check_keys(entry, "part", path, where)
    families = tuple(_family(f, path, f"{where}.families[{i}]")
                     for i, f in enumerate(plan_list(entry, "families", path, where)))
    names = [family.name for family in families]
    if len(set(names)) != len(names):
        raise PlanError(f"{path}: {where}.families: two families of one name (names: "
                        f"{', '.join(names)})")
    _tested_once(families, path, where)
    outcomes = tuple(plan_value(entry, "outcomes", list, path, where))
    if len(outcomes) != 3 or not all(isinstance(o, str) for o in outcomes):
        raise PlanError(f"{path}: {where}.outcomes must name 3 outcomes (value: {outcomes})")
    for i, word in enumerate(outcomes):
        plan_text(word, path, f"{where}.outcomes[{i}]")
    if len({" ".join(o.casefold().split()) for o in outcomes}) != 3:   # as a reader tells them
        raise PlanError(f"{path}: {where}.outcomes must be 3 distinct outcomes (value: "
                        f"{list(outcomes)})")
    hidden = None if "hidden" not in entry else plan_value(entry, "hidden", int, path, where)
    if hidden is not None and hidden < 1:
        raise PlanError(f"{path}: {where}.hidden must be an integer >= 1 (value: {hidden})")
    rule_out = entry.get("rule_out_below")
    seeds = plan_seeds(entry, "seeds", path, where)
    sensitivity = plan_seeds(entry, "sensitivity_seeds", path, where, False)
    if not set(sensitivity) <= set(seeds):
        raise PlanError(f"{path}: {where}.sensitivity_seeds must be some of the part's seeds "
                        f"{list(seeds)} (value: {list(sensitivity)})")
    return Part(name=plan_value(entry, "name", str, path, where),
                title=plan_value(entry, "title", str, path, where),
                grid=locate_grid(path, plan_value(entry, "grid", str, path, where)),
                grid_name=plan_value(entry, "grid", str, path, where),
                seeds=seeds, families=families, outcomes=outcomes, sensitivity_seeds=sensitivity,
                rule_out_below=None if rule_out is None
                else plan_value(entry, "rule_out_below", float, path, where),
                hidden=hidden)


def _family(entry: dict, path: Path, where: str) -> Family:
    check_keys(entry, "family", path, where)
    role = plan_value(entry, "role", str, path, where)
    if role not in ROLES:
        raise PlanError(f"{path}: {where}.role must be one of {', '.join(ROLES)} "
                        f"(value: {role!r})")
    endpoints = []
    for i, e in enumerate(plan_list(entry, "endpoints", path, where)):
        endpoint = _endpoint(e, path, f"{where}.endpoints[{i}]")
        if len(frozenset(endpoint.contrast.configs)) == 1:
            raise PlanError(f"{path}: {where}.endpoints[{i}]: x and y are one configuration, "
                            f"{endpoint.x!r}")
        endpoints.append(endpoint)
    return Family(plan_value(entry, "name", str, path, where), role, tuple(endpoints))


def _tested_once(families: tuple[Family, ...], path: Path, where: str) -> None:
    """Refuse an endpoint (two configurations, either order, and a metric) tested twice in one
    part, in one family (it would enter Holm's correction twice) or in two (one test would be
    reported as two, and counted in the second family's correction)."""
    tested = {}
    for f, family in enumerate(families):
        for i, endpoint in enumerate(family.endpoints):
            here = f"families[{f}].endpoints[{i}]"
            same = tested.setdefault((frozenset(endpoint.contrast.configs), endpoint.metric),
                                     here)
            if same != here:
                raise PlanError(f"{path}: {where}.{here}: {endpoint.x} - {endpoint.y} on "
                                f"{endpoint.metric} is tested already ({where}.{same}); an "
                                "endpoint is tested once in a part (twice, it would enter "
                                "Holm's correction twice)")


def _endpoint(entry: dict, path: Path, where: str) -> Endpoint:
    """One endpoint of a family: two configurations (``plan_config``), a metric the runs have,
    the paper's gain, finite."""
    check_keys(entry, "endpoint", path, where)
    for side in ("x", "y"):
        plan_config(entry, side, path, where)
    metric = plan_value(entry, "metric", str, path, where)
    task, _, score = metric.partition("_")
    if metric not in METRICS and not (task in TASKS and per_class(score)):
        raise PlanError(f"{path}: {where}.metric: {metric!r} is not a score of the runs "
                        f"({', '.join(METRICS)}, or a per-class score such as "
                        "gesture_f1_G2)")
    return Endpoint(entry["x"], entry["y"], metric,
                    plan_value(entry, "paper_gain", float, path, where))


def locate_grid(plan: Path, grid: str) -> Path:
    """``grid`` in the plan's folder or the nearest folder above that holds it; if none does
    (not run yet), as named, relative to the plan's folder (never to the current folder: the
    command reads the same grids wherever it is run from)."""
    for folder in (plan.parent, *plan.parent.resolve().parents):
        if (folder / grid).is_dir():
            return folder / grid
    return plan.parent / grid


def as_named(text: str, grid: Path, name: str) -> str:
    """``text`` with ``grid``'s path as found here written as the plan ``name``s it, so that what
    the command writes does not depend on where the checkout lies."""
    return text.replace(str(grid), name) if name else text


def analyse(plan: Plan) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """``confirm.csv``'s and ``confirm_per_fold.csv``'s tables, and one line per part not
    analysed (its grid not complete for the part's seeds)."""
    config = StatsConfig(confidence=plan.confidence)
    rows, per_fold, skipped = [], [], []
    for part in plan.parts:
        found = complete_runs(part, skipped)
        if found is None:
            continue
        runs, _ = found
        _check_metrics(plan, part, runs)
        analyses = {"planned": part.seeds}
        if part.sensitivity_seeds:
            analyses["sensitivity"] = part.sensitivity_seeds
        analyses |= {f"seed {seed}": (seed,) for seed in part.seeds}
        for analysis, seeds in analyses.items():
            endpoint_rows(part, analysis, seeds, runs[runs.seed.isin(seeds)], config, rows,
                          per_fold)
    return tables(rows, per_fold) + (skipped,)


def _check_metrics(plan: Plan, part: Part, runs: pd.DataFrame) -> None:
    """Raise ``PlanError`` for an endpoint of ``part`` on a metric its grid's runs have not (a
    per-class score of a class the task has not, ``gesture_f1_G99``): the plan is wrong, not
    the grid incomplete."""
    for family in part.families:
        for endpoint in family.endpoints:
            if endpoint.metric not in runs.columns:
                raise PlanError(f"{plan.path}: part {part.name}, family {family.name}: metric "
                                f"{endpoint.metric!r} is not a score of the runs of "
                                f"{as_named(str(part.grid), part.grid, part.grid_name)}")


def tables(rows: list[dict], per_fold: list[dict]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The rows as ``confirm.csv``'s and ``confirm_per_fold.csv``'s tables (their columns even
    when empty)."""
    return (pd.DataFrame(rows, columns=COLUMNS),
            pd.DataFrame(per_fold, columns=PER_FOLD_COLUMNS))


def endpoint_rows(part: Part, analysis: str, seeds: tuple[int, ...], chosen: pd.DataFrame,
                  config: StatsConfig, rows: list[dict], per_fold: list[dict]) -> None:
    """Append to ``rows`` and ``per_fold`` every endpoint of ``part`` tested on the runs
    ``chosen`` (those of ``seeds``); Holm's correction and the outcome only for the ``planned``
    analysis."""
    for family in part.families:
        results = [paired(chosen, e.contrast, e.metric, config) for e in family.endpoints]
        adjusted = (holm([r.p_value for r in results], size=len(family.endpoints))
                    if analysis == "planned" else [np.nan] * len(results))
        for endpoint, result, p_holm in zip(family.endpoints, results, adjusted):
            row = _row(part, family, analysis, seeds, endpoint, result, p_holm, config)
            rows.append({**row, "commits": _commits(chosen, endpoint)})
            per_fold += [{"part": part.name, "analysis": analysis,
                          "comparison": row["comparison"], "metric": endpoint.metric,
                          "fold": fold, "difference": d}
                         for fold, d in zip(result.folds, result.differences)]


def complete_runs(part: Part, skipped: list[str]) -> tuple[pd.DataFrame, dict] | None:
    """The part's runs (with the ``commit`` that trained each) and their records (run folder ->
    its config.json): every run its grid records for the part's seeds finished and usable
    (``collect.run_records``), of one setting per configuration (``pooling.pool``), at the
    plan's width, and every side of every endpoint with exactly the part's seeds on each of the
    grid's folds (the folds any of the part's runs has). None, and a line in ``skipped`` saying
    why, otherwise."""
    if not part.grid.is_dir():
        skipped.append(as_named(f"{part.name}: not analysed, its grid {part.grid} does not "
                                "exist (yet)", part.grid, part.grid_name))
        return None
    recorded, _ = recorded_runs(part.grid)
    wanted = [run for run in recorded if key_from_path(part.grid / run, part.grid).seed
              in part.seeds]
    done = sum((part.grid / run / "finished.json").is_file() for run in wanted)
    try:
        runs, problems, records = run_records(part.grid, allow_incomplete=True, seeds=part.seeds)
    except (IncompleteEvidence, MixedSettings) as error:
        problems, runs, records = [str(error)], None, {}
    problems = [line for line in problems if not line.startswith(LEFT_OUT)]
    incomplete = runs is None or bool(problems)
    if not incomplete:
        problems = _plan_problems(part, runs, records)
    if problems:
        shown = "; ".join(" ".join(line.split()) for line in problems[:SHOWN_PROBLEMS])
        more = (f" (and {len(problems) - SHOWN_PROBLEMS} more)"
                if len(problems) > SHOWN_PROBLEMS else "")
        state = (f"{done} of {len(wanted)} runs of seeds {' '.join(map(str, part.seeds))} in "
                 f"{part.grid} finished (the plan analyses complete grids only)" if incomplete
                 else f"its grid {part.grid} does not hold what the plan tests")
        skipped.append(as_named(f"{part.name}: not analysed, {state}: {shown}{more}",
                                part.grid, part.grid_name))
        return None
    return runs.assign(commit=[run_commit(record) for record in records.values()]), records


def run_commit(record: RunRecord) -> str:
    """The commits whose code trained the run, space-separated and sorted: the session that
    started it (its config.json's provenance) and, when another, the one that finished it
    (finished.json's: a run resumed from its checkpoint by another checkout). Each 7 digits, with
    ``-dirty`` when the checkout had uncommitted changes; ``unknown`` when not recorded (a
    finished.json that records no provenance, as an early engine's, adds nothing)."""
    sessions = [record.saved.get("provenance") or {}]
    try:
        finished = read_json(record.path.parent / FINISHED)
    except RunFolderError:
        finished = None
    if not isinstance(finished, dict):
        sessions.append({})                 # unreadable: the finishing session is unknown
    elif "provenance" in finished:
        sessions.append(finished["provenance"] or {})
    return " ".join(sorted({_commit(provenance) for provenance in sessions}))


def _commit(provenance: dict) -> str:
    """One session's commit (``run_commit``)."""
    commit = provenance.get("git_commit")
    if not commit:
        return "unknown"
    return commit[:7] + ("-dirty" if provenance.get("git_dirty") else "")


def _commits(runs: pd.DataFrame, endpoint: Endpoint) -> str:
    """The commits that trained ``runs`` of the endpoint's sides, sorted (PLAN.md names the
    commit each part's runs are trained by; the pooling rule compares settings, not code)."""
    sides = pd.concat([side.select(runs) for side in endpoint.contrast.configs])
    return " ".join(sorted({commit for cell in sides.commit for commit in cell.split()}))


def fold_seed_gaps(runs: pd.DataFrame, side: ConfigId, folds: list[str],
                   seeds: tuple[int, ...]) -> list[str]:
    """Each of ``folds`` (and any other fold ``side`` has in ``runs``) whose runs of ``side``
    are not one per seed of ``seeds``, with the seeds it has: ``["C (0 2)", "D (none)"]``."""
    found = side.select(runs).groupby("fold").seed.apply(lambda s: tuple(sorted(s)))
    wanted = tuple(sorted(seeds))
    return [f"{fold} ({' '.join(map(str, found.get(fold, ()))) or 'none'})"
            for fold in sorted(set(folds) | set(found.index)) if found.get(fold, ()) != wanted]


def _plan_problems(part: Part, runs: pd.DataFrame, records: dict) -> list[str]:
    """What keeps the part's usable ``runs`` (and their ``records``) from being the plan's
    design: a run of another width than the plan's, a side of an endpoint without exactly the
    part's seeds on each fold the part's runs have."""
    problems = [f"{run}: {architecture(record)}, but the plan's part is at {part.hidden} units"
                for run, record in sorted(records.items())
                if part.hidden is not None and architecture(record) != f"lstm-{part.hidden}"]
    folds = sorted(set(runs.fold))
    sides = {side for family in part.families for e in family.endpoints
             for side in e.contrast.configs}
    for side in sorted(sides, key=lambda s: s.label):
        if side.select(runs).empty:
            problems.append(f"{side.label}: no run of this configuration (the grid holds "
                            f"{', '.join(config_labels(runs))})")
            continue
        wrong = fold_seed_gaps(runs, side, folds, part.seeds)
        if wrong:
            problems.append(f"{side.label} does not have seeds "
                            f"{' '.join(map(str, part.seeds))} on every fold of {part.grid}: "
                            f"seeds on {', '.join(wrong)}")
    return problems


def _row(part: Part, family: Family, analysis: str, seeds: tuple[int, ...], endpoint: Endpoint,
         result, p_holm: float, config: StatsConfig) -> dict:
    low, high = result.ci
    planned_primary = analysis == "planned" and family.role == "primary"
    threshold = endpoint.paper_gain if part.rule_out_below is None else part.rule_out_below
    return {"part": part.name, "family": family.name, "role": family.role, "analysis": analysis,
            "seeds": " ".join(map(str, seeds)), "comparison": result.contrast,
            "metric": endpoint.metric, "folds": result.pairs, "diff": result.mean,
            "ci_low": low, "ci_high": high, "p_value": result.p_value, "p_holm": p_holm,
            "paper_gain": endpoint.paper_gain,
            "paper_in_ci": bool(shown(low) <= endpoint.paper_gain <= shown(high)),
            "rule_out": bool(shown(high) < threshold) if planned_primary else None,
            "outcome": (outcome(part, result.mean, p_holm, high, config.alpha)
                        if planned_primary else None),
            "folds_favouring": f"{int((np.asarray(result.differences) > TIES).sum())}/"
                               f"{result.pairs}"}


def shown(value: float) -> float:
    """An interval end as PLAN.md compares it with a paper's gain: "the paper's gains are
    compared to the interval with their published digit and ours with two decimals, so a reader
    can see on which side they lie" (2.996 is 3.00: not below the paper's +3.0)."""
    return round(value, DECIMALS)


def outcome(part: Part, mean: float, p_holm: float, ci_high: float, alpha: float) -> str:
    """The part's decision rule (module docstring) for one primary endpoint; ``ci_high`` is
    compared with ``rule_out_below`` at two decimals (``shown``)."""
    first, second, third = part.outcomes
    if part.rule_out_below is None:
        if p_holm <= alpha and mean != 0:
            return first if mean > 0 else second
        return third
    if p_holm <= alpha and mean > 0:
        return first
    if shown(ci_high) < part.rule_out_below:
        return f"{second} (reversed)" if p_holm <= alpha and mean < 0 else second
    return third

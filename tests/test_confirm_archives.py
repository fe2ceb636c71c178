"""The committed plan against the committed archives' structure, before their grids are complete.

PLAN.md forbids any look at the new seeds' scores before a part's grid is complete, yet a check
that the real archives trip over (a file the fake grids lack, grid.json's spec and provenance,
archive.json, runs of several sessions) would only show once they are. So each part's grid is
rebuilt here from runs already analysed and published, seed 0's, never reading a file of another
seed: part 1 from ``results/paper/grid``'s seed-0 runs, copied as every run its grid.json
records; part 2 from the width grids' seed-0 runs (A's from ``h512-a180``, APoc's from
``h512``), copied as every run of ``results/confirm/h512.toml`` under a grid.json of that spec.
Both parts, and the exploratory analysis, must then be analysed: nothing here asserts a number.
"""
from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest

from multitask.evidence.plans.confirm import analyse, read_plan
from multitask.evidence.plans.exploratory import (EXPLORATORY_FILE, analyse_exploratory,
                                                  read_exploratory)
from multitask.grid.folder import GRID_RECORD
from multitask.grid.spec import expand, load_spec, spec_payload
from rnn_seg.runs.folder import write_json

from tests.fake_grid import FOLDS

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "results" / "paper" / "grid"
WIDTH = ROOT / "results" / "width"
#: The files of the committed archives a grid's record names (never a run's).
RECORDS = (GRID_RECORD, "archive.json")


def _as_seed(source: Path, run_dir: Path, seed: int) -> None:
    """Copy the seed-0 run ``source`` to ``run_dir`` as a run of ``seed``."""
    shutil.copytree(source, run_dir)
    config = json.loads((run_dir / "config.json").read_text())
    config["run"]["train"]["seed"] = seed
    (run_dir / "config.json").write_text(json.dumps(config))


def _seed_zero(run: str) -> str:
    """The seed-0 run of ``run``'s configuration and fold (``.../seed<k>/<fold>``)."""
    *head, _, fold = run.split("/")
    return "/".join([*head, "seed0", fold])


def _paper_grid(dest: Path) -> None:
    """Part 1's grid: the archive's records, every run it records made of its seed-0 run."""
    dest.mkdir(parents=True)
    for name in RECORDS:
        shutil.copyfile(PAPER / name, dest / name)
    for run in json.loads((PAPER / GRID_RECORD).read_text())["runs"]:
        _as_seed(PAPER / _seed_zero(run), dest / run, int(run.split("/seed")[1].split("/")[0]))


def _replication_grid(dest: Path, width: Path) -> None:
    """Part 2's grid: every run of h512.toml, made of the width grids' seed-0 runs."""
    recorded = json.loads((width / "h512" / GRID_RECORD).read_text())["spec"]
    spec = dataclasses.replace(load_spec(ROOT / "results" / "confirm" / "h512.toml"),
                               data_dir=recorded["data_dir"])
    keys = expand(spec, FOLDS)
    for key in keys:
        source = width / ("h512-a180" if key.variant == "A" else "h512")
        _as_seed(source / _seed_zero(str(key.path())), dest / key.path(), key.seed)
    write_json(dest / GRID_RECORD, {"spec": spec_payload(spec),
                                    "runs": [str(key.path()) for key in keys]})


@pytest.mark.skipif(not (PAPER / GRID_RECORD).is_file() or not (WIDTH / "h512").is_dir(),
                    reason="the committed archives are not in this checkout")
@pytest.mark.slow
def test_the_committed_archives_structure_is_analysed_once_complete(tmp_path: Path):
    confirm = tmp_path / "results" / "confirm"
    confirm.mkdir(parents=True)
    for name in ("plan.toml", EXPLORATORY_FILE):
        shutil.copyfile(ROOT / "results" / "confirm" / name, confirm / name)
    for name in ("h512", "h512-a180"):
        shutil.copytree(WIDTH / name, tmp_path / "results" / "width" / name)
    _paper_grid(tmp_path / "results" / "paper" / "grid")
    _replication_grid(confirm / "h512", tmp_path / "results" / "width")
    plan = read_plan(confirm / "plan.toml")
    table, _, skipped = analyse(plan)
    assert skipped == [] and set(table.part) == {part.name for part in plan.parts}
    explored, _, notes = analyse_exploratory(plan, read_exploratory(confirm / EXPLORATORY_FILE,
                                                                    plan))
    assert notes == [] and not explored.empty

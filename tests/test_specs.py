"""Every grid spec committed under results/ reads and expands; the smoke grid stays small and
needs no data."""
from __future__ import annotations

from pathlib import Path

import pytest

from multitask.grid.spec import expand, load_spec, release_users, with_budget

ROOT = Path(__file__).resolve().parents[1]
#: Confirmatory plans (``multitask.evidence.plans.confirm``) and the exploratory analyses
#: beside them (``multitask.evidence.plans.exploratory``) are TOML too, but no grid spec.
PLANS = sorted((ROOT / "results").rglob("plan.toml"))
EXPLORATORY = sorted((ROOT / "results").rglob("exploratory.toml"))
SPECS = sorted(set((ROOT / "results").rglob("*.toml")) - set(PLANS) - set(EXPLORATORY))


def test_there_are_specs():
    assert {"smoke.toml", "converged.toml", "spec.toml"} <= {path.name for path in SPECS}


@pytest.mark.parametrize("path", SPECS, ids=[str(p.relative_to(ROOT)) for p in SPECS])
def test_every_committed_spec_expands(path):
    spec = with_budget(load_spec(path))
    if spec.data_dir != "synthetic" and not (spec.release_dir() / "transcriptions").is_dir():
        pytest.skip(f"{spec.release_dir()} not found")
    keys = expand(spec, release_users(spec))
    assert keys and len(set(keys)) == len(keys)


@pytest.mark.parametrize("path", PLANS, ids=[str(p.relative_to(ROOT)) for p in PLANS])
def test_every_committed_plan_reads(path):
    from multitask.evidence.plans.confirm import read_plan

    plan = read_plan(path)
    assert plan.parts and all(family.endpoints for part in plan.parts
                              for family in part.families)


@pytest.mark.parametrize("path", EXPLORATORY, ids=[str(p.relative_to(ROOT)) for p in EXPLORATORY])
def test_every_committed_exploratory_file_reads_beside_its_plan(path):
    from multitask.evidence.plans.confirm import read_plan
    from multitask.evidence.plans.exploratory import read_exploratory

    assert read_exploratory(path, read_plan(path.parent / "plan.toml"))


def test_the_smoke_grid_is_small_and_synthetic():
    spec = with_budget(load_spec(ROOT / "results" / "smoke.toml"))
    keys = expand(spec, release_users(spec))
    assert spec.data_dir == "synthetic" and spec.budget.hidden <= 32
    assert len({key.fold for key in keys}) == 2 and {key.seed for key in keys} == {0}
    assert len(keys) <= 12

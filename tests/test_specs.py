"""Every grid spec committed under results/ reads and expands; the smoke grid stays small and
needs no data."""
from __future__ import annotations

from pathlib import Path

import pytest

from jigsaws_tools.toml_files import read_toml
from multitask.evidence.plans.factors import FOLD_SETTINGS
from multitask.grid.spec import expand, load_spec, release_users, spec_from_dict, with_budget

ROOT = Path(__file__).resolve().parents[1]
#: Confirmatory plans (``multitask.evidence.plans.confirm``) and the exploratory analyses
#: beside them (``multitask.evidence.plans.exploratory``) are TOML too, but no grid spec; nor
#: is a factor study's settled choice, ``fold_settings`` tables to add to one
#: (``multitask.evidence.plans.factors``).
PLANS = sorted((ROOT / "results").rglob("plan.toml"))
EXPLORATORY = sorted((ROOT / "results").rglob("exploratory.toml"))
CHOICES = sorted((ROOT / "results").rglob(FOLD_SETTINGS))
SPECS = sorted(set((ROOT / "results").rglob("*.toml")) - set(PLANS) - set(EXPLORATORY)
               - set(CHOICES))


def test_there_are_specs():
    assert {"smoke.toml", "converged.toml", "spec.toml"} <= {path.name for path in SPECS}


@pytest.mark.parametrize("path", SPECS, ids=[str(p.relative_to(ROOT)) for p in SPECS])
def test_every_committed_spec_expands(path):
    spec = with_budget(load_spec(path))
    if spec.data_dir != "synthetic" and not (spec.release_dir() / "transcriptions").is_dir():
        pytest.skip(f"{spec.release_dir()} not found")
    keys = expand(spec, release_users(spec))
    assert keys and len(set(keys)) == len(keys)


@pytest.mark.parametrize("path", CHOICES, ids=[str(p.relative_to(ROOT)) for p in CHOICES])
def test_every_committed_fold_settings_file_adds_to_an_ed_tcn_spec(path):
    """Its tables alone, each of a user of the release, valid for ED-TCN (the factor study's
    backbone); none when every fold keeps the baseline's setting."""
    raw = read_toml(path, "fold settings")
    assert set(raw) <= {"fold_settings"}
    spec = spec_from_dict({"encoder": "ed-tcn", "data_dir": "synthetic", **raw}, str(path))
    assert expand(spec, release_users(spec))


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

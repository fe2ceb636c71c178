"""What a design of folds x seeds can detect (``multitask.evidence.statistics.design``,
``multitask-tables design``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from multitask.evidence.cli import main as tables_main
from multitask.evidence.plans import design as design_study
from multitask.evidence.statistics.design import (detection_power, holm_config,
                                                  variance_split)
from multitask.evidence.statistics.paired import ConfigId, Contrast, StatsConfig, paired
from tests.test_confirm import project  # noqa: F401  (the fixture)

FOLDS = tuple("BCDEFGHI")
CONTRAST = Contrast(ConfigId("APc"), ConfigId("A"))
#: A small simulation: these tests compare powers with each other, never with a number.
QUICK = StatsConfig(power_samples=20_000)


def _runs(rng: np.random.Generator, tau: float, sigma: float, seeds: int = 3,
          gain: float = 2.0) -> pd.DataFrame:
    """Per-run scores of A and APc drawn from ``statistics.design``'s model: a fold effect
    shared by both, APc's gain varying over folds with sd ``tau``, seed noise ``sigma``."""
    rows = []
    for fold in FOLDS:
        base, effect = rng.normal(85, 5), gain + rng.normal(0, tau)
        for variant, shift in (("A", 0.0), ("APc", effect)):
            for seed in range(seeds):
                rows.append({"annotations": "revised", "direction": "bidirectional",
                             "variant": variant, "weighting": "fixed", "seed": seed,
                             "fold": fold, "gesture_edit": base + shift + rng.normal(0, sigma)})
    return pd.DataFrame(rows)


def test_the_split_is_the_claims_seed_share_and_adds_up_to_the_variance():
    runs = _runs(np.random.default_rng(1), tau=2.0, sigma=1.5)
    split = variance_split(runs, CONTRAST, "gesture_edit")
    result = paired(runs, CONTRAST, "gesture_edit")
    assert split.share == pytest.approx(result.seed_share)
    if split.ratio < 1:
        assert split.sd_with(3) == pytest.approx(result.sd)       # the runs' own design
        assert split.sd_with(math.inf) ** 2 == pytest.approx(result.sd ** 2
                                                             - result.seed_variance)
    low, high = split.share_interval(0.95)
    assert 0 <= low <= split.share <= high <= 1
    sd_low, sd_high = split.sd_interval(0.95)
    assert sd_low < result.sd < sd_high


def test_the_seed_shares_interval_covers_the_true_share_about_as_often_as_it_says():
    tau, sigma, seeds = 2.0, 3.0, 3
    true_share = (2 * sigma ** 2 / seeds) / (tau ** 2 + 2 * sigma ** 2 / seeds)
    rng = np.random.default_rng(7)
    covered = []
    for _ in range(200):
        low, high = variance_split(_runs(rng, tau, sigma, seeds), CONTRAST,
                                   "gesture_edit").share_interval(0.95)
        covered.append(low <= true_share <= high)
    assert 0.9 <= np.mean(covered) <= 0.99


def test_more_seeds_never_pass_the_ceiling_and_holm_never_raises_the_power():
    split = variance_split(_runs(np.random.default_rng(3), tau=2.0, sigma=3.0), CONTRAST,
                           "gesture_edit")
    holm = holm_config(QUICK, 2)
    powers = [detection_power(8, 2.3, split.sd_with(k), QUICK) for k in (1, 2, 3, 10, math.inf)]
    assert powers == sorted(powers)
    for k in (1, 3, math.inf):
        assert (detection_power(8, 2.3, split.sd_with(k), holm)
                <= detection_power(8, 2.3, split.sd_with(k), QUICK))
    assert (detection_power(12, 2.3, split.sd_with(math.inf), QUICK)
            > detection_power(8, 2.3, split.sd_with(math.inf), QUICK))   # more users do
    assert detection_power(8, 2.3, 0.0, QUICK) == 1.0
    assert detection_power(8, -2.3, 0.0, QUICK) == 1.0


def test_one_seed_leaves_the_split_unknown():
    runs = _runs(np.random.default_rng(4), tau=2.0, sigma=1.0, seeds=1)
    with pytest.raises(ValueError, match="one seed"):
        variance_split(runs, CONTRAST, "gesture_edit")


@pytest.mark.slow
def test_the_command_writes_the_design_of_the_plans_primary_endpoints(
        project: Path, tmp_path: Path, monkeypatch, capsys):  # noqa: F811
    monkeypatch.chdir(project)
    monkeypatch.setattr(design_study, "StatsConfig", lambda confidence: StatsConfig(
        confidence, power_samples=QUICK.power_samples))                # a quick simulation
    monkeypatch.setattr(design_study, "MORE_FOLDS_SAMPLES", QUICK.power_samples)
    out = tmp_path / "design"
    plan = "confirm/plan.toml"
    assert tables_main(["design", plan, "--out", str(out)]) == 0
    design = pd.read_csv(out / "design.csv")
    assert list(design.comparison) == ["APoc-gradnorm - A-fixed", "APc-fixed - A-fixed"]
    assert set(design.family_size) == {2} and set(design.grid) == {"grids/wide"}
    assert (design.power_holm <= design.power).all() and (design.power <= design.ceiling).all()
    assert "replication: not analysed" in capsys.readouterr().err
    table = pd.read_csv(out / "design_power.csv")
    assert set(table.folds) == {8, 10, 12} and "inf" in set(table.seeds.astype(str))
    first = (out / "design.csv").read_bytes()
    assert tables_main(["design", plan, "--part", "wide", "--grid", "grids/wide",
                        "--seeds", "0", "1", "2", "--out", str(out)]) == 0
    assert (out / "design.csv").read_bytes() == first       # the same runs, the same file
    assert tables_main(["design", plan, "--grid", "grids/wide", "--out", str(out)]) == 2
    assert "name the part" in capsys.readouterr().err

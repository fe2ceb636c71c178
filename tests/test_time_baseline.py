"""The time-only progress baseline: fitted on training trials only, scored like the heads."""
import numpy as np
import pandas as pd
import pytest

from jigsaws_tools.dataset import DataConfig, load_dataset
from multitask.evidence.render.tables import PAPER_TABLES
from multitask.evidence.statistics.time_baseline import chance_accuracy, time_baseline_rows
from multitask.models.time_baseline import TimeBaseline, fold_scores, scores


def _ramp(length, stages=5):
    """A trial moving through ``stages`` stages in equal shares of its time (by each sample's
    midpoint)."""
    return ((np.arange(length) + 0.5) / length * stages).astype(int)


def test_offline_reads_the_stage_at_relative_time():
    model = TimeBaseline.fit([_ramp(50), _ramp(80), _ramp(60)], 5, "offline")   # bins unfilled
    for length in (37, 200):                          # any length: relative time
        np.testing.assert_array_equal(model.predict(length), _ramp(length))


def test_online_reads_the_stage_at_elapsed_time_and_ends_in_the_last_stage():
    model = TimeBaseline.fit([_ramp(50), _ramp(50), _ramp(30)], 5, "online")
    np.testing.assert_array_equal(model.predict(50), _ramp(50))      # the majority: 50 samples
    assert model.predict(80)[-1] == 4                               # past the longest trial
    np.testing.assert_array_equal(model.predict(20), model.predict(80)[:20])   # a prefix


def test_scores_are_the_heads_metrics():
    got = scores([_ramp(40)], [_ramp(40)], 5)
    assert got == {"accuracy": 100.0, "edit": 100.0, "f1@10": 100.0, "mae": 0.0}
    off = scores([np.zeros(40, int)], [np.full(40, 4)], 5)
    assert off["accuracy"] == 0.0 and off["mae"] == 100.0
    assert chance_accuracy([np.array([0, 1, 1]), np.array([1])]) == 75.0
    with pytest.raises(ValueError, match="mode"):
        TimeBaseline.fit([_ramp(5)], 5, "sideways")


def test_folds_fit_on_training_users_only(synth_dir):
    dataset = load_dataset(DataConfig(str(synth_dir)))
    folds = fold_scores(dataset, ["B", "C"], "offline")
    assert list(folds.fold) == ["B", "C"]
    assert {"progress_accuracy", "progress_edit", "progress_f1@10", "progress_mae"} <= set(folds)
    train, test = dataset.louo_split("B")
    model = TimeBaseline.fit([t.progress for t in train], 5, "offline")
    mine = scores([model.predict(len(t.progress)) for t in test], [t.progress for t in test], 5)
    assert folds.iloc[0]["progress_accuracy"] == pytest.approx(mine["accuracy"])
    assert 0 <= mine["accuracy"] <= 100


def test_table_rows_only_for_tables_reporting_progress(synth_dir, tmp_path):
    (tmp_path / "grid.json").write_text(
        '{"spec": {"data_dir": "%s", "task": "Suturing"}, "runs": ["runs/revised/bidirectional/'
        'A-fixed/seed0/B", "runs/revised/bidirectional/A-fixed/seed0/C"]}' % synth_dir)
    table1, table2 = PAPER_TABLES[0], PAPER_TABLES[1]
    columns = ["model", "config", "metric", "left_mean", "left_std", "right_mean", "right_std",
               "diff", "folds"]
    rows = time_baseline_rows(tmp_path, table1, columns)
    assert set(rows.metric) == {"progress_mae", "progress_accuracy", "progress_edit",
                                "progress_f1@10"} and set(rows.folds) == {2}
    assert time_baseline_rows(tmp_path, table2, columns).empty         # gestures only
    assert isinstance(rows, pd.DataFrame) and list(rows.columns) == columns

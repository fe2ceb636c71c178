"""The real JIGSAWS Needle_Passing release (skipped without it): every labelled trial loads, with
the task's labels and progress stages; the release's gaps are reported, not errors."""
from __future__ import annotations

import logging

import numpy as np
import pytest

from jigsaws_tools.cli.main import main as tools_main
from jigsaws_tools.dataset import DataConfig, default_data_dir, load_dataset
from jigsaws_tools.release import discover, read_kinematics
from jigsaws_tools.task_definition import load_task
from multitask.grid.spec import GridSpec, release_users

TASK = "Needle_Passing"


@pytest.fixture(scope="module")
def needle_dir():
    path = default_data_dir().parent / TASK
    if not (path / "transcriptions").is_dir():
        pytest.skip(f"real JIGSAWS {TASK} not found at {path}")
    return path


@pytest.fixture(scope="module")
def dataset(needle_dir):
    return load_dataset(DataConfig(str(needle_dir), task=TASK), use_cache=False)


def test_the_release_without_labels_for_user_g_has_seven_folds(needle_dir, caplog):
    with caplog.at_level(logging.WARNING):
        index = discover(needle_dir, load_task(TASK))
    assert len(index.trials) == 28 and index.users == tuple("BCDEFHI")
    assert {f"{TASK}_G00{k}" for k in range(1, 6)} <= set(index.missing_transcription)
    warned = {name for name in index.missing_transcription if name in caplog.text}
    assert warned == set(index.missing_transcription)           # reported, one line each
    assert release_users(GridSpec(task=TASK, data_dir=str(needle_dir))) == tuple("BCDEFHI")


def test_every_trial_has_the_tasks_labels_and_stages(dataset):
    task = load_task(TASK)
    assert len(dataset.trials) == 28
    seen = set()
    for trial in dataset.trials:
        assert set(np.unique(trial.gestures)) <= set(range(task.num_gestures))
        assert set(np.unique(trial.progress)) <= set(range(task.num_stages))
        assert np.all(trial.progress[trial.gestures == task.gesture_index["G11"]] == 4)
        seen |= {task.gestures[g] for g in np.unique(trial.gestures)}
    assert seen == set(task.gestures)                 # G1-G6, G8-G11: every class occurs


def test_one_off_gestures_occur_in_one_trial_each(dataset):
    task = load_task(TASK)
    for gesture, trial in (("G9", f"{TASK}_C005"), ("G10", f"{TASK}_D003")):
        having = [t.name for t in dataset.trials if task.gesture_index[gesture] in t.gestures]
        assert having == [trial]


def test_the_short_h004_transcription_leaves_its_last_frames_unlabelled(needle_dir, dataset):
    frames = len(read_kinematics(needle_dir / "kinematics/AllGestures" / f"{TASK}_H004.txt"))
    h004 = next(t for t in dataset.trials if t.name == f"{TASK}_H004")
    assert frames == 3653 and h004.frames.max() <= 3480     # samples of labelled frames only


def test_inspect_and_stages_report_the_gaps(needle_dir, capsys):
    assert tools_main(["inspect", "--data-dir", str(needle_dir), "--task", TASK]) == 0
    out = capsys.readouterr().out
    assert "28 complete trials" in out and f"{TASK}_G001" in out.split("missing transcription:")[1]
    assert tools_main(["stages", "--data-dir", str(needle_dir), "--task", TASK]) == 0
    out = capsys.readouterr().out
    assert "of 28 trials follow the stage order" in out

"""The reader, annotation versions and progress labels on the real release."""
import logging

import numpy as np

from jigsaws_tools.annotations import amendments, amendment_report, apply_amendments
from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.gestures import GESTURE_INDEX, UNLABELLED
from jigsaws_tools.release import (discover, frame_labels, read_kinematics, read_meta,
                                   read_transcription, meta_path, transcriptions_dir)


def test_38_complete_trials_and_missing_ones_reported(real_dir, caplog):
    with caplog.at_level(logging.WARNING):
        index = discover(real_dir)
    assert len(index.trials) == 38
    assert index.missing_kinematics == ("Suturing_G001",)
    assert index.missing_transcription == ("Suturing_H002",)
    warned = [r.getMessage() for r in caplog.records]
    assert any("Suturing_G001" in m for m in warned) and any("Suturing_H002" in m for m in warned)
    assert all("\n" not in m for m in warned)


def test_labelled_frames_over_the_39_transcriptions(real_dir):
    paths = sorted(transcriptions_dir(real_dir).glob("Suturing_*.txt"))
    assert len(paths) == 39
    assert sum(s.n_frames for p in paths for s in read_transcription(p)) == 129_166


def test_b001_frames_and_unlabelled(real_dir):
    index = discover(real_dir)
    b001 = next(t for t in index.trials if t.name == "Suturing_B001")
    kinematics = read_kinematics(b001.kinematics)
    assert kinematics.shape == (5635, 76)
    labels = frame_labels(read_transcription(b001.transcription, len(kinematics)), len(kinematics))
    assert np.count_nonzero(labels == UNLABELLED) == 79


def test_meta_file(real_dir):
    meta = read_meta(meta_path(real_dir))
    assert meta["Suturing_B001"].skill == "N" and meta["Suturing_B001"].grs == 13
    assert meta["Suturing_D001"].skill == "E"


def test_revised_changes_exactly_the_listed_ranges(real_dir):
    index = discover(real_dir)
    for t in index.trials:
        n = len(read_kinematics(t.kinematics))
        original = frame_labels(read_transcription(t.transcription, n), n)
        revised, _ = apply_amendments(t.name, original, "revised")
        listed = np.zeros(n, bool)
        expected = original.copy()
        for a in amendments("revised"):
            if a.trial == t.name:
                listed[a.start - 1:a.end] = True
                expected[a.start - 1:a.end] = GESTURE_INDEX[a.gesture]
        assert np.array_equal(revised, expected), t.name
        assert not np.any((revised != original) & ~listed), t.name


def test_amendment_report_covers_all_twelve(real_dir):
    report = amendment_report(discover(real_dir), "revised")
    assert len(report) == 12
    g001 = [e for name, e in report if name == "Suturing_G001"]
    assert len(g001) == 2 and all("no kinematics" in e.status for e in g001)
    assert all(e.frames_changed > 0 for _, e in report)


def test_dataset_progress_and_shapes(real_dir):
    dataset = load_dataset(DataConfig(str(real_dir)))
    assert len(dataset.trials) == 38 and dataset.users == tuple("BCDEFGHI")
    for t in dataset.trials:
        assert t.inputs.shape == (len(t), 14) and t.inputs.dtype == np.float32
        assert set(np.unique(t.progress)) <= set(range(5))
        assert np.all(t.progress[t.gestures == GESTURE_INDEX["G11"]] == 4)
    b001 = next(t for t in dataset.trials if t.name == "Suturing_B001")
    assert len(b001) == int(np.ceil((5635 - 79) / 6))
    train, test = dataset.louo_split("G")
    assert len(test) == 4 and len(train) == 34

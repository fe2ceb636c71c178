"""Metrics on hand-computed cases."""
import numpy as np
import pytest

from rnn_seg.metrics import (accuracy, class_scores, confusion_matrix, edit_distance, edit_score,
                             f1_score, overlap_counts, segmentation_metrics, segments)
from rnn_seg.tasks import SoftmaxClassification, task_metrics, task_scores


def test_segments():
    labels, starts, ends = segments(np.array([1, 1, 2, 2, 2, 1]))
    assert labels.tolist() == [1, 2, 1] and starts.tolist() == [0, 2, 5] and ends.tolist() == [2, 5, 6]
    assert [len(a) for a in segments(np.array([], int))] == [0, 0, 0]


def test_dipietro_edit_distance_example():
    assert edit_distance(np.array([1, 3, 2, 2, 3]), np.array([1, 2, 2, 2, 3])) == 1


def test_edit_score():
    y = np.array([0, 0, 1, 1, 2, 2])
    assert edit_score(y, y) == 100.0
    assert edit_score(np.array([0, 0, 0, 1, 1, 1]), y) == pytest.approx(100 * (1 - 1 / 3))
    assert edit_score(np.array([0, 1, 0, 1, 2, 2]), y) == pytest.approx(100 * (1 - 2 / 5))
    assert edit_score(np.array([], int), np.array([], int)) == 100.0
    assert edit_score(np.array([5, 5]), np.array([1, 1])) == 0.0


def test_f1_one_segment_and_all_wrong():
    y = np.zeros(10, int)
    assert f1_score(y, y, 50) == 100.0
    assert f1_score(np.ones(10, int), y, 10) == 0.0
    assert overlap_counts(np.ones(10, int), y, 10).__dict__ == {"tp": 0, "fp": 1, "fn": 1}


def test_f1_overlap_thresholds_and_duplicate_matches():
    y = np.array([0] * 10 + [1] * 10)
    # prediction: class 0 for 4 frames, 1 for 16: IoU(0)=0.4, IoU(1)=10/16=0.625
    p = np.array([0] * 4 + [1] * 16)
    assert f1_score(p, y, 10) == 100.0
    assert f1_score(p, y, 50) == pytest.approx(100 * 2 * 1 / (2 * 1 + 1 + 1))
    # two predicted segments of class 1 matching the same true segment: second is a FP
    p2 = np.array([0] * 10 + [1] * 5 + [0] + [1] * 4)
    c = overlap_counts(p2, y, 10)
    assert (c.tp, c.fp, c.fn) == (2, 2, 0)


def test_empty_sequences():
    e = np.array([], int)
    assert overlap_counts(e, e, 10).f1 == 0.0
    assert overlap_counts(e, np.array([1, 1]), 10).fn == 1


def test_pooled_vs_mean_f1_and_class_accuracy():
    y1, p1 = np.array([0, 0, 1, 1]), np.array([0, 0, 1, 1])
    y2, p2 = np.array([0, 0, 0, 0, 2, 2, 2, 2]), np.array([1, 1, 1, 1, 1, 1, 1, 1])
    m = segmentation_metrics([p1, p2], [y1, y2])
    assert m["f1@10"] == pytest.approx(50.0)             # (100 + 0) / 2
    assert m["f1@10_pooled"] == pytest.approx(100 * 2 * 2 / (2 * 2 + 1 + 2))
    assert m["accuracy"] == pytest.approx(50.0) and m["accuracy_pooled"] == pytest.approx(100 * 4 / 12)
    acc = class_scores(confusion_matrix([p1, p2], [y1, y2], 4))[1]       # per-class accuracy
    assert acc[0] == pytest.approx(100 * 2 / 6) and acc[1] == 100.0 and acc[2] == 0.0
    assert np.isnan(acc[3])
    assert accuracy(p1, y1) == 100.0


def test_unequal_lengths_are_a_clear_error():
    with pytest.raises(ValueError, match="1 predicted, 4 true"):
        accuracy(np.array([1]), np.array([1, 1, 2, 2]))
    with pytest.raises(ValueError, match="differ in length"):
        f1_score(np.zeros(3, int), np.zeros(5, int), 10)
    with pytest.raises(ValueError, match="differ in length"):
        edit_score(np.zeros(3, int), np.zeros(5, int))
    with pytest.raises(ValueError, match="2 predicted sequences but 1 true"):
        segmentation_metrics([np.zeros(2, int)] * 2, [np.zeros(2, int)])


def test_confusion_matrix_and_per_class_scores_by_hand():
    # classes 0..3; class 3 neither occurs nor is predicted, class 2 is predicted but absent
    preds = [np.array([0, 0, 1, 1]), np.array([1, 2, 0])]
    trues = [np.array([0, 1, 1, 1]), np.array([1, 1, 0])]
    confusion = confusion_matrix(preds, trues, 4)
    assert confusion.tolist() == [[2, 0, 0, 0],      # row = true, column = predicted
                                  [1, 3, 1, 0],
                                  [0, 0, 0, 0],
                                  [0, 0, 0, 0]]
    assert confusion.sum() == 7                      # every step counted once
    precision, recall, f1 = class_scores(confusion)
    # class 0: TP 2, FP 1, FN 0; class 1: TP 3, FP 0, FN 2; class 2: TP 0, FP 1, FN 0
    np.testing.assert_allclose(precision[:3], [100 * 2 / 3, 100.0, 0.0])
    np.testing.assert_allclose(recall[:2], [100.0, 60.0])
    np.testing.assert_allclose(f1[:3], [100 * 4 / 5, 100 * 6 / 8, 0.0])
    assert np.isnan(recall[2]) and np.isnan(precision[3]) and np.isnan(recall[3])
    assert np.isnan(f1[3])


def test_task_metrics_name_per_class_scores_and_confusion_by_class():
    task = SoftmaxClassification("gesture", ["a", "b", "c"])
    outputs = [np.eye(3, dtype=np.float32)[[0, 1, 1, 0]]]          # decodes to a b b a
    labels = [np.array([0, 1, 0, 0])]
    metrics = task_metrics(task, outputs, labels)
    assert metrics["precision_a"] == 100.0 and metrics["recall_a"] == pytest.approx(200 / 3)
    assert metrics["f1_b"] == pytest.approx(100 * 2 / 3) and metrics["precision_b"] == 50.0
    assert all(np.isnan(metrics[f"{k}_c"]) for k in ("precision", "recall", "f1", "accuracy"))
    scored, confusion = task_scores(task, outputs, labels)
    assert confusion.tolist() == [[2, 1, 0], [0, 1, 0], [0, 0, 0]]
    assert scored.keys() == metrics.keys() and all(
        scored[k] == metrics[k] or np.isnan(metrics[k]) for k in metrics)

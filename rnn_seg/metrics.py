"""Frame-wise and segmental metrics of label sequences (all scores in percent).

* accuracy: correctly labelled frames / frames.
* edit score (Lea et al. 2017): ``100 * (1 - lev(P, Y) / max(|P|, |Y|))`` on the segment label
  sequences P, Y (consecutive repeats collapsed); 100 when both are empty.
* edit distance (DiPietro et al. 2016): the raw Levenshtein distance ``lev(P, Y)``.
* F1@k (Lea et al.): each predicted segment is matched to the true segment of the same label with
  the highest IoU; it is a true positive when that IoU >= k/100 and the true segment is still
  unused, else a false positive; unused true segments are false negatives. The IoU threshold
  ``k`` is in percent everywhere (``f1@10``: k = 10).
  Reported per sequence and averaged (Lea's TCN code), or pooled: TP/FP/FN summed over sequences
  before one F1 (MS-TCN's code). Tables name which.
* per class, frame-wise over the pooled frames of all sequences (``confusion_matrix``,
  ``class_scores``): precision TP / (TP + FP), recall TP / (TP + FN) (= the class's accuracy) and
  F1 2 TP / (2 TP + FP + FN), each NaN when its denominator is 0 (a class neither present nor
  predicted, or never predicted for precision).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

F1_OVERLAPS = (10, 25, 50)


def segments(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run-length segments of ``[T]`` labels: ``(label [S], start [S], end [S])``, end exclusive."""
    labels = np.asarray(labels)
    if labels.size == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty, empty
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    ends = np.r_[starts[1:], labels.size]
    return labels[starts], starts, ends


def check_same_length(pred: np.ndarray, true: np.ndarray) -> None:
    """A prediction and its ground truth label the same frames: raise ``ValueError`` otherwise."""
    if len(pred) != len(true):
        raise ValueError(f"predicted and true labels differ in length: {len(pred)} predicted, "
                         f"{len(true)} true")


def accuracy(pred: np.ndarray, true: np.ndarray) -> float:
    """Percentage of ``[T]`` frames whose predicted label equals the true one."""
    pred, true = np.asarray(pred), np.asarray(true)
    check_same_length(pred, true)
    return 100.0 * float(np.mean(pred == true))


def levenshtein(a: Sequence[int], b: Sequence[int]) -> int:
    """Edit distance (insertions, deletions, substitutions, each of cost 1)."""
    row = np.arange(len(b) + 1)
    for i, x in enumerate(a, start=1):
        prev_diag, row[0] = row[0], i
        for j, y in enumerate(b, start=1):
            prev_diag, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev_diag + (x != y))
    return int(row[-1])


def edit_distance(pred: np.ndarray, true: np.ndarray) -> int:
    """DiPietro's segment-level edit distance (unnormalised)."""
    return levenshtein(segments(pred)[0].tolist(), segments(true)[0].tolist())


def edit_score(pred: np.ndarray, true: np.ndarray) -> float:
    """Lea et al.'s normalised edit score of ``[T]`` predicted against ``[T]`` true labels."""
    check_same_length(pred, true)
    p, y = segments(pred)[0].tolist(), segments(true)[0].tolist()
    longest = max(len(p), len(y))
    return 100.0 if longest == 0 else 100.0 * (1.0 - levenshtein(p, y) / longest)


@dataclass(frozen=True)
class SegmentCounts:
    tp: int
    fp: int
    fn: int

    def __add__(self, other: "SegmentCounts") -> "SegmentCounts":
        return SegmentCounts(self.tp + other.tp, self.fp + other.fp, self.fn + other.fn)

    @property
    def f1(self) -> float:
        """F1 in percent; 0 when there are no true positives."""
        return 0.0 if self.tp == 0 else 100.0 * 2 * self.tp / (2 * self.tp + self.fp + self.fn)


def overlap_counts(pred: np.ndarray, true: np.ndarray, k: float) -> SegmentCounts:
    """TP / FP / FN of the overlap matching (module docstring) on the segments of ``pred`` and
    ``true``.

    Args:
        pred: ``[T]`` int64 predicted labels, one per time step.
        true: ``[T]`` int64 true labels (not checked for equal lengths: see ``f1_score``).
        k: IoU threshold in percent (e.g. 10).
    """
    overlap = k / 100.0
    p_label, p_start, p_end = segments(pred)
    y_label, y_start, y_end = segments(true)
    used = np.zeros(len(y_label), dtype=bool)
    tp = 0
    for label, start, end in zip(p_label, p_start, p_end):
        intersection = np.minimum(end, y_end) - np.maximum(start, y_start)
        union = np.maximum(end, y_end) - np.minimum(start, y_start)
        iou = np.where(y_label == label, np.clip(intersection, 0, None) / union, 0.0)
        if iou.size == 0:
            continue
        best = int(np.argmax(iou))
        if iou[best] >= overlap and not used[best]:
            used[best] = True
            tp += 1
    return SegmentCounts(tp, len(p_label) - tp, len(y_label) - int(used.sum()))


def f1_score(pred: np.ndarray, true: np.ndarray, k: int) -> float:
    """F1@k of predicted against true labels, in percent.

    Args:
        pred: ``[T]`` int64 predicted labels, one per time step.
        true: ``[T]`` int64 true labels; a different length raises ``ValueError``.
        k: IoU threshold in percent (e.g. 10 for F1@10).
    """
    check_same_length(pred, true)
    return overlap_counts(pred, true, k).f1


def confusion_matrix(preds: Sequence[np.ndarray], trues: Sequence[np.ndarray], num_classes: int
                     ) -> np.ndarray:
    """Counts of (true, predicted) label pairs, pooled over the sequences.

    Args:
        preds: one ``[T_i]`` int64 array of predicted labels per sequence.
        trues: the ``[T_i]`` int64 true labels, in 0..num_classes-1, in the order of ``preds``.
        num_classes: number of classes K.

    Returns:
        ``[K, K]`` int64: row = true class, column = predicted class; sums to ``sum(T_i)``.
    """
    for p, y in zip(preds, trues, strict=True):
        check_same_length(p, y)
    pred, true = np.concatenate(preds), np.concatenate(trues)
    return np.bincount(true * num_classes + pred, minlength=num_classes ** 2).reshape(
        num_classes, num_classes)


def class_scores(confusion: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frame-wise ``(precision, recall, f1)`` of each class, in percent, from a ``[K, K]``
    confusion matrix (rows true, columns predicted): each ``[K]`` float64, NaN where undefined
    (module docstring)."""
    confusion = np.asarray(confusion, dtype=np.float64)
    tp = np.diag(confusion)
    predicted, true = confusion.sum(axis=0), confusion.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return (100.0 * tp / np.where(predicted > 0, predicted, np.nan),
                100.0 * tp / np.where(true > 0, true, np.nan),
                100.0 * 2 * tp / np.where(predicted + true > 0, predicted + true, np.nan))


def segmentation_metrics(preds: Sequence[np.ndarray], trues: Sequence[np.ndarray]
                         ) -> dict[str, float]:
    """Metrics over several sequences.

    ``accuracy``, ``edit``, ``edit_distance`` and ``f1@k`` are means of per-sequence values (as in
    Lea et al. and DiPietro et al.); ``accuracy_pooled`` counts frames over all sequences and
    ``f1@k_pooled`` sums TP/FP/FN over all sequences first (as MS-TCN does).
    """
    if len(preds) != len(trues):
        raise ValueError(f"{len(preds)} predicted sequences but {len(trues)} true ones")
    pairs = list(zip(preds, trues))
    for p, y in pairs:
        check_same_length(p, y)
    out = {"accuracy": float(np.mean([accuracy(p, y) for p, y in pairs])),
           "accuracy_pooled": accuracy(np.concatenate(preds), np.concatenate(trues)),
           "edit": float(np.mean([edit_score(p, y) for p, y in pairs])),
           "edit_distance": float(np.mean([edit_distance(p, y) for p, y in pairs]))}
    for k in F1_OVERLAPS:
        counts = [overlap_counts(p, y, k) for p, y in pairs]
        out[f"f1@{k}"] = float(np.mean([c.f1 for c in counts]))
        out[f"f1@{k}_pooled"] = sum(counts, SegmentCounts(0, 0, 0)).f1
    return out

"""The numbers van Amsterdam et al. (ICRA 2020) publish, transcribed from their Tables I-III.

Keys are our configuration names ``<variant>-<weighting>`` (``fixed`` = w1 = w2 = 1, ``gradnorm`` =
alpha 1.5) and metric names ``<task>_<metric>`` as in ``multitask.evidence.collect``; values are
``(mean, std)`` over the 8 folds (std ``None`` where the paper gives none).
"""
from __future__ import annotations

Number = tuple[float, float | None]

#: Table I: revised annotations, bidirectional LSTM.
TABLE_1: dict[str, dict[str, Number]] = {
    "A-fixed": {"gesture_accuracy": (85.3, 5.8), "gesture_edit": (83.1, 7.4),
                "gesture_f1@10": (88.5, 5.7)},
    "APr-fixed": {"gesture_accuracy": (85.1, 6.6), "gesture_edit": (84.2, 6.7),
                  "gesture_f1@10": (89.0, 5.5), "progress_mae": (5.3, 1.5)},
    "APr-gradnorm": {"gesture_accuracy": (85.2, 6.3), "gesture_edit": (85.9, 6.4),
                     "gesture_f1@10": (90.1, 5.4), "progress_mae": (5.1, 1.5)},
    "APc-fixed": {"gesture_accuracy": (85.7, 5.7), "gesture_edit": (85.4, 5.7),
                  "gesture_f1@10": (90.1, 4.9), "progress_accuracy": (89.0, 2.7),
                  "progress_edit": (89.3, 6.7), "progress_f1@10": (93.2, 4.4)},
    "APc-gradnorm": {"gesture_accuracy": (85.8, 5.6), "gesture_edit": (85.7, 5.7),
                     "gesture_f1@10": (90.2, 4.9), "progress_accuracy": (89.1, 2.8),
                     "progress_edit": (89.2, 6.6), "progress_f1@10": (93.2, 3.4)},
    "APoc-fixed": {"gesture_accuracy": (85.5, 5.8), "gesture_edit": (86.2, 6.3),
                   "gesture_f1@10": (90.5, 5.0), "progress_accuracy": (87.9, 3.5),
                   "progress_edit": (83.7, 4.8), "progress_f1@10": (90.0, 3.1)},
    "APoc-gradnorm": {"gesture_accuracy": (86.0, 5.4), "gesture_edit": (86.1, 6.2),
                      "gesture_f1@10": (90.7, 4.8), "progress_accuracy": (88.4, 3.1),
                      "progress_edit": (83.6, 4.5), "progress_f1@10": (90.0, 3.1)},
    "Pr-fixed": {"progress_mae": (6.2, 1.1)},
    "Pc-fixed": {"progress_accuracy": (89.2, 2.8), "progress_edit": (87.8, 7.8),
                 "progress_f1@10": (91.9, 4.9)},
    "Poc-fixed": {"progress_accuracy": (87.0, 4.0), "progress_edit": (87.3, 5.7),
                  "progress_f1@10": (91.9, 3.6)},
}

#: Table II: original JIGSAWS annotations (accuracy, edit). The paper does not say which loss
#: weighting APc and APoc used here; we compare with w1 = w2 = 1 (docs/REPRODUCTION.md). The
#: BiLSTM row is DiPietro et al.'s published result, which our model A reproduces.
TABLE_2: dict[str, dict[str, Number]] = {
    "A-fixed": {"gesture_accuracy": (83.3, None), "gesture_edit": (81.1, None)},
    "APoc-fixed": {"gesture_accuracy": (85.3, None), "gesture_edit": (84.5, None)},
    "APc-fixed": {"gesture_accuracy": (85.5, None), "gesture_edit": (85.3, None)},
}
#: Related work the paper lists in Table II (not reproduced here).
TABLE_2_RELATED: dict[str, dict[str, Number]] = {
    "TCN": {"gesture_accuracy": (79.6, None), "gesture_edit": (85.8, None)},
    "TCN+RL": {"gesture_accuracy": (82.1, None), "gesture_edit": (87.9, None)},
}

#: Table III: online recognition with a forward LSTM (revised annotations).
TABLE_3: dict[str, dict[str, Number]] = {
    "A-fixed": {"gesture_accuracy": (80.5, None), "gesture_edit": (75.3, None)},
    "APc-fixed": {"gesture_accuracy": (82.2, None), "gesture_edit": (76.2, None)},
}

"""The folders ``multitask-evaluate`` and ``multitask-export`` write whole, checked before any
work (``rnn_seg.runs.outputs.check_new_output``): without TensorFlow, so that a command refuses
an output folder at once, before it loads a model."""
from __future__ import annotations

from pathlib import Path

from rnn_seg.runs.outputs import check_new_output

#: What an evaluation folder holds: all ``--overwrite`` may replace.
EVALUATION_ENTRIES = frozenset({"metrics.json", "predictions", "plots"})
#: What a SavedModel folder holds: all ``--overwrite`` may replace.
EXPORT_ENTRIES = frozenset({"saved_model.pb", "fingerprint.pb", "variables", "assets",
                            "assets.extra"})


def check_evaluation_folder(out: Path, overwrite: bool) -> None:
    """``out`` may receive an evaluation: new or empty, or with ``overwrite`` an earlier one; not
    inside a run folder but in its ``evaluate/``."""
    check_new_output(out, "multitask-evaluate", EVALUATION_ENTRIES, overwrite,
                     run_place="evaluate")


def check_export_folder(out: Path, overwrite: bool) -> None:
    """``out`` may receive a SavedModel: new or empty, or with ``overwrite`` an earlier export."""
    check_new_output(out, "multitask-export", EXPORT_ENTRIES, overwrite)

"""How trials follow their task's progress stages (``jigsaws_tools.stage_order``)."""
from __future__ import annotations

import numpy as np
import pytest

from jigsaws_tools.cli.main import main as tools_main
from jigsaws_tools.release import discover
from jigsaws_tools.stage_order import stage_order, trial_transitions, transition_kind
from jigsaws_tools.synth import SynthConfig, write_release
from jigsaws_tools.task_definition import SUTURING, load_task


@pytest.mark.parametrize("before, after, kind", [
    (0, 1, "next"), (2, 3, "next"), (3, 4, "next"), (3, 1, "new cycle"), (3, 0, "new cycle"),
    (2, 1, "back"), (1, 0, "back"), (1, 3, "skip"), (0, 4, "skip"), (4, 1, "after end"),
])
def test_transition_kinds_of_five_stages(before, after, kind):
    assert transition_kind(before, after, num_stages=5) == kind


def _frames(*gestures: str, frames: int = 3) -> np.ndarray:
    """30 Hz class indices of Suturing: each gesture for ``frames`` frames."""
    return np.repeat([SUTURING.gesture_index[g] for g in gestures], frames)


def test_a_retried_push_and_a_skipped_push_break_the_order_and_are_named():
    labels = _frames("G1", "G2", "G3", "G6", "G2", "G3", "G8", "G2", "G6", "G11")
    labels[4] = -1                                      # unlabelled frames are transparent
    kinds = trial_transitions(labels, SUTURING)
    # G8 is an adjustment: it takes G2's stage, so push -> position is a step back
    assert kinds == [("next", "G1", "G2"), ("next", "G2", "G3"), ("next", "G3", "G6"),
                     ("new cycle", "G6", "G2"), ("next", "G2", "G3"), ("back", "G3", "G8"),
                     ("skip", "G2", "G6"), ("next", "G6", "G11")]


def test_the_synthetic_release_of_every_task_follows_its_order(tmp_path):
    for name in ("Suturing", "Knot_Tying", "Needle_Passing"):
        task = load_task(name)
        root = write_release(tmp_path / name, SynthConfig(seed=2, users=("B", "C"),
                                                         trials_per_user=3), task)
        table, breaks = stage_order(discover(root, task), "original")
        assert len(table) == 6 and table.in_order.all() and not breaks
        assert (table["new cycle"] > 0).all()


def test_stages_command_reports_every_trial(tmp_path, capsys):
    task = load_task("Needle_Passing")
    root = write_release(tmp_path / "np", SynthConfig(seed=3, users=("B", "C"),
                                                     trials_per_user=2), task)
    assert tools_main(["stages", "--data-dir", str(root), "--task", "Needle_Passing"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("stages: 0 reach -> 1 position -> 2 push -> 3 pull -> 4 drop")
    assert sum(line.startswith("Needle_Passing_") for line in out.splitlines()) == 4
    assert "4 of 4 trials follow the stage order" in out and "out of order: none" in out

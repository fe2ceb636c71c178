"""How a release's trials follow their task's progress stages.

Progress (``progress``) is meant to rise within every cycle of a task: stage 0 (reach), 1, ...,
up to the cycle's last stage (``K - 2``: Suturing's pull), then either a new cycle (back to an
earlier stage) or the final stage ``K - 1`` (the drop). Between two consecutive runs of one stage
(30 Hz frames, adjustments already given their stage), a transition ``s -> t`` is

* ``next``: ``t = s + 1``;
* ``new cycle``: ``s = K - 2`` and ``t < s``;
* ``back``: ``t < s`` from a stage before the cycle's last (a step retried: push -> position);
* ``skip``: ``t > s + 1`` (a stage left out);
* ``after end``: from the final stage ``K - 1``.

The first two follow the order; ``stage_order`` counts every kind per trial and names the
gestures on both sides of each transition that breaks it.
"""
from __future__ import annotations

from collections import Counter

import numpy as np
import pandas as pd

from .gestures import UNLABELLED
from .progress import progress_labels
from .release import ReleaseIndex
from .summary import trial_labels
from .task_definition import TaskDefinition

KINDS = ("next", "new cycle", "back", "skip", "after end")
IN_ORDER = ("next", "new cycle")


def transition_kind(before: int, after: int, num_stages: int) -> str:
    """The kind of the stage transition ``before -> after`` (stages ``0..num_stages-1``)."""
    last_of_cycle = num_stages - 2
    if before == num_stages - 1:
        return "after end"
    if after == before + 1:
        return "next"
    if after < before:
        return "new cycle" if before == last_of_cycle else "back"
    return "skip"


def trial_transitions(gestures: np.ndarray, task: TaskDefinition) -> list[tuple[str, str, str]]:
    """``(kind, gesture before, gesture after)`` for every stage change of one trial.

    Args:
        gestures: ``[n_frames]`` class indices at 30 Hz, ``UNLABELLED`` (-1) anywhere (skipped).
        task: the trial's task (its vocabulary and stages).
    """
    labelled = gestures[gestures != UNLABELLED]
    stages = progress_labels(labelled, task)
    changes = np.flatnonzero(np.diff(stages)) + 1          # first frame of each new stage run
    return [(transition_kind(int(stages[i - 1]), int(stages[i]), task.num_stages),
             task.gestures[labelled[i - 1]], task.gestures[labelled[i]]) for i in changes]


def stage_order(index: ReleaseIndex, version: str) -> tuple[pd.DataFrame, Counter]:
    """Per complete trial of ``index``, how many stage transitions of each kind its labels
    (annotation ``version``) make, and over all trials, how often each gesture pair breaks the
    order (``Counter`` of ``"G3 -> G2 (back)"``).

    Returns:
        A table indexed by trial with one column per kind (``KINDS``) and ``in_order`` (True when
        every transition is ``next`` or ``new cycle``), and the counter.
    """
    task = index.task
    rows, breaks = [], Counter()
    for trial in index.trials:
        _, labels = trial_labels(trial, task, version, index.recording_format)
        transitions = trial_transitions(labels, task)
        counts = Counter(kind for kind, _, _ in transitions)
        rows.append({"trial": trial.name, **{kind: counts[kind] for kind in KINDS}})
        breaks.update(f"{a} -> {b} ({kind})" for kind, a, b in transitions
                      if kind not in IN_ORDER)
    table = pd.DataFrame(rows).set_index("trial")
    table["in_order"] = table[[k for k in KINDS if k not in IN_ORDER]].sum(axis=1) == 0
    return table, breaks

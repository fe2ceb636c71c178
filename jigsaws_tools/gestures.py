"""The label of unlabelled frames, and the paper's (Suturing's) gesture vocabulary.

Every task-dependent piece takes a ``TaskDefinition`` (``jigsaws_tools.task_definition``); these
names are Suturing's classes for code that is about the paper's task only (its annotation
amendments).
"""
from __future__ import annotations

from .task_definition import SUTURING

#: Suturing uses G1-G6 and G8-G11 (no G7); class index = position in this tuple.
GESTURES: tuple[str, ...] = SUTURING.gestures
GESTURE_INDEX: dict[str, int] = SUTURING.gesture_index

#: Label value of a 30 Hz frame that no transcription segment covers.
UNLABELLED = -1

"""The Suturing gesture vocabulary and its mapping to class indices 0-9."""
from __future__ import annotations

#: Suturing uses G1-G6 and G8-G11 (no G7); class index = position in this tuple.
GESTURES: tuple[str, ...] = ("G1", "G2", "G3", "G4", "G5", "G6", "G8", "G9", "G10", "G11")
NUM_GESTURES = len(GESTURES)
GESTURE_INDEX: dict[str, int] = {name: i for i, name in enumerate(GESTURES)}

GESTURE_DESCRIPTIONS: dict[str, str] = {
    "G1": "Reaching for needle with right hand",
    "G2": "Positioning needle",
    "G3": "Pushing needle through tissue",
    "G4": "Transferring needle from left to right",
    "G5": "Moving to center with needle in grip",
    "G6": "Pulling suture with left hand",
    "G8": "Orienting needle",
    "G9": "Using right hand to help tighten suture",
    "G10": "Loosening more suture",
    "G11": "Dropping suture at end and moving to end points",
}

#: Label value of a 30 Hz frame that no transcription segment covers.
UNLABELLED = -1

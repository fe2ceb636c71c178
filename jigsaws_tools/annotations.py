"""Annotation versions: the release's labels ("original") and the paper's 12 amendments ("revised").

The amendments come from the appendix of van Amsterdam et al. (ICRA 2020) and ship as
``jigsaws_tools/data/revised_amendments.csv`` (trial, start, end, gesture; 1-based inclusive
frames at 30 Hz, the convention of the release's transcriptions). Applying a version relabels
every frame of each listed range, whatever its previous label. They are Suturing's: for any other
task both versions are the release's labels.
"""
from __future__ import annotations

import csv
from collections import Counter
from dataclasses import dataclass
from importlib import resources

import numpy as np

from .errors import FormatError, JigsawsError
from .gestures import GESTURE_INDEX, UNLABELLED
from .release import (KINEMATICS_HZ, ReleaseIndex, frame_labels, read_kinematics,
                      read_transcription, transcriptions_dir)
from .task_definition import PAPER_TASK, SUTURING, TaskDefinition

ANNOTATION_VERSIONS = ("original", "revised")
_AMENDMENT_FILES = {"revised": "revised_amendments.csv"}    # of the paper's task only


@dataclass(frozen=True)
class Amendment:
    """Frames ``start..end`` (1-based, inclusive, 30 Hz) of ``trial`` are relabelled ``gesture``."""

    trial: str
    start: int
    end: int
    gesture: str


@dataclass(frozen=True)
class AmendmentEffect:
    """What one amendment did to one trial's per-frame labels."""

    amendment: Amendment
    status: str                      # "applied", or why it was not
    frames_changed: int              # frames whose label differs afterwards
    previous: dict[str, int]         # previous label -> frame count within the range


def check_version(version: str) -> str:
    if version not in ANNOTATION_VERSIONS:
        raise JigsawsError(f"unknown annotation version {version!r}; "
                           f"choose one of {', '.join(ANNOTATION_VERSIONS)}")
    return version


def amendments(version: str, task: TaskDefinition = SUTURING) -> tuple[Amendment, ...]:
    """The amendments a version applies to ``task``'s release (none for ``original`` and for
    tasks other than Suturing)."""
    if not _table_name(version, task):
        return ()
    source = resources.files("jigsaws_tools") / "data" / _table_name(version, task)
    with source.open(encoding="utf-8") as f:
        return tuple(_parse_amendment(str(source), number, row)
                     for number, row in enumerate(csv.DictReader(f), start=2))


def labels_named(version: str, index: ReleaseIndex) -> str:
    """How a report names the labels of ``index``'s trials under ``version``: ``"revised
    annotations: 12 amendments"`` where the version amends some of them, else what they are, the
    transcriptions as given (``"labels as transcribed: no amendment applies to these trials"``
    for your own recordings, another task, or a release that lacks the amended trials)."""
    if version == "original":
        return "original annotations"
    names = {t.name for t in index.trials}
    applied = sum(a.trial in names for a in amendments(version, index.task))
    if not applied:
        return "labels as transcribed: no amendment applies to these trials"
    return f"{version} annotations: {applied} amendment{'s' * (applied != 1)}"


def amendment_table_text(version: str, task: TaskDefinition = SUTURING) -> str:
    """The raw table behind a version ('' when it amends nothing); part of the dataset cache key."""
    name = _table_name(version, task)
    return (resources.files("jigsaws_tools") / "data" / name).read_text("utf-8") if name else ""


def _table_name(version: str, task: TaskDefinition) -> str | None:
    check_version(version)
    return _AMENDMENT_FILES.get(version) if task.name == PAPER_TASK else None


def _parse_amendment(path: str, number: int, row: dict[str, str]) -> Amendment:
    try:
        start, end = int(row["start"]), int(row["end"])
    except (KeyError, TypeError, ValueError):
        raise FormatError(path, number, row, "expected integer start and end columns") from None
    if row.get("gesture") not in GESTURE_INDEX:
        raise FormatError(path, number, row.get("gesture"), "unknown Suturing gesture")
    if start < 1 or end < start:
        raise FormatError(path, number, f"{start} {end}", "frames must satisfy 1 <= start <= end")
    return Amendment(row["trial"], start, end, row["gesture"])


def apply_amendments(trial: str, labels: np.ndarray, version: str,
                     task: TaskDefinition = SUTURING, rate_hz: float = KINEMATICS_HZ
                     ) -> tuple[np.ndarray, list[AmendmentEffect]]:
    """Relabel one trial's frames under ``version``.

    Args:
        trial: trial name, e.g. ``"Suturing_B004"``.
        labels: ``[n_rows]`` int class indices of ``task``'s vocabulary, a row per frame of the
            trial's recording (``UNLABELLED`` = -1).
        version: an annotation version (``ANNOTATION_VERSIONS``).
        task: the trial's task; only Suturing has amendments.
        rate_hz: the recording's rate. The amendments are frame ranges of the release's 30 Hz
            recordings: a trial of the release's name recorded at another rate is refused
            (``JigsawsError``) rather than relabelled at the wrong rows.

    Returns:
        The amended copy of ``labels`` and the effect of each amendment of this trial.
    """
    labels = labels.copy()
    effects = []
    for a in amendments(version, task):
        if a.trial != trial:
            continue
        if rate_hz != KINEMATICS_HZ:
            raise JigsawsError(f"trial {trial}: annotation version {version!r} relabels frames "
                               f"{a.start}-{a.end} of the release's {KINEMATICS_HZ:g} Hz "
                               f"recording of this name, and this one is at {rate_hz:g} Hz; "
                               "use annotations 'original', or rename the trial")
        if a.end > len(labels):
            effects.append(AmendmentEffect(a, f"skipped: range ends beyond the {len(labels)} "
                                              f"frames of the trial", 0, {}))
            continue
        window = labels[a.start - 1:a.end]
        previous = Counter("unlabelled" if v == UNLABELLED else task.gestures[v] for v in window)
        if a.gesture not in task.gesture_index:
            raise JigsawsError(f"amendment of {trial} relabels frames {a.gesture}, which the "
                               f"vocabulary of task {task.name} lacks")
        new = task.gesture_index[a.gesture]
        changed = int(np.count_nonzero(window != new))
        window[:] = new
        effects.append(AmendmentEffect(a, "applied", changed, dict(sorted(previous.items()))))
    return labels, effects


def amendment_report(index: ReleaseIndex, version: str) -> list[tuple[str, AmendmentEffect]]:
    """Effect of every amendment of ``version`` on the release behind ``index``.

    A trial with a transcription but no kinematics is relabelled on its transcription alone (status
    says so); a trial absent altogether is reported with status ``"skipped: trial absent"``.
    """
    complete = {t.name: t for t in index.trials}
    report = []
    task = index.task
    for name in dict.fromkeys(a.trial for a in amendments(version, task)):
        transcription = transcriptions_dir(index.root) / f"{name}.txt"
        if name in complete:
            n_frames = len(read_kinematics(complete[name].kinematics))
            status = None
        elif transcription.is_file():
            n_frames, status = None, "applied to the transcription only (no kinematics)"
        else:
            report += [(name, AmendmentEffect(a, "skipped: trial absent", 0, {}))
                       for a in amendments(version, task) if a.trial == name]
            continue
        segments = read_transcription(transcription, n_frames, task)
        n_frames = n_frames or segments[-1].end
        _, effects = apply_amendments(name, frame_labels(segments, n_frames, task), version, task)
        report += [(name, e if status is None or e.status != "applied"
                    else AmendmentEffect(e.amendment, status, e.frames_changed, e.previous))
                   for e in effects]
    return report

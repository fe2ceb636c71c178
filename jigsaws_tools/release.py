"""Reader for the official JIGSAWS release layout of one task (e.g. ``Suturing/``).

Layout::

    <root>/kinematics/AllGestures/<Task>_<User><Trial>.txt   76 columns, 30 Hz, one line per frame
    <root>/transcriptions/<Task>_<User><Trial>.txt           "start end G<k>", 1-based inclusive frames
    <root>/meta_file_<Task>.txt                              name, skill level, GRS, 6 GRS items
"""
from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import FormatError, ReleaseNotFoundError
from .gestures import GESTURE_INDEX, UNLABELLED

NUM_KINEMATIC_COLUMNS = 76
KINEMATICS_HZ = 30.0
TASK = "Suturing"
_TRIAL_FILE = re.compile(rf"^{TASK}_([A-Z])(\d{{3}})\.txt$")


log = logging.getLogger(__name__)

@dataclass(frozen=True)
class Segment:
    """One transcription line: frames ``start..end`` (1-based, inclusive, 30 Hz) carry ``gesture``."""

    start: int
    end: int
    gesture: str

    @property
    def n_frames(self) -> int:
        return self.end - self.start + 1


@dataclass(frozen=True)
class TrialMeta:
    """One line of the meta file: self-proclaimed skill (E/I/N) and GRS total and items."""

    skill: str
    grs: int
    grs_items: tuple[int, ...]


@dataclass(frozen=True)
class TrialFiles:
    """Paths of one trial found in a release."""

    name: str
    user: str
    trial: int
    kinematics: Path
    transcription: Path


@dataclass(frozen=True)
class ReleaseIndex:
    """The trials of a release: complete ones, and names lacking kinematics or a transcription."""

    root: Path
    trials: tuple[TrialFiles, ...]
    missing_kinematics: tuple[str, ...]
    missing_transcription: tuple[str, ...]

    @property
    def users(self) -> tuple[str, ...]:
        return tuple(sorted({t.user for t in self.trials}))


def trial_name(user: str, trial: int) -> str:
    """``("B", 1) -> "Suturing_B001"``."""
    return f"{TASK}_{user}{trial:03d}"


def kinematics_dir(root: Path) -> Path:
    return Path(root) / "kinematics" / "AllGestures"


def transcriptions_dir(root: Path) -> Path:
    return Path(root) / "transcriptions"


def meta_path(root: Path) -> Path:
    return Path(root) / f"meta_file_{TASK}.txt"


def _trial_names(folder: Path) -> dict[str, Path]:
    return {p.stem: p for p in sorted(folder.iterdir()) if _TRIAL_FILE.match(p.name)}


def discover(root: Path | str) -> ReleaseIndex:
    """Index the trials of a release folder, sorted by user letter then trial number.

    A trial with only one of kinematics / transcription is reported in one warning line (logger
    ``jigsaws_tools.release``) and left out of ``trials``; the index lists it as missing.
    """
    root = Path(root)
    if not root.is_dir():
        raise ReleaseNotFoundError(root, "JIGSAWS Suturing folder")
    kin_dir, tr_dir = kinematics_dir(root), transcriptions_dir(root)
    for folder, what in ((kin_dir, "kinematics folder"), (tr_dir, "transcriptions folder")):
        if not folder.is_dir():
            raise ReleaseNotFoundError(folder, what)
    kin, trans = _trial_names(kin_dir), _trial_names(tr_dir)
    missing_kin = tuple(sorted(set(trans) - set(kin)))
    missing_tr = tuple(sorted(set(kin) - set(trans)))
    for name in missing_kin:
        log.warning("%s: transcription present but no kinematics; trial skipped", name)
    for name in missing_tr:
        log.warning("%s: kinematics present but no transcription; trial skipped", name)
    trials = []
    for name in sorted(set(kin) & set(trans)):
        user, number = _TRIAL_FILE.match(name + ".txt").groups()
        trials.append(TrialFiles(name, user, int(number), kin[name], trans[name]))
    if not trials:
        raise ReleaseNotFoundError(root, "a trial with both kinematics and a transcription")
    return ReleaseIndex(root, tuple(trials), missing_kin, missing_tr)


def read_kinematics(path: Path | str) -> np.ndarray:
    """Read a kinematics file: ``[n_frames, 76]`` float64, one row per 30 Hz frame."""
    path = Path(path)
    try:
        data = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError:
        _diagnose_kinematics(path)
        raise
    if data.shape[1] != NUM_KINEMATIC_COLUMNS:
        _diagnose_kinematics(path)
    if not np.isfinite(data).all():
        row = int(np.argwhere(~np.isfinite(data))[0, 0])
        raise FormatError(path, _data_line_number(path, row), "nan/inf", "non-finite kinematic value")
    return data


def _data_line_number(path: Path, row: int) -> int:
    """1-based file line of the ``row``-th non-blank line."""
    seen = -1
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            if line.strip():
                seen += 1
                if seen == row:
                    return number
    return row + 1


def _diagnose_kinematics(path: Path) -> None:
    """Find the first malformed line of a kinematics file and raise a FormatError naming it."""
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            fields = line.split()
            if not fields:
                continue
            if len(fields) != NUM_KINEMATIC_COLUMNS:
                raise FormatError(path, number, len(fields),
                                  f"expected {NUM_KINEMATIC_COLUMNS} kinematic columns")
            for column, field in enumerate(fields, start=1):
                try:
                    float(field)
                except ValueError:
                    raise FormatError(path, number, field,
                                      f"non-numeric kinematic value in column {column}") from None


def read_transcription(path: Path | str, n_frames: int | None = None) -> list[Segment]:
    """Read ``start end G<k>`` lines (CRLF and trailing spaces tolerated).

    Segments must be in increasing order, non-overlapping, with ``1 <= start <= end`` and, when
    ``n_frames`` (the kinematics length) is given, ``end <= n_frames``.
    """
    path = Path(path)
    segments: list[Segment] = []
    with open(path, encoding="utf-8", errors="replace", newline=None) as f:
        for number, line in enumerate(f, start=1):
            fields = line.split()
            if not fields:
                continue
            segment = _parse_segment(path, number, fields)
            if n_frames is not None and segment.end > n_frames:
                raise FormatError(path, number, segment.end,
                                  f"end frame beyond the {n_frames} kinematic frames")
            if segments and segment.start <= segments[-1].end:
                raise FormatError(path, number, segment.start,
                                  f"segment overlaps or precedes the previous one "
                                  f"(which ends at frame {segments[-1].end})")
            segments.append(segment)
    if not segments:
        raise FormatError(path, None, "", "transcription has no segments")
    return segments


def _parse_segment(path: Path, number: int, fields: list[str]) -> Segment:
    if len(fields) != 3:
        raise FormatError(path, number, " ".join(fields), "expected 'start end G<k>'")
    try:
        start, end = int(fields[0]), int(fields[1])
    except ValueError:
        raise FormatError(path, number, " ".join(fields[:2]), "non-integer frame number") from None
    gesture = fields[2]
    if gesture not in GESTURE_INDEX:
        raise FormatError(path, number, gesture,
                          f"unknown Suturing gesture (expected one of {', '.join(GESTURE_INDEX)})")
    if start < 1 or end < start:
        raise FormatError(path, number, f"{start} {end}",
                          "frames must satisfy 1 <= start <= end")
    return Segment(start, end, gesture)


def read_meta(path: Path | str) -> dict[str, TrialMeta]:
    """Read ``meta_file_Suturing.txt``: trial name -> skill level and GRS scores."""
    path = Path(path)
    if not path.is_file():
        raise ReleaseNotFoundError(path, "meta file")
    meta: dict[str, TrialMeta] = {}
    with open(path, encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, start=1):
            fields = line.split()
            if not fields:
                continue
            if len(fields) != 9:
                raise FormatError(path, number, line.strip(),
                                  "expected name, skill, GRS and 6 GRS items")
            name, skill = fields[0], fields[1]
            if skill not in ("E", "I", "N"):
                raise FormatError(path, number, skill, "skill level must be E, I or N")
            try:
                scores = [int(v) for v in fields[2:]]
            except ValueError:
                raise FormatError(path, number, " ".join(fields[2:]), "non-integer GRS score") from None
            meta[name] = TrialMeta(skill, scores[0], tuple(scores[1:]))
    return meta


def frame_labels(segments: list[Segment], n_frames: int) -> np.ndarray:
    """Per-frame gesture class indices ``[n_frames]`` int64 at 30 Hz; uncovered frames are -1."""
    labels = np.full(n_frames, UNLABELLED, dtype=np.int64)
    for s in segments:
        labels[s.start - 1:s.end] = GESTURE_INDEX[s.gesture]
    return labels

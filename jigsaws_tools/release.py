"""Reader for the official JIGSAWS release layout of one task (e.g. ``Suturing/``).

Layout::

    <root>/kinematics/AllGestures/<Task>_<User><Trial>.txt   76 columns, 30 Hz, one line per frame
    <root>/transcriptions/<Task>_<User><Trial>.txt           "start end G<k>", 1-based inclusive
    <root>/meta_file_<Task>.txt                              name, skill level, GRS, 6 GRS items

``<Task>`` is ``TaskDefinition.name``; every function that depends on it takes the task (default:
the paper's Suturing). Another layout of recordings (columns, rate, folders, file names) is a
``RecordingFormat`` (``recording_format``); ``discover`` and ``read_recording`` take one, the
release's by default.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn, Sequence

import numpy as np

from .errors import OBTAIN_HINT, FormatError, JigsawsError, ReleaseNotFoundError
from .gestures import UNLABELLED
from .messages import data_logger
from .recording_format import JIGSAWS_FORMAT, RecordingFormat, another_layout_hint
from .task_definition import SUTURING, TaskDefinition

NUM_KINEMATIC_COLUMNS = 76
KINEMATICS_HZ = 30.0
#: The largest magnitude of a usable kinematic value: float32's, the models' type.
LARGEST_VALUE = float(np.finfo(np.float32).max)
_BOM = b"\xef\xbb\xbf"
_ANY_TRIAL_FILE = re.compile(r"^(.+)_[A-Z]\d{3}\.txt$", re.IGNORECASE)
#: The longest step of a time column, and the farthest a time may lie from the time its row gives
#: (``row / rate_hz`` after the first row's; see ``DRIFT_TOLERANCE``), in sample periods
#: ``1 / rate_hz``. Robot logs stamp samples with jitter and the odd late wake-up or dropped
#: sample (a step of up to two periods, then a short one); such a sample moves a prediction row's
#: time by at most a period and its input by one row, which no score notices. Two or more samples
#: missing in a row (a step of three periods or more), or times wandering off their rows, mean a
#: gap or another rate, and are refused.
GAP_PERIODS = 2.5
#: How far a recording's times may drift from those its rows give, as a fraction of the time
#: elapsed, on top of ``GAP_PERIODS``: a clock or control loop up to 1 % off its nominal rate
#: passes, so every prediction row's time is within 1 % (and 2.5 periods) of the recorded one.
DRIFT_TOLERANCE = 0.01
#: How to get past a time column the checks refuse (the end of their messages).
_TIME_ADVICE = "resample the recording to a uniform grid, or drop time_column from the format"
#: Why a line starting with ``#`` is refused, and what to do.
_COMMENT = ("a comment line: comments are not allowed in a recording, every non-blank line after "
            "its header is one sample (delete such lines, e.g. grep -v '^#')")

log = data_logger(__name__)


@dataclass(frozen=True)
class Segment:
    """One transcription line: frames ``start..end`` (1-based, inclusive, 30 Hz) are
    ``gesture``."""

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
    """The trials of one task's release: complete ones, names lacking kinematics or a
    transcription, and files that exist but cannot be used (``"<file>: <reason>"``)."""

    root: Path
    trials: tuple[TrialFiles, ...]
    missing_kinematics: tuple[str, ...]
    missing_transcription: tuple[str, ...]
    task: TaskDefinition = SUTURING
    unusable: tuple[str, ...] = ()
    recording_format: RecordingFormat = JIGSAWS_FORMAT

    @property
    def users(self) -> tuple[str, ...]:
        return tuple(sorted({t.user for t in self.trials}))


def trial_name(user: str, trial: int, task: TaskDefinition = SUTURING) -> str:
    """A release trial's file name without extension: ``("B", 1) -> "Suturing_B001"``
    (``JIGSAWS_FORMAT``'s ``trial``).

    Args:
        user: the user's letter, e.g. ``"B"``.
        trial: the trial's number, 1-based.
        task: whose name prefixes the file name.
    """
    return JIGSAWS_FORMAT.trial_name(task, user, trial)


def kinematics_dir(root: Path) -> Path:
    """The release's folder of kinematics files (``JIGSAWS_FORMAT``'s ``recordings``)."""
    return Path(root) / JIGSAWS_FORMAT.recordings


def transcriptions_dir(root: Path) -> Path:
    """The release's folder of transcriptions (``JIGSAWS_FORMAT``'s ``transcriptions``)."""
    return Path(root) / JIGSAWS_FORMAT.transcriptions


def meta_path(root: Path, task: TaskDefinition = SUTURING) -> Path:
    return Path(root) / f"meta_file_{task.name}.txt"


def require_layout(root: Path, task: TaskDefinition = SUTURING,
                   recording_format: RecordingFormat = JIGSAWS_FORMAT) -> None:
    """Raise ``ReleaseNotFoundError`` unless ``root`` is a folder holding a release's kinematics
    and transcriptions folders (those ``recording_format`` names; nothing in them is read). In
    the release's layout, a folder that holds something else is a one-line ``JigsawsError``
    (``_refuse_another_layout``)."""
    hint = OBTAIN_HINT if recording_format.is_default else (
        f"a {recording_format.name} data folder holds the folders its format's [files] names: "
        f"{recording_format.recordings} and {recording_format.transcriptions} (docs/DATA.md, "
        f"'Your own recordings')")
    if not root.is_dir():
        what = "JIGSAWS" if recording_format.is_default else f"{recording_format.name} data"
        raise ReleaseNotFoundError(root, f"{what} {task.name} folder", hint)
    if recording_format.is_default:
        _refuse_another_layout(root, task)
    for folder, what in ((root / recording_format.recordings, "kinematics folder"),
                         (root / recording_format.transcriptions, "transcriptions folder")):
        if not folder.is_dir():
            raise ReleaseNotFoundError(folder, what, hint)


def _refuse_another_layout(root: Path, task: TaskDefinition) -> None:
    """Raise a one-line ``JigsawsError`` if the folder ``root`` holds something but no release
    recordings folder: naming the task's folder if it is inside (``jigsaws/`` for
    ``jigsaws/Suturing``), else with the ``--format`` hint."""
    if (root / JIGSAWS_FORMAT.recordings).is_dir() or not any(root.iterdir()):
        return
    inside = root / task.name
    advice = f"give its {task.name} folder, {inside}" if inside.is_dir() else another_layout_hint()
    raise JigsawsError(f"{root}: not a JIGSAWS {task.name} release, no "
                       f"{JIGSAWS_FORMAT.recordings} folder; {advice}")


def discover(root: Path | str, task: TaskDefinition = SUTURING,
             recording_format: RecordingFormat = JIGSAWS_FORMAT) -> ReleaseIndex:
    """Index the trials of ``task`` in a release folder, sorted by user letter then trial number.

    Its recordings and transcriptions are found in the folders and by the file names that
    ``recording_format`` declares (the release's by default).

    A trial that cannot be used (only one of kinematics / transcription, an empty file, a folder or
    a broken link where a file should be) is reported in one warning line (logger
    ``jigsaws_tools.release``) and left out of ``trials``. Files named with an upper-case extension
    (``.TXT``) are read, with one warning per folder. A file named with a lower-case user letter
    (``Suturing_c001.txt``) is a ``FormatError``: read as user ``c`` it would be another user than
    ``C``, in the training set when ``C`` is tested.
    """
    root = Path(root)
    fmt = recording_format
    require_layout(root, task, fmt)
    kin_dir, tr_dir = root / fmt.recordings, root / fmt.transcriptions
    kin, kin_unusable = _trial_files(kin_dir, task, fmt, fmt.extension)
    trans, trans_unusable = _trial_files(tr_dir, task, fmt, ".txt")
    unusable = {**trans_unusable, **kin_unusable}
    missing_kin = tuple(sorted(set(trans) - set(kin) - set(kin_unusable)))
    missing_tr = tuple(sorted(set(kin) - set(trans) - set(trans_unusable)))
    for name in sorted(set(kin) | set(trans) | set(unusable)):
        reasons = [r for r in (kin_unusable.get(name), trans_unusable.get(name)) if r]
        if name not in kin and name not in kin_unusable:
            reasons.append("no kinematics")
        if name not in trans and name not in trans_unusable:
            reasons.append("no transcription")
        if reasons:
            log.warning("%s: %s; trial skipped", name, "; ".join(reasons))
    trials = []
    pattern = fmt.trial_pattern(task)
    for name in sorted(set(kin) & set(trans)):
        match = pattern.fullmatch(name)
        trials.append(TrialFiles(name, match["user"], int(match["trial"]), kin[name],
                                 trans[name]))
    if not trials:
        others = _other_tasks(kin_dir, task)
        if others:
            raise JigsawsError(f"{root}: no {task.name} trial found; it holds {', '.join(others)} "
                               f"trials (choose the task with --task or --task-file)")
        if fmt.is_default and not kin and not kin_unusable and any(kin_dir.iterdir()):
            raise JigsawsError(f"{kin_dir}: no file named like "
                               f"{fmt.trial_name(task, 'B', 1)}{fmt.extension}; "
                               f"{another_layout_hint()}")
        raise ReleaseNotFoundError(root, f"a {task.name} trial with both kinematics and a "
                                         f"transcription")
    return ReleaseIndex(root, tuple(trials), missing_kin, missing_tr, task,
                        tuple(reason for _, reason in sorted(unusable.items())), fmt)


def require_user(root: Path | str, user: str, task: TaskDefinition = SUTURING,
                 recording_format: RecordingFormat = JIGSAWS_FORMAT,
                 role: str = "test user", option: str = "--test-user") -> None:
    """Raise a one-line ``JigsawsError`` unless the folder ``root`` holds complete trials of
    ``user`` (the ``role`` the ``option`` gives it), naming the users it holds; from the file
    names alone (``discover``), before any recording is read."""
    index = discover(root, task, recording_format)
    if user not in index.users:
        raise JigsawsError(f"unknown {role} {user!r} ({option}): {root} holds "
                           f"{task.name} trials of users {', '.join(index.users)}")


def _trial_files(folder: Path, task: TaskDefinition, recording_format: RecordingFormat,
                 extension: str) -> tuple[dict[str, Path], dict[str, str]]:
    """``folder``'s trial files of ``task`` named as ``recording_format`` says, with
    ``extension``: usable ones (name -> path) and unusable ones (name -> why). A file with the
    extension in other case (``.TXT``) is used (warned once per folder) unless a twin with the
    exact extension exists."""
    pattern = recording_format.trial_pattern(task)
    prefix = recording_format.trial_prefix(task)
    usable: dict[str, Path] = {}
    unusable: dict[str, str] = {}
    upper = []
    for path in sorted(folder.iterdir()):
        name, suffix = path.name[:-len(extension)], path.name[-len(extension):]
        match = pattern.fullmatch(name)
        if suffix.lower() != extension.lower() or not match or not path.name.startswith(prefix):
            continue
        _refuse_lower_case_user(path, match)
        if suffix != extension:
            if (folder / f"{name}{extension}").exists():
                continue
            upper.append(path.name)
        problem = _unusable(path)
        if problem:
            unusable[name] = f"{path}: {problem}"
        else:
            usable[name] = path
    if upper:
        log.warning("%s: %d file(s) named with an upper-case extension read as trials (%s)",
                    folder, len(upper), ", ".join(upper[:3]) + (", ..." if len(upper) > 3 else ""))
    return usable, unusable


def _refuse_lower_case_user(path: Path, match: re.Match) -> None:
    """A ``FormatError`` for the trial file ``path`` if its user letter (``match``, of
    ``RecordingFormat.trial_pattern``) is lower case, naming the file to rename it to."""
    user = match["user"]
    if user.isupper():
        return
    start, end = match.span("user")
    renamed = path.name[:start] + user.upper() + path.name[end:]
    raise FormatError(path, None, user, f"user letter in lower case: a user is one upper-case "
                                        f"letter ({user} and {user.upper()} would be two users); "
                                        f"rename the file {renamed}")


def _unusable(path: Path) -> str | None:
    """Why ``path`` cannot be read as a trial file, or None."""
    if path.is_symlink() and not path.exists():
        return "broken symbolic link or link loop"
    if path.is_dir():
        return "a folder, not a file"
    if not path.is_file():
        return "not a regular file"
    if path.stat().st_size == 0:
        return "empty file (0 bytes)"
    return None


def _other_tasks(folder: Path, task: TaskDefinition) -> list[str]:
    """Names of the other tasks whose trial files ``folder`` holds."""
    return sorted({m.group(1) for p in folder.iterdir()
                   if (m := _ANY_TRIAL_FILE.match(p.name)) and m.group(1) != task.name})


def _check_readable(path: Path, what: str) -> None:
    """A clear error for a path that cannot hold ``what``; one warning for a byte-order mark."""
    if not path.exists() and not path.is_symlink():
        raise ReleaseNotFoundError(path, what)
    problem = _unusable(path)
    if problem:
        raise FormatError(path, None, str(path), f"cannot be read as a {what}: {problem}")
    with open(path, "rb") as f:
        if f.read(len(_BOM)) == _BOM:
            log.warning("%s: starts with a UTF-8 byte-order mark; ignored", path)


def unusable_value(values: np.ndarray) -> tuple[int, int, str] | None:
    """The first kinematic value the models cannot take, as ``(row, column, problem)`` of
    ``values`` ``[rows, columns]`` (0-based): a non-finite one, or one beyond float32's range
    (``LARGEST_VALUE``), where the models compute and it would become infinite. None: all usable.
    """
    for bad, problem in ((~np.isfinite(values), "non-finite kinematic value"),
                         (np.abs(values) > LARGEST_VALUE, "kinematic value beyond float32's "
                          f"range (magnitude at most {LARGEST_VALUE:.4g}, the models' type)")):
        found = np.argwhere(bad)
        if len(found):
            return int(found[0][0]), int(found[0][1]), problem
    return None


def read_kinematics(path: Path | str) -> np.ndarray:
    """Read a kinematics file: ``[n_frames, 76]`` float64, one row per 30 Hz frame."""
    return read_recording(path)


def read_recording(path: Path | str, recording_format: RecordingFormat = JIGSAWS_FORMAT,
                   features: Sequence[str] | None = None) -> np.ndarray:
    """Read a recording in ``recording_format``: ``[n_rows, F]`` float64, one row per sample at
    the format's ``rate_hz``: every non-blank line after the header. There are no comment lines
    (the release has none; a transcription's row numbers would be ambiguous with them): a line
    starting with ``#`` is refused, and every error's line is the file's own line number.

    Args:
        path: the recording file.
        recording_format: its layout (the release's by default).
        features: the model features to return, in order (``jigsaws_tools.features``; each read
            from ``recording_format.column_of(feature)``); None = every column of the file.

    Raises:
        FormatError: naming the file, the line, the column and the value: a byte that is not
            UTF-8, a missing column, a row of another width, a non-numeric value or one the
            models cannot take (``unusable_value``: non-finite, beyond float32's range),
            times (``time_column``) that do not increase or whose rate is not the format's.
    """
    path, fmt = Path(path), recording_format
    _check_readable(path, "kinematics file")
    lines = _text_lines(path)
    names, header_line = _column_names(path, fmt, lines)
    wanted = list(names) if features is None else [fmt.column_of(f) for f in features]
    for column, feature in zip(wanted, features or wanted):
        if column not in names:
            _missing_column(path, fmt, header_line, names, column, feature)
    if fmt.time_column and fmt.time_column not in names:
        _missing_column(path, fmt, header_line, names, fmt.time_column, "time_column")
    rows = [(number, line) for number, line in enumerate(lines, start=1)
            if number > header_line and line.strip()]
    if not rows:
        raise FormatError(path, None, "", "kinematics file has only blank lines"
                          + (" after its header" if header_line else ""))
    data = _parse_rows(path, fmt, names, rows)
    numbers = [number for number, _ in rows]
    unusable = unusable_value(data)
    if unusable:
        row, column, problem = unusable
        raise FormatError(path, numbers[row], float(data[row, column]),
                          f"{problem} in column {column + 1} ({names[column]})")
    if fmt.time_column:
        _check_times(path, fmt, data[:, names.index(fmt.time_column)], numbers)
    return data[:, [names.index(c) for c in wanted]]


def _text_lines(path: Path) -> list[str]:
    """The lines of the text file ``path`` (UTF-8, a byte-order mark allowed, any line ends); a
    byte that is not UTF-8 is a ``FormatError`` naming its line."""
    lines = []
    for number, line in enumerate(path.read_bytes().removeprefix(_BOM).splitlines(), start=1):
        try:
            lines.append(line.decode("utf-8"))
        except UnicodeDecodeError as error:
            raise FormatError(path, number, line[error.start:error.end],
                              f"not UTF-8 text (byte {error.start + 1} of the line); save the "
                              f"file as UTF-8") from None
    return lines


def _column_names(path: Path, fmt: RecordingFormat, lines: list[str]) -> tuple[list[str], int]:
    """The file's column names and the 1-based line of its header (0: none; ``fmt.columns``)."""
    if not fmt.header:
        return list(fmt.columns), 0
    for number, line in enumerate(lines, start=1):
        if line.lstrip().startswith("#"):
            raise FormatError(path, number, line.strip(), _COMMENT)
        if line.strip():
            names = [n.strip().strip('"\'') for n in
                     (line.split(fmt.separator) if fmt.separator else line.split())]
            repeated = next((n for n in names if names.count(n) > 1), None)
            if repeated is not None:
                raise FormatError(path, number, repeated, "column name repeated in the header")
            if fmt.time_column and fmt.time_column not in names:
                _missing_column(path, fmt, number, names, fmt.time_column, "time_column")
            return names, number
    raise FormatError(path, None, "", "kinematics file has only blank lines")


def _parse_rows(path: Path, fmt: RecordingFormat, names: list[str],
                rows: list[tuple[int, str]]) -> np.ndarray:
    """``rows`` (file line, text) as ``[len(rows), len(names)]`` float64; a malformed row is a
    ``FormatError`` naming its line (``_diagnose_rows``)."""
    try:
        data = np.loadtxt([line for _, line in rows], dtype=np.float64, ndmin=2,
                          delimiter=fmt.separator, comments=None)
    except ValueError as error:
        _diagnose_rows(path, names, fmt, rows, str(error))
    if data.shape[1] != len(names):
        _diagnose_rows(path, names, fmt, rows, f"rows of {data.shape[1]} columns")
    return data


def _missing_column(path: Path, fmt: RecordingFormat, header_line: int, names: list[str],
                    column: str, feature: str) -> None:
    shown = ", ".join(names[:8]) + (", ..." if len(names) > 8 else "")
    where = "header" if header_line else f"{fmt.name} format's columns"
    raise FormatError(path, header_line or None, column,
                      f"no column {column!r} for {feature} in the {where} ({shown})")


def _check_times(path: Path, fmt: RecordingFormat, times: np.ndarray, numbers: list[int]
                 ) -> None:
    """The time column [s] must follow ``fmt.rate_hz``; the first row that does not is a
    ``FormatError`` naming its line (``numbers``: each row's file line) and its time.

    Times increase, by at most ``GAP_PERIODS`` sample periods a step (a 10 s dropout is refused
    at the first row after it), and each lies within ``GAP_PERIODS`` periods plus
    ``DRIFT_TOLERANCE`` of the time elapsed of the time its row gives, ``row / rate_hz`` after
    the first row's, which is the time a prediction row carries. Steps alone would let a clock
    drift (every step 1.4 periods long passes them), so the distance is bounded at every row, not
    only the last, as a clock slow, then fast, can end on time. Jitter, a late stamp or a single
    dropped sample pass.
    """
    period = 1 / fmt.rate_hz
    steps = np.diff(times)
    column = f"time column {fmt.time_column!r}"
    bad = (steps <= 0) | (steps > GAP_PERIODS * period)
    if bad.any():
        row = int(np.argmax(bad)) + 1
        step, before = steps[row - 1], f"{times[row - 1]:g} s on the line before"
        if step <= 0:
            raise FormatError(path, numbers[row], float(times[row]),
                              f"{column} does not increase ({before}); {_TIME_ADVICE}")
        raise FormatError(path, numbers[row], float(times[row]),
                          f"{column} jumps {step:.6g} s ({1 / step:.4g} Hz) from {before}, "
                          f"{step / period:.1f} periods of rate_hz = {fmt.rate_hz:g} ({fmt.name} "
                          f"format; at most {GAP_PERIODS:g}): {_gap_or_rate(fmt, steps)}")
    expected = np.arange(len(times)) * period
    drifted = (np.abs(times - times[0] - expected)
               > GAP_PERIODS * period + DRIFT_TOLERANCE * expected)
    if drifted.any():
        row = int(np.argmax(drifted))
        raise FormatError(path, numbers[row], float(times[row]),
                          f"{column} drifts from rate_hz = {fmt.rate_hz:g} of the {fmt.name} "
                          f"format: {times[row] - times[0]:.6g} s after the first row's "
                          f"{times[0]:g} s, where {row} rows give {expected[row]:.6g} s "
                          f"(allowed: {DRIFT_TOLERANCE:.0%} of it and {GAP_PERIODS:g} periods): "
                          f"{_gap_or_rate(fmt, steps)}")


def _gap_or_rate(fmt: RecordingFormat, steps: np.ndarray) -> str:
    """What times refused by ``_check_times`` (``steps``: between rows, [s]) mean, and what to do:
    when their median step gives a rate more than ``DRIFT_TOLERANCE`` from the format's, that
    rate, and a format declaring it; else a gap (or a clock off its rate) in a recording at the
    format's rate."""
    positive = steps[steps > 0]
    rate = 1 / float(np.median(positive)) if len(positive) else fmt.rate_hz
    if abs(rate - fmt.rate_hz) <= DRIFT_TOLERANCE * fmt.rate_hz:
        return f"a gap in a recording at {fmt.rate_hz:g} Hz; {_TIME_ADVICE}"
    shown = f"{round(rate)}" if abs(rate - round(rate)) <= 1e-3 * rate else f"{rate:.4g}"
    return (f"its times fit {shown} Hz (median step {1 / rate:.6g} s), not the format's "
            f"{fmt.rate_hz:g} Hz: read it with a format of rate_hz = {shown} (a copy of "
            f"{fmt.name}'s), or {_TIME_ADVICE}")


def _diagnose_rows(path: Path, names: list[str], fmt: RecordingFormat,
                   rows: list[tuple[int, str]], numpy_error: str) -> NoReturn:
    """Raise a ``FormatError`` naming the first malformed row (a row of another width in the
    release's layout with the ``--format`` hint), or, if no row looks malformed, naming the file
    and ``numpy_error``, what ``numpy.loadtxt`` refused."""
    hint = f"; {another_layout_hint()}" if fmt.is_default else ""
    for number, line in rows:
        if line.lstrip().startswith("#"):
            raise FormatError(path, number, line.strip(), _COMMENT)
        fields = line.split(fmt.separator) if fmt.separator else line.split()
        if len(fields) != len(names):
            raise FormatError(path, number, len(fields),
                              f"expected {len(names)} kinematic columns{hint}")
        for column, field in enumerate(fields, start=1):
            if not _is_number(field):
                raise FormatError(path, number, field, f"non-numeric kinematic value in "
                                  f"column {column} ({names[column - 1]})")
    raise FormatError(path, None, numpy_error.split("\n")[0],
                      f"cannot be read as {len(names)} numeric columns")


def _is_number(field: str) -> bool:
    """``field`` is a number as ``numpy.loadtxt`` reads one: as ``float`` does, but without
    ``float``'s underscores between digits and non-ASCII digits."""
    try:
        float(field)
    except ValueError:
        return False
    return "_" not in field and field.strip().isascii()


def read_transcription(path: Path | str, n_frames: int | None = None,
                       task: TaskDefinition = SUTURING) -> list[Segment]:
    """Read ``start end G<k>`` lines (CRLF and trailing spaces tolerated).

    Args:
        path: the transcription file.
        n_frames: the kinematics length; when given, every ``end <= n_frames``.
        task: whose gesture vocabulary the labels must belong to.

    Segments must be in increasing order, non-overlapping, with ``1 <= start <= end``.
    """
    path = Path(path)
    _check_readable(path, "transcription")
    segments: list[Segment] = []
    with open(path, encoding="utf-8-sig", errors="replace", newline=None) as f:
        for number, line in enumerate(f, start=1):
            fields = line.split()
            if not fields:
                continue
            segment = _parse_segment(path, number, fields, task)
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


def _parse_segment(path: Path, number: int, fields: list[str], task: TaskDefinition) -> Segment:
    if len(fields) != 3:
        raise FormatError(path, number, " ".join(fields), "expected 'start end G<k>'")
    try:
        start, end = int(fields[0]), int(fields[1])
    except ValueError:
        raise FormatError(path, number, " ".join(fields[:2]), "non-integer frame number") from None
    gesture = fields[2]
    if gesture not in task.gesture_index:
        raise FormatError(path, number, gesture, f"unknown {task.name} gesture "
                                                 f"(expected one of {', '.join(task.gestures)})")
    if start < 1 or end < start:
        raise FormatError(path, number, f"{start} {end}",
                          "frames must satisfy 1 <= start <= end")
    return Segment(start, end, gesture)


def read_meta(path: Path | str) -> dict[str, TrialMeta]:
    """Read ``meta_file_<Task>.txt``: trial name -> skill level and GRS scores."""
    path = Path(path)
    if not path.is_file():
        raise ReleaseNotFoundError(path, "meta file")
    meta: dict[str, TrialMeta] = {}
    with open(path, encoding="utf-8-sig", errors="replace") as f:
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
                raise FormatError(path, number, " ".join(fields[2:]),
                                  "non-integer GRS score") from None
            meta[name] = TrialMeta(skill, scores[0], tuple(scores[1:]))
    return meta


def frame_labels(segments: list[Segment], n_frames: int, task: TaskDefinition = SUTURING
                 ) -> np.ndarray:
    """Per-frame class indices of ``task``'s vocabulary; uncovered frames are -1.

    Args:
        segments: the trial's transcription lines (``read_transcription``).
        n_frames: number of 30 Hz kinematic frames of the trial.
        task: whose gesture vocabulary gives the class indices.

    Returns:
        ``[n_frames]`` int64 at 30 Hz.
    """
    labels = np.full(n_frames, UNLABELLED, dtype=np.int64)
    for s in segments:
        labels[s.start - 1:s.end] = task.gesture_index[s.gesture]
    return labels

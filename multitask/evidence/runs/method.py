"""Another method's predictions, read and scored as a grid's runs are scored.

A prediction folder holds one file per trial of the task (every trial of the release: each is a
test trial of the LOUO fold of its user), named ``<trial>.csv`` or ``<trial>.txt``, all of one
format:

* CSV (``rnn_seg.predictions``' format, as ``multitask-predict`` writes it): a header, then one
  row per prediction with columns ``frame`` (1-based, at the recording's rate) and ``gesture``
  (a gesture name of the task, e.g. ``G3``), and optionally ``progress`` (a stage name, e.g.
  ``push``); other columns are ignored;
* text: one gesture name per line, nothing else (as MS-TCN's and ED-TCN's users write them).

Both are UTF-8 (a byte-order mark is allowed), with ``\n`` or ``\r\n`` line endings.

Rows are predictions at ``rate`` Hz, a divisor of the recording's rate (30 Hz for JIGSAWS): with
``step = recording rate / rate`` frames per row, row ``i`` (0-based) is the prediction at frame
``i * step + 1``, holding until the next row, so a trial of ``n`` frames has ``ceil(n / step)``
rows (``Layout``: at 30 Hz one per frame, at 5 Hz one per 6 frames from the first). A CSV's
``frame`` column must say so.

Scoring (``fold_scores``): our runs are scored at their 5 Hz samples, the trial's labelled frames,
every 6th from the first (``jigsaws_tools.dataset.Trial.frames``); each such sample takes the
prediction of the row holding its frame (``Layout.rows_of``), and the fold's scores are
``rnn_seg.metrics.segmentation_metrics`` over its trials' samples, as ``rnn_seg.tasks.task_scores``
gives a run's: ``gesture_<metric>`` and, with progress predictions, ``progress_<metric>`` and
``progress_mae`` (100 x mean |stage - true stage| / (stages - 1), per trial then averaged).

Every file is checked before anything is scored (``read_folder``): a missing trial, a file that is
no trial of the task (or a trial's name in another case), a trial of another task, a file of
another format or an extension in upper case, a file that is not UTF-8, a CSV column it reads
(``CSV_COLUMNS``) named twice or not exactly (``Gesture``, `` progress``; other columns are
ignored), an unknown or empty label (spaces around a label are ignored), a wrong frame, a file of
the wrong length (with the rate whose length it has, if any), or progress predictions in some
files only is a ``ValueError`` naming the file (line and value); across a method's folders
(``method_scores``), a folder given twice or progress predictions in some seeds only.
"""
from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from jigsaws_tools.dataset import DataConfig, load_dataset
from jigsaws_tools.release import discover, read_recording
from jigsaws_tools.task_definition import TaskDefinition
from rnn_seg.metrics import segmentation_metrics

from .collect import refuse_repeated

#: The columns a predictions CSV's rows are read from (``frame``, ``gesture`` required).
CSV_COLUMNS = ("frame", "gesture", "progress")
#: The formats by file extension.
FORMATS = {".csv": "CSV (frame,gesture[,progress])", ".txt": "text (one gesture per line)"}
#: The first line of MS-TCN's result files (its ``predict``), whose labels follow on one line.
MS_TCN_HEADER = "### Frame level recognition: ###"
#: A trial's name in any task: ``<Task>_<User><three digits>``.
_TRIAL_NAME = re.compile(r"^(?P<task>\w+?)_(?P<user>[A-Za-z])(?P<trial>\d{3})$")


@dataclass(frozen=True)
class Layout:
    """Predictions at ``rate_hz`` of recordings at ``recording_hz`` (module docstring)."""

    rate_hz: float
    recording_hz: float

    def __post_init__(self):
        ratio = self.recording_hz / self.rate_hz if self.rate_hz > 0 else math.nan
        if not (ratio >= 1 and abs(ratio - round(ratio)) < 1e-9 * ratio):
            raise ValueError(f"--rate {self.rate_hz:g}: predictions must come at a divisor of the "
                             f"recordings' {self.recording_hz:g} Hz (e.g. "
                             f"{self.recording_hz:g}, {self.recording_hz / 6:g})")

    @property
    def step(self) -> int:
        """Frames per row."""
        return round(self.recording_hz / self.rate_hz)

    def rows(self, n_frames: int) -> int:
        """The rows of a trial of ``n_frames`` frames."""
        return -(-n_frames // self.step)

    def frame_of(self, row: int) -> int:
        """The 1-based frame of 0-based ``row``."""
        return row * self.step + 1

    def rows_of(self, frames: np.ndarray) -> np.ndarray:
        """``[T]`` 0-based rows holding the ``[T]`` 1-based frames."""
        return (np.asarray(frames, dtype=np.int64) - 1) // self.step


@dataclass(frozen=True)
class TrialTruth:
    """What a trial is scored against: its ``n_frames`` recording frames; the 1-based
    ``frames`` ``[T]`` of its scored 5 Hz samples and their ``gestures`` and ``progress``
    ``[T]`` (class indices of the task)."""

    name: str
    user: str
    n_frames: int
    frames: np.ndarray
    gestures: np.ndarray
    progress: np.ndarray


def truth(config: DataConfig) -> list[TrialTruth]:
    """Every complete trial of ``config``'s release, as a grid's runs score it."""
    dataset = load_dataset(config)
    files = {f.name: f for f in discover(config.data_dir, config.task,
                                         config.recording_format).trials}
    return [TrialTruth(t.name, t.user,
                       len(read_recording(files[t.name].kinematics, config.recording_format)),
                       t.frames, t.gestures, t.progress) for t in dataset.trials]


@dataclass(frozen=True)
class Predicted:
    """One trial's predictions at its scored samples: ``gestures`` ``[T]`` and ``progress``
    ``[T]`` (or None) class indices."""

    gestures: np.ndarray
    progress: np.ndarray | None


def read_folder(folder: Path, trials: Sequence[TrialTruth], task: TaskDefinition,
                layout: Layout) -> dict[str, Predicted]:
    """Every trial's predictions in ``folder``, checked (module docstring), by trial name."""
    folder = Path(folder)
    if not folder.is_dir():
        what = "not a folder" if folder.exists() else "no such folder"
        raise FileNotFoundError(f"{folder}: {what} (give a folder of prediction files)")
    files = _trial_files(folder, {t.name for t in trials}, task)
    predicted = {t.name: _read_trial(files[t.name], t, task, layout) for t in trials}
    without = [files[name] for name, p in predicted.items() if p.progress is None]
    if 0 < len(without) < len(predicted):
        raise ValueError(f"{without[0]}: no progress column, which {len(predicted) - len(without)} "
                         f"of the folder's {len(predicted)} files have; give progress "
                         "predictions in every file or in none")
    return predicted


def _trial_files(folder: Path, expected: set[str], task: TaskDefinition) -> dict[str, Path]:
    """Trial name -> its file in ``folder``; a ``ValueError`` for anything else there, a missing
    trial, or two formats."""
    found: dict[str, Path] = {}
    spelled = {name.casefold(): name for name in expected}
    for path in sorted(p for p in folder.iterdir() if not p.name.startswith(".")):
        name = _TRIAL_NAME.match(path.stem)
        if path.suffix not in FORMATS or not path.is_file():
            what = ("a folder" if path.is_dir() else "its extension must be lower case (.csv, .txt)"
                    if path.suffix.lower() in FORMATS else "not a prediction file")
            raise ValueError(f"{path}: {what} (give <trial>.csv or <trial>.txt files only)")
        if path.stem not in expected and path.stem.casefold() in spelled:
            raise ValueError(f"{path}: no trial {path.stem}; the release spells it "
                             f"{spelled[path.stem.casefold()]} (trial names are case-sensitive)")
        if name and name["task"] != task.name and name["task"].casefold() == \
                task.name.casefold():
            raise ValueError(f"{path}: no trial {path.stem}; the release spells its task "
                             f"{task.name} (trial names are case-sensitive)")
        if name and name["task"] != task.name:
            raise ValueError(f"{path}: a trial of another task ({name['task']}); the predictions "
                             f"are scored on {task.name}")
        if path.stem not in expected:
            raise ValueError(f"{path}: no trial {path.stem} in the {task.name} release scored "
                             "(an extra trial)")
        if path.stem in found:
            raise ValueError(f"{path}: trial {path.stem} twice (and {found[path.stem].name})")
        found[path.stem] = path
    suffixes = sorted({p.suffix for p in found.values()})
    if len(suffixes) > 1:
        raise ValueError(f"{folder}: files of two formats ({', '.join(suffixes)}); one format "
                         "per folder")
    missing = sorted(expected - set(found))
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise ValueError(f"{folder}: no predictions of trial {missing[0]}{more} "
                         f"({len(found)} of {len(expected)} trials)")
    return found


def _read_trial(path: Path, trial: TrialTruth, task: TaskDefinition, layout: Layout
                ) -> Predicted:
    """The predictions of ``trial`` in ``path`` taken at its scored samples."""
    text = _text(path)
    if path.suffix == ".txt" and text.startswith(MS_TCN_HEADER):
        raise ValueError(f"{path}:1: MS-TCN's results layout (value: {MS_TCN_HEADER!r}, then the "
                         "labels space-separated on one line); write one gesture name per line")
    rows = _read_csv(path, text, layout) if path.suffix == ".csv" else {
        "gesture": list(enumerate(text.splitlines(), start=1))}
    gestures = _indices(path, rows["gesture"], task.gestures, "gesture")
    progress = rows.get("progress")
    progress = None if progress is None else _indices(path, progress, task.stage_names,
                                                      "progress stage")
    expected = layout.rows(trial.n_frames)
    if len(gestures) != expected:
        unit = "rows" if path.suffix == ".csv" else "lines"
        raise ValueError(f"{path}: trial {trial.name}: {len(gestures)} {unit}, expected "
                         f"{expected} (its {trial.n_frames} frames at "
                         f"{layout.recording_hz:g} Hz, one per {layout.step} at --rate "
                         f"{layout.rate_hz:g}){_rate_hint(len(gestures), trial, layout)}")
    chosen = layout.rows_of(trial.frames)
    return Predicted(gestures[chosen], None if progress is None else progress[chosen])


def _text(path: Path) -> str:
    """The text of a prediction file: UTF-8, a byte-order mark dropped; a ``ValueError`` naming
    the line of the first byte that is not UTF-8."""
    data = path.read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        raise ValueError(f"{path}:{line}: byte {data[error.start:error.start + 1]!r} is not "
                         "UTF-8 text; write the file as UTF-8") from None


def _rate_hint(rows: int, trial: TrialTruth, layout: Layout) -> str:
    """``"; that is its length at --rate R..."`` when ``rows`` is ``trial``'s length at another
    rate ``R`` that divides the recording's, else ``""``."""
    recording = round(layout.recording_hz)
    for step in (s for s in range(1, recording + 1) if recording % s == 0 and s != layout.step):
        if -(-trial.n_frames // step) == rows:
            return (f"; that is its length at --rate {layout.recording_hz / step:g}: was it "
                    "written at that rate?")
    return ""


def _read_csv(path: Path, text: str, layout: Layout) -> dict[str, list[tuple[int, str]]]:
    """Column -> ``(line, value)`` per row of ``gesture`` (and ``progress``) of a predictions CSV
    (``text``, read from ``path``), its ``frame`` column checked against ``layout``."""
    reader = csv.DictReader(io.StringIO(text, newline=""))
    header = reader.fieldnames or []
    for name in header:
        if name not in CSV_COLUMNS and name.strip().casefold() in CSV_COLUMNS:
            raise ValueError(f"{path}:1: column {name!r} (value: {','.join(header)!r}); write "
                             f"{name.strip().casefold()!r}: column names are exact")
    twice = [c for c in CSV_COLUMNS if header.count(c) > 1]
    if twice:
        raise ValueError(f"{path}:1: column {twice[0]!r} twice (value: {','.join(header)!r}); "
                         "one column per name")
    needed = [c for c in ("frame", "gesture") if c not in header]
    if needed:
        raise ValueError(f"{path}:1: no column {', '.join(needed)} (value: "
                         f"{','.join(reader.fieldnames or [])!r}); a predictions CSV has "
                         "frame,gesture[,progress]")
    columns = ["gesture"] + (["progress"] if "progress" in reader.fieldnames else [])
    rows: dict[str, list[tuple[int, str]]] = {c: [] for c in columns}
    for row, values in enumerate(reader):
        line = reader.line_num
        if values["frame"] != str(layout.frame_of(row)):
            raise ValueError(f"{path}:{line}: frame {values['frame']!r}, expected "
                             f"{layout.frame_of(row)} (row {row + 1} at --rate "
                             f"{layout.rate_hz:g}; frames count from 1)")
        for column in columns:
            rows[column].append((line, values[column] or ""))   # None: a short row
    return rows


def _indices(path: Path, rows: list[tuple[int, str]], names: Sequence[str], what: str
             ) -> np.ndarray:
    """``[n]`` the class index of each ``(line, name)``; a ``ValueError`` naming the first that
    is not one of ``names``."""
    index = {name: k for k, name in enumerate(names)}
    for line, value in rows:
        if not value.strip():
            raise ValueError(f"{path}:{line}: no {what} (an empty line or cell); one of: "
                             f"{', '.join(names)}")
        if value.strip() not in index:
            raise ValueError(f"{path}:{line}: unknown {what} {value!r}; known: "
                             f"{', '.join(names)}")
    return np.array([index[value.strip()] for _, value in rows], dtype=np.int64)


def fold_scores(predicted: dict[str, Predicted], trials: Sequence[TrialTruth],
                num_stages: int) -> pd.DataFrame:
    """One row per LOUO fold (``fold``, then ``gesture_<metric>`` and, when every trial has
    progress predictions, ``progress_<metric>`` and ``progress_mae``): the scores of its user's
    trials (module docstring)."""
    rows = []
    for user in sorted({t.user for t in trials}):
        mine = [t for t in trials if t.user == user]
        row = {"fold": user}
        row.update({f"gesture_{k}": v for k, v in segmentation_metrics(
            [predicted[t.name].gestures for t in mine], [t.gestures for t in mine]).items()})
        if all(predicted[t.name].progress is not None for t in mine):
            preds = [predicted[t.name].progress for t in mine]
            row.update({f"progress_{k}": v for k, v in segmentation_metrics(
                preds, [t.progress for t in mine]).items()})
            row["progress_mae"] = float(100 * np.mean(
                [np.mean(np.abs(p - t.progress)) for p, t in zip(preds, mine)])
                / (num_stages - 1))
        rows.append(row)
    return pd.DataFrame(rows)


def method_scores(folders: Sequence[Path], config: DataConfig, rate_hz: float
                  ) -> tuple[pd.DataFrame, dict[str, list[str]]]:
    """The prediction folders of a method, one per seed, scored: one row per seed and fold
    (``seed``: the folder's place in ``folders``, from 0; ``fold``; the scores, ``fold_scores``),
    and each fold's trials (names). Every folder is checked before any is scored; a folder given
    twice, or progress predictions in some folders or files only, is a ``ValueError``."""
    refuse_repeated(folders, "one folder per seed of the method")
    trials = truth(config)
    layout = Layout(rate_hz, config.recording_format.rate_hz)
    predicted = [read_folder(folder, trials, config.task, layout) for folder in folders]
    progress = [next(iter(p.values())).progress is not None for p in predicted]
    if len(set(progress)) > 1:
        have, lack = folders[progress.index(True)], folders[progress.index(False)]
        raise ValueError(f"{lack}: no progress predictions, which {have} has; give them for "
                         "every seed of the method or for none")
    scores = pd.concat([fold_scores(p, trials, config.task.num_stages).assign(seed=seed)
                        for seed, p in enumerate(predicted)], ignore_index=True)
    folds: dict[str, list[str]] = {}
    for trial in trials:
        folds.setdefault(trial.user, []).append(trial.name)
    return scores, folds

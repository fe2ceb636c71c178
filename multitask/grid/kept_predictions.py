"""A run's test predictions as a scores archive keeps them, and the ground truth beside them.

A finished run writes, at each evaluation point, one predictions CSV per test trial
(``rnn_seg.predictions``: the predicted and the true labels, the heads' scores). Its archive
(``archive``) keeps, in ``test_predictions.json`` beside its ``metrics.json``, what the figures
and per-trial analyses need of its last evaluation point, and nothing of the data's:

* per task (``gesture``, ``progress``), the predicted class of every 5 Hz sample: class indices
  into the task's ``classes``, ``uint8``, zlib-compressed, base64;
* a regression head's output (APr's ``progress_value``, in stages: 0 is the first stage),
  rounded to ``1 / VALUE_SCALE`` stage, as ``int32`` differences of consecutive samples
  (the first from 0), zlib-compressed, base64.

Never the true labels (``<task>_true``), the frames or times (which say where a trial's labels
begin), nor the heads' class scores: quantised to ``uint8`` and compressed, these would take
15 to 25 kB a run, as much as the rest of its archive, and no table or figure reads them. The
file's layout (``FORMAT``)::

    {"format": "kept-predictions 1", "evaluation": "epoch0120", "value_scale": 1000,
     "classes": {"gesture": ["G1", ...], "progress": ["reach", ...]},
     "trials": {"Suturing_B001": {"samples": 473, "gesture": "<base64>", "progress": "<base64>",
                                  "progress_value": "<base64>"}, ...}}

Read it with ``read_kept_predictions`` (which reads a grid's run folder, its CSVs, into the same
arrays, rounded alike, so that what is drawn from a run and from its archive is the same). Sample
``k`` of a trial is the ``k``-th sample of that trial as the run's data configuration loads it
(``jigsaws_tools.dataset.Trial``: for JIGSAWS, every 6th 30 Hz frame of its labelled span);
``read_truth`` re-reads from the data its 1-based frame ``frames[k]`` and its true labels. A
prediction at 30 Hz holds at every frame from ``frames[k]`` to ``frames[k + 1] - 1`` (the rule of
``multitask-predict``).

Size (measured on the synthetic release, about 2 000 samples a fold; the real Suturing release
has about 2 500): 1 kB a run of A, 1.5 kB of APc or APoc, 6.5 kB of APr (its regression output):
for the mix of the paper's grid about 2.5 kB a run, 0.25 MB per 100 runs (at most 0.7 MB when
every run is APr), beside about 26 kB a run for the rest of its archive.
"""
from __future__ import annotations

import base64
import binascii
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rnn_seg.runs.folder import RunFolderError, read_json

from ..models.run_record import read_run_record

#: The file of a run folder in an archive that holds its kept predictions.
FILE = "test_predictions.json"
FORMAT = "kept-predictions 1"
#: A regression output is kept in steps of 1 / VALUE_SCALE (of a stage).
VALUE_SCALE = 1000
#: The suffix of a regression head's output column (``<task>_value``, ``rnn_seg.predictions``).
VALUE = "value"


@dataclass(frozen=True)
class TrialPredictions:
    """One test trial's kept predictions, ``T`` samples (5 Hz for JIGSAWS).

    labels: per task, ``[T]`` int64 predicted class index (into ``KeptPredictions.classes``);
    values: per task with a regression head, ``[T]`` float64 output in stages (rounded to
    ``1 / VALUE_SCALE``).
    """

    labels: dict[str, np.ndarray]
    values: dict[str, np.ndarray]


@dataclass(frozen=True)
class KeptPredictions:
    """A run's kept test predictions: its evaluation point (e.g. ``epoch0120``), each task's
    class names in index order, and each test trial's predictions, by trial name in name
    order."""

    evaluation: str
    classes: dict[str, tuple[str, ...]]
    trials: dict[str, TrialPredictions]


@dataclass(frozen=True)
class TrialTruth:
    """One trial as the data holds it, ``T`` samples: ``frames`` ``[T]`` int64 1-based frame of
    each sample at ``frame_hz`` (30 Hz in the release), ``labels`` per task ``[T]`` int64 true
    class index."""

    frames: np.ndarray
    frame_hz: float
    labels: dict[str, np.ndarray]

    @property
    def seconds(self) -> np.ndarray:
        """``[T]`` seconds since the recording's first frame."""
        return (self.frames - 1) / self.frame_hz


def prediction_files(run_dir: Path | str) -> dict[str, Path]:
    """The per-trial prediction CSVs the run in ``run_dir`` wrote at its last evaluation point,
    by trial name, in name order; empty when it kept none (an archived run)."""
    points = sorted((Path(run_dir) / "eval").glob("*/predictions"))
    return {p.stem: p for p in sorted(points[-1].glob("*.csv"))} if points else {}


def kept_trials(run_dir: Path | str) -> list[str]:
    """The names of the test trials whose predictions the run (or its archive) in ``run_dir``
    kept, in name order; empty when none."""
    path = Path(run_dir) / FILE
    if path.is_file():
        return sorted(_checked(read_json(path), path)["trials"])
    return list(prediction_files(run_dir))


def read_kept_predictions(run_dir: Path | str) -> KeptPredictions | None:
    """The test predictions of the run in ``run_dir`` at its last evaluation point: from its
    archive's ``test_predictions.json``, else from its predictions CSVs (rounded as the archive
    keeps them); None when it has neither.

    Raises:
        RunFolderError: a file that is no such record, or a CSV of an unknown class; naming it.
    """
    path = Path(run_dir) / FILE
    record = (_checked(read_json(path), path) if path.is_file() else kept_record(run_dir))
    return None if record is None else _decoded(record, path)


def kept_record(run_dir: Path | str) -> dict | None:
    """The ``test_predictions.json`` record (module docstring) of the run in ``run_dir``, made
    from its last evaluation point's CSVs; None when it wrote none."""
    files = prediction_files(run_dir)
    if not files:
        return None
    run = read_run_record(Path(run_dir))
    classes = {task: run.classes(task) for task in run.tasks}
    wide = [task for task, names in classes.items() if len(names) > 256]
    if wide:
        raise RunFolderError(f"{run.path}: {wide[0]}: {len(classes[wide[0]])} classes; kept "
                             "predictions hold at most 256")
    trials = {name: _trial_record(path, classes) for name, path in files.items()}
    return {"format": FORMAT, "evaluation": next(iter(files.values())).parent.parent.name,
            "value_scale": VALUE_SCALE,
            "classes": {task: list(names) for task, names in classes.items()},
            "trials": trials}


def read_truth(run_dir: Path | str, trial: str, data_dir: Path | str | None = None
               ) -> TrialTruth:
    """``trial`` as the data the run in ``run_dir`` trained on holds it, loaded with the run's
    data configuration (annotations, preprocessing, task, recording format) from ``data_dir``,
    else from the folder its config.json records.

    Raises:
        OSError: that folder is not here; ValueError: it holds no such trial, or one of another
            length than the run's kept predictions of it.
    """
    from dataclasses import replace

    from jigsaws_tools.dataset import load_dataset

    record = read_run_record(Path(run_dir))
    folder = Path(data_dir if data_dir is not None else record.config.data.data_dir)
    if not folder.is_dir():
        raise OSError(f"the data folder {folder} is not here")
    data = replace(record.config.data, data_dir=str(folder))
    found = {t.name: t for t in load_dataset(data).trials}
    if trial not in found:
        raise ValueError(f"{folder} holds no trial {trial}")
    truth = found[trial]
    return TrialTruth(truth.frames, data.recording_format.rate_hz,
                      {"gesture": truth.gestures, "progress": truth.progress})


def _trial_record(path: Path, classes: dict[str, tuple[str, ...]]) -> dict:
    """One trial's entry of the record from its predictions CSV ``path`` (the one format of
    ``rnn_seg.predictions``, or an earlier version's: class indices in ``<task>_pred``)."""
    table = pd.read_csv(path)
    if "sample" in table and not np.array_equal(table["sample"], np.arange(len(table))):
        raise RunFolderError(f"{path}: sample: not the samples 0, 1, ... of a trial in order")
    entry: dict = {"samples": len(table)}
    for task, names in classes.items():
        if task in table:
            known = table[task].isin(names)
            if not known.all():
                raise RunFolderError(f"{path}: {task}: {table[task][~known].iloc[0]!r} is none "
                                     "of the run's classes")
            index = table[task].map({name: k for k, name in enumerate(names)}).to_numpy()
        else:
            index = table[f"{task}_pred"].to_numpy()
        entry[task] = _pack(np.asarray(index, dtype="<u1"))
        if f"{task}_{VALUE}" in table:
            steps = np.rint(table[f"{task}_{VALUE}"].to_numpy() * VALUE_SCALE).astype(np.int64)
            entry[f"{task}_{VALUE}"] = _pack(np.diff(steps, prepend=0).astype("<i4"))
    return entry


def _pack(array: np.ndarray) -> str:
    return base64.b64encode(zlib.compress(array.tobytes(), 9)).decode("ascii")


def _unpack(text: str, dtype: str, length: int) -> np.ndarray:
    array = np.frombuffer(zlib.decompress(base64.b64decode(text, validate=True)), dtype=dtype)
    if len(array) != length:
        raise ValueError(f"{len(array)} samples, not {length}")
    return array


def _checked(record, path: Path) -> dict:
    """``record`` once it is a record of ``FORMAT``; else a ``RunFolderError`` naming ``path``."""
    if not isinstance(record, dict) or record.get("format") != FORMAT:
        raise RunFolderError(f"{path}: not a record of kept predictions (format: {FORMAT})")
    return record


def _decoded(record: dict, path: Path) -> KeptPredictions:
    """The arrays of a record; a damaged one is a ``RunFolderError`` naming ``path``."""
    trials = {}
    try:
        scale = record["value_scale"]
        for name, entry in sorted(record["trials"].items()):
            length = entry["samples"]
            labels = {task: _unpack(entry[task], "<u1", length).astype(np.int64)
                      for task in record["classes"] if task in entry}
            values = {task: np.cumsum(_unpack(entry[f"{task}_{VALUE}"], "<i4", length),
                                      dtype=np.int64) / scale
                      for task in record["classes"] if f"{task}_{VALUE}" in entry}
            trials[name] = TrialPredictions(labels, values)
    except (KeyError, TypeError, ValueError, binascii.Error, zlib.error) as error:
        raise RunFolderError(f"{path}: damaged kept predictions ({type(error).__name__}: "
                             f"{error})") from None
    return KeptPredictions(record["evaluation"],
                           {task: tuple(names) for task, names in record["classes"].items()},
                           trials)

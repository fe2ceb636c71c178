"""A trained run loaded from its folder: its configuration, tasks and model with saved weights.

``load_run(path)`` rebuilds the run's ``RunConfig`` from ``config.json`` (``from_jsonable``), its
tasks (the variant's, or model A's for a ``baseline-train`` run) and model, and restores a
checkpoint's weights. ``TrainedRun.predict`` then labels a recording's raw kinematics with the
run's own preprocessing, keeping every frame (``jigsaws_tools.preprocessing.preprocess_recording``;
docs/REPRODUCTION.md, "Prediction on unlabelled recordings").
"""
from __future__ import annotations

import json
import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from baseline.config import RunConfig
from jigsaws_tools.features import feature_columns
from jigsaws_tools.preprocessing import Normalisation, preprocess_recording
from jigsaws_tools.release import NUM_KINEMATIC_COLUMNS, discover, read_kinematics
from rnn_seg.runs.checkpoints import restore_weights
from rnn_seg.model import SegmentationModel
from rnn_seg.runs.folder import (RunFolderError, from_jsonable, is_finished, read_json,
                                 write_json)
from rnn_seg.tasks import Task
from rnn_seg.trainer import predict

from ..models.heads import HeadConfig
from .predictions import RecordingPrediction
from ..models.variants import get_variant

CONFIG_FILE = "config.json"
#: Fixed normalisation statistics of a forward run's streaming inputs, saved once per run.
STREAM_NORMALISATION_FILE = "stream_normalisation.json"

log = logging.getLogger(__name__)


# -- configuration ------------------------------------------------------------------------------
def read_run_config(run_dir: Path) -> tuple[RunConfig, dict]:
    """``(RunConfig, the whole config.json)`` of a run folder."""
    if not Path(run_dir).is_dir():
        raise RunFolderError(f"{run_dir}: no such run folder")
    path = Path(run_dir) / CONFIG_FILE
    if not path.is_file():
        raise RunFolderError(f"{path}: not found; a run folder is what multitask-train, "
                             "baseline-train or multitask-grid wrote (--out)")
    try:
        saved = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise RunFolderError(f"{path}:{error.lineno}: not valid JSON ({error.msg})") from None
    if not isinstance(saved, dict) or "run" not in saved:
        raise RunFolderError(f"{path}: no 'run' configuration")
    return from_jsonable(RunConfig, _upgraded(saved["run"]), f"{path}: run"), saved


def _upgraded(run: dict) -> dict:
    """A run configuration written by an earlier version, in today's terms: ``train.plots`` was
    a bool (figures at every evaluation point or none)."""
    train = run.get("train", {})
    if isinstance(train, dict) and isinstance(train.get("plots"), bool):
        return {**run, "train": {**train, "plots": "all" if train["plots"] else "none"}}
    return run


def run_tasks(saved: dict, config: RunConfig, where: str) -> tuple[str, list[Task]]:
    """``(variant name, tasks)`` of a run's config.json: its variant's tasks on the run's task
    definition with its head settings, or model A's for a ``baseline-train`` run (which records
    no variant).

    Args:
        saved: the parsed config.json.
        config: its ``run`` entry, as a ``RunConfig``.
        where: the place named in errors (``RunFolderError``), e.g. the config.json's path.
    """
    variant = saved.get("variant", "A")
    heads = from_jsonable(HeadConfig, saved.get("heads", {}), f"{where}: heads")
    try:
        tasks = get_variant(variant).tasks(config.data.task, heads)
    except ValueError as error:
        raise RunFolderError(f"{where}: {error}") from None
    names = [t.name for t in tasks]
    if saved.get("tasks", names) != names:
        raise RunFolderError(f"{where}: tasks {saved['tasks']} are not variant {variant}'s "
                             f"({names})")
    return variant, tasks


@dataclass
class TrainedRun:
    """A run folder's configuration, tasks and model with the weights of one checkpoint."""

    run_dir: Path
    config: RunConfig
    variant: str
    tasks: tuple[Task, ...]
    model: SegmentationModel
    checkpoint: int                 # sweep count after which the weights were saved

    @property
    def finished(self) -> bool:
        return is_finished(self.run_dir)

    @property
    def online(self) -> bool:
        """A forward (causal) model: its output at a sample depends only on the past."""
        return not self.config.encoder.bidirectional

    @property
    def sample_hz(self) -> float:
        return self.config.data.preprocessing.sample_hz

    def features(self, kinematics: np.ndarray, where: str = "kinematics") -> np.ndarray:
        """The run's input columns ``[n_frames, F]`` of a recording ``[n_frames, 76]``."""
        kinematics = np.asarray(kinematics, dtype=np.float64)
        if kinematics.ndim != 2 or kinematics.shape[1] != NUM_KINEMATIC_COLUMNS:
            raise ValueError(f"{where}: expected [frames, {NUM_KINEMATIC_COLUMNS}] kinematics "
                             f"(JIGSAWS columns), got shape {list(kinematics.shape)}")
        if not len(kinematics):
            raise ValueError(f"{where}: no kinematic frames")
        bad = np.argwhere(~np.isfinite(kinematics))
        if len(bad):
            frame, column = bad[0]
            raise ValueError(f"{where}: frame {frame + 1}, column {column + 1}: non-finite "
                             f"kinematic value ({kinematics[frame, column]}); the recording "
                             "files refuse it too")
        return kinematics[:, feature_columns(self.config.data.feature_set)]

    def outputs(self, inputs: list[np.ndarray]) -> dict[str, list[np.ndarray]]:
        """Raw head outputs ``[T_i, K]`` per task of preprocessed sequences ``[T_i, F]``, each
        run alone from a fresh state (``per_sequence``), without dropout."""
        return predict(self.model, inputs, "per_sequence")

    def predict(self, kinematics: np.ndarray | str | Path, causal: bool = False,
                normalisation: Normalisation | None = None, where: str = "kinematics"
                ) -> RecordingPrediction:
        """Predict every task for one recording.

        Args:
            kinematics: ``[n_frames, 76]`` JIGSAWS-layout kinematics at 30 Hz, or the path of a
                kinematics file.
            causal: preprocess as a stream would (causal filter, fixed statistics); forward
                models only. Default: the run's offline preprocessing.
            normalisation: the fixed statistics for ``causal`` (None = ``stream_normalisation()``).
            where: the recording's name in error messages (default: the path, if one is given).

        Returns:
            The predictions per 5 Hz sample and per 30 Hz frame.
        """
        if isinstance(kinematics, (str, Path)):
            where, kinematics = str(kinematics), read_kinematics(kinematics)
        features = self.features(kinematics, where)
        if causal:
            self.require_online("causal (streaming) preprocessing")
            if normalisation is None:
                normalisation = self.stream_normalisation()
        try:
            inputs, frames = preprocess_recording(features, self.config.data.preprocessing,
                                                  causal, normalisation)
        except ValueError as error:
            raise ValueError(f"{where}: {len(features)} frames cannot be preprocessed: "
                             f"{error}") from None
        outputs = {name: seqs[0] for name, seqs in self.outputs([inputs]).items()}
        return RecordingPrediction(self.tasks, outputs, frames, len(features), self.sample_hz)

    def require_online(self, what: str) -> None:
        if not self.online:
            raise ValueError(f"{what} needs a forward (online) model; {self.run_dir} is "
                             "bidirectional (trained without --direction forward)")

    def stream_normalisation(self, data_dir: Path | str | None = None) -> Normalisation:
        """Fixed normalisation statistics of this run's streaming inputs.

        Read from ``<run>/stream_normalisation.json`` when present; otherwise computed from the
        run's training trials (``training_normalisation``, in ``data_dir`` or the run's data
        folder) and saved there for later use without the data.
        """
        path = self.run_dir / STREAM_NORMALISATION_FILE
        if path.is_file():
            saved = read_json(path)
            return from_jsonable(Normalisation, saved.get("normalisation")
                                 if isinstance(saved, dict) else saved, f"{path}: normalisation")
        stats, trials = training_normalisation(self.config, data_dir)
        try:
            write_json(path, {"normalisation": stats, "trials": trials,
                              "steps": "causal low-pass on each whole trial, one frame in "
                                       f"{self.config.data.preprocessing.resample_factor} "
                                       "from the first, unlabelled frames included"})
        except OSError as error:
            log.warning("%s: not saved (%s); computed again next time", path, error)
        return stats


def training_normalisation(config: RunConfig, data_dir: Path | str | None = None
                           ) -> tuple[Normalisation, list[str]]:
    """Mean and standard deviation of the causally preprocessed samples of a run's training
    trials (every frame, as a stream sees them), pooled; and the trials' names.

    ``data_dir``: the release holding them (default: the run's ``data.data_dir``).
    """
    index = discover(data_dir or config.data.data_dir, config.data.task)
    trials = [t for t in index.trials if t.user != config.test_user]
    columns = feature_columns(config.data.feature_set)
    steps = replace(config.data.preprocessing, normalise=False)
    samples = [preprocess_recording(read_kinematics(t.kinematics)[:, columns], steps,
                                    causal=True)[0] for t in trials]
    return Normalisation.fit(samples), [t.name for t in trials]


def load_run(path: Path | str, checkpoint: int | None = None) -> TrainedRun:
    """Load a run folder with the weights of its latest checkpoint (normally the final one) or of
    the checkpoint saved after sweep ``checkpoint`` (``rnn_seg.runs.checkpoints.restore_weights``;
    a ``RunFolderError`` names what is missing or does not fit). The model runs the TensorFlow-op
    loops whatever loops it trained with (``EncoderConfig.loops``): the same numbers to float32
    rounding, no compilation per recording length, and an export that needs no XLA."""
    run_dir = Path(path)
    config, saved = read_run_config(run_dir)
    variant, tasks = run_tasks(saved, config, str(run_dir / CONFIG_FILE))
    model = SegmentationModel(len(feature_columns(config.data.feature_set)),
                              replace(config.encoder, loops="graph"), tasks, config.train.seed)
    sweep = restore_weights(model, run_dir, sweep=checkpoint)
    run = TrainedRun(run_dir, config, variant, tuple(tasks), model, sweep)
    if not run.finished:
        log.warning("%s: the run is unfinished; using its checkpoint after sweep %d", run_dir,
                    sweep)
    return run

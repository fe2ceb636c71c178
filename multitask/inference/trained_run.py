"""A trained run loaded from its folder: its configuration, tasks and model with saved weights.

``load_run(path)`` rebuilds the run's ``RunConfig`` from ``config.json`` (``from_jsonable``), its
tasks (the variant's, or model A's for a ``baseline-train`` run) and model, and restores a
checkpoint's weights. ``TrainedRun.predict`` then labels a recording's raw kinematics with the
run's own preprocessing, keeping every frame (``jigsaws_tools.preprocessing.preprocess_recording``;
docs/REPRODUCTION.md, "Prediction on unlabelled recordings"), in the run's recording format or
another (``jigsaws_tools.recording_format``: columns, sample rate).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from baseline.builder import data_fingerprint
from baseline.config import RunConfig
from jigsaws_tools.dataset import check_format_fits
from jigsaws_tools.features import feature_columns
from jigsaws_tools.preprocessing import Normalisation, decimation, preprocess_recording
from jigsaws_tools.recording_format import RecordingFormat, load_format
from jigsaws_tools.release import discover, read_recording, unusable_value
from rnn_seg.runs.checkpoints import restore_weights
from rnn_seg.model import SegmentationModel
from rnn_seg.runs.folder import (RunFolderError, from_jsonable, is_finished, read_json,
                                 write_json)
from rnn_seg.config import Loops
from rnn_seg.tasks import Task
from rnn_seg.trainer import predict

from ..models.heads import HeadConfig
from ..models.run_record import read_run_record
from .predictions import RecordingPrediction
from .run_record import (CONFIG_FILE, STREAM_NORMALISATION_FILE, data_folder,  # noqa: F401
                         read_run_config)
from ..models.variants import get_variant

#: What a data fingerprint other than the run's means (``TrainedRun.trained_on``).
FINGERPRINT_DIFFERS = ("its data fingerprint differs from config.json's: other files, or another "
                       "version's way of deriving labels from them")

log = logging.getLogger(__name__)


# -- configuration ------------------------------------------------------------------------------
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
    data_fingerprint: str | None = None     # of the data it trained on, as config.json records

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

    def recording_format(self, recording_format: str | Path | RecordingFormat | None = None
                         ) -> RecordingFormat:
        """``recording_format`` (a built-in name, a format file, a format), checked to give this
        run's features at its sample rate; None = the format the run trained on (the JIGSAWS
        release's unless it was trained with one)."""
        if recording_format is None:
            return self.config.data.recording_format
        fmt = load_format(recording_format)
        where = str(recording_format) if isinstance(recording_format, (str, Path)) else ""
        check_format_fits(fmt, self.config.data.feature_set, self.config.data.preprocessing,
                          where)
        return fmt

    def input_columns(self, recording_format: str | Path | RecordingFormat | None = None
                      ) -> list[str]:
        """The columns of a recording's values ``[n_frames, C]`` passed as an array, in order
        (``features``, ``predict``, ``StreamingPredictor.push``, an export's signature): all the
        format's columns when its files have no header (the release's 76), else the columns of
        the run's features in the format's names (a header, which says which is which, comes
        with a file only). Default: the run's format."""
        fmt = self.recording_format(recording_format)
        if not fmt.header:
            return list(fmt.columns)
        return [fmt.column_of(f) for f in self.config.data.features]

    def feature_indices(self, recording_format: str | Path | RecordingFormat | None = None
                        ) -> list[int]:
        """0-based positions of the run's features among ``input_columns``."""
        fmt = self.recording_format(recording_format)
        columns = self.input_columns(fmt)
        return [columns.index(fmt.column_of(f)) for f in self.config.data.features]

    def features(self, kinematics: np.ndarray, where: str = "kinematics",
                 recording_format: str | Path | RecordingFormat | None = None) -> np.ndarray:
        """The run's input columns ``[n_frames, F]`` of a recording ``[n_frames, C]`` whose
        columns are ``input_columns(recording_format)`` (default: the run's format; the
        release's 76)."""
        fmt = self.recording_format(recording_format)
        columns = self.input_columns(fmt)
        kinematics = np.asarray(kinematics, dtype=np.float64)
        if kinematics.ndim != 2 or kinematics.shape[1] != len(columns):
            shown = ", ".join(columns[:3]) + (", ..." if len(columns) > 3 else "")
            raise ValueError(f"{where}: expected [frames, {len(columns)}] kinematics ({fmt.name} "
                             f"columns {shown}), got shape {list(kinematics.shape)}")
        if not len(kinematics):
            raise ValueError(f"{where}: no kinematic frames")
        unusable = unusable_value(kinematics)
        if unusable:
            frame, column, problem = unusable
            raise ValueError(f"{where}: frame {frame + 1}, column {column + 1}: {problem} "
                             f"({kinematics[frame, column]}); the recording files refuse it too")
        return kinematics[:, self.feature_indices(fmt)]

    def read_inputs(self, path: Path | str,
                    recording_format: str | Path | RecordingFormat | None = None) -> np.ndarray:
        """A recording file's values in ``input_columns(recording_format)`` ``[n_frames, C]``
        (``jigsaws_tools.release.read_recording``: every error names the file and line)."""
        fmt = self.recording_format(recording_format)
        return read_recording(path, fmt, None if not fmt.header else self.config.data.features)

    def outputs(self, inputs: list[np.ndarray]) -> dict[str, list[np.ndarray]]:
        """Raw head outputs ``[T_i, K]`` per task of preprocessed sequences ``[T_i, F]``, each
        run alone from a fresh state (``per_sequence``), without dropout."""
        return predict(self.model, inputs, "per_sequence")

    def predict(self, kinematics: np.ndarray | str | Path, causal: bool = False,
                normalisation: Normalisation | None = None, where: str = "kinematics",
                recording_format: str | Path | RecordingFormat | None = None
                ) -> RecordingPrediction:
        """Predict every task for one recording.

        Args:
            kinematics: the path of a recording file, or its values ``[n_frames, C]`` in
                ``input_columns(recording_format)`` (the release's: ``[n_frames, 76]`` at 30 Hz).
            causal: preprocess as a stream would (causal filter, fixed statistics); forward
                models only. Default: the run's offline preprocessing.
            normalisation: the fixed statistics for ``causal`` (None = ``stream_normalisation()``).
            where: the recording's name in error messages (default: the path, if one is given).
            recording_format: the recording's layout and rate (a built-in name, a format file or
                a ``RecordingFormat``; default: the run's, the JIGSAWS release's unless it
                trained on another).

        Returns:
            The predictions per 5 Hz sample and per frame (row) of the recording.
        """
        fmt = self.recording_format(recording_format)
        if isinstance(kinematics, (str, Path)):
            where = str(kinematics)
            features = read_recording(kinematics, fmt, self.config.data.features)
        else:
            features = self.features(kinematics, where, fmt)
        if causal:
            self.require_online("causal (streaming) preprocessing")
            if normalisation is None:
                normalisation = self.stream_normalisation()
        try:
            inputs, frames = preprocess_recording(features, self.config.data.preprocessing,
                                                  causal, normalisation, fmt.rate_hz)
        except ValueError as error:
            raise ValueError(f"{where}: {len(features)} frames cannot be preprocessed: "
                             f"{error}") from None
        outputs = {name: seqs[0] for name, seqs in self.outputs([inputs]).items()}
        return RecordingPrediction(self.tasks, outputs, frames, len(features), self.sample_hz,
                                   fmt.rate_hz)

    def trained_on(self, fingerprint: str) -> bool | None:
        """Whether the data of fingerprint ``fingerprint`` (``Dataset.fingerprint``,
        ``baseline.builder.data_fingerprint``) is the data the run trained on, whose fingerprint
        config.json records. None when config.json records none (a run of an early version): it
        cannot be told."""
        if self.data_fingerprint is None:
            return None
        return fingerprint == self.data_fingerprint

    def require_online(self, what: str) -> None:
        if not self.online:
            raise ValueError(f"{what} needs a forward (online) model; {self.run_dir} is "
                             "bidirectional (trained without --direction forward)")

    def stream_normalisation(self, data_dir: Path | str | None = None,
                             fingerprint: str | None = None) -> Normalisation:
        """Fixed normalisation statistics of this run's streaming inputs.

        Read from ``<run>/stream_normalisation.json`` when present; otherwise computed from the
        run's training trials (``training_normalisation``, in ``data_dir`` or the run's data
        folder) and saved there for later use without the data, unless that release is known
        not to be the data the run trained on (``trained_on``): those serve this call only.
        ``fingerprint``: that release's data fingerprint in the run's format, when the caller
        has it (``Dataset.fingerprint``); None = hash the release if the run records one.
        """
        path = self.run_dir / STREAM_NORMALISATION_FILE
        if path.is_file():
            saved = read_json(path)
            return from_jsonable(Normalisation, saved.get("normalisation")
                                 if isinstance(saved, dict) else saved, f"{path}: normalisation")
        folder = data_folder(self.config, self.run_dir, data_dir)
        stats, trials = training_normalisation(self.config, folder)
        if fingerprint is None and self.data_fingerprint is not None:
            fingerprint = data_fingerprint(replace(self.config.data, data_dir=str(folder)))
        if fingerprint is not None and self.trained_on(fingerprint) is False:
            log.warning("%s is not the data %s trained on (%s): the stream's statistics come "
                        "from its trials, and are not saved in the run", folder, self.run_dir,
                        FINGERPRINT_DIFFERS)
            return stats
        data = self.config.data
        rows = decimation(data.preprocessing, data.recording_format.rate_hz)
        try:
            write_json(path, {"normalisation": stats, "trials": trials,
                              "data_fingerprint": self.data_fingerprint,
                              "steps": f"causal low-pass on each whole trial, one row in {rows} "
                                       "from the first, unlabelled rows included"})
        except OSError as error:
            log.warning("%s: not saved (%s); computed again next time", path, error)
        return stats


def training_normalisation(config: RunConfig, data_dir: Path | str | None = None
                           ) -> tuple[Normalisation, list[str]]:
    """Mean and standard deviation of the causally preprocessed samples of a run's training
    trials (every frame, as a stream sees them), pooled; and the trials' names.

    ``data_dir``: the release holding them (default: the run's ``data.data_dir``, which must
    be absolute or relative to the working directory).
    """
    data = config.data
    index = discover(data_dir or data.data_dir, data.task, data.recording_format)
    trials = [t for t in index.trials if t.user != config.test_user]
    steps = replace(data.preprocessing, normalise=False)
    samples = [preprocess_recording(read_recording(t.kinematics, data.recording_format,
                                                   data.features), steps, causal=True,
                                    rate_hz=data.recording_format.rate_hz)[0] for t in trials]
    return Normalisation.fit(samples), [t.name for t in trials]


def load_run(path: Path | str, checkpoint: int | None = None,
             loops: Loops | None = None) -> TrainedRun:
    """Load a run folder with the weights of its latest checkpoint (normally the final one) or of
    the checkpoint saved after sweep ``checkpoint`` (``rnn_seg.runs.checkpoints.restore_weights``;
    a ``RunFolderError`` names what is missing or does not fit).

    An LSTM's model runs ``loops``; None = the fused loops for a run that started on them (so its
    own evaluations are repeated exactly; the graph loops, after one line, where they cannot be
    built here), else the TensorFlow-op loops: for a run trained on XLA's loops the same numbers
    to float32 rounding, without a compilation per recording length."""
    run_dir = Path(path)
    record = read_run_record(run_dir)
    config, saved = record.config, record.saved
    variant, tasks = run_tasks(saved, config, str(run_dir / CONFIG_FILE))
    encoder = config.encoder
    if encoder.kind == "lstm":
        encoder = replace(encoder, loops=loops or ("fused" if record.loops() == "fused"
                                                   else "graph"))
    model = SegmentationModel(len(feature_columns(config.data.feature_set)), encoder, tasks,
                              config.train.seed)
    sweep = restore_weights(model, run_dir, sweep=checkpoint)
    run = TrainedRun(run_dir, config, variant, tuple(tasks), model, sweep,
                     saved.get("data_fingerprint"))
    if not run.finished:
        log.warning("%s: the run is unfinished; using its checkpoint after sweep %d", run_dir,
                    sweep)
    return run

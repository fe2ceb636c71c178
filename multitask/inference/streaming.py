"""Online prediction: a forward model fed one frame (row of a recording) at a time.

``StreamingPredictor.push(frame)`` preprocesses causally (``StreamingPreprocessor``: a forward-only
low-pass designed at the recording format's rate, its state carried, one frame in
``decimation`` kept (every 6th at the release's 30 Hz), normalisation statistics fixed in advance
from the run's training trials) and, on each kept frame, advances the LSTM by one step with its
state carried between calls. Frames are in the recording format the run trained on (the
release's 76 columns at 30 Hz, or your own format's: ``TrainedRun.input_columns``) or another
given one. Its outputs equal ``TrainedRun.predict(kinematics, causal=True)``, the whole-sequence
pass under the same preprocessing (tests/test_inference.py, tests/test_recording_format.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tensorflow as tf

from jigsaws_tools.preprocessing import Normalisation, StreamingPreprocessor
from jigsaws_tools.recording_format import RecordingFormat
from jigsaws_tools.release import unusable_value

from .predictions import RecordingPrediction
from .trained_run import TrainedRun


@dataclass(frozen=True)
class SamplePrediction:
    """What a streaming model outputs at one kept frame (one 5 Hz sample).

    ``frame``: the 1-based frame (row of the recording) just pushed; per task, ``outputs`` the
    raw head outputs ``[K]``, ``scores`` ``[K]`` (``Task.scores``), ``labels`` the predicted
    class index (into ``Task.class_names``, as ``RecordingPrediction.labels`` and the exported
    SavedModel give it) and ``label_names`` its name (a gesture such as ``G3``, a stage such as
    ``reach``, as ``RecordingPrediction.label_names`` and the predictions CSV give it).
    """

    frame: int
    outputs: dict[str, np.ndarray]
    scores: dict[str, np.ndarray]
    labels: dict[str, int]
    label_names: dict[str, str]


class StreamingPredictor:
    """Frame-by-frame predictions of a forward (online) run.

    Args:
        run: a loaded forward run (``load_run``).
        normalisation: fixed input statistics (None = ``run.stream_normalisation()``, which reads
            or computes those of the run's training trials).
        recording_format: the frames' layout and rate (a built-in name, a format file or a
            format, checked to give the run's features; default: the run's).
    """

    def __init__(self, run: TrainedRun, normalisation: Normalisation | None = None,
                 recording_format: str | Path | RecordingFormat | None = None):
        run.require_online("streaming")
        self.run = run
        self.recording_format = run.recording_format(recording_format)
        self.normalisation = (run.stream_normalisation() if normalisation is None
                              else normalisation)
        self._width = len(run.input_columns(self.recording_format))
        self._columns = run.feature_indices(self.recording_format)
        self.reset()

    def reset(self) -> None:
        """Start a new recording: fresh filter and LSTM state, frame count 0."""
        self._preprocess = StreamingPreprocessor(self.run.config.data.preprocessing,
                                                 self.normalisation,
                                                 self.recording_format.rate_hz)
        self._state = self.run.model.initial_state(1)

    @property
    def frames(self) -> int:
        """Frames pushed since the last ``reset``."""
        return self._preprocess.frames

    def push(self, frame: np.ndarray) -> SamplePrediction | None:
        """Feed the next frame, ``[C]`` in ``run.input_columns(recording_format)`` (the
        release's 76 JIGSAWS columns, at 30 Hz); returns the prediction when the frame is one
        the model samples (one in ``decimation`` from the first: every 6th at 30 Hz), else
        None. A frame of the wrong width or with a value the model cannot take (non-finite,
        beyond float32's range) is a ``ValueError`` and is not taken: the stream goes on with
        the next frame as if it had not come."""
        frame = np.asarray(frame, dtype=np.float64)
        if frame.shape != (self._width,):
            raise ValueError(f"frame {self.frames + 1}: expected {self._width} kinematic "
                             f"values ({self.recording_format.name} columns), got shape "
                             f"{list(frame.shape)}")
        unusable = unusable_value(frame[None])
        if unusable:
            _, column, problem = unusable
            raise ValueError(f"frame {self.frames + 1}, column {column + 1}: {problem} "
                             f"({frame[column]}); the frame is not taken")
        sample = self._preprocess.push(frame[self._columns])
        if sample is None:
            return None
        outputs, self._state = _step(self.run.model, tf.constant(sample[None]), self._state)
        outputs = {name: value.numpy()[0] for name, value in outputs.items()}
        scores = {t.name: t.scores(outputs[t.name][None])[0] for t in self.run.tasks}
        labels = {t.name: int(t.decode(outputs[t.name][None])[0]) for t in self.run.tasks}
        names = {t.name: t.class_names[labels[t.name]] for t in self.run.tasks}
        return SamplePrediction(self.frames, outputs, scores, labels, names)


@tf.function(reduce_retracing=True, autograph=False)          # as SegmentationModel.infer
def _step(model, x, state):
    return model.step(x, state)


def stream_recording(predictor: StreamingPredictor, kinematics: np.ndarray,
                     where: str = "kinematics") -> RecordingPrediction:
    """Push every frame of a recording through ``predictor`` from a fresh state and collect
    its predictions per sample and frame.

    Args:
        predictor: the streaming model; it is reset first.
        kinematics: ``[n_frames, C]`` float at the predictor's recording format's rate, in its
            ``input_columns`` (the release's: ``[n_frames, 76]`` at 30 Hz).
        where: what errors call the recording, e.g. its file name.

    Returns:
        The predictions at the 5 Hz samples, and per frame by holding the last sample's.
    """
    fmt = predictor.recording_format
    predictor.run.features(kinematics, where, fmt)          # checks the shape and values
    predictor.reset()
    samples = [s for s in map(predictor.push, kinematics) if s is not None]
    run = predictor.run
    outputs = {t.name: np.stack([s.outputs[t.name] for s in samples]) for t in run.tasks}
    return RecordingPrediction(run.tasks, outputs,
                               np.array([s.frame for s in samples], dtype=np.int64),
                               len(kinematics), run.sample_hz, fmt.rate_hz)


def stream_file(predictor: StreamingPredictor, path: Path | str) -> RecordingPrediction:
    """``stream_recording`` of a recording file in the predictor's recording format."""
    return stream_recording(predictor, predictor.run.read_inputs(path, predictor.recording_format),
                            str(path))

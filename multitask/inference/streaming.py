"""Online prediction: a forward model fed one 30 Hz frame at a time.

``StreamingPredictor.push(frame)`` preprocesses causally (``StreamingPreprocessor``: a forward-only
low-pass with its state carried, every 6th frame kept, normalisation statistics fixed in advance
from the run's training trials) and, on each kept frame, advances the LSTM by one step with its
state carried between calls. Its outputs equal ``TrainedRun.predict(kinematics, causal=True)``, the
whole-sequence pass under the same preprocessing (tests/test_inference.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import tensorflow as tf

from jigsaws_tools.features import feature_columns
from jigsaws_tools.preprocessing import Normalisation, StreamingPreprocessor
from jigsaws_tools.release import NUM_KINEMATIC_COLUMNS

from .predictions import RecordingPrediction
from .trained_run import TrainedRun


@dataclass(frozen=True)
class SamplePrediction:
    """What a streaming model outputs at one kept frame (one 5 Hz sample).

    ``frame``: the 1-based 30 Hz frame just pushed; per task, ``outputs`` the raw head outputs
    ``[K]``, ``scores`` ``[K]`` (``Task.scores``) and ``labels`` the predicted class name.
    """

    frame: int
    outputs: dict[str, np.ndarray]
    scores: dict[str, np.ndarray]
    labels: dict[str, str]


class StreamingPredictor:
    """Frame-by-frame predictions of a forward (online) run.

    Args:
        run: a loaded forward run (``load_run``).
        normalisation: fixed input statistics (None = ``run.stream_normalisation()``, which reads
            or computes those of the run's training trials).
    """

    def __init__(self, run: TrainedRun, normalisation: Normalisation | None = None):
        run.require_online("streaming")
        self.run = run
        self.normalisation = (run.stream_normalisation() if normalisation is None
                              else normalisation)
        self._columns = list(feature_columns(run.config.data.feature_set))
        self.reset()

    def reset(self) -> None:
        """Start a new recording: fresh filter and LSTM state, frame count 0."""
        self._preprocess = StreamingPreprocessor(self.run.config.data.preprocessing,
                                                 self.normalisation)
        self._state = self.run.model.initial_state(1)

    @property
    def frames(self) -> int:
        """Frames pushed since the last ``reset``."""
        return self._preprocess.frames

    def push(self, frame: np.ndarray) -> SamplePrediction | None:
        """Feed the next 30 Hz frame (``[76]``, JIGSAWS columns); returns the prediction when the
        frame is one the model samples (every 6th from the first), else None."""
        frame = np.asarray(frame, dtype=np.float64)
        if frame.shape != (NUM_KINEMATIC_COLUMNS,):
            raise ValueError(f"frame {self.frames + 1}: expected {NUM_KINEMATIC_COLUMNS} kinematic "
                             f"values, got shape {list(frame.shape)}")
        sample = self._preprocess.push(frame[self._columns])
        if sample is None:
            return None
        outputs, self._state = _step(self.run.model, tf.constant(sample[None]), self._state)
        outputs = {name: value.numpy()[0] for name, value in outputs.items()}
        scores = {t.name: t.scores(outputs[t.name][None])[0] for t in self.run.tasks}
        labels = {t.name: t.class_names[int(t.decode(outputs[t.name][None])[0])]
                  for t in self.run.tasks}
        return SamplePrediction(self.frames, outputs, scores, labels)


@tf.function(reduce_retracing=True)
def _step(model, x, state):
    return model.step(x, state)


def stream_recording(predictor: StreamingPredictor, kinematics: np.ndarray,
                     where: str = "kinematics") -> RecordingPrediction:
    """Push every frame of a recording through ``predictor`` from a fresh state and collect
    its predictions per sample and frame.

    Args:
        predictor: the streaming model; it is reset first.
        kinematics: ``[n_frames, 76]`` float at 30 Hz, in the JIGSAWS column layout.
        where: what errors call the recording, e.g. its file name.

    Returns:
        The predictions at the 5 Hz samples, and per frame by holding the last sample's.
    """
    predictor.run.features(kinematics, where)           # checks the shape
    predictor.reset()
    samples = [s for s in map(predictor.push, kinematics) if s is not None]
    run = predictor.run
    outputs = {t.name: np.stack([s.outputs[t.name] for s in samples]) for t in run.tasks}
    return RecordingPrediction(run.tasks, outputs,
                               np.array([s.frame for s in samples], dtype=np.int64),
                               len(kinematics), run.sample_hz)

"""A trained run as a self-contained TensorFlow SavedModel, loadable without this package.

``tf.saved_model.load(DIR).signatures[...]``:

* ``serving_default(kinematics)``: one recording, ``kinematics`` ``[n_frames, C]`` float64 at the
  recording format's rate, in the columns ``model.json``'s ``recording.columns`` lists: the
  format's own columns when its files have no header (the release's 76 JIGSAWS columns at 30 Hz
  for a run trained on the release), else the columns of the run's features, by the names the
  format gives them, in that order. The run's offline preprocessing runs inside the graph
  (feature columns; zero-phase Butterworth low-pass designed at the recording's rate, computed as
  ``scipy.signal.sosfiltfilt`` does, odd padding included; one frame in ``resample_step`` from
  the first, 6 at 30 Hz, 20 at 100 Hz; z-normalisation over the recording), then the network.
  Returns, per frame (row) as ``multitask-predict``'s CSV: ``frame`` ``[n]`` int64 (1-based),
  ``sample`` ``[n]`` int64 (the 5 Hz sample it takes its prediction from) and, per task,
  ``<task>`` ``[n]`` int64 (class index) and ``<task>_scores`` ``[n, K]`` float32 (the CSV's score
  columns). Recordings need more frames than the filter's padding (15).
* ``features(features)``: preprocessed samples ``[T, F]`` float32 -> ``<task>`` ``[T]`` and
  ``<task>_scores`` ``[T, K]`` per sample, for inputs preprocessed outside.

A non-finite input value (NaN, inf) is an error (``InvalidArgumentError``), as in
``multitask-predict``, rather than scores of NaN for every frame.

``assets.extra/model.json`` documents the signatures, every task's class names, score columns
and whether its classes are ordered (``tasks``, keyed by the task's name as the outputs are:
``tasks.gesture.classes``), the recording format the run trained on (columns, rate;
``recording``), the preprocessing parameters (filter sections, columns, step) and the run's
configuration.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import tensorflow as tf
from scipy import signal

from jigsaws_tools.errors import WriteFailed
from jigsaws_tools.preprocessing import butterworth, decimation
from rnn_seg.runs.folder import to_jsonable, write_json
from rnn_seg.runs.publish import staged_folder

from .output_folders import check_export_folder
from .trained_run import CONFIG_FILE, TrainedRun, load_run

#: 3: ``tasks`` keyed by task name, as the signatures' outputs are (2: a list); 2: the input
#: columns and rate of the run's recording format (1: the release's only).
EXPORT_FORMAT = 3
DESCRIPTION_FILE = Path("assets.extra") / "model.json"
#: The attribute by which an op names its custom gradient (``tf.custom_gradient``).
GRADIENT_TYPE = "_gradient_op_type"


def _sosfilt(sos: np.ndarray, x: tf.Tensor, state: tf.Tensor) -> tf.Tensor:
    """``scipy.signal.sosfilt`` along axis 0 of ``x`` ``[n, F]`` float64 from the initial state
    ``state`` ``[n_sections, 2, F]`` (direct form II transposed, in scipy's operation order)."""
    sections = [tuple(float(v) for v in row) for row in sos]

    def body(t, z, out):
        """Frame ``t`` ``[F]`` through every section; ``z`` holds each one's two state rows."""
        value, new = x[t], []
        for (b0, b1, b2, _, a1, a2), (z0, z1) in zip(sections, z):
            y = b0 * value + z0
            new.append((b1 * value - a1 * y + z1, b2 * value - a2 * y))
            value = y
        return t + 1, new, out.write(t, value)

    z = [(state[s, 0], state[s, 1]) for s in range(len(sections))]
    out = tf.TensorArray(tf.float64, size=tf.shape(x)[0])
    *_, out = tf.while_loop(lambda t, *_: t < tf.shape(x)[0], body, (0, z, out))
    return out.stack()


def _sosfiltfilt(sos: np.ndarray, x: tf.Tensor) -> tf.Tensor:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` (odd padding of ``3 * ntaps`` frames)."""
    ntaps = 2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
    edge = int(3 * ntaps)
    tf.debugging.assert_greater(tf.shape(x)[0], edge, message=f"a recording needs more than "
                                f"{edge} frames for the zero-phase low-pass filter")
    ext = tf.concat([2.0 * x[:1] - tf.reverse(x[1:edge + 1], [0]), x,
                     2.0 * x[-1:] - tf.reverse(x[-edge - 1:-1], [0])], axis=0)
    zi = tf.constant(signal.sosfilt_zi(sos)[:, :, None])                       # [S, 2, 1]
    y = _sosfilt(sos, ext, zi * ext[0])
    y = _sosfilt(sos, tf.reverse(y, [0]), zi * y[-1])
    return tf.reverse(y, [0])[edge:-edge]


class ExportedRun(tf.Module):
    """The run's model and offline preprocessing as ``tf.function`` signatures."""

    def __init__(self, run: TrainedRun):
        super().__init__(name="exported_run")
        fmt = run.config.data.recording_format
        self.model = run.model
        self._tasks = run.tasks
        self._prep = run.config.data.preprocessing
        self._columns = run.feature_indices()
        self._step = decimation(self._prep, fmt.rate_hz)
        self._sos = butterworth(self._prep.cutoff_hz, self._prep.filter_order, fmt.rate_hz)
        size = len(self._columns)
        self.features = tf.function(self._features, autograph=False,       # as model.infer
                                    input_signature=[tf.TensorSpec([None, size], tf.float32)])
        self.serve = tf.function(self._serve, autograph=False, input_signature=[
            tf.TensorSpec([None, len(run.input_columns())], tf.float64, name="kinematics")])

    def _features(self, features: tf.Tensor) -> dict[str, tf.Tensor]:
        """Samples ``[T, F]`` -> per task ``<task>`` ``[T]`` and ``<task>_scores`` ``[T, K]``."""
        features = tf.debugging.assert_all_finite(features, "features hold a non-finite value")
        resets = tf.one_hot([0], tf.shape(features)[0], on_value=True, off_value=False)
        outputs = self.model(features[None], resets, None)
        result = {}
        for t in self._tasks:
            result[t.name] = t.decode_tf(outputs[t.name][0])
            result[f"{t.name}_scores"] = t.scores_tf(outputs[t.name][0])
        return result

    def _serve(self, kinematics: tf.Tensor) -> dict[str, tf.Tensor]:
        """One recording ``[n_frames, C]`` -> per-frame predictions (module docstring)."""
        kinematics = tf.debugging.assert_all_finite(kinematics,
                                                    "kinematics hold a non-finite value")
        x = tf.gather(kinematics, self._columns, axis=1)
        if self._prep.lowpass:
            x = _sosfiltfilt(self._sos, x)
        x = x[::self._step]
        if self._prep.normalise:
            std = tf.math.reduce_std(x, axis=0, keepdims=True)
            x = (x - tf.reduce_mean(x, axis=0, keepdims=True)) / tf.where(std > 0, std, 1.0)
        per_sample = self._features(tf.cast(x, tf.float32))
        frames = tf.range(1, tf.shape(kinematics)[0] + 1, dtype=tf.int64)
        samples = (frames - 1) // self._step
        result = {"frame": frames, "sample": samples}
        result.update({name: tf.gather(value, samples) for name, value in per_sample.items()})
        return result


def describe(run: TrainedRun) -> dict:
    """The contents of ``assets.extra/model.json``."""
    prep, fmt = run.config.data.preprocessing, run.config.data.recording_format
    columns = run.input_columns()
    return {
        "format": EXPORT_FORMAT,
        "run": {"run_dir": str(run.run_dir.resolve()), "variant": run.variant,
                "checkpoint_sweep": run.checkpoint, "finished": run.finished},
        "recording": {"format": fmt.name, "rate_hz": fmt.rate_hz, "columns": columns,
                      "features": {f: fmt.column_of(f) for f in run.config.data.features},
                      "definition": to_jsonable(fmt)},
        "signatures": {
            "serving_default": {
                "inputs": {"kinematics": f"[n_frames, {len(columns)}] float64, one recording "
                                         f"at {fmt.rate_hz:g} Hz, in the columns "
                                         f"recording.columns ({fmt.name} format)"},
                "outputs": {"frame": "[n_frames] int64, 1-based",
                            "sample": "[n_frames] int64, the sample whose prediction the frame "
                                      "takes: (frame - 1) // resample_step",
                            **_task_outputs(run, "n_frames")}},
            "features": {
                "inputs": {"features": f"[T, {len(run.config.data.features)}] float32, "
                                       "preprocessed samples"},
                "outputs": _task_outputs(run, "T")}},
        "tasks": {t.name: {"classes": list(t.class_names), "score_columns": t.score_columns(),
                           "ordered": t.ordered} for t in run.tasks},
        "preprocessing": {
            "feature_columns_1based": [c + 1 for c in run.feature_indices()],
            "lowpass": prep.lowpass,
            "lowpass_sos": butterworth(prep.cutoff_hz, prep.filter_order, fmt.rate_hz).tolist(),
            "lowpass_method": "scipy.signal.sosfiltfilt(sos, x, axis=0) on the whole recording",
            "resample_step": decimation(prep, fmt.rate_hz),
            "sample_hz": prep.sample_hz,
            "normalise": prep.normalise,
            "normalise_method": "per column: (x - mean) / std over the recording's samples "
                                "(population std; 0 -> 1)",
            "settings": to_jsonable(prep)},
    }


def _task_outputs(run: TrainedRun, length: str) -> dict[str, str]:
    out = {}
    for t in run.tasks:
        out[t.name] = f"[{length}] int64 class index into tasks.{t.name}.classes"
        out[f"{t.name}_scores"] = (f"[{length}, {len(t.score_columns())}] float32, columns "
                                   f"{', '.join(t.score_columns())}")
    return out


def _on_graph_loops(run: TrainedRun) -> TrainedRun:
    """``run``, or its checkpoint reloaded on the graph loops where its LSTM runs other ones: a
    SavedModel holds TensorFlow's own ops, not the fused ones of this package's library."""
    if run.model.encoder.config.loops == "graph":
        return run
    return load_run(run.run_dir, run.checkpoint, loops="graph")


def _without_gradient_types(folder: Path) -> None:
    """Drop the custom-gradient type of the SavedModel's ops in ``folder``: the LSTM's
    hand-written backward pass is not saved (``experimental_custom_gradients=False``), so the ops
    that would call it (``tf.custom_gradient``'s ``IdentityN``) keep none, and loading the model
    prints no "unsaved custom gradients" warning. The model is for inference: no gradient flows
    through the LSTM. ``fingerprint.pb`` is written again for the changed ``saved_model.pb``."""
    from tensorflow.core.protobuf import saved_model_pb2
    from tensorflow.python.saved_model import fingerprinting_utils

    path = folder / "saved_model.pb"
    saved = saved_model_pb2.SavedModel.FromString(path.read_bytes())
    for graph in saved.meta_graphs:
        library = graph.graph_def.library.function
        for node in [*graph.graph_def.node, *(node for f in library for node in f.node_def)]:
            if GRADIENT_TYPE in node.attr:
                del node.attr[GRADIENT_TYPE]
    path.write_bytes(saved.SerializeToString(deterministic=True))
    fingerprinting_utils.write_fingerprint(str(folder))


def export_run(run: TrainedRun, out: Path, overwrite: bool = False) -> Path:
    """Write ``run`` as a SavedModel folder (whole or not at all).

    Args:
        run: the loaded run and checkpoint.
        out: the folder to create.
        overwrite: replace an existing ``out``, an earlier export (never a run, a grid or a
            run's own files: ``rnn_seg.runs.outputs``).

    Returns:
        ``out``.
    """
    check_export_folder(out, overwrite)
    module = ExportedRun(_on_graph_loops(run))
    with staged_folder(out, overwrite) as folder:
        try:
            tf.saved_model.save(module, str(folder),
                                signatures={"serving_default": module.serve,
                                            "features": module.features},
                                # inference only: the LSTM's hand-written gradient is not exported
                                options=tf.saved_model.SaveOptions(
                                    experimental_custom_gradients=False))
        except tf.errors.OpError as error:      # TensorFlow's own error, not an OSError
            raise WriteFailed.from_message(out, str(error), "SavedModel") or error from None
        _without_gradient_types(Path(folder))
        write_json(folder / DESCRIPTION_FILE, describe(run))
        (folder / DESCRIPTION_FILE).with_name(CONFIG_FILE).write_text(
            (run.run_dir / CONFIG_FILE).read_text())
    return Path(out)

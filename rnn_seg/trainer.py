"""Training loop over sweeps: progress output, checkpoints with resume, evaluation points.

A run directory holds::

    config.json                  every configuration of the run, its settings hash and provenance;
                                 written when the run starts, never rewritten
    checkpoints/ckpt-<N>.*       TF checkpoints after N sweeps (model, optimiser state, dropout RNG,
                                 sweep count, settings hash) and the clock at N (seconds per
                                 phase and since the start); see rnn_seg.runs.checkpoints
    history.csv                  one line per logged epoch / unit: training losses, time; test
                                 (and with ``monitor_train`` training) scores every
                                 ``monitor_every`` units; every column any output setting can
                                 fill, empty where not computed (``rnn_seg.runs.logs``)
    timing.json                  seconds per phase, over every session of a resumed run
                                 (``rnn_seg.runs.timing``)
    tensorboard/                 the same scalars for TensorBoard, with ``tensorboard``
    eval/<unit><N>/metrics.json  test metrics and confusion matrices at evaluation point N
    eval/<unit><N>/predictions/<sequence>.csv, plots/<sequence>.png (figures: last point only,
                                 unless ``plots="all"``; CSV format: ``rnn_seg.predictions``)
    metrics.json                 every evaluation point, their mean, the confusion matrices summed
                                 over the points, and whether the training loss had stopped
                                 falling (``rnn_seg.convergence``)
    finished.json                written last (settings hash, start and end time, provenance, the
                                 training segments: which loops and precision trained which
                                 sweeps, and why; rnn_seg.runs.segments); a run without it is
                                 incomplete and resumes
    .lock                        while a process trains the run: its lock (rnn_seg.runs.lock)

A run folder always matches its weights: launching a run into a folder that records other settings
stops before any work (``rnn_seg.runs.settings``) unless asked to restart.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from datetime import timedelta
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pandas as pd
import tensorflow as tf
from tensorflow.core.framework import summary_pb2

from .runs.checkpoints import CheckpointStore, checkpoint_sweeps
from .config import (PLOT_POINTS, PREDICTION_MODES, PlotPoints,  # noqa: F401 (re-exported)
                     PredictionMode, TrainConfig, check_eval_points,
                     require_native_precision)
from .convergence import history_convergence
from .encoders.registry import resume_on
from .runs.lock import hold_folder
from .model import ModelParams, SegmentationModel
from .optim import OptimConfig, build_optimizer
from .plots import plot_sequence
from .runs.folder import (CONFIG, HISTORY, RUN_LOGS, clear_run_dir, is_finished, mark_finished,
                          point_dir, read_json, remove_temporary_files, write_atomic, write_json)
from .runs.logs import append_csv_row, resume_log  # noqa: F401 (append_csv_row re-exported)
from .sweeps import make_sweep, pad_sweep, reset_flags, sweep_indices, sweeps_per_epoch
from .predictions import prediction_csv, prediction_table
from .tasks import Task, task_metrics, task_scores
from .runs.provenance import now, provenance, started_loops
from .runs.segments import SEGMENTS, closed, earlier_segments, session_segment
from .runs.settings import SettingsMismatchError, check_run_dir, settings_hash
from .runs.timing import PhaseClock

#: What TensorBoard's scalar plugin reads (written without the tensorboard package).
_SCALAR_METADATA = summary_pb2.SummaryMetadata(
    plugin_data=summary_pb2.SummaryMetadata.PluginData(plugin_name="scalars"),
    data_class=summary_pb2.DATA_CLASS_SCALAR).SerializeToString()

class TrainingDiverged(RuntimeError):
    """A training loss became NaN or infinite; nothing after the last checkpoint was saved."""



@dataclass
class SequenceSet:
    """Named sequences: inputs ``[T_i, F]`` float32, integer labels ``[T_i]`` per task, and the
    1-based source frame number ``[T_i]`` of each sample at ``frame_hz`` (written next to
    predictions; without them each sample is its own frame, at the sampling rate)."""

    names: list[str]
    inputs: list[np.ndarray]
    labels: dict[str, list[np.ndarray]]
    frames: list[np.ndarray] = field(default_factory=list)
    frame_hz: float | None = None

    def __post_init__(self):
        if self.frames and self.frame_hz is None:
            raise ValueError("SequenceSet: frames given without their rate (frame_hz)")

    def time_base(self, i: int, sample_hz: float) -> tuple[np.ndarray, float]:
        """``(frames [T_i], their rate in Hz)`` of sequence ``i``, sampled at ``sample_hz``."""
        if self.frames:
            return self.frames[i], self.frame_hz
        return np.arange(1, len(self.inputs[i]) + 1), sample_hz

    def __len__(self) -> int:
        return len(self.names)


def predict(model: SegmentationModel, inputs: Sequence[np.ndarray], mode: PredictionMode
            ) -> dict[str, list[np.ndarray]]:
    """Raw head outputs ``[T_i, K]`` per sequence, without dropout.

    ``sweep`` (DiPietro's way): all sequences in one wrapped sweep, outputs cut to each length; in
    ``original`` reset mode the reverse direction of a shorter sequence then enters its last frames
    with the state of the wrapped copy after them. ``per_sequence``: each sequence alone, no
    wrapping. (Either way, ``original`` mode restarts the reverse state before each first frame.)
    A model with a convolutional encoder (``model.padded``) always predicts each sequence alone:
    its outputs do not depend on padding, and a wrapped sweep is not its input.

    Args:
        model: the model to run (its compiled ``infer`` pass).
        inputs: one ``[T_i, F]`` float32 array per sequence.
        mode: ``"sweep"`` or ``"per_sequence"`` (above).

    Returns:
        ``{task name: one [T_i, K] float32 array per sequence}``, in the order of ``inputs``.
    """
    whole = mode == "sweep" and not model.padded
    groups = [list(range(len(inputs)))] if whole else [[i] for i in range(len(inputs))]
    out: dict[str, list[np.ndarray]] = {name: [None] * len(inputs) for name in model.heads}
    for group in groups:
        lengths = [len(inputs[i]) for i in group]
        duration = max(lengths)
        outputs = model.infer(tf.constant(make_sweep([inputs[i] for i in group], duration)),
                              tf.constant(reset_flags(lengths, duration)))
        for name, value in outputs.items():
            value = value.numpy()
            for row, i in enumerate(group):
                out[name][i] = value[row, :lengths[row]]
    return out


class Trainer:
    """Trains ``model`` on ``train`` with a weighted sum of task losses; evaluates on ``test``.

    ``configs`` is what ``config.json`` records (configuration dataclasses and plain values): its
    settings (``rnn_seg.runs.settings``) are checked against a folder already in use.

    A run, top to bottom (``run``)::

        hold the folder's lock              rnn_seg.runs.lock
        prepare()                           check or clear the folder, write config.json
        resume()                            restore the newest checkpoint -> first sweep
        compile()                           trace the training step and ``model.infer`` once
        for every sweep:
            step(sweep, lr)                 one training sweep (graph code):
                batch(sweep)                    inputs, resets, targets (, valid) of the sweep
                loss_gradients(...)             task losses and gradients
                                                                [hook: per_task_gradients]
                update(losses, grads, lr)       apply them, return what to log [hook: update]
            after_sweep(sweep, lr, out)     book-keeping:
                record(out)                     the task losses of the sweep   [hook: record]
                _log_progress(...)              every ``log_every`` units: history.csv, the
                                                progress line, test scores every
                                                ``monitor_every`` units          [hook: _on_log]
                _evaluate(point)                at the evaluation points
                checkpoint                      every ``checkpoint_every`` units
        finish()                            metrics.json, timing.json, finished.json

    Subclasses change how task weights are chosen by overriding ``update`` and ``record`` (with
    ``per_task_gradients`` they get each task's gradient instead of the sum's), register further
    checkpointed state in ``extra_state`` and write their own per-unit logs in ``_on_log``;
    ``multitask.models.gradnorm.GradNormTrainer`` does all four. ``rnn_seg.stack.TrainerStack``
    replaces only ``step`` (several members in one vectorised step) and calls the rest per member.
    """

    per_task_gradients = False

    def __init__(self, model: SegmentationModel, tasks: Sequence[Task], optim: OptimConfig,
                 config: TrainConfig, train: SequenceSet, test: SequenceSet, run_dir: Path,
                 configs: dict, sample_hz: float, log: Callable[[str], None] = print):
        self.model, self.tasks, self.optim, self.config = model, list(tasks), optim, config
        self.train, self.test, self.run_dir, self.log = train, test, Path(run_dir), log
        self.sample_hz = sample_hz
        require_native_precision(model.encoder.config.precision)
        self.variables = tf.nest.flatten(model.params())      # the order of every gradient list
        self.sgd = build_optimizer(self.variables, optim)     # checkpointed as "sgd" (any kind)
        self.dropout_rng = tf.random.Generator.from_seed(config.seed + 1_000_003)
        self.sweep = tf.Variable(0, dtype=tf.int64, trainable=False, name="sweep")
        self.sweeps_per_epoch = sweeps_per_epoch(len(train), config.batch_size)
        self.total_sweeps = optim.sweeps(optim.total, self.sweeps_per_epoch)
        points = config.eval_points or (optim.total,)
        check_eval_points(points, optim)
        self.eval_sweeps = {optim.sweeps(p, self.sweeps_per_epoch): p for p in points}
        self.configs = configs
        self.settings_hash = settings_hash(configs)     # config.json's, once ``prepare`` ran
        self._saved_hash = tf.Variable("", dtype=tf.string, trainable=False, name="settings")
        self._targets = {t.name: [t.encode(y) for y in train.labels[t.name]] for t in self.tasks}
        self._train_step = tf.function(self._train_step_graph, autograph=False,  # as infer's
                                       input_signature=self._step_signature(train))
        self.clock = PhaseClock()
        self._test_outputs_at: tuple[int, dict] | None = None   # (sweep, outputs) of the test set
        self._store: CheckpointStore | None = None                  # set by prepare()
        self._record: dict = {}                                     # config.json, by prepare()
        self._segments: list[dict] = []                             # by resume()
        self._losses: list[np.ndarray] = []                         # since the last progress line
        self._summaries: tf.summary.SummaryWriter | None = None     # with config.tensorboard
        self._started = time.time()
        self._last_line = (0, self._started)                       # (sweeps done, time)
        self._first_sweep: tuple[int, float] | None = None           # this session's, when done

    @property
    def sweeps_per_unit(self) -> int:
        """Sweeps in one unit of the schedule (an epoch, or one sweep)."""
        return self.optim.sweeps(1, self.sweeps_per_epoch)

    # -- state ---------------------------------------------------------------------------------
    def extra_state(self) -> dict:
        return {}

    def checkpoint_sweeps(self) -> list[int]:
        """Sweep counts of the checkpoints on disk, oldest first."""
        return checkpoint_sweeps(self.run_dir)

    # -- one step ------------------------------------------------------------------------------
    def dropout_seeds(self) -> tf.Tensor:
        """``[dropout_calls, 2]`` int64 seeds for one training call, drawn one at a time."""
        return tf.stack([self.dropout_rng.make_seeds(1)[:, 0]
                         for _ in range(self.model.dropout_calls)])

    def update(self, losses: tf.Tensor, grads: list[list[tf.Tensor]], learning_rate: tf.Tensor
               ) -> tf.Tensor:
        """Apply one sweep's gradients (graph code).

        Args:
            losses: ``[n_tasks]`` float32 task losses of the sweep, in task order.
            grads: one gradient list (in ``self.variables`` order) per objective of
                ``loss_gradients``: the sum of the losses, or with ``per_task_gradients`` each task.
            learning_rate: scalar float32, the sweep's learning rate.

        Returns:
            What ``record`` reads back: here the task losses ``[n_tasks]``.
        """
        self.sgd.apply(grads[0], self.variables, learning_rate)
        return losses

    def record(self, out: np.ndarray) -> np.ndarray:
        """Read one sweep's ``update`` result; returns the task losses ``[n_tasks]``."""
        return out

    def step(self, sweep: int, learning_rate: float) -> np.ndarray:
        """Train on sweep number ``sweep`` (no book-keeping); returns ``update``'s result."""
        inputs, resets, targets, valid = self.batch(sweep)
        args = [tf.constant(inputs), tf.constant(resets), tuple(tf.constant(y) for y in targets),
                tf.constant(learning_rate, tf.float32)]
        if valid is not None:
            args.append(tf.constant(valid))
        return self._train_step(*args).numpy()

    def _step_signature(self, train: SequenceSet) -> list:
        """Shapes of one sweep (any duration): traced once, never again."""
        features = train.inputs[0].shape[1]
        batch = self.config.batch_size
        signature = [tf.TensorSpec([batch, None, features], tf.float32),
                     tf.TensorSpec([batch, None], tf.bool),
                     tuple(tf.TensorSpec([batch, None, t.num_outputs], tf.float32)
                           for t in self.tasks),
                     tf.TensorSpec([], tf.float32)]
        if self.model.padded:
            signature.append(tf.TensorSpec([batch, None], tf.bool))
        return signature

    def compile(self) -> None:
        """Trace the training step and the evaluation pass (once per process)."""
        self._train_step.get_concrete_function()
        self.model.infer.get_concrete_function()

    def _train_step_graph(self, inputs, resets, targets, learning_rate, valid=None):
        losses, grads = loss_gradients(self.model, self.tasks, self.per_task_gradients,
                                       self.model.params(), inputs, resets, targets,
                                       self.dropout_seeds(), valid)
        return self.update(losses, grads, learning_rate)

    def _on_log(self, done: int) -> None:
        """Called at every progress line (after ``done`` sweeps); for subclasses' own logs."""

    def batch(self, sweep: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...],
                                         np.ndarray | None]:
        """Training sweep ``sweep``: inputs ``[B, T, F]``, resets ``[B, T]``, one target array
        ``[B, T, K_task]`` per task and ``valid`` ``[B, T]``, ``T`` the longest sequence's
        length. For a recurrent encoder the others are wrapped and ``valid`` is None; for a
        convolutional one (``model.padded``) they are zero-padded at the end, ``valid`` marking
        their steps (``rnn_seg.sweeps``)."""
        idx = sweep_indices(len(self.train), self.config.batch_size, self.config.seed, sweep)
        lengths = [len(self.train.inputs[i]) for i in idx]
        duration = max(lengths)
        fill = pad_sweep if self.model.padded else make_sweep
        inputs = fill([self.train.inputs[i] for i in idx], duration)
        targets = tuple(fill([self._targets[t.name][i] for i in idx], duration)
                        for t in self.tasks)
        if not self.model.padded:
            return inputs, reset_flags(lengths, duration), targets, None
        valid = np.arange(duration)[None, :] < np.asarray(lengths)[:, None]
        return inputs, reset_flags([duration] * len(idx), duration), targets, valid

    # -- the loop ------------------------------------------------------------------------------
    def run(self, restart: bool = False) -> dict:
        """Train to the end (resuming from the newest checkpoint) and return ``metrics.json``'s
        content. ``restart``: delete the folder's previous config and results first, whatever
        settings they record. Holds the folder's lock throughout (``rnn_seg.runs.lock``)."""
        with hold_folder(self.run_dir):
            self.prepare(restart)
            if not self.finished():
                start = self.resume()
                with self.clock.phase("trace"):
                    self.compile()
                self._last_line = (start, time.time())     # time per unit: sweeps, not tracing
                for sweep in range(start, self.total_sweeps):
                    lr = self.optim.learning_rate_at(sweep, self.sweeps_per_epoch)
                    with self.clock.phase("train"):
                        out = self.step(sweep, lr)
                    self.after_sweep(sweep, lr, out)
            return self.finish()

    def finished(self) -> bool:
        return is_finished(self.run_dir)

    def prepare(self, restart: bool = False) -> None:
        """Make ``run_dir`` this run's, before any work: check that a folder in use records the
        same settings (else ``SettingsMismatchError`` naming each difference) or, with
        ``restart``, delete its config and results; write config.json if new; remove temporary
        files an interrupted run left. Call it holding the folder's lock (``run`` does)."""
        if restart:
            clear_run_dir(self.run_dir)
        else:
            check_run_dir(self.run_dir, self.configs)
        config_path = self.run_dir / CONFIG
        if not config_path.is_file():
            # provenance's loops: those this process runs (graph where fused ones cannot be built)
            write_json(config_path, {**self.configs, "settings_hash": self.settings_hash,
                                     "provenance": {**provenance(), "started": now(),
                                                    "loops": self.model.encoder.config.loops}})
        self._record = read_json(config_path)
        resume_on(self.model.encoder, started_loops(self._record))
        self.settings_hash = self._record.get("settings_hash", self.settings_hash)
        self._saved_hash.assign(self.settings_hash)
        checkpoint = tf.train.Checkpoint(model=self.model, sgd=self.sgd, sweep=self.sweep,
                                         dropout_rng=self.dropout_rng, settings=self._saved_hash,
                                         **self.extra_state())
        self._store = CheckpointStore(self.run_dir, checkpoint, self.config.keep_checkpoints,
                                      self.eval_sweeps, self.log)
        removed = remove_temporary_files(self.run_dir) + self._store.remove_leftovers()
        if removed:
            self.log(f"{self.run_dir}: removed {len(removed)} temporary file(s) of an "
                     "interrupted run")

    def resume(self) -> int:
        """Restore the newest readable checkpoint (``prepare``-ing the folder first if needed);
        returns the sweep to continue from (0 = the start)."""
        if self._store is None:
            self.prepare()
        done = self._store.restore()
        if done:
            saved = self._saved_hash.numpy().decode()
            if saved != self.settings_hash:
                raise SettingsMismatchError(
                    f"{self.run_dir}: checkpoint ckpt-{done} was saved with settings {saved}, "
                    f"not those of its config.json ({self.settings_hash})")
            self._saved_hash.assign(self.settings_hash)
            self.log(f"resuming from sweep {done} ({self.run_dir / 'checkpoints'}/ckpt-{done}) "
                     f"with {self.model.encoder.config.loops} loops")   # not a setting: say it
        for name in RUN_LOGS:                       # rows past the checkpoint will be redone
            for warning in resume_log(self.run_dir / name, done, self.log_columns().get(name)):
                self.log(f"warning: {warning}")
        self._losses, self._started = [], time.time()
        self._last_line = (done, self._started)
        if done:
            self._continue_clock(done)
        self._segments = [*earlier_segments(self._store.clock(done) if done else None, done,
                                            self._record),
                          session_segment(self.model.encoder, done)]
        return done

    def _continue_clock(self, done: int) -> None:
        """Count the sessions before checkpoint ``done`` of a resumed run: the seconds per phase
        and since the start saved with that checkpoint."""
        saved = self._store.clock(done)
        if saved is None:
            self.log(f"warning: checkpoint ckpt-{done} predates the clock kept with checkpoints: "
                     "timing.json and history.csv's elapsed_seconds count from this session")
            return
        for name, seconds in saved["phases"].items():
            self.clock.add(name, float(seconds))
        self._started -= float(saved["elapsed_seconds"])

    def after_sweep(self, sweep: int, lr: float, out: np.ndarray) -> None:
        """Book-keeping after a sweep: loss check, progress line, evaluation point, checkpoint.

        Args:
            sweep: 0-based number of the sweep just trained.
            lr: its learning rate (``OptimConfig.learning_rate_at``).
            out: ``update``'s result for it, as numpy (read by ``record``).
        """
        losses = self.record(out)
        done = sweep + 1
        if self._first_sweep is None:
            self._first_sweep = (done, time.time())
        if not np.all(np.isfinite(losses)):
            self._diverged(done, losses)
        self._losses.append(losses)
        self.sweep.assign(done)
        if done % (self.sweeps_per_unit * self.config.log_every) == 0 or done == self.total_sweeps:
            with self.clock.phase("monitor"):
                self._log_progress(done, lr, np.mean(self._losses, axis=0))
            self._losses = []
        if done in self.eval_sweeps:
            with self.clock.phase("evaluate"):
                self._evaluate(self.eval_sweeps[done])
        if (done in self.eval_sweeps or done == self.total_sweeps
                or done % (self.sweeps_per_unit * self.config.checkpoint_every) == 0):
            with self.clock.phase("checkpoint"):
                self._store.save(done, {"phases": self.clock.report(),
                                        "elapsed_seconds": time.time() - self._started,
                                        SEGMENTS: closed(self._segments, done)})

    def log_columns(self) -> dict[str, list[str]]:
        """The columns of the run's CSV logs (``rnn_seg.runs.logs``) it knows: ``history.csv``'s,
        every column any output setting can fill (training scores for ``monitor_train``)."""
        scores = [f"{split}_{t.name}_{k}" for split in ("train", "test") for t in self.tasks
                  for k in ("acc", "edit")]
        return {HISTORY: ["unit", "n", "sweep", "lr", *(f"loss_{t.name}" for t in self.tasks),
                          *scores, "unit_seconds", "elapsed_seconds"]}

    def _diverged(self, done: int, losses: np.ndarray) -> None:
        bad = ", ".join(f"{t.name} {v}" for t, v in zip(self.tasks, losses) if not np.isfinite(v))
        unit = done / self.sweeps_per_unit
        last = max(self.checkpoint_sweeps(), default=0)
        raise TrainingDiverged(
            f"{self.run_dir}: training diverged at sweep {done} ({self.optim.unit_name} {unit:g}): "
            f"loss {bad}. Nothing after the last checkpoint (sweep {last}) was saved; lower the "
            f"learning rate and restart the run (e.g. --restart).")

    def _monitored(self, done: int) -> bool:
        """Whether the progress line after ``done`` sweeps scores the model: every
        ``monitor_every`` units and at the end."""
        every = self.optim.sweeps(self.config.monitor_every, self.sweeps_per_epoch)
        return done == self.total_sweeps or (every > 0 and done % every == 0)

    def _log_progress(self, done: int, lr: float, losses: np.ndarray) -> None:
        """One ``history.csv`` row and one short progress line: the training losses of the sweeps
        since the last line (free), time per unit and ETA, and every ``monitor_every`` units the
        test set's scores (and the training set's with ``monitor_train``)."""
        now, since = time.time(), self._last_line
        unit_seconds = (now - since[1]) * self.sweeps_per_unit / max(1, done - since[0])
        self._last_line = (done, now)
        scores = {}
        if self.config.monitor_train:
            scores.update({f"train_{k}": v for k, v in self._scores(self.train, done).items()})
        scores.update({f"test_{k}": v for k, v in self._scores(self.test, done).items()})
        row = {"unit": self.optim.unit, "n": round(done / self.sweeps_per_unit, 3), "sweep": done,
               "lr": lr, **{f"loss_{t.name}": float(v) for t, v in zip(self.tasks, losses)},
               **scores, "unit_seconds": round(unit_seconds, 3),
               "elapsed_seconds": round(now - self._started, 1)}
        self._append_history(row)
        self._write_summaries(row)
        self._on_log(done)
        self.log(self._progress_line(row, self._seconds_left(done, now, since)))

    def _seconds_left(self, done: int, now: float, since: tuple[int, float]) -> float:
        """The ETA after ``done`` sweeps: the sweeps left at the pace of those since the last
        line (``since``: sweeps done and time then). When those begin with this session's first
        sweep, its time is left out: it holds TensorFlow's one-off work (graph optimisation,
        the kernels' first calls), which the first line's ETA of a short run counted once per
        sweep left (a 3-minute run's first ETA read 12 minutes)."""
        first_done, first_time = self._first_sweep or since
        if since[0] < first_done < done:
            since = (first_done, first_time)
        per_sweep = (now - since[1]) / max(1, done - since[0])
        return (self.total_sweeps - done) * per_sweep

    def _progress_line(self, row: dict, seconds_left: float) -> str:
        """``[B] epoch 12/30  loss gesture 0.412 progress 0.233  test acc/edit gesture 84.1/80.2
        1.8 s/epoch  ETA 0:00:32``: the time per unit measured since the last line, and the time
        left (``_seconds_left``)."""
        unit = self.optim.unit_name
        losses = " ".join(f"{t.name} {row[f'loss_{t.name}']:.3f}" for t in self.tasks)
        parts = [f"[{self.run_dir.name}] {unit} {row['n']:g}/{self.optim.total}", f"loss {losses}"]
        for split in ("train", "test"):
            if row.get(f"{split}_{self.tasks[0].name}_acc") is not None:
                parts.append(f"{split} acc/edit " + " ".join(
                    f"{t.name} {row[f'{split}_{t.name}_acc']:.1f}/"
                    f"{row[f'{split}_{t.name}_edit']:.1f}"
                    for t in self.tasks))
        parts.append(f"{row['unit_seconds']:.1f} s/{unit}  ETA "
                     f"{timedelta(seconds=round(seconds_left))}")
        return "  ".join(parts)

    def _write_summaries(self, row: dict) -> None:
        """The row's numbers as TensorBoard scalars (``config.tensorboard``)."""
        if not self.config.tensorboard:
            return
        if self._summaries is None:
            self._summaries = tf.summary.create_file_writer(str(self.run_dir / "tensorboard"))
        with self._summaries.as_default(step=row["sweep"]):
            for name, value in row.items():
                if isinstance(value, float) and name != "elapsed_seconds":
                    tf.summary.write(name.replace("_", "/", 1), tf.constant(value, tf.float32),
                                     metadata=_SCALAR_METADATA)
        self._summaries.flush()

    def _test_outputs(self) -> dict[str, list[np.ndarray]]:
        """Test-set outputs of the current model, computed once per sweep (progress line and
        evaluation point usually fall on the same sweep)."""
        sweep = int(self.sweep.numpy())
        if self._test_outputs_at is None or self._test_outputs_at[0] != sweep:
            self._test_outputs_at = (sweep, predict(self.model, self.test.inputs,
                                                    self.config.prediction))
        return self._test_outputs_at[1]

    def _scores(self, data: SequenceSet, done: int) -> dict[str, float | None]:
        """Accuracy and edit score of every task on ``data`` when this progress line is
        monitored, else None for each (an empty cell in ``history.csv``)."""
        out: dict[str, float | None] = {}
        outputs = None
        if self._monitored(done):
            outputs = (self._test_outputs() if data is self.test
                       else predict(self.model, data.inputs, self.config.prediction))
        for t in self.tasks:
            m = (task_metrics(t, outputs[t.name], data.labels[t.name]) if outputs
                 else {"accuracy": None, "edit": None})
            out[f"{t.name}_acc"], out[f"{t.name}_edit"] = m["accuracy"], m["edit"]
        return out

    def _append_history(self, row: dict) -> None:
        append_csv_row(self.run_dir / HISTORY, row, self.log_columns()[HISTORY])

    def _evaluate(self, point: int) -> None:
        """Write predictions, plots and metrics of the test set at evaluation point ``point``."""
        label = f"{self.optim.unit_name} {point}"
        metrics = write_evaluation(point_dir(self.run_dir, self.optim.unit, point), self.tasks,
                                   self.test, self._test_outputs(),
                                   {"point": point, "unit": self.optim.unit,
                                    "sweep": int(self.sweep.numpy())}, label,
                                   self.sample_hz, self._plotted(point))
        self.log(f"[{self.run_dir.name}] evaluation at {label}: "
                 f"{metrics_summary(self.tasks, metrics)}")

    def _plotted(self, point: int) -> bool:
        """Whether evaluation point ``point`` draws per-sequence figures (``config.plots``)."""
        return self.config.plots == "all" or (
            self.config.plots == "last" and point == max(self.eval_sweeps.values()))

    def finish(self) -> dict:
        """Write ``metrics.json`` (every evaluation point, their mean, the convergence
        diagnostic) and ``timing.json``, prune the checkpoints (``TrainConfig.keep_checkpoints``)
        and mark the run finished (once); returns the metrics. A metric that is NaN at every
        point (e.g. the accuracy of a class absent from the test set) is ``null``. The confusion
        matrices are summed over the points (``summed_confusion``)."""
        if self.finished():
            self.log(f"{self.run_dir}: already finished")
            return read_json(self.run_dir / "metrics.json")
        points = sorted(self.eval_sweeps.values())
        saved = {p: read_json(point_dir(self.run_dir, self.optim.unit, p) / "metrics.json")
                 for p in points}
        per_point = {p: saved[p]["metrics"] for p in points}
        mean = {task: {k: _mean([per_point[p][task][k] for p in points])
                       for k in per_point[points[0]][task]}
                for task in per_point[points[0]]}
        result = {"points": per_point, "mean": mean, "unit": self.optim.unit,
                  "convergence": history_convergence(pd.read_csv(self.run_dir / HISTORY),
                                                     [t.name for t in self.tasks],
                                                     self.optim.total)}
        confusion = summed_confusion([saved[p].get("confusion") for p in points])
        if confusion is not None:
            result["confusion"] = confusion
        write_json(self.run_dir / "metrics.json", result)
        write_json(self.run_dir / "timing.json", self.clock.report())
        self._store.finalize()
        mark_finished(self.run_dir, {
            "sweeps": self.total_sweeps, "settings_hash": self.settings_hash,
            "started": self._record.get("provenance", {}).get("started"), "finished": now(),
            "provenance": provenance(), SEGMENTS: closed(self._segments, self.total_sweeps)})
        return read_json(self.run_dir / "metrics.json")


def write_evaluation(folder: Path, tasks: Sequence[Task], data: SequenceSet,
                     outputs: dict[str, list[np.ndarray]], header: dict, label: str,
                     sample_hz: float, plots: bool = True) -> dict[str, dict[str, float]]:
    """Score ``outputs`` against ``data``'s labels and write an evaluation folder: one predictions
    CSV (``rnn_seg.predictions``: one row per scored sample, true labels beside the predicted
    ones) and plot per sequence, and ``metrics.json`` (``header``'s keys, then ``metrics`` and
    ``confusion``: per task its ``classes`` and ``counts`` ``[K, K]``, rows true, columns
    predicted, summing to the samples scored).

    Args:
        folder: where to write (``predictions/``, ``plots/``, ``metrics.json``).
        tasks: the tasks of the model's heads.
        data: the labelled sequences scored.
        outputs: raw head outputs ``[T_i, K]`` per task and sequence of ``data``.
        header: leading entries of ``metrics.json`` (e.g. the evaluation point and its unit).
        label: what is evaluated, for the plot titles (e.g. ``"epoch 120"``).
        sample_hz: the sequences' sampling rate (plot axes).
        plots: whether to draw the per-sequence plots.

    Returns:
        The metrics per task (``task_metrics``).
    """
    scores = {t.name: task_scores(t, outputs[t.name], data.labels[t.name]) for t in tasks}
    metrics = {name: scored for name, (scored, _) in scores.items()}
    confusion = {t.name: {"classes": list(t.class_names), "counts": scores[t.name][1]}
                 for t in tasks}
    for i, name in enumerate(data.names):
        true = {t.name: data.labels[t.name][i] for t in tasks}
        frames, frame_hz = data.time_base(i, sample_hz)
        table = prediction_table(tasks, {t.name: outputs[t.name][i] for t in tasks},
                                 np.arange(len(frames)), frames, frame_hz, true)
        write_atomic(folder / "predictions" / f"{name}.csv", prediction_csv(table))
        if plots:
            pred = {t.name: t.decode(outputs[t.name][i]) for t in tasks}
            plot_sequence(f"{name} - {label}", tasks, true, pred, folder / "plots" / f"{name}.png",
                          sample_hz)
    write_json(folder / "metrics.json", {**header, "metrics": metrics, "confusion": confusion})
    return metrics


def summed_confusion(points: Sequence[dict | None]) -> dict | None:
    """Per task, the ``classes`` and ``counts`` of evaluation points' confusion matrices (their
    ``metrics.json`` ``confusion``) summed over the points; None when a point has none (written
    before confusion matrices were saved)."""
    if not points or any(p is None for p in points):
        return None
    return {task: {"classes": first["classes"],
                   "counts": np.sum([p[task]["counts"] for p in points], axis=0)}
            for task, first in points[0].items()}


def metrics_summary(tasks: Sequence[Task], metrics: dict[str, dict[str, float]]) -> str:
    """One line of each task's accuracy, edit score and F1@10."""
    return ", ".join(f"{t.name} acc {metrics[t.name]['accuracy']:.1f} edit "
                     f"{metrics[t.name]['edit']:.1f} F1@10 {metrics[t.name]['f1@10']:.1f}"
                     for t in tasks)


def loss_gradients(model: SegmentationModel, tasks: Sequence[Task], per_task: bool,
                   params: ModelParams, inputs: tf.Tensor, resets: tf.Tensor,
                   targets: Sequence[tf.Tensor], dropout_seeds: tf.Tensor,
                   valid: tf.Tensor | None = None) -> tuple[tf.Tensor, list[list[tf.Tensor]]]:
    """Task losses of ``model`` run with weights ``params`` on one sweep (``model.losses``), and
    their gradients.

    A pure function of its arguments, so ``tf.vectorized_map`` can run it for several models'
    stacked weights at once (``rnn_seg.stack``).

    Args:
        model: the model whose ``apply`` runs (its own weights are not used).
        tasks: the tasks of the model's heads, in the order of ``targets``.
        per_task: differentiate each task's loss instead of the sum of the losses.
        params: the weights run and differentiated (``model.params()``'s structure).
        inputs: ``[B, T, F]`` float32 inputs of the sweep.
        resets: ``[B, T]`` bool, True where the state restarts before the step.
        targets: one ``[B, T, K_task]`` float32 array per task (``Task.encode``).
        dropout_seeds: ``[dropout_calls, 2]`` int64 stateless seeds of the sweep's masks.
        valid: ``[B, T]`` bool marking the steps of a sweep padded at the end (None = all
            valid): padding counts in no loss and never reaches a valid step.

    Returns:
        ``(losses, gradients)``: the task losses ``[n_tasks]`` float32 and one gradient list with
        respect to ``tf.nest.flatten(params)`` for the sum of the losses, or with ``per_task``
        one per task.
    """
    flat = tf.nest.flatten(params)
    with tf.GradientTape(persistent=per_task, watch_accessed_variables=False) as tape:
        tape.watch(flat)
        losses = model.losses(params, tasks, inputs, resets, targets, dropout_seeds, valid)
        objectives = tf.unstack(losses) if per_task else [tf.reduce_sum(losses)]
    return losses, [tape.gradient(y, flat, unconnected_gradients="zero") for y in objectives]


def _mean(values: Sequence[float | None]) -> float:
    """Mean of metric values read from JSON (``None`` = NaN)."""
    return float(np.mean([np.nan if v is None else v for v in values]))

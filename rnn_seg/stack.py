"""Several independent models trained together: one vectorised TensorFlow step for all of them.

A ``TrainerStack`` drives ordinary ``Trainer`` members (each with its own run directory, data,
seed, dropout stream, checkpoints, logs and evaluation points) sweep by sweep, and replaces only
their training step: the members' weights are stacked and ``tf.vectorized_map`` runs
``loss_gradients`` for all of them at once, so every recurrent step is one batched product for
all members instead of one small product each. Each member then applies its own update
(clipping, momentum, GradNorm) to its own variables.

Members' sweeps have different durations; each is padded at the end to the longest one, the
padded steps masked out of the losses and the reverse LSTM direction restarted at each row's last
valid step. Dropout seeds come from each member's own generator, and masks are drawn in forward
time order, so the valid steps get the very masks a lone run draws: a member trains as it would
alone, up to float rounding (tests/test_stack.py). A member's run directory is
indistinguishable from a lone run's: either way can resume it. Members interrupted at different
checkpoints each resume from their own; the ones behind train until they catch up with the others,
then join their step.
"""
from __future__ import annotations

import logging
import time
from contextlib import ExitStack
from functools import partial
from typing import Sequence

import numpy as np
import tensorflow as tf

from .runs.lock import hold_folder
from .trainer import Trainer, loss_gradients


class _NoFallbackWarnings(logging.Filter):
    """``vectorized_map`` warns that it loops over members for the stateless random ops of
    dropout (no vectorised kernel): one small op per member and layer, expected here."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "Using a while_loop for converting StatelessRandom" not in record.getMessage()


tf.get_logger().addFilter(_NoFallbackWarnings())


class TrainerStack:
    """Train ``trainers`` (same model shapes, tasks, trainer class and number of sweeps)
    together; two or more must run the ``graph`` loops (``EncoderConfig(loops="graph")``, not the
    default ``auto``, where the fused loops build): ``tf.vectorized_map`` maps TensorFlow ops, and
    would run compiled loops member by member."""

    def __init__(self, trainers: Sequence[Trainer]):
        self.trainers = list(trainers)
        self.compiled_steps: dict[tuple[int, ...], object] = {}   # vectorised step per member set
        if not self.trainers:
            raise ValueError("a stack needs at least one trainer")
        folders = [t.run_dir.resolve() for t in self.trainers]
        if len(set(folders)) < len(folders):
            raise ValueError(f"cannot stack runs sharing a folder: {[str(f) for f in folders]}")
        for t in self.trainers if len(self.trainers) > 1 else ():   # one alone: its own step
            loops = getattr(t.model.encoder.config, "loops", "graph")   # a TCN's are TF ops
            if loops != "graph":
                raise ValueError(f"cannot stack {t.run_dir}: its LSTM runs the {loops} loops, "
                                 "which a vectorised step would run member by member: build "
                                 "its model with loops 'graph' (what 'auto' is in a stacked grid)")
        first = self.trainers[0]
        for t in self.trainers[1:]:
            _require_same(first, t, "trainer class", lambda x: type(x).__name__)
            _require_same(first, t, "tasks", lambda x: [task.name for task in x.tasks])
            _require_same(first, t, "number of sweeps", lambda x: x.total_sweeps)
            _require_same(first, t, "batch size", lambda x: x.config.batch_size)
            _require_same(first, t, "weight shapes", lambda x: [v.shape.as_list()
                                                                for v in x.variables])

    def run(self, restart: bool = False) -> list[dict]:
        """Train every unfinished member to the end, each resuming from its newest checkpoint,
        and return each member's metrics, in order. Holds every member's folder lock; checks
        (or with ``restart`` clears) every folder before any work, as ``Trainer.run`` does.
        Members that resume behind the others train alone (or stacked among themselves) until
        the others' sweep, then all together."""
        with ExitStack() as locks:
            for t in self.trainers:
                locks.enter_context(hold_folder(t.run_dir))
            for t in self.trainers:
                t.prepare(restart)
            active = [t for t in self.trainers if not t.finished()]
            starts = [t.resume() for t in active]
            for t in active:
                with t.clock.phase("trace"):
                    t.model.infer.get_concrete_function()
            total = self.trainers[0].total_sweeps
            for sweep in range(min(starts, default=total), total):
                members = tuple(k for k, start in enumerate(starts) if start <= sweep)
                lrs = [active[k].optim.learning_rate_at(sweep, active[k].sweeps_per_epoch)
                       for k in members]
                began = time.perf_counter()
                if len(members) == 1:         # the plain step is faster than a stack of one
                    outs = [active[members[0]].step(sweep, lrs[0])]
                else:
                    if members not in self.compiled_steps:
                        self.compiled_steps[members] = _compiled_step([active[k] for k in members])
                        began = time.perf_counter()
                    outs = [out.numpy() for out in self.compiled_steps[members](
                        *padded_batches([active[k].batch(sweep) for k in members]),
                        tf.constant(lrs, tf.float32))]
                shared = (time.perf_counter() - began) / len(members)
                for k, lr, out in zip(members, lrs, outs):
                    active[k].clock.add("train", shared)
                    active[k].after_sweep(sweep, lr, out)
            return [t.finish() for t in self.trainers]


def train_together(trainers: Sequence[Trainer]) -> list[dict]:
    """Run ``trainers`` as stacks of those with equal numbers of sweeps (folds with different
    numbers of training trials can differ); returns each one's metrics, in order."""
    by_sweeps: dict[int, list[int]] = {}
    for i, t in enumerate(trainers):
        by_sweeps.setdefault(t.total_sweeps, []).append(i)
    results: dict[int, dict] = {}
    for members in by_sweeps.values():
        results.update(zip(members, TrainerStack([trainers[i] for i in members]).run()))
    return [results[i] for i in range(len(trainers))]


def _compiled_step(members: list[Trainer]):
    """The members' vectorised training step, traced once for sweeps of any duration; the
    tracing time is shared among the members' clocks."""
    template = members[0]
    features = template.train.inputs[0].shape[1]
    m, b = len(members), template.config.batch_size
    signature = [tf.TensorSpec([m, b, None, features], tf.float32),
                 tf.TensorSpec([m, b, None], tf.bool),
                 tuple(tf.TensorSpec([m, b, None, t.num_outputs], tf.float32)
                       for t in template.tasks),
                 tf.TensorSpec([m, b, None], tf.bool),
                 tf.TensorSpec([m], tf.float32)]
    began = time.perf_counter()
    step = tf.function(partial(_vector_step, members), input_signature=signature,
                       autograph=False)                                 # as model.infer
    step.get_concrete_function()
    for t in members:
        t.clock.add("trace", (time.perf_counter() - began) / m)
    return step


def _require_same(a: Trainer, b: Trainer, what: str, key) -> None:
    if key(a) != key(b):
        raise ValueError(f"cannot stack {a.run_dir} and {b.run_dir}: different {what} "
                         f"({key(a)} vs {key(b)})")


def padded_batches(batches: Sequence[tuple]) -> tuple:
    """Members' sweeps ``(inputs [B, T_k, F], resets [B, T_k], targets ([B, T_k, K_task], ...),
    valid [B, T_k] or None)`` (``Trainer.batch``) -> ``(inputs [M, B, T, F], resets [M, B, T],
    targets (...), valid [M, B, T])`` tensors, every sweep zero-padded at the end to the longest
    duration ``T``."""
    duration = max(batch[0].shape[1] for batch in batches)

    def pad(arrays):
        return tf.constant(np.stack([np.pad(a, [(0, 0), (0, duration - a.shape[1])]
                                            + [(0, 0)] * (a.ndim - 2)) for a in arrays]))

    inputs, resets, targets, valid = zip(*batches)
    valid = [np.ones(r.shape, bool) if v is None else v for r, v in zip(resets, valid)]
    return pad(inputs), pad(resets), tuple(pad(y) for y in zip(*targets)), pad(valid)


def _vector_step(members: list[Trainer], inputs, resets, targets, valid, learning_rates):
    """One training sweep of every member; returns each member's ``update`` result."""
    template = members[0]
    params = tf.nest.map_structure(lambda *v: tf.stack(v), *[t.model.params() for t in members])
    seeds = tf.stack([t.dropout_seeds() for t in members])                # [M, calls, 2]

    def member(args):
        p, x, r, y, s, v = args
        return loss_gradients(template.model, template.tasks, template.per_task_gradients,
                              p, x, r, y, s, v)

    losses, grads = tf.vectorized_map(member, (params, inputs, resets, targets, seeds, valid),
                                      fallback_to_while_loop=True)
    return [t.update(losses[k], [[g[k] for g in objective] for objective in grads],
                     learning_rates[k])
            for k, t in enumerate(members)]

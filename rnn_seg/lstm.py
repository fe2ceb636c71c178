"""LSTM layers with DiPietro et al.'s cell: forget gate, peepholes, zero initial state, resets.

Cell, for each time step t (``*`` elementwise, ``sigma`` the logistic function)::

    g = tanh(x W_gx + h_{t-1} W_gh + b_g)
    i = sigma(x W_ix + h_{t-1} W_ih + w_ic * c_{t-1} + b_i)
    f = sigma(x W_fx + h_{t-1} W_fh + w_fc * c_{t-1} + b_f)
    c_t = g * i + c_{t-1} * f
    o = sigma(x W_ox + h_{t-1} W_oh + w_oc * c_t + b_o)
    h_t = o * tanh(c_t)

Where the reset flag of step t is set, ``(c_{t-1}, h_{t-1})`` is replaced by the zero initial state
before the step. The four gate matrices are stored fused, in gate order (g, i, f, o): ``W_x``
``[F, 4H]``, ``W_h`` ``[H, 4H]``, ``b`` ``[4H]``; peepholes ``w_ic, w_fc, w_oc`` ``[H]`` each. All
weights
start uniform in ``[-init_scale, init_scale]``, biases at zero, as in the original code.

Shapes: batch-major ``[B, T, ...]`` at the API, time-major inside the scan. A forward-only encoder
also runs one step at a time with its state carried between calls (``RecurrentEncoder.step``).

Precision: ``fp32`` computes everything in float32. ``bf16`` runs the layer's matrix products
(input product ``x W_x``, recurrent ``h W_h`` forward, ``dz W_h^T`` backward, and the weight
gradients ``dW_x``, ``dW_h``) on bfloat16 operands; oneDNN accumulates each product in float32
and rounds its result to bfloat16, which is widened to float32 at once. Weights, cell state,
nonlinearities, peepholes, losses, clipping and updates stay float32. It needs a CPU with native
bfloat16 arithmetic (AVX512_BF16 or AMX; ``require_native_precision``).

Loops: ``graph`` runs the forward and backward loops over time as TensorFlow ops, step by step.
``xla`` compiles each loop (with the backward pass's per-step factors) into one XLA kernel: the
same equations, so results agree with ``graph`` to float32 rounding (tested), while a step no
longer pays TensorFlow's per-op dispatch, which is most of a step's cost in a small model
(docs/PERFORMANCE.md). XLA compiles a kernel per input shape, so a sequence's steps are padded
to a bucket (two per octave) and the loop stops at the last real step; each bucket compiles once
per process. ``fused`` runs each loop as one C++ op (``rnn_seg.kernels``: weights laid out once per
call, gates and peepholes fused with each step's product), built on first use; where it cannot be
built or loaded, the encoder says why in one line and runs the ``graph`` loops. ``auto`` (the
default) is ``fused`` where they build and load, else ``graph``, after the same line; the loops a
run ran are in its provenance (``config.json``).
"""
from __future__ import annotations

import functools
import sys
from dataclasses import replace
from typing import Callable, NamedTuple

import tensorflow as tf

from .config import (LOOPS, PRECISIONS, RESET_MODES, RUNNABLE_LOOPS,  # noqa: F401 (re-exported)
                     EncoderConfig, Loops, Precision, ResetMode, cpu_flags, native_bf16,
                     require_native_precision)
from .kernels import build as fused_build
from .kernels import loops as fused_loops

_DTYPES = {"fp32": tf.float32, "bf16": tf.bfloat16}


class LayerParams(NamedTuple):
    """Weights of one LSTM layer in one direction, as variables or (stacked) tensors."""

    W_x: tf.Tensor      # [F, 4H]
    W_h: tf.Tensor      # [H, 4H]
    peep: tf.Tensor     # [3, H], rows w_ic, w_fc, w_oc
    b: tf.Tensor        # [4H]


class LSTMCellWeights(tf.Module):
    """Trainable weights of one LSTM layer in one direction."""

    def __init__(self, input_size: int, hidden: int, init_scale: float, rng: tf.random.Generator,
                 name: str):
        super().__init__(name=name)

        def uniform(shape, var_name):
            return tf.Variable(rng.uniform(shape, -init_scale, init_scale), name=var_name)

        self.W_x = uniform([input_size, 4 * hidden], "W_x")
        self.W_h = uniform([hidden, 4 * hidden], "W_h")
        self.peep = uniform([3, hidden], "peepholes")   # rows: w_ic, w_fc, w_oc
        self.b = tf.Variable(tf.zeros([4 * hidden]), name="b")

    def params(self) -> LayerParams:
        return LayerParams(self.W_x, self.W_h, self.peep, self.b)


def product(a: tf.Tensor, b: tf.Tensor, dtype: tf.DType = tf.float32, **matmul) -> tf.Tensor:
    """``a @ b`` (``tf.matmul`` options) with both operands in ``dtype``; a float32 result.

    Args:
        a: left operand, e.g. ``[B, H]`` hidden state or ``[B, 4H]`` gate gradients, float32.
        b: right operand, e.g. ``[H, 4H]`` recurrent weights or their ``[4H, H]`` transpose,
            float32 or already in ``dtype``.
        dtype: the operands' dtype in the product: float32, or bfloat16 for ``bf16`` precision
            (module docstring).
        **matmul: ``tf.matmul`` options, e.g. ``transpose_a=True``.

    Returns:
        The product, float32.
    """
    return tf.cast(tf.matmul(tf.cast(a, dtype), tf.cast(b, dtype), **matmul), tf.float32)


class RecurrentProducts(NamedTuple):
    """One layer's two per-step products with its recurrent weights, in the products' dtype and
    the operand layout oneDNN runs fastest for that dtype at a batch of 5 rows (measured with
    ``bench/product_layouts.py``, docs/PERFORMANCE.md): float32 ``h W`` and ``dz W^T`` with
    ``W^T`` stored; bfloat16 ``dz W^T`` read through ``transpose_b`` and, forward,
    ``(W^T h^T)^T`` on a CPU with AMX tiles, ``h (W^T)^T`` through ``transpose_b`` on one with
    AVX512_BF16 alone (each 2-3x faster than the other layout on the other CPU)."""

    forward: Callable[[tf.Tensor], tf.Tensor]      # h [B, H] -> h W_h [B, 4H] float32
    backward: Callable[[tf.Tensor], tf.Tensor]     # dz [B, 4H] -> dz W_h^T [B, H] float32


def recurrent_products(W_h: tf.Tensor, dtype: tf.DType = tf.float32) -> RecurrentProducts:
    """The per-step products with ``W_h`` ``[H, 4H]``, its copies cast and transposed once."""
    W = tf.cast(W_h, dtype)
    W_t = tf.transpose(W)                                                        # [4H, H]
    if dtype == tf.float32:
        return RecurrentProducts(lambda h: tf.matmul(h, W), lambda dz: tf.matmul(dz, W_t))

    def forward_tiles(h):
        return tf.transpose(tf.matmul(W_t, tf.cast(h, dtype), transpose_b=True))

    def forward_rows(h):
        return tf.matmul(tf.cast(h, dtype), W_t, transpose_b=True)

    forward = forward_tiles if "amx_bf16" in cpu_flags() else forward_rows
    return RecurrentProducts(
        lambda h: tf.cast(forward(h), tf.float32),
        lambda dz: tf.cast(tf.matmul(tf.cast(dz, dtype), W, transpose_b=True), tf.float32))


def lstm_scan(x_proj: tf.Tensor, resets: tf.Tensor, W_h: tf.Variable, peep: tf.Variable,
              precision: Precision = "fp32", loops: Loops = "graph") -> tf.Tensor:
    """Run the cell over time, with a hand-written backward pass through time.

    Args:
        x_proj: ``[T, B, 4H]`` time-major ``x W_x + b`` for every step (one product for all steps).
        resets: ``[T, B, 1]`` float32, 1.0 where the state restarts before the step.
        W_h: ``[H, 4H]`` recurrent weights.
        peep: ``[3, H]`` peepholes (rows w_ic, w_fc, w_oc).
        precision: of the recurrent products and ``dW_h`` (module docstring).
        loops: how the loops over time run (module docstring; ``auto``: ``runnable``'s).

    Returns:
        ``[T, B, H]`` hidden outputs h_t.
    """
    return _BPTT[precision, runnable(loops, precision)](
        x_proj, 1.0 - resets, tf.convert_to_tensor(W_h), tf.convert_to_tensor(peep))


def _bptt_in(dtype: tf.DType, loops: Loops):
    """``lstm_scan`` on plain tensors (``keep = 1 - resets``) with products in ``dtype``.

    The forward loop keeps every step's gate activations. Before the backward loop, every factor
    of the chain rule that does not depend on the incoming gradient is computed for all steps at
    once, so each backward step is one product ``dz W_h^T`` and a few multiply-adds; ``dW_h`` and
    the peephole gradients are then single reductions over all steps. Reference and test of this
    hand-written gradient: ``tests/lstm_reference.py`` (a NumPy cell and a step-by-step
    TensorFlow cell differentiated by autodiff) and ``tests/test_lstm.py``.
    """
    forward_loop, backward_loop = _LOOP_FUNCTIONS[loops]

    @tf.custom_gradient
    def bptt(x_proj, keep, W_h, peep):
        """``lstm_scan`` and its gradient; arguments as ``lstm_scan``'s, ``keep = 1 - resets``."""
        steps = tf.shape(x_proj)[0]
        pad = _padding(steps) if loops == "xla" else (lambda x: x)
        # the loops are differentiated by hand (grad), so no tape records them: an XLA kernel
        # cannot hand its loop's intermediate lists to one
        x_proj, keep, W_h, peep = (tf.stop_gradient(v) for v in (x_proj, keep, W_h, peep))
        W = tf.cast(W_h, dtype)                          # once per call, not per loop
        keep_in = pad(keep)
        state = forward_loop(pad(x_proj), keep_in, W, peep, steps)
        h, c = state[0][:steps], state[1][:steps]                 # [T, B, H]

        def grad(dh_out):
            hidden = tf.shape(W_h)[0]
            h_prev, c_prev = keep * _shift(h), keep * _shift(c)      # state entering each step
            dz = backward_loop(pad(dh_out), keep_in, state, pad(c_prev), W, peep,
                               steps)[:steps]                                 # [T, B, 4H]
            dW_h = _weight_gradient(tf.reshape(h_prev, [-1, hidden]),
                                    tf.reshape(dz, [-1, 4 * hidden]), dtype, loops)
            _, dz_i, dz_f, dz_o = tf.split(dz, 4, axis=2)
            dpeep = tf.stack([tf.reduce_sum(dz_i * c_prev, [0, 1]),
                              tf.reduce_sum(dz_f * c_prev, [0, 1]),
                              tf.reduce_sum(dz_o * c, [0, 1])])
            return dz, None, dW_h, dpeep

        return h, grad
    return bptt


def _weight_gradient(h_prev: tf.Tensor, dz: tf.Tensor, dtype: tf.DType, loops: Loops
                     ) -> tf.Tensor:
    """``dW_h = h_prev^T dz``: ``h_prev`` ``[N, H]`` (the state entering each of N = T B steps
    and rows), ``dz`` ``[N, 4H]`` -> ``[H, 4H]`` float32; by the fused loops' own product where
    they run it (``fused_weight_gradient``), else by ``product`` in ``dtype``."""
    if loops == "fused" and dtype == tf.float32 and fused_weight_gradient():
        return fused_loops.weight_gradient(h_prev, dz)
    return product(h_prev, dz, dtype, transpose_a=True)


@functools.lru_cache(maxsize=None)
def fused_weight_gradient() -> bool:
    """Whether the (loaded) fused loops sum ``dW_h`` (float32) with their own product
    (``rnn_seg.kernels``): yes where it is a vector product (``FAST_PRODUCTS``) and TensorFlow's
    oneDNN operations are off (its default on processors without AVX-512 VNNI or newer, and with
    ``TF_ENABLE_ONEDNN_OPTS=0``), for TensorFlow's matmul then runs Eigen's contraction, at 0.45x
    that product's rate on the AVX2 EPYC; else TensorFlow's matmul sums it (docs/PERFORMANCE.md,
    "On an AVX2 EPYC whose cores have L3 slices of their own")."""
    if _fused_slower():
        return False
    try:
        from tensorflow.python.util import _pywrap_util_port
    except ImportError:                 # a TensorFlow that no longer says: keep its matmul
        return False
    return not _pywrap_util_port.IsMklEnabled()


def _forward_loop(x_proj, keep, W, peep, steps, bounded=False):
    """``_forward`` with the products of ``W`` (``W_h`` in the products' dtype):
    ``(h, c, g, i, f, o)`` ``[size, B, H]`` for inputs padded to ``size`` >= ``steps`` time steps
    (zeros after ``steps``); ``bounded``: as ``_forward``'s."""
    return _forward(x_proj, keep, recurrent_products(W, W.dtype).forward, peep, steps, bounded)


def _backward_loop(dh_out, keep, state, c_prev, W, peep, steps, bounded=False):
    """``dz`` ``[size, B, 4H]`` (zeros after ``steps``): the backward factors of the forward
    loop's ``state`` (``c_prev``: the cell state entering each step) and ``_backward``, with the
    products of ``W`` (``W_h`` in the products' dtype); ``bounded``: as ``_backward``'s."""
    factors = _backward_factors(state, c_prev, keep, peep)
    return _backward(dh_out, keep, factors, recurrent_products(W, W.dtype).backward, steps,
                     bounded)


_LOOP_FUNCTIONS = {
    "graph": (_forward_loop, _backward_loop),
    "xla": (tf.function(functools.partial(_forward_loop, bounded=True), jit_compile=True),
            tf.function(functools.partial(_backward_loop, bounded=True), jit_compile=True)),
    "fused": (fused_loops.forward_loop, fused_loops.backward_loop)}
_BPTT = {(precision, loops): _bptt_in(dtype, loops)
         for precision, dtype in _DTYPES.items() for loops in RUNNABLE_LOOPS}


def _padding(steps: tf.Tensor) -> Callable[[tf.Tensor], tf.Tensor]:
    """Time-major ``[steps, ...]`` -> zeros appended up to the steps XLA's loops are compiled
    for: ``steps`` rounded up to a multiple of half its power of two (at least 16), e.g.
    600 -> 768, 900 -> 1024, 1100 -> 1536; two sizes per octave, so a run compiles few kernels
    and pads at most a third."""
    octave = tf.math.floor(tf.experimental.numpy.log2(tf.cast(steps, tf.float64)) + 1e-9)
    quantum = tf.cast(tf.pow(tf.constant(2.0, tf.float64), tf.maximum(octave - 1.0, 4.0)),
                      tf.int32)
    size = (steps + quantum - 1) // quantum * quantum

    def to_bucket(x: tf.Tensor) -> tf.Tensor:     # not "pad": AutoGraph names it tf__<name>
        return tf.pad(x, tf.concat([[[0, size - steps]], tf.zeros([x.shape.rank - 1, 2], tf.int32)],
                                   axis=0))
    return to_bucket


def _shift(x: tf.Tensor) -> tf.Tensor:
    """``[T, ...]`` -> the previous step's value at each step, zeros at the first."""
    return tf.concat([tf.zeros_like(x[:1]), x[:-1]], axis=0)


def lstm_cell(z_x: tf.Tensor, c_prev: tf.Tensor, h_prev: tf.Tensor,
              recurrent: Callable[[tf.Tensor], tf.Tensor],
              peepholes: tuple[tf.Tensor, tf.Tensor, tf.Tensor]) -> tuple[tf.Tensor, ...]:
    """One step of the cell (the module docstring's equations) for a batch.

    Args:
        z_x: ``[B, 4H]`` the input's share of the gate inputs, ``x W_x + b``.
        c_prev: ``[B, H]`` cell state entering the step (after any reset).
        h_prev: ``[B, H]`` hidden state entering the step (after any reset).
        recurrent: the product ``h W_h`` of a state ``[B, H]``, float32 ``[B, 4H]``
            (``RecurrentProducts.forward``).
        peepholes: ``(w_ic, w_fc, w_oc)``, ``[H]`` each.

    Returns:
        ``(c, h, g, i, f, o)``, each ``[B, H]``.
    """
    w_ic, w_fc, w_oc = peepholes
    z = z_x + recurrent(h_prev)
    z_g, z_i, z_f, z_o = tf.split(z, 4, axis=1)
    g = tf.tanh(z_g)
    i = tf.sigmoid(z_i + w_ic * c_prev)
    f = tf.sigmoid(z_f + w_fc * c_prev)
    c = g * i + c_prev * f
    o = tf.sigmoid(z_o + w_oc * c)
    h = o * tf.tanh(c)
    return c, h, g, i, f, o


def _forward(x_proj, keep, recurrent, peep, steps, bounded=False):
    """The cell over the first ``steps`` of ``x_proj`` ``[T, B, 4H]``; returns
    ``(h, c, g, i, f, o)``, each ``[T, B, H]`` float32, zeros after ``steps``.
    ``recurrent`` is the step's product ``h W_h`` (``RecurrentProducts.forward``); ``bounded``
    gives the loop its ``T`` as a maximum, which XLA needs (and the op loops need not pay)."""
    hidden = tf.shape(peep)[1]
    peepholes = (peep[0], peep[1], peep[2])

    def body(t, c_prev, h_prev, records):
        """Step ``t`` (``lstm_cell``, state ``[B, H]``); records ``(h, c, g, i, f, o)``."""
        k = keep[t]
        c, h, g, i, f, o = lstm_cell(x_proj[t], c_prev * k, h_prev * k, recurrent, peepholes)
        return t + 1, c, h, [r.write(t, v) for r, v in zip(records, (h, c, g, i, f, o))]

    zeros = tf.zeros(tf.stack([tf.shape(x_proj)[1], hidden]))
    records = [tf.TensorArray(tf.float32, size=tf.shape(x_proj)[0]) for _ in range(6)]
    *_, records = tf.while_loop(lambda t, *_: t < steps, body, (0, zeros, zeros, records),
                                parallel_iterations=1,
                                maximum_iterations=tf.shape(x_proj)[0] if bounded else None)
    return [r.stack() for r in records]


def _backward_factors(state, c_prev, keep, peep):
    """Per-step factors of the chain rule that do not depend on the incoming gradient;
    ``c_prev`` ``[T, B, H]`` is the cell state entering each step (after its reset).

    Returns ``(out_c, gates_dc, gates_dh, to_prev)``: ``dc = dc_next + dh * out_c``;
    ``dz = dc * gates_dc + dh * gates_dh`` (``[T, B, 4, H]``, gate order g, i, f, o);
    ``dc_{t-1} = dc * to_prev`` (``to_prev`` includes the reset).
    """
    _, c, g, i, f, o = state
    w_ic, w_fc, w_oc = peep[0], peep[1], peep[2]
    tc = tf.tanh(c)
    d_i, d_f = i * (1.0 - i), f * (1.0 - f)                          # sigmoid derivatives
    out_o = tc * o * (1.0 - o)                                       # dz_o / dh
    out_c = o * (1.0 - tc * tc) + out_o * w_oc                       # dc / dh, same step
    zeros = tf.zeros_like(c)
    gates_dc = tf.stack([i * (1.0 - g * g), g * d_i, c_prev * d_f, zeros], axis=2)
    gates_dh = tf.stack([zeros, zeros, zeros, out_o], axis=2)
    to_prev = keep * (f + g * d_i * w_ic + c_prev * d_f * w_fc)
    return out_c, gates_dc, gates_dh, to_prev


def _backward(dh_out, keep, factors, recurrent, steps, bounded=False):
    """Reverse loop over the first ``steps`` of ``[T, ...]`` inputs; returns ``dz``
    ``[T, B, 4H]``, the gradient of the gate inputs (zeros after ``steps``).

    ``dh_out`` ``[T, B, H]`` is the gradient arriving at the outputs; the state passed back one
    step is ``dc * to_prev`` and ``keep * dz W_h^T`` (``recurrent``: the product ``dz W_h^T``,
    ``RecurrentProducts.backward``); ``bounded`` as ``_forward``'s.
    """
    batch = tf.shape(dh_out)[1]
    out_c, gates_dc, gates_dh, to_prev = factors

    def body(t, dh_next, dc_next, records):
        """Step ``t`` back; ``dh_next``, ``dc_next`` ``[B, H]`` reach h_t, c_t from step t + 1."""
        dh = dh_out[t] + dh_next
        dc = dc_next + dh * out_c[t]
        dz = tf.reshape(dc[:, None] * gates_dc[t] + dh[:, None] * gates_dh[t], [batch, -1])
        return t - 1, keep[t] * recurrent(dz), dc * to_prev[t], records.write(t, dz)

    zeros = tf.zeros_like(dh_out[0])
    records = tf.TensorArray(tf.float32, size=tf.shape(dh_out)[0])
    *_, records = tf.while_loop(lambda t, *_: t >= 0, body, (steps - 1, zeros, zeros, records),
                                parallel_iterations=1,
                                maximum_iterations=tf.shape(dh_out)[0] if bounded else None)
    return records.stack()


def reverse_resets(resets: tf.Tensor, mode: ResetMode) -> tf.Tensor:
    """Reset flags for the reverse direction, in forward time order, ``[B, T]``.

    ``original`` reproduces DiPietro's code: the flags are reversed together with the inputs, so in
    reverse time the state restarts before each sequence's *first* frame (and carries over from the
    following wrapped copy into a sequence's last frame). ``corrected`` restarts the reverse state
    before each sequence's *last* frame: the flag of step t is the forward flag of step t + 1.
    """
    if mode == "original":
        return resets
    ones = tf.ones_like(resets[:, :1])
    return tf.concat([resets[:, 1:], ones], axis=1)


EncoderParams = dict[str, list[LayerParams]]     # direction ("fw", "rv") -> one entry per layer


class RecurrentEncoder(tf.Module):
    """Stacked (bi)directional LSTM: ``[B, T, F]`` -> ``[B, T, H]`` or ``[B, T, 2H]`` (fw, rv)."""

    def __init__(self, input_size: int, config: EncoderConfig, rng: tf.random.Generator):
        super().__init__(name="encoder")
        self.asked_loops = config.loops          # before ``auto`` (or a fallback) is resolved
        self.config = config = runnable_loops(config)
        self.loops_why = loops_reason(self.asked_loops, config.loops, config.precision)
        self.cells = {
            d: [LSTMCellWeights(input_size if layer == 0 else config.hidden, config.hidden,
                                config.init_scale, rng, name=f"{d}_layer{layer}")
                for layer in range(config.layers)]
            for d in self.directions}

    @property
    def directions(self) -> tuple[str, ...]:
        return ("fw", "rv") if self.config.bidirectional else ("fw",)

    def resume_on(self, started: str) -> None:
        """Run ``started``, the loops this encoder's run started on (its config.json's
        provenance), where it was asked for ``auto``: a run resumed with the default keeps its
        path (``runnable``'s fallback aside), so its provenance, ``load_run`` and the execution
        comparisons read what trained it. Explicit loops are kept: a run may resume on any.
        Call before the first trace."""
        if self.asked_loops == "auto" and started in RUNNABLE_LOOPS \
                and started != self.config.loops:
            self.config = runnable_loops(replace(self.config, loops=started))
            self.loops_why = (f"auto: the loops the run started on ({started})"
                              if self.config.loops == started else
                              loops_reason(started, self.config.loops, self.config.precision))

    @property
    def dropout_calls(self) -> int:
        """Dropout masks drawn per call: each direction's input and every layer's output."""
        return len(self.directions) * (self.config.layers + 1)

    def params(self) -> EncoderParams:
        return {d: [cell.params() for cell in cells] for d, cells in self.cells.items()}

    def __call__(self, inputs: tf.Tensor, resets: tf.Tensor, dropout_seeds: tf.Tensor | None
                 ) -> tf.Tensor:
        return self.apply(self.params(), inputs, resets, dropout_seeds)

    def initial_state(self, batch: int = 1) -> tf.Tensor:
        """The zero state ``[layers, 2, batch, H]`` (per layer ``c``, ``h``) before a first step."""
        return tf.zeros([self.config.layers, 2, batch, self.config.hidden])

    def step(self, params: EncoderParams, x: tf.Tensor, state: tf.Tensor
             ) -> tuple[tf.Tensor, tf.Tensor]:
        """One time step of a forward-only encoder, without dropout, for online use. Stepping
        through a sequence gives ``apply``'s outputs for it (a sequence starting with a reset).

        Args:
            params: the encoder's weights (``params()``).
            x: ``[B, F]`` inputs of this step.
            state: ``[layers, 2, B, H]`` state after the previous step (``initial_state`` before
                a sequence's first).

        Returns:
            ``(features [B, H], state after the step)``.
        """
        if "rv" in params:
            raise ValueError("only a forward (online) encoder runs one step at a time; a "
                             "bidirectional one needs the whole sequence")
        states = []
        for layer, p in enumerate(params["fw"]):
            c, h, *_ = lstm_cell(tf.matmul(x, p.W_x) + p.b, state[layer, 0], state[layer, 1],
                                 recurrent_products(p.W_h).forward,
                                 (p.peep[0], p.peep[1], p.peep[2]))
            states.append(tf.stack([c, h]))
            x = h
        return x, tf.stack(states)

    def apply(self, params: EncoderParams, inputs: tf.Tensor, resets: tf.Tensor,
              dropout_seeds: tf.Tensor | None, valid: tf.Tensor | None = None) -> tf.Tensor:
        """The encoder with weights ``params`` (this encoder's own, or any of the same shapes).

        Args:
            params: one ``LayerParams`` per layer and direction (``params()``'s structure).
            inputs: ``[B, T, F]`` float32.
            resets: ``[B, T]`` bool, True where the state restarts before the step.
            dropout_seeds: ``[dropout_calls, 2]`` int64 stateless seeds, used in the order fw
                input, rv input, then per layer fw and rv output; None = no dropout.
            valid: ``[B, T]`` bool marking the steps of a sweep padded at the end (None = all
                valid): the reverse state then starts afresh at each row's last valid step, so
                padding never reaches a valid step.

        Returns:
            ``[B, T, H]`` or, bidirectional, ``[B, T, 2H]`` (forward features first).

        Every direction keeps its own stack (layer l+1 of a direction reads layer l of the same
        direction) and draws its own dropout masks, as in the original; between layers every
        tensor is in forward time, and each direction flips it into its own time order and back.
        The directions' loops are independent, so TensorFlow's inter-op threads can run them
        side by side.
        """
        flags = self._reset_flags(resets, valid, directions=tuple(params))
        seeds = iter(range(self.dropout_calls))

        def drop(v):
            """Dropout on forward-time ``v``: a sweep padded at the end keeps every valid step's
            mask."""
            seed = None if dropout_seeds is None else dropout_seeds[next(seeds)]
            return dropout(v, self.config.keep_prob, seed)

        x = tf.transpose(inputs, [1, 0, 2])                                      # [T, B, F]
        layer_inputs = {d: drop(x) for d in params}
        for layer in range(self.config.layers):
            layer_outputs = {}
            for d, layer_input in layer_inputs.items():
                in_own_time = _flip(d, layer_input)
                hidden = self._layer(params[d][layer], in_own_time, flags[d])   # [T, B, H]
                layer_outputs[d] = drop(_flip(d, hidden))
            layer_inputs = layer_outputs
        features = tf.concat(list(layer_inputs.values()), axis=2)           # [T, B, H or 2H]
        return tf.transpose(features, [1, 0, 2])

    def _reset_flags(self, resets: tf.Tensor, valid: tf.Tensor | None,
                     directions: tuple[str, ...]) -> dict[str, tf.Tensor]:
        """Each direction's reset flags in its own time order, ``[T, B, 1]`` float32."""
        flags = {"fw": resets}
        if "rv" in directions:
            rv = reverse_resets(resets, self.config.reset_mode)
            if valid is not None:
                rv = rv | (valid & ~tf.concat([valid[:, 1:], tf.zeros_like(valid[:, :1])], 1))
            flags["rv"] = tf.reverse(rv, [1])
        return {d: tf.transpose(tf.cast(f, tf.float32))[:, :, None] for d, f in flags.items()}

    def _layer(self, params: LayerParams, x: tf.Tensor, resets: tf.Tensor) -> tf.Tensor:
        """``[T, B, F]`` -> ``[T, B, H]``; the input product for all steps at once."""
        dtype = _DTYPES[self.config.precision]
        x_proj = tf.cast(tf.tensordot(tf.cast(x, dtype), tf.cast(params.W_x, dtype), 1),
                         tf.float32) + params.b
        return lstm_scan(x_proj, resets, params.W_h, params.peep, self.config.precision,
                         self.config.loops)


def runnable_loops(config: EncoderConfig) -> EncoderConfig:
    """``config`` with the loops this process runs (``runnable``)."""
    loops = runnable(config.loops, config.precision)
    return config if loops == config.loops else replace(config, loops=loops)


def runnable(loops: Loops, precision: Precision) -> Loops:
    """The loops that run here for ``loops``: ``auto`` is ``fused`` where ``rnn_seg.kernels``
    builds and loads them for ``precision`` with a vector product (AVX2 or AVX-512), else
    ``graph``; ``fused`` runs wherever the library loads, and falls back to ``graph`` where it
    does not. Each fallback says why in one line on stderr (once per process and reason)."""
    if loops not in ("auto", "fused"):
        return loops
    unavailable = _fused_unavailable(precision)
    if unavailable:
        _say_once(f"fused LSTM loops unavailable ({unavailable}): running the graph loops")
        return "graph"
    if loops == "auto" and _fused_slower():
        _say_once(f"auto: {_fused_slower()}: running the graph loops")
        return "graph"
    return "fused"


def loops_reason(asked: Loops, ran: Loops, precision: Precision) -> str:
    """Why a process runs ``ran`` loops where ``asked`` was asked for (``runnable``), in words
    for a run's record."""
    if ran == "graph" and ran != asked:
        return _graph_because(precision)
    reason = "asked for" if ran == asked else (
        f"auto: the fused loops build and load here ({fused_build.describe()}); the fastest "
        "of this project's loops on AVX2 and AVX-512 processors at 128 and 1024 units "
        f"({AUTO_EVIDENCE})")
    return f"{reason}; {weight_gradient_path(precision)}" if ran == "fused" else reason


def weight_gradient_path(precision: Precision) -> str:
    """What sums ``dW_h`` on the fused loops at ``precision`` (``_weight_gradient``), in words
    for a run's record and the benches."""
    if precision == "fp32" and fused_weight_gradient():
        return "dW_h by their own product (TensorFlow's oneDNN operations off)"
    return "dW_h by TensorFlow's matmul"


#: Where the measurements behind ``auto``'s choice are.
AUTO_EVIDENCE = 'docs/PERFORMANCE.md, "Which loops auto runs"'
#: The fused loops' float32 products that beat the graph loops (``rnn_seg.kernels.build``'s
#: ``product_path``); the generic one, compiled for a processor without AVX2 and FMA, ran a sweep
#: 1.9x (128 units) to 3.1x (1024) slower than the graph loops.
FAST_PRODUCTS = ("AVX2", "AVX-512")


def _graph_because(precision: Precision) -> str:
    """Why the graph loops run in place of the fused ones (``runnable``)."""
    unavailable = _fused_unavailable(precision)
    return (f"fused loops unavailable: {unavailable}" if unavailable
            else f"auto: {_fused_slower()} ({AUTO_EVIDENCE})")


@functools.lru_cache(maxsize=None)
def _fused_unavailable(precision: Precision) -> str | None:
    """``rnn_seg.kernels.build.unavailable``, asked once per process (a failed build is not
    retried)."""
    return fused_build.unavailable(precision)


@functools.lru_cache(maxsize=None)
def _fused_slower() -> str | None:
    """Why ``auto`` passes over the loaded fused library (its product is not one of
    ``FAST_PRODUCTS``), or None."""
    product = fused_build.built_record().get("product", "an unrecorded")
    if product in FAST_PRODUCTS:
        return None
    return f"the fused loops here run the {product} product, slower than the graph loops"


@functools.lru_cache(maxsize=None)
def _say_once(line: str) -> None:
    print(line, file=sys.stderr)


def _flip(direction: str, x: tf.Tensor) -> tf.Tensor:
    """Time-major ``x`` between forward time and ``direction``'s own order (its own inverse)."""
    return x if direction == "fw" else tf.reverse(x, [0])


def dropout(x: tf.Tensor, keep_prob: float, seed: tf.Tensor | None) -> tf.Tensor:
    """Inverted dropout with an independent mask per element and time step (never across time).

    Args:
        x: time-major ``[T, B, F]`` (or ``[T, B, H]``) float32 layer inputs or outputs.
        keep_prob: probability of keeping an element, in (0, 1]; kept elements are scaled by
            ``1 / keep_prob``, and 1.0 means no dropout.
        seed: ``[2]`` int64 stateless seed; None = no dropout.

    Returns:
        ``x``'s shape, float32.
    """
    if seed is None or keep_prob >= 1.0:
        return x
    return tf.nn.experimental.stateless_dropout(x, rate=1.0 - keep_prob, seed=seed)

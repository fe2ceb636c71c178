"""The TF LSTM layer against the NumPy reference: outputs and gradients, both reset modes."""
import numpy as np
import pytest
import tensorflow as tf

from rnn_seg.lstm import EncoderConfig, RecurrentEncoder, reverse_resets
from rnn_seg.sweeps import make_sweep, reset_flags
from tests.fused_loops import LOOPS, needs_fused, needs_fused_bf16
from tests.lstm_reference import bidirectional_forward, lstm_forward, tf_lstm_forward

F, H = 3, 6


def _encoder(mode, bidirectional=True, layers=1, loops="graph", hidden=H, precision="fp32"):
    config = EncoderConfig(hidden=hidden, layers=layers, bidirectional=bidirectional,
                           keep_prob=1.0, reset_mode=mode, loops=loops, precision=precision)
    enc = RecurrentEncoder(F, config, tf.random.Generator.from_seed(3))
    for cells in enc.cells.values():     # non-zero biases so they are checked too
        for cell in cells:
            cell.b.assign(tf.random.stateless_uniform(cell.b.shape, [1, 2], -0.1, 0.1))
    return enc


def _params(cell):
    return tuple(v.numpy().astype(np.float64) for v in (cell.W_x, cell.W_h, cell.peep, cell.b))


def _wrapped_batch():
    rng = np.random.default_rng(0)
    seqs = [rng.normal(size=(n, F)).astype(np.float32) for n in (7, 3, 5)]
    lengths = [len(s) for s in seqs]
    return make_sweep(seqs), reset_flags(lengths, max(lengths))


@pytest.mark.parametrize("loops", LOOPS)
@pytest.mark.parametrize("mode", ["original", "corrected"])
def test_bidirectional_outputs_match_reference(mode, loops):
    enc = _encoder(mode, loops=loops)
    x, r = _wrapped_batch()
    got = enc(tf.constant(x), tf.constant(r), None).numpy()
    want = bidirectional_forward(x.astype(np.float64), r, _params(enc.cells["fw"][0]),
                                 _params(enc.cells["rv"][0]), mode)
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_reset_modes_differ_only_where_the_original_resets_the_reverse_state():
    """Original: the reverse state restarts before each copy's first frame, so that frame sees only
    itself in reverse; a wrapped copy's last frames carry state from the next copy. The longest
    sequence (no wrap) differs between the modes at its first frame only."""
    x, r = _wrapped_batch()
    a = _encoder("original")(tf.constant(x), tf.constant(r), None).numpy()
    b = _encoder("corrected")(tf.constant(x), tf.constant(r), None).numpy()
    np.testing.assert_allclose(a[..., :H], b[..., :H], atol=1e-6)   # forward identical
    np.testing.assert_allclose(a[0, 1:, H:], b[0, 1:, H:], atol=1e-6)
    assert not np.allclose(a[0, 0, H:], b[0, 0, H:])
    assert not np.allclose(a[1, 1:3, H:], b[1, 1:3, H:])           # wrapped: state leaks in


def test_corrected_reverse_equals_each_sequence_alone():
    rng = np.random.default_rng(1)
    seqs = [rng.normal(size=(n, F)).astype(np.float32) for n in (6, 4)]
    enc = _encoder("corrected")
    x, r = make_sweep(seqs), reset_flags([6, 4], 6)
    together = enc(tf.constant(x), tf.constant(r), None).numpy()
    alone = enc(tf.constant(seqs[1][None]), tf.constant(reset_flags([4], 4)), None).numpy()
    np.testing.assert_allclose(together[1, :4], alone[0], atol=1e-6)


def test_reverse_resets_corrected_marks_last_frames():
    r = tf.constant(reset_flags([3, 2], 5))
    np.testing.assert_array_equal(reverse_resets(r, "corrected").numpy(),
                                  [[0, 0, 1, 0, 1], [0, 1, 0, 1, 1]])


@pytest.mark.parametrize("loops", LOOPS)
@pytest.mark.parametrize("mode", ["original", "corrected"])
def test_gradients_match_reference(mode, loops):
    """d(sum of outputs * weights)/d(params) against central finite differences of the reference."""
    enc = _encoder(mode, loops=loops)
    x, r = _wrapped_batch()
    readout = np.random.default_rng(2).normal(size=(x.shape[0], x.shape[1], 2 * H))
    with tf.GradientTape() as tape:
        y = enc(tf.constant(x), tf.constant(r), None)
        loss = tf.reduce_sum(y * readout)
    variables = [enc.cells["fw"][0].W_h, enc.cells["rv"][0].peep, enc.cells["rv"][0].W_x,
                 enc.cells["fw"][0].b]
    grads = [g.numpy() for g in tape.gradient(loss, variables)]

    def ref_loss():
        out = bidirectional_forward(x.astype(np.float64), r, _params(enc.cells["fw"][0]),
                                    _params(enc.cells["rv"][0]), mode)
        return float(np.sum(out * readout))

    rng = np.random.default_rng(3)
    for var, grad in zip(variables, grads):
        base = var.numpy()
        for _ in range(4):
            idx = tuple(rng.integers(0, s) for s in base.shape)
            eps = 1e-3
            for sign in (+1, -1):
                bumped = base.copy()
                bumped[idx] += sign * eps
                var.assign(bumped)
                if sign > 0:
                    up = ref_loss()
                else:
                    down = ref_loss()
            var.assign(base)
            np.testing.assert_allclose(grad[idx], (up - down) / (2 * eps), rtol=2e-2, atol=2e-3)


@pytest.mark.parametrize("loops", LOOPS)
@pytest.mark.parametrize("mode", ["original", "corrected"])
def test_hand_written_backward_equals_autodiff(mode, loops):
    """Every gradient of a two-layer BiLSTM against autodiff through the step-by-step TF cell."""
    enc = _encoder(mode, layers=2, loops=loops)
    x, r = _wrapped_batch()
    x, r = tf.constant(x), tf.constant(r)
    readout = tf.constant(np.random.default_rng(4).normal(size=(*x.shape[:2], 2 * H)), tf.float32)
    with tf.GradientTape(persistent=True) as tape:
        fast = tf.reduce_sum(enc(x, r, None) * readout)
        rv_resets = tf.reverse(reverse_resets(r, mode), [1])
        fw, rv = x, tf.reverse(x, [1])
        for layer in range(2):
            fw = tf_lstm_forward(fw, r, *_variables(enc.cells["fw"][layer]))
            rv = tf_lstm_forward(rv, rv_resets, *_variables(enc.cells["rv"][layer]))
        slow = tf.reduce_sum(tf.concat([fw, tf.reverse(rv, [1])], 2) * readout)
    np.testing.assert_allclose(fast.numpy(), slow.numpy(), rtol=1e-6, atol=1e-6)
    variables = enc.trainable_variables
    for var, got, want in zip(variables, tape.gradient(fast, variables),
                              tape.gradient(slow, variables)):
        np.testing.assert_allclose(got.numpy(), want.numpy(), rtol=1e-4, atol=1e-6,
                                   err_msg=var.name)


def _outputs_and_gradients(mode, loops, hidden=H, precision="fp32", layers=2):
    """A BiLSTM's outputs and every gradient on a wrapped sweep of 37, 16 and 9 steps (XLA pads
    it to 48: one sequence a whole compiled size)."""
    rng = np.random.default_rng(5)
    lengths = (37, 16, 9)
    x = make_sweep([rng.normal(size=(n, F)).astype(np.float32) for n in lengths])
    x, r = tf.constant(x), tf.constant(reset_flags(lengths, max(lengths)))
    readout = tf.constant(rng.normal(size=(*x.shape[:2], 2 * hidden)), tf.float32)
    enc = _encoder(mode, layers=layers, loops=loops, hidden=hidden, precision=precision)
    assert enc.config.loops == loops                 # not fallen back to another path
    with tf.GradientTape() as tape:
        y = enc(x, r, None)
        loss = tf.reduce_sum(y * readout)
    return [y, *tape.gradient(loss, enc.trainable_variables)]


@pytest.mark.parametrize("loops", ["xla", pytest.param("fused", marks=needs_fused)])
@pytest.mark.parametrize("mode", ["original", "corrected"])
def test_compiled_loops_equal_the_op_loops(mode, loops):
    """XLA's loops (padded to a compiled size, stopped at the last real step) and the fused C++
    loops give a two-layer BiLSTM's outputs and every gradient of the op-by-op loops, to float32
    rounding."""
    for got, want in zip(_outputs_and_gradients(mode, loops), _outputs_and_gradients(mode, "graph")):
        np.testing.assert_allclose(got.numpy(), want.numpy(), rtol=1e-5, atol=1e-6)


@needs_fused
def test_fused_loops_split_between_threads_equal_the_op_loops():
    """At 130 units the intra-op threads share 9 panels of 16 units (AVX-512) or 17 of 8 (AVX2),
    the last one partial, each thread its own part first, then what is left of the other's: same
    outputs and gradients as the op loops, and the same to the last bit whichever thread computed
    which panel."""
    fused, again, graph = (_outputs_and_gradients("corrected", loops, hidden=130, layers=1)
                           for loops in ("fused", "fused", "graph"))
    for got, repeated, want in zip(fused, again, graph):
        np.testing.assert_allclose(got.numpy(), want.numpy(), rtol=1e-4, atol=1e-6)
        np.testing.assert_array_equal(got.numpy(), repeated.numpy())


@needs_fused
@pytest.mark.parametrize("rows, units, columns", [(0, 3, 12), (1, 1, 4), (7, 5, 20),
                                                  (300, 13, 52), (600, 130, 516)])
def test_the_fused_weight_gradient_sums_every_row_of_any_shape(rows, units, columns):
    """The fused loops' own ``h_prev^T dz`` (``rnn_seg.kernels``): rows past one block of k
    (256), units past one block of A's rows (96) and not whole micro-panels of 6, columns not
    whole panels, no rows at all (zeros): float64's product to float32 rounding."""
    from rnn_seg.kernels.loops import weight_gradient
    rng = np.random.default_rng(rows + units)
    a, b = (rng.normal(size=shape).astype(np.float32) for shape in ((rows, units), (rows, columns)))
    got = weight_gradient(tf.constant(a), tf.constant(b)).numpy()
    assert got.shape == (units, columns)
    want = a.astype(np.float64).T @ b.astype(np.float64)
    scale = np.abs(a.astype(np.float64)).T @ np.abs(b.astype(np.float64))
    assert np.all(np.abs(got - want) <= 1e-6 * scale)


@needs_fused
def test_fused_loops_take_any_number_of_rows():
    """The fused ops run a batch in passes of up to 6 rows: 13 rows (6 + 6 + 1), 20 units (a
    partial panel), give the op loops' outputs and gradients."""
    rng = np.random.default_rng(6)
    x = tf.constant(rng.normal(size=(13, 11, F)), tf.float32)
    r = tf.constant(rng.random((13, 11)) < 0.2)
    results = {}
    for loops in ("graph", "fused"):
        enc = _encoder("corrected", loops=loops, hidden=20)
        with tf.GradientTape() as tape:
            y = enc(x, r, None)
            loss = tf.reduce_sum(y * y)
        results[loops] = [y, *tape.gradient(loss, enc.trainable_variables)]
    for got, want in zip(results["fused"], results["graph"]):
        np.testing.assert_allclose(got.numpy(), want.numpy(), rtol=1e-5, atol=1e-6)


@needs_fused_bf16
def test_fused_bf16_loops_equal_the_op_loops_to_bf16_rounding():
    """bfloat16 products in the fused ops round as TensorFlow's do (operands and results to
    bfloat16, sums in float32): outputs and gradients agree with the op loops' bfloat16 path far
    inside bfloat16's own error (0.4 % a product; here at most 0.1 %, relative L2 norm)."""
    fused, graph = (_outputs_and_gradients("original", loops, hidden=40, precision="bf16")
                    for loops in ("fused", "graph"))
    for got, want in zip(fused, graph):
        error = np.linalg.norm(got.numpy() - want.numpy()) / np.linalg.norm(want.numpy())
        assert error < 1e-3


def test_compiled_loop_sizes_are_two_per_octave():
    from rnn_seg.lstm import _padding

    sizes = {n: _padding(tf.constant(n))(tf.zeros([n, 1])).shape[0]
             for n in (1, 9, 16, 37, 600, 768, 900, 1100)}
    assert sizes == {1: 16, 9: 16, 16: 16, 37: 48, 600: 768, 768: 768, 900: 1024, 1100: 1536}


def _variables(cell):
    return cell.W_x, cell.W_h, cell.peep, cell.b


def test_two_layers_forward_only_matches_reference():
    enc = _encoder("original", bidirectional=False, layers=2)
    x, r = _wrapped_batch()
    got = enc(tf.constant(x), tf.constant(r), None).numpy()
    h1 = lstm_forward(x.astype(np.float64), r, *_params(enc.cells["fw"][0]))
    want = lstm_forward(h1, r, *_params(enc.cells["fw"][1]))
    assert got.shape == (3, 7, H)
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_dropout_only_in_training_and_independent_per_step():
    config = EncoderConfig(hidden=32, keep_prob=0.5)
    enc = RecurrentEncoder(16, config, tf.random.Generator.from_seed(0))
    x = tf.random.stateless_normal([4, 30, 16], [0, 1])
    r = tf.zeros([4, 30], bool)
    clean = enc(x, r, None).numpy()
    np.testing.assert_array_equal(clean, enc(x, r, None).numpy())
    assert np.all(clean != 0)
    seeds = tf.transpose(tf.random.Generator.from_seed(1).make_seeds(enc.dropout_calls))
    dropped = enc(x, r, seeds).numpy() == 0
    assert 0.4 < dropped.mean() < 0.6            # output dropout at keep 0.5
    varies_in_time = dropped.any(axis=1) & ~dropped.all(axis=1)
    assert varies_in_time.mean() > 0.95          # a fresh mask at every step, not across time
    init = config.init_scale
    w = enc.cells["fw"][0].W_h.numpy()
    assert np.abs(w).max() <= init and np.all(enc.cells["fw"][0].b.numpy() == 0)


@pytest.mark.parametrize("layers", [1, 2])
def test_forward_steps_equal_the_whole_sequence(layers):
    """Online use: one step at a time, state carried, equals one pass over the sequence."""
    enc = _encoder("original", bidirectional=False, layers=layers)
    x = np.random.default_rng(4).normal(size=(1, 9, F)).astype(np.float32)
    whole = enc(tf.constant(x), tf.constant(reset_flags([9], 9)), None).numpy()[0]
    state, steps = enc.initial_state(1), []
    for t in range(9):
        h, state = enc.step(enc.params(), tf.constant(x[:, t]), state)
        steps.append(h.numpy()[0])
    np.testing.assert_allclose(np.stack(steps), whole, rtol=1e-5, atol=1e-6)


def test_a_bidirectional_encoder_does_not_step():
    enc = _encoder("original")
    with pytest.raises(ValueError, match="forward"):
        enc.step(enc.params(), tf.zeros([1, F]), enc.initial_state(1))

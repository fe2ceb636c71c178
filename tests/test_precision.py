"""bfloat16 products: gradients within bfloat16 tolerance of float32, refused without hardware."""
from dataclasses import replace

import numpy as np
import pytest
import tensorflow as tf

from rnn_seg import config, lstm
from rnn_seg.lstm import EncoderConfig, require_native_precision
from rnn_seg.model import SegmentationModel
from rnn_seg.sweeps import make_sweep, reset_flags
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import loss_gradients
from tests.fused_loops import needs_fused_bf16

F, H, K = 14, 64, 10
#: bfloat16 keeps 8 significant bits: each product's result is within 2^-8 (0.4 %) of float32.
#: Through 60 recurrent steps forward and back, whole gradients differ from float32 by 0.1-0.4 %
#: (relative L2 norm) here; the stated tolerance is 2 %.
GRADIENT_TOLERANCE = 0.02


def _gradients(precision: str, bidirectional: bool = True, loops: str = "graph"):
    config = EncoderConfig(hidden=H, bidirectional=bidirectional, precision=precision,
                           loops=loops)
    task = SoftmaxClassification("gesture", [f"G{k}" for k in range(K)])
    model = SegmentationModel(F, config, [task], seed=0)
    rng = np.random.default_rng(0)
    seqs = [rng.normal(size=(n, F)).astype(np.float32) for n in (60, 41, 52)]
    lengths = [len(s) for s in seqs]
    x, r = make_sweep(seqs), reset_flags(lengths, max(lengths))
    y = np.eye(K, dtype=np.float32)[rng.integers(0, K, r.shape)]
    seeds = tf.constant([[1, 2]] * model.dropout_calls, tf.int64)
    losses, (grads,) = loss_gradients(model, [task], False, model.params(), tf.constant(x),
                                      tf.constant(r), [tf.constant(y)], seeds)
    return float(losses[0]), [g.numpy() for g in grads]


@pytest.mark.parametrize("loops", ["graph", pytest.param("fused", marks=needs_fused_bf16)])
@pytest.mark.parametrize("bidirectional", [True, False])
def test_bf16_gradients_agree_with_fp32(bidirectional, loops):
    loss32, grads32 = _gradients("fp32", bidirectional, loops)
    loss16, grads16 = _gradients("bf16", bidirectional, loops)
    assert loss16 == pytest.approx(loss32, rel=0.01)
    for g32, g16 in zip(grads32, grads16):
        error = np.linalg.norm(g16 - g32) / np.linalg.norm(g32)
        assert error < GRADIENT_TOLERANCE, (g32.shape, error)
    assert any(not np.array_equal(a, b) for a, b in zip(grads32, grads16))   # really bf16


@pytest.mark.parametrize("flags", [{"amx_bf16", "avx512_bf16"}, {"avx512_bf16"}])
def test_bf16_recurrent_products_in_either_layout_agree_with_fp32(monkeypatch, flags):
    """Each CPU's bfloat16 layout computes the same products, within bfloat16 rounding."""
    monkeypatch.setattr(lstm, "cpu_flags", lambda: frozenset(flags))
    rng = np.random.default_rng(0)
    W = tf.constant(rng.uniform(-0.1, 0.1, (H, 4 * H)), tf.float32)
    h, dz = (tf.constant(rng.normal(size=shape), tf.float32) for shape in ((5, H), (5, 4 * H)))
    exact, bf16 = lstm.recurrent_products(W), lstm.recurrent_products(W, tf.bfloat16)
    for reference, ours in ((exact.forward(h), bf16.forward(h)),
                            (exact.backward(dz), bf16.backward(dz))):
        assert ours.dtype == tf.float32 and ours.shape == reference.shape
        error = np.linalg.norm(ours - reference) / np.linalg.norm(reference)
        assert 0 < error < GRADIENT_TOLERANCE


def test_bf16_is_refused_without_native_support(monkeypatch):
    monkeypatch.setattr(config, "native_bf16", lambda: False)
    with pytest.raises(ValueError, match="native bfloat16"):
        require_native_precision("bf16")
    require_native_precision("fp32")


def test_unknown_precision_is_an_error():
    with pytest.raises(ValueError, match="precision must be one of"):
        replace(EncoderConfig(), precision="fp16")


def test_training_refuses_bf16_before_reading_data(monkeypatch, tmp_path, capsys):
    from baseline.cli import main

    monkeypatch.setattr(config, "native_bf16", lambda: False)
    missing = tmp_path / "no-release"
    assert main(["--precision", "bf16", "--data-dir", str(missing), "--out",
                 str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "native bfloat16" in err and "not found" not in err       # refused before the data

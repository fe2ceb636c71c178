"""Several models in one vectorised step train as each would alone (dropout included)."""
import json

import numpy as np
import pytest
import tensorflow as tf

from multitask.models.gradnorm import GradNormConfig, GradNormTrainer
from multitask.models.heads import OrdinalProgress
from rnn_seg.lstm import EncoderConfig
from rnn_seg.model import SegmentationModel
from rnn_seg.optim import OptimConfig
from rnn_seg.stack import TrainerStack, padded_batches
from rnn_seg.tasks import SoftmaxClassification
from rnn_seg.trainer import SequenceSet, TrainConfig, Trainer
from tests.fused_loops import needs_fused

F, SWEEPS = 4, 6


def _data(seed: int) -> SequenceSet:
    """Ten sequences of 12-40 steps; the stack members get different lengths, so they pad."""
    rng = np.random.default_rng(seed)
    inputs = [rng.normal(size=(rng.integers(12, 40), F)).astype(np.float32) for _ in range(10)]
    labels = {"gesture": [(x[:, 0] > 0).astype(int) + (x[:, 1] > 0.5) for x in inputs],
              "progress": [np.minimum(np.arange(len(x)) * 5 // len(x), 4) for x in inputs]}
    return SequenceSet([f"s{i}" for i in range(10)], inputs, labels)


def _trainer(run_dir, seed: int, gradnorm: bool, mode: str = "corrected",
             loops: str = "graph") -> Trainer:
    tasks = [SoftmaxClassification("gesture", ["a", "b", "c"]), OrdinalProgress()]
    model = SegmentationModel(F, EncoderConfig(hidden=8, keep_prob=0.5, reset_mode=mode,
                                               loops=loops), tasks, seed)
    data = _data(seed)
    args = (model, tasks, OptimConfig(learning_rate=0.5, momentum=0.5, unit="sweeps",
                                      total=SWEEPS, decay_start=3, decay_every=2),
            TrainConfig(seed=seed, eval_points=(SWEEPS,), plots="none"), data, data, run_dir, {},
            5.0)
    if gradnorm:
        return GradNormTrainer(*args, log=lambda m: None, gradnorm=GradNormConfig())
    return Trainer(*args, log=lambda m: None)


def _weights(trainer):
    return [v.numpy() for v in trainer.variables]


@pytest.mark.slow
@pytest.mark.parametrize("gradnorm,mode", [(False, "original"), (True, "corrected")])
def test_stacked_members_equal_lone_runs(tmp_path, gradnorm, mode):
    alone = [_trainer(tmp_path / f"alone{s}", s, gradnorm, mode) for s in (0, 1)]
    for t in alone:
        t.run()
    stacked = [_trainer(tmp_path / f"stack{s}", s, gradnorm, mode) for s in (0, 1)]
    lengths = [b[0].shape[1] for b in (t.batch(0) for t in stacked)]
    assert len(set(lengths)) > 1                               # the first sweep pads
    TrainerStack(stacked).run()
    for a, b in zip(alone, stacked):
        for wa, wb in zip(_weights(a), _weights(b)):
            np.testing.assert_allclose(wb, wa, atol=2e-5)
        if gradnorm:
            np.testing.assert_allclose(b.weights.numpy(), a.weights.numpy(), atol=1e-4)
        ma = json.loads((a.run_dir / "metrics.json").read_text())["mean"]
        mb = json.loads((b.run_dir / "metrics.json").read_text())["mean"]
        assert mb["gesture"]["accuracy"] == pytest.approx(ma["gesture"]["accuracy"], abs=0.5)
        assert (b.run_dir / "finished.json").exists()


@pytest.mark.slow
def test_stack_resumes_from_the_common_checkpoint(tmp_path):
    """Members checkpointed at different sweeps restart together from the older one."""
    lone = _trainer(tmp_path / "lone", 0, False)
    lone.run()
    first = [_trainer(tmp_path / f"m{s}", s, False) for s in (0, 1)]
    for t, reached in zip(first, (3, 2)):         # as if killed while saving checkpoints
        t.resume()
        for sweep in range(reached):
            lr = t.optim.learning_rate_at(sweep, t.sweeps_per_epoch)
            t.after_sweep(sweep, lr, t.step(sweep, lr))
    assert [t.checkpoint_sweeps()[-1] for t in first] == [3, 2]
    again = [_trainer(tmp_path / f"m{s}", s, False) for s in (0, 1)]
    TrainerStack(again).run()
    for wa, wb in zip(_weights(lone), _weights(again[0])):
        np.testing.assert_allclose(wb, wa, atol=2e-5)


def test_stack_refuses_members_that_differ(tmp_path):
    a = _trainer(tmp_path / "a", 0, False)
    b = _trainer(tmp_path / "b", 1, True)
    with pytest.raises(ValueError, match="different trainer class"):
        TrainerStack([a, b])


@pytest.mark.parametrize("loops", ["xla", pytest.param("auto", marks=needs_fused)])
def test_stack_refuses_members_on_compiled_loops(tmp_path, loops):
    """A vectorised step maps TensorFlow ops over the members; compiled loops (``auto``'s
    fused ones where they build) would run member by member: refused, naming the member."""
    a = _trainer(tmp_path / "a", 0, False, loops=loops)
    b = _trainer(tmp_path / "b", 1, False)
    with pytest.raises(ValueError, match=f"cannot stack {tmp_path / 'a'}: its LSTM runs the"):
        TrainerStack([a, b])
    TrainerStack([a])                           # alone, a member runs its own step


def test_padding_is_masked_out_of_the_losses():
    task = SoftmaxClassification("g", ["a", "b"])
    batches = [(np.ones((2, n, F), np.float32), np.zeros((2, n), bool),
                (np.tile(np.eye(2, dtype=np.float32)[[0]], (2, n, 1)),), None) for n in (3, 5)]
    inputs, resets, (targets,), valid = padded_batches(batches)
    assert inputs.shape == (2, 2, 5, F) and valid.numpy()[0].sum() == 6
    logits = tf.random.stateless_normal([2, 5, 2], [0, 1])
    short = task.loss(logits[:, :3], targets[0, :, :3])
    assert float(task.loss(logits, targets[0], valid[0])) == pytest.approx(float(short), rel=1e-6)

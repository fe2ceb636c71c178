"""A generic engine for recurrent sequence segmentation: any task, any label set.

Read first: ``trainer.Trainer`` (its docstring lists what one training sweep calls, in order),
then ``model.SegmentationModel`` (an encoder shared by one dense head per task).

* ``config``: the encoder, optimiser and training dataclasses (no TensorFlow import);
* ``lstm``: DiPietro et al.'s peephole LSTM with resets and its hand-written backward pass;
  ``kernels/``: its loops over time as compiled C++ ops (``loops = "fused"``, optional);
* ``encoders/``: the encoder concept, the LSTM beside Lea et al.'s ED-TCN and Farha & Gall's
  MS-TCN, chosen by the run's configuration;
* ``model``, ``dense``: the encoder plus one head per ``tasks.Task``;
* ``tasks``: what a head predicts (targets, loss, decoding);
* ``sweeps``: batches of sequences wrapped (or padded) to the longest; ``optim``: SGD, RMSprop,
  Adam and the schedule;
* ``trainer``: the training loop with checkpoints, resume and evaluation points;
* ``stack``: several models trained in one vectorised step; ``threads``: the thread plan;
* ``metrics``: accuracy, edit score and F1@k; ``plots``: per-sequence figures;
* ``validation``: configuration checks;
* ``runs/``: run folders you can trust (strict JSON and atomic writes, the files a run owns,
  the settings a folder is checked against, checkpoints, the one-writer lock, provenance,
  timing).

Imports: ``jigsaws_tools`` (and TensorFlow, numpy); nothing of ``baseline`` or ``multitask``.
Inside, ``runs/`` imports only ``config`` and ``validation`` of the engine, so the run-folder
files load without TensorFlow.
"""
from jigsaws_tools.lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "EncoderConfig": "config",
    "SegmentationModel": "model",
    "restore_weights": "runs.checkpoints",
    "OptimConfig": "config",
    "SoftmaxClassification": "tasks",
    "Task": "tasks",
    "SequenceSet": "trainer",
    "TrainConfig": "config",
    "Trainer": "trainer",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)

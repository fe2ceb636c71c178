"""Model "A": DiPietro et al.'s (MICCAI 2016) bidirectional-LSTM gesture recogniser on the engine.

Read first: ``builder.train_baseline`` (one LOUO fold from a ``config.RunConfig``), then
``builder.build_trainer``, which the multi-task variants reuse. ``options`` holds the command-line
options every training CLI shares, ``launch`` how they run (lock, errors, Ctrl-C); ``cli`` is
``baseline-train``.

Imports ``jigsaws_tools`` and ``rnn_seg``; nothing of ``multitask``, which builds on it.
"""
from jigsaws_tools.lazy import lazy_exports

#: Public name -> the submodule defining it, imported on first use (``jigsaws_tools.lazy``).
_PUBLIC = {
    "build_trainer": "builder",
    "gesture_task": "builder",
    "train_baseline": "builder",
    "RunConfig": "config",
}
__all__ = sorted(_PUBLIC)
__getattr__ = lazy_exports(__name__, _PUBLIC)

"""Model "A": DiPietro et al.'s (MICCAI 2016) bidirectional-LSTM gesture recogniser on the engine.

Read first: ``builder.train_baseline`` (one LOUO fold from a ``config.RunConfig``), then
``builder.build_trainer``, which the multi-task variants reuse. ``options`` holds the command-line
options every training CLI shares, ``launch`` how they run (lock, errors, Ctrl-C); ``cli`` is
``baseline-train``.
"""
from importlib import import_module

#: Public name -> the submodule defining it.
_PUBLIC = {
    "build_trainer": "builder",
    "gesture_task": "builder",
    "train_baseline": "builder",
    "RunConfig": "config",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    """Import a public name's module on first use, so light submodules (``options``) do not
    pull in TensorFlow."""
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

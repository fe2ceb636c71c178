"""JIGSAWS I/O for any task defined as data (Suturing, Knot_Tying, Needle_Passing or your own),
preprocessing, annotation versions and progress labels.

Also what every command of the package shares: ``cli_common`` (``--version``, ``-v``, quiet
TensorFlow, one-line errors), ``arg_types`` (range-checked option types), ``options`` and
``task_options`` (the options that choose a release and its task); ``plots`` draws label ribbons.
"""
from importlib import import_module

#: Public name -> the submodule defining it.
_PUBLIC = {
    "DataConfig": "dataset",
    "Dataset": "dataset",
    "Trial": "dataset",
    "load_dataset": "dataset",
    "Normalisation": "preprocessing",
    "PreprocessConfig": "preprocessing",
    "preprocess_recording": "preprocessing",
    "TaskDefinition": "task_definition",
    "load_task": "task_definition",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    """Import a public name's module on first use, so that command lines (``cli_common``,
    ``arg_types``) start without loading NumPy and SciPy."""
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

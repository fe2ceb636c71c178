"""JIGSAWS Suturing I/O, preprocessing, annotation versions and progress labels.

Also what every command of the package shares: ``cli_common`` (``--version``, ``-v``, quiet
TensorFlow, one-line errors), ``arg_types`` (range-checked option types) and ``options`` (the
options that choose a release); ``plots`` draws label ribbons.
"""
from importlib import import_module

#: Public name -> the submodule defining it.
_PUBLIC = {
    "DataConfig": "dataset",
    "Dataset": "dataset",
    "Trial": "dataset",
    "load_dataset": "dataset",
    "PreprocessConfig": "preprocessing",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    """Import a public name's module on first use, so that command lines (``cli_common``,
    ``arg_types``) start without loading NumPy and SciPy."""
    if name in _PUBLIC:
        return getattr(import_module(f".{_PUBLIC[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

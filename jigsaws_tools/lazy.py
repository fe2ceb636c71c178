"""Lazy package attributes: a package's public names, imported from their submodules on first use.

Each package of this project (``jigsaws_tools``, ``rnn_seg``, ``baseline``, ``multitask``) lists its
public names in its ``__init__.py`` and imports none of them there, so that a light submodule
(command-line options, configuration dataclasses, table code) can be imported without the heavy
ones (TensorFlow, SciPy, NumPy)::

    _PUBLIC = {"SegmentationModel": "model", "Trainer": "trainer"}   # name -> submodule
    __all__ = sorted(_PUBLIC)
    __getattr__ = lazy_exports(__name__, _PUBLIC)
"""
from __future__ import annotations

from importlib import import_module
from typing import Any, Callable, Mapping


def lazy_exports(package: str, public: Mapping[str, str]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` (PEP 562) for ``package``.

    Args:
        package: the package's ``__name__``.
        public: each public name -> the submodule (relative to ``package``) that defines it.

    Returns:
        ``__getattr__(name)``: ``name`` from its submodule, imported on first use; an
        ``AttributeError`` for any other name.
    """

    def __getattr__(name: str) -> Any:
        if name in public:
            return getattr(import_module(f".{public[name]}", package), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__

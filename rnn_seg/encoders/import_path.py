"""A user's encoder named by its import path, ``package.module:name``, without TensorFlow.

``custom_encoder`` checks the path and hashes its module's source file, found without running
the module (``importlib.util.find_spec``), for a run's ``CustomEncoderConfig``;
``load_builder`` imports the module and returns what ``name`` names, checked to be a function
or class (what builds the Keras layer: ``rnn_seg.encoders.keras_layer``); ``check_source``
refuses to rebuild a trained run's encoder from a source other than the one it was trained with.
Every problem is one ``EncoderImportError`` line naming the path. The module must be
importable by the process that trains or loads the run: installed, or its folder on
``PYTHONPATH``.
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import re
from pathlib import Path
from typing import Any, Callable

#: ``package.module:name``: dotted Python identifiers, a colon, an identifier.
_IMPORT_PATH = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*")


class EncoderImportError(ValueError):
    """A user's encoder that cannot be found, imported, built or trusted; one line naming it."""


def is_import_path(text: object) -> bool:
    """Whether ``text`` names a user's encoder (holds a colon) rather than a built-in one."""
    return isinstance(text, str) and ":" in text


def split_path(path: object) -> tuple[str, str]:
    """``("package.module", "name")`` of ``path``; an ``EncoderImportError`` unless it has that
    form."""
    if not isinstance(path, str) or not _IMPORT_PATH.fullmatch(path):
        raise EncoderImportError(f"encoder {path!r}: not an import path package.module:name "
                                 "(or one of lstm, ed-tcn, ms-tcn)")
    module, name = path.split(":")
    return module, name


def module_source(path: str) -> Path:
    """The source file of ``path``'s module, found without running it (its parent packages are
    imported); an ``EncoderImportError`` when there is none."""
    module, _ = split_path(path)
    try:
        spec = importlib.util.find_spec(module)
    except Exception as error:          # a parent package that fails to import, whatever why
        raise EncoderImportError(f"encoder {path}: module {module} cannot be found "
                                 f"({type(error).__name__}: {error})") from None
    if spec is None:
        raise EncoderImportError(f"encoder {path}: no module {module} (is it installed, or its "
                                 "folder on PYTHONPATH?)")
    if not spec.has_location or spec.origin is None:
        raise EncoderImportError(f"encoder {path}: module {module} has no source file to record "
                                 f"(origin: {spec.origin})")
    if not Path(spec.origin).is_file():             # imported earlier, its file since removed
        raise EncoderImportError(f"encoder {path}: no module {module}: its source "
                                 f"{spec.origin} is not there")
    return Path(spec.origin)


def source_sha256(path: str) -> str:
    """The SHA-256 of the bytes of ``path``'s module source file, in hexadecimal."""
    source = module_source(path)
    try:
        return hashlib.sha256(source.read_bytes()).hexdigest()
    except OSError as error:
        raise EncoderImportError(f"encoder {path}: {source}: unreadable ({error.strerror})"
                                 ) from None


def custom_encoder(path: str, causal: bool = False):
    """The ``CustomEncoderConfig`` of ``path`` as its source is now (causal when online)."""
    from .config import CustomEncoderConfig

    return CustomEncoderConfig(path=path, source_sha256=source_sha256(path), causal=causal)


def check_source(config) -> None:
    """Refuse (``EncoderImportError``) a ``CustomEncoderConfig`` whose module source is no longer
    the one its run recorded: the weights were trained for that code."""
    now = source_sha256(config.path)
    if now != config.source_sha256:
        raise EncoderImportError(
            f"encoder {config.path}: its source {module_source(config.path)} has changed since "
            f"the run was configured (sha256 {config.source_sha256[:12]} recorded, "
            f"{now[:12]} now); restore that source, or train a new run")


def load_builder(path: str) -> Callable[..., Any]:
    """Import ``path``'s module and return the function or class its name names."""
    module_name, name = split_path(path)
    try:
        module = importlib.import_module(module_name)
    except Exception as error:          # the user's module may raise anything on import
        raise EncoderImportError(f"encoder {path}: module {module_name} cannot be imported "
                                 f"({type(error).__name__}: {error})") from None
    if not hasattr(module, name):
        raise EncoderImportError(f"encoder {path}: module {module_name} has no name {name!r}")
    builder = getattr(module, name)
    if not callable(builder) or _is_layer(builder):
        raise EncoderImportError(
            f"encoder {path}: {name} is of type {type(builder).__name__}, not a function or class "
            "building a Keras layer from (input_size, config)")
    return builder


def _is_layer(value: object) -> bool:
    """Whether ``value`` is a Keras layer already built (one instance would share its weights
    between every run of a process), told without importing Keras."""
    return any(cls.__module__.startswith("keras") and cls.__name__ == "Layer"
               for cls in type(value).__mro__)

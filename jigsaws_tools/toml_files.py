"""The package's TOML definition files (task definitions, recording formats): reading one, and
checking its keys and value types, each error naming the file, the key and the value."""
from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any, Callable, TypeVar

from .errors import DefinitionError

T = TypeVar("T")


def read_definition(path: Path | str, what: str, parse: Callable[[dict], T]) -> T:
    """``parse`` of the TOML file ``path``: a missing, unreadable or invalid file, or a
    ``DefinitionError`` of ``parse`` (which names the key and value only), is a
    ``DefinitionError`` naming the file too.

    Args:
        path: the file.
        what: what the file is, for the message of a missing one (e.g. ``"task definition"``).
        parse: the file's tables -> its object, raising ``DefinitionError`` on a bad value.
    """
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except FileNotFoundError:
        raise DefinitionError(path, None, str(path), f"{what} file not found") from None
    except (OSError, UnicodeDecodeError) as error:
        raise DefinitionError(path, None, str(path), f"cannot read: {error}") from None
    except tomllib.TOMLDecodeError as error:
        raise DefinitionError(path, None, "", f"not valid TOML: {error}") from None
    try:
        return parse(raw)
    except DefinitionError as error:
        raise DefinitionError(path, error.key, error.value, error.problem) from None


def known_keys(raw: dict, key: str, known: tuple[str, ...], required: tuple[str, ...]) -> None:
    """Refuse a key of the table ``raw`` (at ``key``) not in ``known``, or a ``required`` one
    missing."""
    prefix = f"{key}." if key else ""
    for name in raw:
        if name not in known:
            raise DefinitionError("", f"{prefix}{name}", raw[name],
                                  f"unknown key; known keys here: {', '.join(known)}")
    for name in required:
        if name not in raw:
            raise DefinitionError("", f"{prefix}{name}", None, "required key missing")


def typed(value: Any, key: str, kind: type | tuple[type, ...], what: str) -> Any:
    """``value`` when it is a ``kind`` (a bool only where ``kind`` is bool), else a
    ``DefinitionError`` saying it should be ``what``."""
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise DefinitionError("", key, value, f"expected {what}")
    return value


def table(value: Any, key: str) -> dict:
    """``value`` when it is a TOML table."""
    return typed(value, key, dict, "a table")

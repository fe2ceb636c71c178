"""The package's TOML definition files (task definitions, recording formats): finding a built-in
one by name, reading one, and checking its keys and value types, each error naming the file, the
key and the value."""
from __future__ import annotations

import functools
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, Callable, TypeVar

from .errors import DefinitionError, JigsawsError
from .files import FileTooLargeError, NotRegularFileError, read_regular

T = TypeVar("T")


def builtin_names(kind: str) -> tuple[str, ...]:
    """Names of the definitions shipped in ``jigsaws_tools/data/<kind>/`` (``"tasks"``,
    ``"formats"``), sorted."""
    return tuple(sorted(p.name.removesuffix(".toml") for p in _builtin_dir(kind).iterdir()
                        if p.name.endswith(".toml")))


def builtin_path(kind: str, name: str) -> Path:
    """The shipped definition file ``name`` of ``kind``."""
    return _builtin_dir(kind) / f"{name}.toml"


def _builtin_dir(kind: str):
    return resources.files("jigsaws_tools") / "data" / kind


def find_definition(value: str | Path, kind: str, what: str, read: Callable[[Path], T]) -> T:
    """``read`` of a built-in definition of ``kind`` named ``value``, or of the file ``value``
    (``*.toml``); any other value is a ``JigsawsError`` listing the built-in names.

    Args:
        value: a built-in name (e.g. ``"Suturing"``) or a file's path.
        kind: the folder of the built-in definitions, ``"tasks"`` or ``"formats"``.
        what: what a definition is, for the message (``"task"``, ``"recording format"``).
        read: a definition file -> its object.
    """
    names = builtin_names(kind)
    if str(value) in names:
        return _read_builtin(kind, str(value), read)
    if str(value).endswith(".toml"):
        return read(Path(value))
    raise JigsawsError(f"unknown {what} {str(value)!r}; built-in {what}s are {', '.join(names)}, "
                       f"or pass a {what} file (*.toml)")


@functools.cache
def _read_builtin(kind: str, name: str, read: Callable[[Path], T]) -> T:
    """``read`` of the shipped definition ``name`` of ``kind``, once per process: the package's
    files do not change while it runs, and a grid's tables look its task up once per run."""
    return read(builtin_path(kind, name))


#: The largest TOML file read, in bytes: every definition, spec or plan is a few kilobytes; a
#: larger file is refused before it is read (a mistaken path, or a parse that would not end).
MAX_TOML_BYTES = 1 << 20


def read_toml(path: Path | str, what: str) -> dict:
    """The tables of the TOML file ``path`` (UTF-8, a byte-order mark allowed): the one reader of
    every TOML file the project reads (task definitions, recording formats, grid specs,
    confirmatory plans and their exploratory analyses).

    A missing file, a folder, a FIFO or other non-regular file (refused at once, ``files``), a
    file of more than ``MAX_TOML_BYTES``, an unreadable or non-UTF-8 file, invalid TOML, arrays
    or tables nested deeper than Python's parser reaches, or an integer longer than Python
    converts (4300 digits) is a one-line ``DefinitionError`` naming the file and what it should
    be (``x.toml: no such spec file``), not the operating system's ``[Errno 2] ...`` or a
    traceback. Values are TOML's: a float may be ``inf`` or ``nan``, for the caller to refuse.

    Args:
        path: the file.
        what: what the file is (e.g. ``"task definition"``, ``"spec"``).
    """
    path = Path(path)
    try:
        return tomllib.loads(read_regular(path, MAX_TOML_BYTES).decode("utf-8-sig"))
    except FileNotFoundError:
        problem = f"no such {what} file"
    except IsADirectoryError:
        problem = f"a folder, not a {what} file"
    except PermissionError:
        problem = f"cannot read this {what} file (permission denied)"
    except OSError as error:
        problem = f"cannot read this {what} file ({error.strerror or error})"
    except NotRegularFileError as error:
        problem = f"{error.kind}, not a {what} file"
    except FileTooLargeError as error:
        problem = f"not a {what} file: larger than {error.limit} bytes"
    except UnicodeDecodeError as error:
        problem = f"not a {what} file: not UTF-8 text (byte {error.start})"
    except tomllib.TOMLDecodeError as error:
        problem = f"not valid TOML: {error}"
    except RecursionError:
        problem = f"not a {what} file: arrays or tables nested too deeply to read"
    except ValueError as error:         # int() of more digits than Python converts; a NUL byte
        problem = f"not a {what} file: {str(error).split(':')[0].lower()}"
    raise DefinitionError(path, None, None, problem)


def read_definition(path: Path | str, what: str, parse: Callable[[dict], T]) -> T:
    """``parse`` of the TOML file ``path``: a file ``read_toml`` refuses, or a
    ``DefinitionError`` of ``parse`` (which names the key and value only), is a
    ``DefinitionError`` naming the file too.

    Args:
        path: the file.
        what: what the file is, for the message of a missing one (e.g. ``"task definition"``).
        parse: the file's tables -> its object, raising ``DefinitionError`` on a bad value.
    """
    raw = read_toml(path, what)
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

"""Run directories: strict-JSON atomic writes, configuration to and from JSON, the files a run
owns, its checkpoints' sweeps, the finished-run marker.

Every JSON file is strict JSON (``null`` for a missing or non-finite number, never ``NaN``) and
every file is written through a temporary file and a rename, with the user's umask.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import re
import secrets
import shutil
import types
import typing
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

import numpy as np

from jigsaws_tools.dataset import holds_unrecorded_default
from jigsaws_tools.errors import NO_SPACE, WriteFailed  # noqa: F401 (re-exported)
from jigsaws_tools.files import NotRegularFileError, read_regular

from ..config import unit_name

CONFIG = "config.json"
FINISHED = "finished.json"
CHECKPOINTS = "checkpoints"
_CHECKPOINT_INDEX = re.compile(r"^ckpt-(\d+)\.index$")
T = TypeVar("T")
HISTORY = "history.csv"
#: A GradNorm run's task weights per progress line (``multitask.models.gradnorm``).
GRADNORM_LOG = "gradnorm.csv"
#: The per-unit CSV logs a run appends to; resume drops their rows past the checkpoint it
#: continues from.
RUN_LOGS = (GRADNORM_LOG, HISTORY)
#: What a run writes besides config.json and its logs; ``clear_run_dir`` removes exactly these,
#: the logs and config.json (a grid's ``train.log``, the lock file and any file of the user stay).
RUN_OUTPUTS = (CHECKPOINTS, "eval", "metrics.json", "timing.json", "tensorboard",
               "evaluate", "stream_normalisation.json", FINISHED)
#: The folders of ``RUN_OUTPUTS``: everything below them is the package's.
RUN_FOLDERS = (CHECKPOINTS, "eval", "tensorboard", "evaluate")
#: A temporary file of ``write_atomic`` or folder of ``publish.staged_folder``:
#: ``.<name>.<random>.tmp``.
_TEMPORARY = re.compile(r"^\.(?P<name>.+)\.[0-9a-z_]{8}\.tmp$")


class RunFolderError(ValueError):
    """A run or grid folder cannot be used as asked: other settings, in use, unreadable, no
    weights to load."""


def to_jsonable(obj: Any) -> Any:
    """Dataclasses (nested), tuples, paths and numpy values as plain JSON values; NaN and
    infinities become None (``null``). A field a dataclass names in its ``unrecorded_defaults``
    class attribute is left out while it holds its default (a field added later, so that earlier
    records and their settings hashes stay the same; ``from_jsonable`` restores the default)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)
                if not holds_unrecorded_default(obj, f.name)}
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


class ConfigError(ValueError):
    """A saved configuration that does not fit its dataclass; names the place and the value."""

    def __init__(self, where: str, problem: str, value: Any):
        super().__init__(f"{where}: {problem} (value: {value!r})")
        self.where, self.problem, self.value = where, problem, value


def from_jsonable(cls: type[T], data: Any, where: str = "config") -> T:
    """Rebuild a (nested) dataclass from ``to_jsonable``'s output: the inverse for the field types
    configurations use (dataclasses, ``int``, ``float``, ``bool``, ``str``, ``Literal``,
    ``X | None``, ``tuple``, ``list``, ``dict``, ``Path``).

    Strict: an unknown key, a value of the wrong type or a missing field without a default is a
    ``ConfigError`` naming its place. A field added to a dataclass later with a default may be
    absent, so older files still load. The dataclass's own validation (``__post_init__``) runs
    as usual.

    Args:
        cls: the dataclass to build.
        data: its saved form (parsed JSON).
        where: the place named in errors, followed by the field path (e.g. ``config.json: run``
            gives ``config.json: run.encoder.hidden``).
    """
    return _from_jsonable(cls, data, where)


def _from_jsonable(tp: Any, value: Any, where: str) -> Any:
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if dataclasses.is_dataclass(tp):
        return _dataclass_from_jsonable(tp, value, where)
    if tp is Any:
        return value
    if origin is Literal:
        if value not in args:
            raise ConfigError(where, f"expected one of {', '.join(map(repr, args))}", value)
        return value
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        chosen = _by_kind(args, value, where)
        if chosen is not None:
            return _dataclass_from_jsonable(chosen, value, where)
        errors = []
        for option in (a for a in args if a is not type(None)):
            try:
                return _from_jsonable(option, value, where)
            except ConfigError as error:
                errors.append(error.problem)
        raise ConfigError(where, " or ".join(errors), value)
    if origin in (tuple, list):
        if not isinstance(value, list):
            raise ConfigError(where, "expected a list", value)
        if origin is tuple and not (len(args) == 2 and args[1] is Ellipsis):
            if len(value) != len(args):
                raise ConfigError(where, f"expected {len(args)} items", value)
            return tuple(_from_jsonable(a, v, f"{where}[{i}]")
                         for i, (a, v) in enumerate(zip(args, value)))
        items = [_from_jsonable(args[0] if args else Any, v, f"{where}[{i}]")
                 for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(where, "expected an object", value)
        return {k: _from_jsonable(args[1] if args else Any, v, f"{where}.{k}")
                for k, v in value.items()}
    return _scalar_from_jsonable(tp, value, where)


def _by_kind(options: tuple, value: Any, where: str) -> type | None:
    """The dataclass among ``options`` that ``value``'s ``kind`` names, when every option is a
    dataclass with a ``kind`` default (e.g. the encoders' configurations): an absent ``kind`` is
    the first option's (a record written before the others existed). None when the options are
    not such a family; a ``ConfigError`` for a ``kind`` none of them has."""
    kinds = {}
    for option in options:
        fields = {f.name: f for f in dataclasses.fields(option)} if (
            dataclasses.is_dataclass(option)) else {}
        if "kind" not in fields or fields["kind"].default is dataclasses.MISSING:
            return None
        kinds[fields["kind"].default] = option
    if not isinstance(value, dict):
        return None
    kind = value.get("kind", next(iter(kinds)))
    if kind not in kinds:
        raise ConfigError(f"{where}.kind", f"expected one of {', '.join(map(repr, kinds))}", kind)
    return kinds[kind]


def _scalar_from_jsonable(tp: Any, value: Any, where: str) -> Any:
    if tp is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if tp is Path and isinstance(value, str):
        return Path(value)
    if tp in (int, bool, str) and type(value) is tp:
        return value
    if tp in (int, float, bool, str, Path):
        raise ConfigError(where, f"expected {tp.__name__}", value)
    raise TypeError(f"{where}: from_jsonable does not handle the type {tp!r}")


@functools.cache
def _field_types(cls: type) -> dict[str, Any]:
    """``cls``'s annotations as types, resolved once per class: resolving them compiles every
    string annotation (``from __future__ import annotations``), which took most of the time of
    reading a grid's records when it was done per record."""
    return typing.get_type_hints(cls)


def _dataclass_from_jsonable(cls: type, value: Any, where: str) -> Any:
    if not isinstance(value, dict):
        raise ConfigError(where, f"expected an object for {cls.__name__}", value)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise ConfigError(where, f"unknown field {unknown[0]!r} of {cls.__name__} (known: "
                                 f"{', '.join(fields)})", value[unknown[0]])
    hints = _field_types(cls)
    kwargs = {}
    for name, f in fields.items():
        if name in value:
            kwargs[name] = _from_jsonable(hints[name], value[name], f"{where}.{name}")
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ConfigError(where, f"missing field {name!r} of {cls.__name__}", value)
    try:
        return cls(**kwargs)
    except Exception as error:          # the dataclass's own validation, whatever its error class
        raise ConfigError(where, str(error), value) from None


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: never half a file. The
    file gets the permissions of any new file (``0o666`` less the umask). A full disk is an
    ``OSError`` naming ``path`` (not its temporary file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException as error:
        tmp.unlink(missing_ok=True)
        if isinstance(error, OSError) and error.errno in NO_SPACE:     # named: path
            raise OSError(error.errno, error.strerror, str(path)) from None
        raise


def require_empty(target: Path) -> None:
    """Refuse (``FileExistsError``) a ``target`` folder that exists and holds anything."""
    if target.is_dir() and any(target.iterdir()):
        raise FileExistsError(f"{target} exists and is not empty; choose another output folder, "
                              "or overwrite it (--overwrite)")


def write_json(path: Path, obj: Any) -> None:
    """``obj`` (see ``to_jsonable``) as strict, indented JSON."""
    write_atomic(path, json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")


def read_json(path: Path) -> Any:
    """Parse a strict JSON file; an unreadable or invalid one, one nested too deeply for Python's
    parser, or one that is no regular file (a FIFO: refused at once), is a ``RunFolderError``
    naming it."""
    def reject(constant: str):
        raise ValueError(f"{constant} is not strict JSON")

    try:
        return json.loads(read_regular(path).decode("utf-8"), parse_constant=reject)
    except NotRegularFileError as error:
        raise RunFolderError(f"{path}: {error.kind}, not a regular file") from None
    except RecursionError:
        raise RunFolderError(f"{path}: not a record: arrays or objects nested too deeply to "
                             "read") from None
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise RunFolderError(f"{path}: unreadable or not valid JSON ({error})") from None


def point_dir(run_dir: Path, unit: str, point: int) -> Path:
    """``eval/<unit><N>`` folder of evaluation point N, e.g. ``eval/epoch0100``.

    Args:
        run_dir: the run folder.
        unit: the schedule's unit, ``"epochs"`` or ``"sweeps"``.
        point: the evaluation point N, in that unit.
    """
    return Path(run_dir) / "eval" / f"{unit_name(unit)}{point:04d}"


def checkpoint_sweeps(run_dir: Path) -> list[int]:
    """Sweep counts of the checkpoints in ``run_dir``, oldest first."""
    folder = Path(run_dir) / CHECKPOINTS
    if not folder.is_dir():
        return []
    return sorted(int(m.group(1)) for p in folder.iterdir()
                  if (m := _CHECKPOINT_INDEX.match(p.name)))


def trained_units(run_dir: Path) -> float:
    """Units of training (epochs, or sweeps for a sweep schedule) that the newest checkpoint of
    ``run_dir`` holds: what a resumed run need not train again. The sweeps per unit come from
    the first row of ``history.csv`` (``n`` units at ``sweep`` sweeps); 0 for a run without a
    checkpoint or a readable history."""
    sweeps = checkpoint_sweeps(run_dir)
    if not sweeps:
        return 0.0
    try:
        with open(Path(run_dir) / HISTORY) as history:
            first = dict(zip(next(history).strip().split(","), next(history).strip().split(",")))
        return sweeps[-1] * float(first["n"]) / int(first["sweep"])
    except (OSError, StopIteration, KeyError, ValueError, ZeroDivisionError):
        return 0.0


def is_finished(run_dir: Path) -> bool:
    return (Path(run_dir) / FINISHED).is_file()


def mark_finished(run_dir: Path, summary: dict) -> None:
    """Written last: its presence means every output of the run is complete."""
    write_json(Path(run_dir) / FINISHED, summary)


def run_outputs(run_dir: Path) -> list[str]:
    """Names of the run outputs and logs present in ``run_dir`` (empty folders do not count)."""
    run_dir = Path(run_dir)
    return [name for name in (*RUN_OUTPUTS, *RUN_LOGS) if _has_files(run_dir / name)]


def clear_run_dir(run_dir: Path) -> None:
    """Delete a run's config.json, outputs (``RUN_OUTPUTS``) and logs (``RUN_LOGS``), by name:
    nothing else in the folder. A symbolic link among them is removed, not followed."""
    run_dir = Path(run_dir)
    for name in (CONFIG, *RUN_OUTPUTS, *RUN_LOGS):
        _remove(run_dir / name)


def remove_temporary_files(run_dir: Path) -> list[Path]:
    """Delete what interrupted writes left in ``run_dir``; returns it. That is the temporary
    file (``.<name>.<random>.tmp``) of a file the run owns (config.json, ``RUN_OUTPUTS``,
    ``RUN_LOGS``) at the top, and any temporary file or staging folder below ``RUN_FOLDERS``
    (an interrupted ``multitask-evaluate`` leaves one in ``evaluate/``); no other file."""
    run_dir = Path(run_dir)
    owned = {CONFIG, *RUN_OUTPUTS, *RUN_LOGS}
    leftovers = [p for p in _children(run_dir)
                 if (m := _TEMPORARY.match(p.name)) and m.group("name") in owned and p.is_file()]
    for folder in RUN_FOLDERS:
        leftovers += _temporary_below(run_dir / folder)
    for path in leftovers:
        _remove(path)
    return sorted(leftovers)


def _children(folder: Path) -> list[Path]:
    return sorted(folder.iterdir()) if folder.is_dir() and not folder.is_symlink() else []


def _temporary_below(folder: Path) -> list[Path]:
    """Temporary files and staging folders below ``folder`` (not inside those folders)."""
    found = []
    for path in _children(folder):
        if _TEMPORARY.match(path.name):
            found.append(path)
        elif path.is_dir():
            found += _temporary_below(path)
    return found


def _remove(path: Path) -> None:
    """Delete a file or a folder; a symbolic link is removed, not followed."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)


def _has_files(path: Path) -> bool:
    if path.is_file():
        return True
    return path.is_dir() and any(p.is_file() for p in path.rglob("*"))

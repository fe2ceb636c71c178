"""Run directories: strict-JSON atomic writes, the files a run owns, the finished-run marker.

Every JSON file is strict JSON (``null`` for a missing or non-finite number, never ``NaN``) and
every file is written through a temporary file and a rename, with the user's umask.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import secrets
import shutil
from pathlib import Path
from typing import Any

import numpy as np

CONFIG = "config.json"
FINISHED = "finished.json"
#: What a run writes besides config.json and its top-level ``*.csv`` logs; ``clear_run_dir``
#: removes exactly these (a grid's ``train.log`` and the lock file stay).
RUN_OUTPUTS = ("checkpoints", "eval", "metrics.json", FINISHED)


class RunFolderError(Exception):
    """A run or grid folder cannot be used as asked: other settings, in use, unreadable."""


def to_jsonable(obj: Any) -> Any:
    """Dataclasses (nested), tuples, paths and numpy values as plain JSON values; NaN and
    infinities become None (``null``)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_jsonable(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
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


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: never half a file. The
    file gets the permissions of any new file (``0o666`` less the umask)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_json(path: Path, obj: Any) -> None:
    """``obj`` (see ``to_jsonable``) as strict, indented JSON."""
    write_atomic(path, json.dumps(to_jsonable(obj), indent=2, allow_nan=False) + "\n")


def read_json(path: Path) -> Any:
    """Parse a strict JSON file; an unreadable or invalid one is a ``RunFolderError`` naming it."""
    def reject(constant: str):
        raise ValueError(f"{constant} is not strict JSON")

    try:
        return json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=reject)
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise RunFolderError(f"{path}: unreadable or not valid JSON ({error})") from None


def point_dir(run_dir: Path, unit: str, point: int) -> Path:
    """``eval/<unit><N>`` folder of evaluation point N, e.g. ``eval/epoch0100``."""
    return Path(run_dir) / "eval" / f"{unit[:-1]}{point:04d}"


def is_finished(run_dir: Path) -> bool:
    return (Path(run_dir) / FINISHED).is_file()


def mark_finished(run_dir: Path, summary: dict) -> None:
    """Written last: its presence means every output of the run is complete."""
    write_json(Path(run_dir) / FINISHED, summary)


def run_outputs(run_dir: Path) -> list[str]:
    """Names of the run outputs present in ``run_dir`` (empty folders do not count)."""
    run_dir = Path(run_dir)
    found = [name for name in RUN_OUTPUTS if _has_files(run_dir / name)]
    return found + sorted(p.name for p in run_dir.glob("*.csv"))


def clear_run_dir(run_dir: Path) -> None:
    """Delete a run's config.json and outputs (``RUN_OUTPUTS`` and top-level ``*.csv``)."""
    run_dir = Path(run_dir)
    for path in [run_dir / CONFIG, *(run_dir / name for name in RUN_OUTPUTS),
                 *run_dir.glob("*.csv")]:
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def remove_temporary_files(run_dir: Path) -> list[Path]:
    """Delete the ``*.tmp`` files an interrupted ``write_atomic`` left; returns them."""
    leftovers = sorted(Path(run_dir).rglob("*.tmp"))
    for path in leftovers:
        path.unlink(missing_ok=True)
    return leftovers


def _has_files(path: Path) -> bool:
    if path.is_file():
        return True
    return path.is_dir() and any(p.is_file() for p in path.rglob("*"))

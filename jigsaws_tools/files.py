"""Reading a file a user names: a regular file only, refused at once otherwise.

A FIFO (named pipe), a socket or a device where a file is expected would block the read until
another process writes into it, or never end. ``read_regular`` opens the path without waiting for
a writer (``O_NONBLOCK``) and refuses anything but a regular file (symbolic links followed),
naming it: task definitions, recording formats and grid specs (``toml_files``), and every JSON
record of a run or grid (``rnn_seg.runs.folder.read_json``) are read through it; trial files are
checked before they are read (``release``).
"""
from __future__ import annotations

import os
import stat
from pathlib import Path

from .errors import JigsawsError


class NotRegularFileError(JigsawsError, ValueError):
    """A path to read is a FIFO, a socket or a device (``kind``), not a regular file."""

    def __init__(self, path: Path | str, kind: str):
        super().__init__(f"{path}: {kind}, not a regular file")
        self.path, self.kind = Path(path), kind


class FileTooLargeError(JigsawsError, ValueError):
    """A file to read holds more than the ``limit`` bytes its kind of file may."""

    def __init__(self, path: Path | str, limit: int):
        super().__init__(f"{path}: larger than {limit} bytes")
        self.path, self.limit = Path(path), limit


def read_regular(path: Path | str, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path``; ``NotRegularFileError`` naming it for a FIFO, a
    socket or a device (at once, without waiting for a writer), ``IsADirectoryError`` for a
    folder, the usual ``OSError`` for a missing or unreadable one, and ``FileTooLargeError``
    for one of more than ``limit`` bytes (None: any size), read no further."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        status = os.fstat(fd)
        if stat.S_ISDIR(status.st_mode):
            raise IsADirectoryError(21, "Is a directory", str(path))
        if not stat.S_ISREG(status.st_mode):
            raise NotRegularFileError(path, file_kind(status.st_mode))
        if limit is not None and status.st_size > limit:
            raise FileTooLargeError(path, limit)
        os.set_blocking(fd, True)
        data = f.read() if limit is None else f.read(limit + 1)
        if limit is not None and len(data) > limit:         # it grew while read
            raise FileTooLargeError(path, limit)
        return data


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` that is no regular file is, in words."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device"


def resolved(path: Path | str, error: type[ValueError] = ValueError) -> Path:
    """``path`` resolved (links, ``..``, relative), or an ``error`` naming it as given when it
    is in a loop of symbolic links (Python < 3.13 raises ``RuntimeError`` there, which
    ``cli.common.run_command`` words with the loop's absolute path instead)."""
    try:
        return Path(path).resolve()
    except RuntimeError:
        raise error(f"{path}: a loop of symbolic links, not a file or folder") from None

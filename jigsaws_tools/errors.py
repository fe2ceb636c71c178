"""Errors raised for missing or malformed JIGSAWS input, and for a write the disk refused."""
from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path

OBTAIN_HINT = (
    "JIGSAWS is distributed by the JHU CIRL lab after registration "
    "(https://cirl.lcsr.jhu.edu/research/hmm/datasets/jigsaws_release/). Point the tools at the "
    "task folder, which must contain kinematics/AllGestures/<Task>_<User><Trial>.txt, "
    "transcriptions/<Task>_<User><Trial>.txt and meta_file_<Task>.txt (e.g. Suturing_B001.txt); "
    "or run `jigsaws-tools synth --out DIR --task <Task>` to write a synthetic release in that "
    "layout."
)


class JigsawsError(Exception):
    """Base class of every data-layer error."""


class ReleaseNotFoundError(JigsawsError, FileNotFoundError):
    """The release folder, or a folder it must contain, does not exist. ``hint``: how to get
    one, on the same line (default: how to obtain JIGSAWS, a paragraph on a line of its own)."""

    def __init__(self, path: Path, what: str, hint: str = OBTAIN_HINT):
        super().__init__(f"{what} not found: {path}{chr(10) if hint == OBTAIN_HINT else '; '}"
                         f"{hint}")
        self.path = Path(path)


class FormatError(JigsawsError, ValueError):
    """A malformed line in a release file; names the file, the 1-based line and the value."""

    def __init__(self, path: Path | str, line: int | None, value: object, problem: str):
        where = f"{path}:{line}" if line is not None else f"{path}"
        super().__init__(f"{where}: {problem} (value: {value!r})")
        self.path = Path(path)
        self.line = line
        self.value = value
        self.problem = problem


class DefinitionError(JigsawsError, ValueError):
    """A task definition breaks the format; names the file (when there is one), the key and the
    value. A problem of the file as a whole (no key, no value: missing, not TOML) names the file
    only."""

    def __init__(self, path: Path | str, key: str | None, value: object, problem: str):
        where = ": ".join(str(part) for part in (path or "task definition", key) if part)
        whole_file = key is None and value is None
        super().__init__(f"{where}: {problem}" + ("" if whole_file else f" (value: {value!r})"))
        self.path = str(path)
        self.key = key
        self.value = value
        self.problem = problem


#: ``errno`` of a write refused for lack of space: a full disk, a quota, a file size limit.
NO_SPACE = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


#: What a training run's ``WriteFailed`` adds to its advice.
RESUMES = "a run resumes from its last complete checkpoint"


class WriteFailed(RuntimeError):
    """A file could not be written for lack of space (``NO_SPACE``): names the file, the reason
    and the space left. Not the user's input: commands report it as a failure (exit 1). What was
    written before stays (a command's published outputs are whole: ``rnn_seg.runs.publish``)."""

    def __init__(self, path: Path | str, reason: str, what: str = "", then: str = ""):
        """``what`` the file is, named before its path (e.g. ``"checkpoint"``); ``then``: what
        running the command again does (e.g. ``RESUMES``)."""
        folder = next((p for p in (Path(path), *Path(path).parents) if p.is_dir()), Path("."))
        free = shutil.disk_usage(folder).free / 1e6
        named = f"{what} {path}" if what else str(path)
        super().__init__(f"cannot write {named} ({reason}); {free:.0f} MB free on its file "
                         "system. Make room and run the same command again"
                         + (f" ({then})" if then else ""))

    @classmethod
    def from_os_error(cls, error: OSError, path: Path | str | None = None
                      ) -> WriteFailed | None:
        """The failure an ``OSError`` stands for when it is a lack of space, else None; it names
        ``path`` (the file being written), else the error's file."""
        if error.errno not in NO_SPACE:
            return None
        return cls(path or error.filename or "a file", error.strerror or str(error))

    @classmethod
    def from_message(cls, path: Path | str, message: str, what: str = "", then: str = ""
                     ) -> WriteFailed | None:
        """The failure to write ``path`` that another library's error ``message`` stands for
        when it names a lack of space (TensorFlow's errors carry the system's reason in their
        text: "...; No space left on device"), else None."""
        reason = message.strip().splitlines()[0] if message.strip() else message
        if not any(os.strerror(code) in message for code in NO_SPACE):
            return None
        return cls(path, reason, what, then)

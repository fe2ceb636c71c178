"""Errors raised for missing or malformed JIGSAWS input."""
from __future__ import annotations

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
    """The release folder, or a folder it must contain, does not exist."""

    def __init__(self, path: Path, what: str):
        super().__init__(f"{what} not found: {path}\n{OBTAIN_HINT}")
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
    value."""

    def __init__(self, path: Path | str, key: str | None, value: object, problem: str):
        where = ": ".join(str(part) for part in (path or "task definition", key) if part)
        super().__init__(f"{where}: {problem} (value: {value!r})")
        self.path = str(path)
        self.key = key
        self.value = value
        self.problem = problem

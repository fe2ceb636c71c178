"""Errors raised for missing or malformed JIGSAWS input."""
from __future__ import annotations

from pathlib import Path

OBTAIN_HINT = (
    "JIGSAWS is distributed by the JHU CIRL lab after registration "
    "(https://cirl.lcsr.jhu.edu/research/hmm/datasets/jigsaws_release/). Point the tools at the "
    "task folder, which must contain kinematics/AllGestures/Suturing_<User><Trial>.txt, "
    "transcriptions/Suturing_<User><Trial>.txt and meta_file_Suturing.txt; or run "
    "`jigsaws-tools synth --out DIR` to write a synthetic release in that layout."
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

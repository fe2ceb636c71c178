"""A recording format as data: which columns of a recording file hold the model's input features,
at what sample rate, and how the files of a data folder are named.

The JIGSAWS release is one format (``data/formats/jigsaws.toml``, the default everywhere); a user
describes another layout (a dVRK, another robot, a simulator) with ``--format my_robot.toml``.
Every key, checked by ``read_format_file``::

    name = "my_robot"               # letters, digits, '_' or '-'
    summary = "..."                 # optional, one line
    rate_hz = 100                   # samples per second of every recording (any positive number;
                                    # the model's rate must divide it: jigsaws_tools.preprocessing
                                    # .decimation)
    delimiter = ","                 # "whitespace" (runs of spaces / tabs), ",", ";" or "\\t"
    header = true                   # the first non-blank line names the columns
    columns = ["t", "x", ...]       # header = false only (and then required): every column in order
    time_column = "t"               # optional: a column of times in seconds, checked against
                                    # rate_hz at every row: increasing, no step over 2.5 sample
                                    # periods, no time farther than 2.5 periods and 1 % from its
                                    # row's (release.GAP_PERIODS, DRIFT_TOLERANCE); never a model
                                    # input

    [features]                      # optional: model feature (jigsaws_tools.features
    psm1_pos_x = "PSM1_x"           # .FEATURE_NAMES) -> the column holding it; a feature not
                                    # listed is read from the column of its own name; no two
                                    # features share a column, none reads the time column

    [files]                         # optional: a training / evaluation data folder's layout
    recordings = "kinematics/AllGestures"   # folder of the recordings, inside the data folder
    transcriptions = "transcriptions"       # folder of their "start end gesture" lines (.txt);
                                            # start and end are 1-based rows of the recording
    trial = "{task}_{user}{trial:03d}"      # a trial's file name without its extension:
                                            # {task} the task's name, {user} one upper-case
                                            # letter A-Z (a lower-case one is refused: c and C
                                            # would be two users), {trial} a number
                                            # ({trial:03d}: exactly 3 digits)
    extension = ".txt"                      # of the recordings

A recording's rows, every non-blank line after the header (no comment lines: a line starting with
``#`` is refused), are its samples at ``rate_hz``; transcriptions count the same rows.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from .errors import DefinitionError
from .features import FEATURE_NAMES
from .task_definition import TaskDefinition
from .toml_files import builtin_path, find_definition, known_keys, read_definition, table, typed

#: The release's format, the default wherever a format can be omitted.
DEFAULT_FORMAT = "jigsaws"
#: ``delimiter`` value -> the separator ``str.split`` / ``numpy.loadtxt`` take (None: whitespace).
DELIMITERS: dict[str, str | None] = {"whitespace": None, ",": ",", ";": ";", "\t": "\t"}
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
_PLACEHOLDER = re.compile(r"\{(task|user|trial(?::0(\d)d)?)\}")


@dataclass(frozen=True)
class RecordingFormat:
    """A recording layout (see the module docstring). Construction checks every invariant
    (``DefinitionError`` naming the key and the value)."""

    name: str
    rate_hz: float
    delimiter: str = "whitespace"
    header: bool = False
    columns: tuple[str, ...] = ()               # header = false: the file's columns in order
    time_column: str = ""
    features: tuple[tuple[str, str], ...] = ()  # (model feature, column) where they differ
    recordings: str = "kinematics/AllGestures"
    transcriptions: str = "transcriptions"
    trial: str = "{task}_{user}{trial:03d}"
    extension: str = ".txt"
    summary: str = ""

    def __post_init__(self):
        _check_format(self)

    @property
    def separator(self) -> str | None:
        """The field separator for ``str.split`` / ``numpy.loadtxt`` (None: whitespace)."""
        return DELIMITERS[self.delimiter]

    def column_of(self, feature: str) -> str:
        """The name of the column that holds model feature ``feature``."""
        return dict(self.features).get(feature, feature)

    def trial_pattern(self, task: TaskDefinition) -> re.Pattern:
        """A trial's file name without extension, with groups ``user`` and ``trial``; case
        matters, but ``user`` takes a letter of either case so that a lower-case one can be
        refused by name (``release.discover``)."""
        parts, end = [], 0
        for match in _PLACEHOLDER.finditer(self.trial):
            parts.append(re.escape(self.trial[end:match.start()]))
            key, digits = match.group(1).split(":")[0], match.group(2)
            parts.append(re.escape(task.name) if key == "task" else "(?P<user>[A-Za-z])"
                         if key == "user" else rf"(?P<trial>\d{{{digits}}})" if digits
                         else r"(?P<trial>\d+)")
            end = match.end()
        parts.append(re.escape(self.trial[end:]))
        return re.compile("".join(parts))

    def trial_prefix(self, task: TaskDefinition) -> str:
        """The literal start of every trial's file name (``"Suturing_"``), case-sensitive."""
        return self.trial.split("{user}")[0].split("{trial")[0].replace("{task}", task.name)

    def trial_name(self, task: TaskDefinition, user: str, trial: int) -> str:
        """A trial's file name without extension, e.g. ``("B", 1) -> "Suturing_B001"``."""
        return self.trial.format(task=task.name, user=user, trial=trial)

    @property
    def is_default(self) -> bool:
        """This is the JIGSAWS release's format (``JIGSAWS_FORMAT``)."""
        return self == JIGSAWS_FORMAT


def another_layout_hint() -> str:
    """The advice that ends an error about a folder or a recording read in the release's layout
    that holds something else (docs/DATA.md, "Your own recordings", shows a format file): to give
    ``--format``. A command that takes no ``--format`` replaces it with its own advice
    (``jigsaws_tools.cli.common.run_command``'s ``layout_advice``, e.g. ``RELEASE_LAYOUT_ONLY``)."""
    return ("recordings of another layout need --format FILE.toml (docs/DATA.md, 'Your own "
            "recordings')")


#: The advice of a command that reads the release's layout only (``another_layout_hint``).
RELEASE_LAYOUT_ONLY = ("this command reads the JIGSAWS release's layout only (recordings of "
                       "another layout: docs/DATA.md, 'Your own recordings')")


def load_format(recording_format: str | Path | RecordingFormat | None) -> RecordingFormat:
    """A built-in format by name, a format file by path (``*.toml``), ``recording_format`` itself,
    or the default (JIGSAWS) for None."""
    if recording_format is None:
        return JIGSAWS_FORMAT
    if isinstance(recording_format, RecordingFormat):
        return recording_format
    return find_definition(recording_format, "formats", "recording format", read_format_file)


def read_format_file(path: Path | str) -> RecordingFormat:
    """Parse and check a recording format file; errors name the file, the key and the value."""
    return read_definition(path, "recording format", _format_from_toml)


def _format_from_toml(raw: dict) -> RecordingFormat:
    known_keys(raw, "", ("name", "summary", "rate_hz", "delimiter", "header", "columns",
                          "time_column", "features", "files"), required=("name", "rate_hz"))
    rate = typed(raw["rate_hz"], "rate_hz", (int, float), "a number of samples per second")
    columns = typed(raw.get("columns", []), "columns", list, "a list of column names")
    features = table(raw.get("features", {}), "features")
    files = table(raw.get("files", {}), "files")
    known_keys(files, "files", ("recordings", "transcriptions", "trial", "extension"),
                required=())
    defaults = RecordingFormat.__dataclass_fields__
    return RecordingFormat(
        name=typed(raw["name"], "name", str, "a string"),
        rate_hz=float(rate),
        delimiter=typed(raw.get("delimiter", "whitespace"), "delimiter", str,
                         f"one of {', '.join(map(repr, DELIMITERS))}"),
        header=typed(raw.get("header", False), "header", bool, "true or false"),
        columns=tuple(typed(c, "columns", str, "a list of column names") for c in columns),
        time_column=typed(raw.get("time_column", ""), "time_column", str, "a column name"),
        features=tuple((f, typed(c, f"features.{f}", str, "a column name"))
                       for f, c in features.items()),
        **{key: typed(files.get(key, defaults[key].default), f"files.{key}", str, "a string")
           for key in ("recordings", "transcriptions", "trial", "extension")},
        summary=typed(raw.get("summary", ""), "summary", str, "a string"))


def _check_format(fmt: RecordingFormat) -> None:
    """Raise ``DefinitionError`` (key, value, problem) at the first broken invariant."""
    if not _NAME.match(fmt.name):
        raise DefinitionError("", "name", fmt.name, "a format name is letters, digits, '_' or '-'")
    if not (math.isfinite(fmt.rate_hz) and fmt.rate_hz > 0):
        raise DefinitionError("", "rate_hz", fmt.rate_hz, "expected a positive finite number")
    if fmt.delimiter not in DELIMITERS:
        raise DefinitionError("", "delimiter", fmt.delimiter,
                              f"expected one of {', '.join(map(repr, DELIMITERS))}")
    if fmt.header and fmt.columns:
        raise DefinitionError("", "columns", list(fmt.columns), "with header = true the file's "
                              "first line names the columns; leave columns out")
    if not fmt.header and not fmt.columns:
        raise DefinitionError("", "columns", None, "with header = false, list every column of "
                              "the file in order")
    if len(set(fmt.columns)) != len(fmt.columns):
        raise DefinitionError("", "columns", list(fmt.columns), "column names must be unique")
    if fmt.columns and fmt.time_column and fmt.time_column not in fmt.columns:
        raise DefinitionError("", "time_column", fmt.time_column, "not one of columns")
    for feature, column in fmt.features:
        if feature not in FEATURE_NAMES:
            raise DefinitionError("", f"features.{feature}", column, "not a model feature (one "
                                  "of jigsaws_tools.features.FEATURE_NAMES, e.g. psm1_pos_x)")
    check_feature_columns(fmt, [feature for feature, _ in fmt.features])
    for key, value in (("files.recordings", fmt.recordings),
                       ("files.transcriptions", fmt.transcriptions)):
        if not value or Path(value).is_absolute() or ".." in Path(value).parts:
            raise DefinitionError("", key, value, "expected a folder inside the data folder")
    placeholders = [m.group(1).split(":")[0] for m in _PLACEHOLDER.finditer(fmt.trial)]
    if sorted(placeholders) != ["task", "trial", "user"] or re.sub(_PLACEHOLDER, "", fmt.trial
                                                                  ).count("{"):
        raise DefinitionError("", "files.trial", fmt.trial, "expected {task}, {user} and {trial} "
                              "(or {trial:0Nd}) once each, and no other {...}")
    if not re.fullmatch(r"\.[A-Za-z0-9]+", fmt.extension):
        raise DefinitionError("", "files.extension", fmt.extension, "expected e.g. '.csv'")


def check_feature_columns(fmt: RecordingFormat, features: Iterable[str], where: str = ""
                          ) -> None:
    """Each of ``features`` reads a column of its own (the one ``[features]`` maps it to, else the
    column of its own name), never the time column; else a ``DefinitionError`` naming ``where``,
    both keys and the column (two features reading one column would feed the model one signal
    twice). The format's own check applies it to the features it lists; a run's data check
    (``dataset.check_format_fits``) to the features it reads, as a listed feature may take the
    column of an unlisted one that only some feature sets read."""
    listed = dict(fmt.features)
    reader: dict[str, str] = {}
    for feature in sorted(features, key=lambda f: f in listed):   # an error names a listed key
        column = fmt.column_of(feature)
        key = f"features.{feature}" if feature in listed else (f"{feature} (not in [features]: "
                                                                f"its own name)")
        if fmt.time_column and column == fmt.time_column:
            raise DefinitionError(where, key, column, "the format's time_column, checked against "
                                  "rate_hz and never a model input")
        if column in reader:
            raise DefinitionError(where, key, column, f"also the column of {reader[column]}: "
                                  f"each feature needs a column of its own")
        reader[column] = key


#: The JIGSAWS release's format, read from its shipped file.
JIGSAWS_FORMAT = read_format_file(builtin_path("formats", DEFAULT_FORMAT))

"""Per-trial training sequences at 5 Hz, LOUO splits, and a standardized on-disk cache.

The cache is an optimisation only: an ``.npz`` of plain arrays plus a ``.json`` of metadata (no
pickle), keyed by ``cache_key``, a hash of every option that shapes the sequences and of the bytes
of every release file read, so a changed option or file never reuses a stale entry. An entry is
verified when read (its key, the arrays' checksum, their lengths); a damaged one is rebuilt with one
warning, and a cache folder that cannot be written is one warning and no cache.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import os
import tempfile
import zipfile
import zlib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar, Sequence

import numpy as np

from .annotations import amendment_table_text, apply_amendments, check_version
from .errors import DefinitionError, JigsawsError
from .features import DEFAULT_FEATURE_SET, feature_names
from .messages import cache_unwritable, data_logger
from .preprocessing import PreprocessConfig, decimation, preprocess
from .progress import progress_labels
from .recording_format import (JIGSAWS_FORMAT, RecordingFormat, check_feature_columns,
                               load_format)
from .release import (ReleaseIndex, TrialFiles, discover, frame_labels, meta_path, read_meta,
                      read_recording, read_transcription)
from .task_definition import PAPER_TASK, SUTURING, TaskDefinition, load_task

CACHE_FORMAT = 2
JIGSAWS_ENV = "JIGSAWS_DIR"
CACHE_ENV = "JIGSAWS_CACHE_DIR"

log = data_logger(__name__)


@dataclass(frozen=True)
class DataConfig:
    """Which release, which inputs, which labels, of which task, in which recording format.

    ``task`` accepts a built-in task's name or a definition file's path too, and holds the
    definition itself after construction (so ``config.json`` records the vocabulary and grammar);
    so does ``recording_format`` (a built-in format's name, a format file's path, or None for the
    release's).
    """

    #: Left out of the settings a run folder is checked against (``rnn_seg.runs.settings``): where
    #: the release is, not what it holds, which the run's data fingerprint (``cache_key``) hashes. A
    #: run resumes with its release reached by another path (relative, moved, a node's local copy).
    output_fields: ClassVar[tuple[str, ...]] = ("data_dir", "data_dir_as_given")
    #: Not recorded (config.json, settings, fingerprint) while they hold their default, so runs
    #: written before the field existed keep their settings and fingerprint.
    unrecorded_defaults: ClassVar[tuple[str, ...]] = ("recording_format", "data_dir_as_given")

    #: The release folder: absolute in the runs this version trains (``with_resolved_data_dir``),
    #: so that every command reading a run finds it from any working directory; a run of an
    #: earlier version may record it relative, as it was typed (``run_record.recorded_data_dir``).
    #: A ``Path`` given is kept as its string.
    data_dir: str
    feature_set: str = DEFAULT_FEATURE_SET
    annotations: str = "revised"
    preprocessing: PreprocessConfig = field(default_factory=PreprocessConfig)
    task: TaskDefinition = SUTURING
    recording_format: RecordingFormat = JIGSAWS_FORMAT
    #: ``data_dir`` as the user typed it (e.g. ``../shared/jigsaws/Suturing``), when it was
    #: resolved; "" when ``data_dir`` is as given.
    data_dir_as_given: str = ""

    def __post_init__(self):
        object.__setattr__(self, "data_dir", os.fsdecode(self.data_dir))   # a Path is taken too
        check_version(self.annotations)
        object.__setattr__(self, "task", load_task(self.task))
        object.__setattr__(self, "recording_format", load_format(self.recording_format))
        check_format_fits(self.recording_format, self.feature_set, self.preprocessing)

    @property
    def features(self) -> tuple[str, ...]:
        """The model's input features, in order (``jigsaws_tools.features.feature_names``)."""
        return feature_names(self.feature_set)

    def with_resolved_data_dir(self) -> DataConfig:
        """This configuration with ``data_dir`` absolute (resolved against the working
        directory) and, when that changed it, the path as given in ``data_dir_as_given``."""
        resolved = str(Path(self.data_dir).resolve())
        if resolved == self.data_dir:
            return self
        return replace(self, data_dir=resolved,
                       data_dir_as_given=self.data_dir_as_given or self.data_dir)


def check_format_fits(recording_format: RecordingFormat, feature_set: str,
                      preprocessing: PreprocessConfig, where: str = "") -> None:
    """Raise ``DefinitionError`` (naming ``where``, default the format's name, its key and value)
    unless recordings in ``recording_format`` can give ``feature_set``'s features at the model's
    rate: its rate is a whole multiple of the model's (``decimation``), without a header its
    columns hold every feature, and each feature reads a column of its own
    (``check_feature_columns``)."""
    fmt = recording_format
    where = where or f"recording format {fmt.name}"
    try:
        decimation(preprocessing, fmt.rate_hz)
    except ValueError as error:
        raise DefinitionError(where, "rate_hz", fmt.rate_hz, str(error)) from None
    for feature in feature_names(feature_set):
        if not fmt.header and fmt.column_of(feature) not in fmt.columns:
            raise DefinitionError(where, "columns",
                                  fmt.column_of(feature),
                                  f"no column holds feature {feature} of feature set "
                                  f"{feature_set} (map it in [features])")
    check_feature_columns(fmt, feature_names(feature_set), where)


@dataclass(frozen=True)
class Trial:
    """One demonstration after preprocessing (``T`` samples at ``sample_hz``, 5 Hz by default).

    inputs ``[T, F]`` float32; gestures ``[T]`` int64 class ``0..num_gestures-1`` of the task;
    progress ``[T]`` int64 stage ``0..num_stages-1``; frames ``[T]`` int64 1-based frame (row of
    the recording: 30 Hz in the release, else the format's rate) each sample came from.
    """

    name: str
    user: str
    trial: int
    skill: str
    inputs: np.ndarray
    gestures: np.ndarray
    progress: np.ndarray
    frames: np.ndarray

    def __len__(self) -> int:
        return len(self.inputs)


@dataclass(frozen=True)
class Dataset:
    """All trials of one configuration, sorted by name, and their data fingerprint
    (``cache_key``: the options and the bytes of every file they were read from)."""

    config: DataConfig
    trials: tuple[Trial, ...]
    fingerprint: str

    @property
    def users(self) -> tuple[str, ...]:
        return tuple(sorted({t.user for t in self.trials}))

    @property
    def num_features(self) -> int:
        return self.trials[0].inputs.shape[1]

    def louo_split(self, test_user: str, held_out: Sequence[str] = ()
                   ) -> tuple[list[Trial], list[Trial]]:
        """Leave-one-user-out: ``(train trials, test trials)``, ``test_user``'s trials held out;
        the trials of the users in ``held_out`` are in neither (a validation run inside an outer
        fold's training users)."""
        for user in (test_user, *held_out):
            if user not in self.users:
                raise JigsawsError(f"unknown {'test' if user == test_user else 'held-out'} user "
                                   f"{user!r}; users are {', '.join(self.users)}")
        if len(self.users) < 2:
            raise JigsawsError(f"{self.config.data_dir}: only user {test_user} has complete "
                               f"{self.config.task.name} trials; leave-one-user-out needs at "
                               f"least two users")
        train = [t for t in self.trials if t.user != test_user and t.user not in held_out]
        if not train:
            raise JigsawsError(f"no training user left: {test_user} tested, "
                               f"{', '.join(held_out)} held out")
        test = [t for t in self.trials if t.user == test_user]
        return train, test


def default_data_dir(task_name: str = PAPER_TASK) -> Path:
    """The release folder of a task: ``$JIGSAWS_DIR`` (the Suturing folder) for Suturing, the
    folder named after the task beside it for another task; without ``$JIGSAWS_DIR``,
    ``../shared/jigsaws/<task_name>`` relative to the project."""
    if os.environ.get(JIGSAWS_ENV):
        path = Path(os.environ[JIGSAWS_ENV])
        return path if task_name in (PAPER_TASK, path.name) else path.parent / task_name
    return Path(__file__).resolve().parents[2] / "shared" / "jigsaws" / task_name


def default_cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "mtrnn-jigsaws")


def load_trial(files: TrialFiles, skill: str, config: DataConfig) -> Trial:
    """Read, relabel, derive progress and preprocess one trial of ``config.task``.

    Args:
        files: the trial's kinematics and transcription files (``discover``).
        skill: the user's self-proclaimed skill level from the meta file (E, I, N; ``"?"`` if
            absent).
        config: release, features, annotation version, preprocessing and task.

    Returns:
        The trial's samples at ``config.preprocessing.sample_hz`` (5 Hz by default).
    """
    task = config.task
    kinematics = read_recording(files.kinematics, config.recording_format, config.features)
    segments = read_transcription(files.transcription, len(kinematics), task)
    gestures, _ = apply_amendments(files.name, frame_labels(segments, len(kinematics), task),
                                   config.annotations, task, config.recording_format.rate_hz)
    labels = np.stack([gestures, progress_labels(gestures, task)], axis=1)
    try:
        inputs, labels, frames = preprocess(kinematics, labels, config.preprocessing,
                                            config.recording_format.rate_hz)
    except ValueError as error:                 # e.g. too short for the low-pass filter
        raise JigsawsError(f"{files.kinematics}: trial {files.name}: {error}") from None
    return Trial(files.name, files.user, files.trial, skill, inputs,
                 labels[:, 0], labels[:, 1], frames)


def load_dataset(config: DataConfig, cache_dir: Path | str | None = None,
                 use_cache: bool = True) -> Dataset:
    """Load every complete trial of ``config.task`` in ``config.data_dir``, from the cache when
    it holds a verified entry for the files' current content.

    Args:
        config: release, features, annotation version, preprocessing and task.
        cache_dir: the cache folder; None = ``$JIGSAWS_CACHE_DIR`` or ``~/.cache/mtrnn-jigsaws``.
        use_cache: read and write the cache; False = always read the release, write nothing.
    """
    index = discover(config.data_dir, config.task, config.recording_format)
    cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = cache_key(config, index)
    if use_cache:
        cached = _read_cache(cache_dir, key, config)
        if cached is not None:
            return cached
    meta_file = meta_path(config.data_dir, config.task)
    meta = read_meta(meta_file) if meta_file.is_file() else {}
    trials = tuple(load_trial(f, meta[f.name].skill if f.name in meta else "?", config)
                   for f in index.trials)
    dataset = Dataset(config, trials, key)
    if use_cache:
        _write_cache(cache_dir, key, dataset)
    return dataset


def cache_key(config: DataConfig, index: ReleaseIndex) -> str:
    """The data fingerprint of ``config``: a hash of every option that shapes the sequences (task
    definition, features, preprocessing, annotation version and its amendment table) and of the
    names and bytes of every file read. The folder's location is not part of it: an identical copy
    elsewhere has the same fingerprint."""
    paths = [p for t in index.trials for p in (t.kinematics, t.transcription)]
    if meta_path(index.root, config.task).is_file():
        paths.append(meta_path(index.root, config.task))
    files = [(p.relative_to(index.root).as_posix(), _file_digest(p)) for p in paths]
    options = {k: v for k, v in asdict(config).items()
               if k not in config.output_fields and not holds_unrecorded_default(config, k)}
    payload = json.dumps({"format": CACHE_FORMAT, "config": options,
                          "amendments": amendment_table_text(config.annotations, config.task),
                          "files": files}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:24]


def data_fingerprint(config: DataConfig) -> str:
    """``cache_key`` of ``config`` over the release it names (read now, its incomplete trials
    not reported again): what a run records as its ``data_fingerprint``."""
    release_log = logging.getLogger("jigsaws_tools.release")
    level = release_log.level
    release_log.setLevel(logging.ERROR)
    try:
        return cache_key(config, discover(config.data_dir, config.task, config.recording_format))
    finally:
        release_log.setLevel(level)


def holds_unrecorded_default(obj: Any, name: str) -> bool:
    """Field ``name`` of dataclass ``obj`` is one its class lists in ``unrecorded_defaults`` (as
    ``DataConfig`` does) and holds its default: records (config.json, settings, the data
    fingerprint) leave it out, so records written before the field existed stay the same."""
    if name not in getattr(type(obj), "unrecorded_defaults", ()):
        return False
    declared = type(obj).__dataclass_fields__[name]
    default = (declared.default_factory() if declared.default_factory is not dataclasses.MISSING
               else declared.default)
    return getattr(obj, name) == default


def _file_digest(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


_ARRAYS = ("inputs", "gestures", "progress", "frames")
#: What a damaged cache entry can raise while it is read and checked.
_UNREADABLE = (OSError, ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile, zlib.error)


def _write_cache(cache_dir: Path, key: str, dataset: Dataset) -> None:
    """Write ``key.npz`` then ``key.json`` atomically; the JSON's presence marks completion and
    holds the arrays' checksum. A cache folder that cannot be written is one warning, no error."""
    arrays = {name: np.concatenate([getattr(t, name) for t in dataset.trials]) for name in _ARRAYS}
    arrays["lengths"] = np.array([len(t) for t in dataset.trials], dtype=np.int64)
    npz_path = cache_dir / f"{key}.npz"
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        _atomic_write(npz_path, lambda f: np.savez(f, **arrays))
        meta = {"format": CACHE_FORMAT, "key": key, "npz_sha256": _file_digest(npz_path),
                "config": asdict(dataset.config),
                "trials": [{"name": t.name, "user": t.user, "trial": t.trial, "skill": t.skill}
                           for t in dataset.trials]}
        _atomic_write(cache_dir / f"{key}.json",
                      lambda f: f.write(json.dumps(meta, indent=1).encode()))
    except OSError as error:
        cache_unwritable(cache_dir, error, "continuing without it")


def _atomic_write(path: Path, write) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def _read_cache(cache_dir: Path, key: str, config: DataConfig) -> Dataset | None:
    """The cached dataset of ``key``, or None when there is none or it fails its checks (one
    warning naming the damaged file; the caller rebuilds it)."""
    json_path, npz_path = cache_dir / f"{key}.json", cache_dir / f"{key}.npz"
    if not json_path.is_file():
        return None                     # never written, or interrupted before completion
    reading = json_path
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
        if meta["format"] != CACHE_FORMAT or meta["key"] != key:
            raise ValueError(f"written for format {meta['format']}, key {meta['key']}")
        reading = npz_path
        if _file_digest(npz_path) != meta["npz_sha256"]:
            raise ValueError("arrays differ from the checksum recorded in "
                             f"{json_path.name}")
        with np.load(npz_path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in (*_ARRAYS, "lengths")}
        trials = _split_trials(arrays, meta["trials"])
    except _UNREADABLE as error:
        detail = " ".join(str(error).split()) or type(error).__name__
        log.warning("%s: damaged dataset cache entry (%s); rebuilding it", reading, detail)
        return None
    return Dataset(config, trials, key)


def _split_trials(arrays: dict[str, np.ndarray], meta: list[dict]) -> tuple[Trial, ...]:
    """Cut the concatenated arrays back into trials, checking that their lengths agree."""
    lengths = arrays["lengths"]
    if len(lengths) != len(meta) or any(len(arrays[n]) != lengths.sum() for n in _ARRAYS):
        raise ValueError(f"{len(meta)} trials listed, {len(lengths)} lengths summing to "
                         f"{lengths.sum()}, arrays of {[len(arrays[n]) for n in _ARRAYS]} rows")
    bounds = np.concatenate([[0], np.cumsum(lengths)])
    return tuple(
        Trial(m["name"], m["user"], m["trial"], m["skill"],
              *(arrays[name][bounds[i]:bounds[i + 1]] for name in _ARRAYS))
        for i, m in enumerate(meta))

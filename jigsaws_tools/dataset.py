"""Per-trial training sequences at 5 Hz, LOUO splits, and a standardized on-disk cache.

The cache is an ``.npz`` of plain arrays plus a ``.json`` of metadata (no pickle), keyed by a hash
of every option that shapes the sequences (features, preprocessing, annotation version and its
amendment table) and of the release files' names, sizes and modification times, so a changed
option or file never reuses a stale cache.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .annotations import amendment_table_text, apply_amendments, check_version
from .errors import JigsawsError
from .features import DEFAULT_FEATURE_SET, feature_columns
from .preprocessing import PreprocessConfig, preprocess
from .progress import progress_labels
from .release import (ReleaseIndex, TrialFiles, discover, frame_labels, meta_path, read_kinematics,
                      read_meta, read_transcription)

CACHE_FORMAT = 1
JIGSAWS_ENV = "JIGSAWS_DIR"
CACHE_ENV = "JIGSAWS_CACHE_DIR"


@dataclass(frozen=True)
class DataConfig:
    """Which release, which inputs, which labels."""

    data_dir: str
    feature_set: str = DEFAULT_FEATURE_SET
    annotations: str = "revised"
    preprocessing: PreprocessConfig = field(default_factory=PreprocessConfig)

    def __post_init__(self):
        check_version(self.annotations)
        feature_columns(self.feature_set)


@dataclass(frozen=True)
class Trial:
    """One demonstration after preprocessing (``T`` samples at ``sample_hz``, 5 Hz by default).

    inputs ``[T, F]`` float32; gestures ``[T]`` int64 class 0-9; progress ``[T]`` int64 stage 0-4;
    frames ``[T]`` int64 1-based 30 Hz frame each sample came from.
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
    """All trials of one configuration, sorted by name."""

    config: DataConfig
    trials: tuple[Trial, ...]

    @property
    def users(self) -> tuple[str, ...]:
        return tuple(sorted({t.user for t in self.trials}))

    @property
    def num_features(self) -> int:
        return self.trials[0].inputs.shape[1]

    def louo_split(self, test_user: str) -> tuple[list[Trial], list[Trial]]:
        """Leave-one-user-out: ``(train trials, test trials)`` with ``test_user``'s trials held out."""
        if test_user not in self.users:
            raise JigsawsError(f"unknown test user {test_user!r}; users are {', '.join(self.users)}")
        train = [t for t in self.trials if t.user != test_user]
        test = [t for t in self.trials if t.user == test_user]
        return train, test


def default_data_dir() -> Path:
    """``$JIGSAWS_DIR`` if set, else ``../shared/jigsaws/Suturing`` relative to the project."""
    if os.environ.get(JIGSAWS_ENV):
        return Path(os.environ[JIGSAWS_ENV])
    return Path(__file__).resolve().parents[2] / "shared" / "jigsaws" / "Suturing"


def default_cache_dir() -> Path:
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "mtrnn-jigsaws")


def load_trial(files: TrialFiles, skill: str, config: DataConfig) -> Trial:
    """Read, relabel, derive progress and preprocess one trial."""
    kinematics = read_kinematics(files.kinematics)
    segments = read_transcription(files.transcription, n_frames=len(kinematics))
    gestures, _ = apply_amendments(files.name, frame_labels(segments, len(kinematics)),
                                   config.annotations)
    labels = np.stack([gestures, progress_labels(gestures)], axis=1)
    inputs, labels, frames = preprocess(kinematics[:, feature_columns(config.feature_set)],
                                        labels, config.preprocessing)
    return Trial(files.name, files.user, files.trial, skill, inputs,
                 labels[:, 0], labels[:, 1], frames)


def load_dataset(config: DataConfig, cache_dir: Path | str | None = None,
                 use_cache: bool = True) -> Dataset:
    """Load every complete trial of ``config.data_dir``, from the cache when it is current."""
    index = discover(config.data_dir)
    cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    key = cache_key(config, index)
    if use_cache:
        cached = _read_cache(cache_dir, key, config)
        if cached is not None:
            return cached
    meta = read_meta(meta_path(config.data_dir)) if meta_path(config.data_dir).is_file() else {}
    trials = tuple(load_trial(f, meta[f.name].skill if f.name in meta else "?", config)
                   for f in index.trials)
    dataset = Dataset(config, trials)
    if use_cache:
        _write_cache(cache_dir, key, dataset)
    return dataset


def cache_key(config: DataConfig, index: ReleaseIndex) -> str:
    """Hash of every option that shapes the sequences and of the release files' fingerprints."""
    paths = [p for t in index.trials for p in (t.kinematics, t.transcription)]
    if meta_path(index.root).is_file():
        paths.append(meta_path(index.root))
    fingerprint = [(str(p.resolve()), p.stat().st_size, p.stat().st_mtime_ns) for p in paths]
    payload = json.dumps({"format": CACHE_FORMAT, "config": asdict(config),
                          "amendments": amendment_table_text(config.annotations),
                          "files": fingerprint}, sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()[:24]


_ARRAYS = ("inputs", "gestures", "progress", "frames")


def _write_cache(cache_dir: Path, key: str, dataset: Dataset) -> None:
    """Write ``key.npz`` then ``key.json`` atomically; the JSON's presence marks completion."""
    cache_dir.mkdir(parents=True, exist_ok=True)
    arrays = {name: np.concatenate([getattr(t, name) for t in dataset.trials]) for name in _ARRAYS}
    arrays["lengths"] = np.array([len(t) for t in dataset.trials], dtype=np.int64)
    meta = {"format": CACHE_FORMAT, "config": asdict(dataset.config),
            "trials": [{"name": t.name, "user": t.user, "trial": t.trial, "skill": t.skill}
                       for t in dataset.trials]}
    _atomic_write(cache_dir / f"{key}.npz", lambda f: np.savez(f, **arrays))
    _atomic_write(cache_dir / f"{key}.json", lambda f: f.write(json.dumps(meta, indent=1).encode()))


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
    json_path, npz_path = cache_dir / f"{key}.json", cache_dir / f"{key}.npz"
    if not (json_path.is_file() and npz_path.is_file()):
        return None
    meta = json.loads(json_path.read_text())
    with np.load(npz_path, allow_pickle=False) as npz:
        arrays = {name: npz[name] for name in (*_ARRAYS, "lengths")}
    bounds = np.concatenate([[0], np.cumsum(arrays["lengths"])])
    trials = tuple(
        Trial(m["name"], m["user"], m["trial"], m["skill"],
              *(arrays[name][bounds[i]:bounds[i + 1]] for name in _ARRAYS))
        for i, m in enumerate(meta["trials"]))
    return Dataset(config, trials)

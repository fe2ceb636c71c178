"""The paper's kinematic preprocessing, one switchable step at a time.

Order (documented in docs/REPRODUCTION.md): (1) zero-phase low-pass filter on the continuous
30 Hz signal, (2) removal of unlabelled frames, (3) resampling 30 Hz -> 5 Hz by keeping every 6th
sample, (4) z-normalisation per trial. Filtering comes first because it needs the contiguous
signal; normalisation comes last so that the network sees exactly zero mean / unit variance.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .gestures import UNLABELLED
from .release import KINEMATICS_HZ


@dataclass(frozen=True)
class PreprocessConfig:
    """Preprocessing switches; defaults reproduce the paper."""

    lowpass: bool = True
    cutoff_hz: float = 1.5
    filter_order: int = 4          # Butterworth order of one pass; filtfilt doubles it
    drop_unlabelled: bool = True
    resample_factor: int = 6       # 30 Hz / 6 = 5 Hz; 1 disables resampling
    normalise: bool = True

    @property
    def sample_hz(self) -> float:
        return KINEMATICS_HZ / self.resample_factor


def lowpass(x: np.ndarray, cutoff_hz: float, order: int, fs_hz: float = KINEMATICS_HZ) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward-backward, second-order sections).

    ``x``: ``[n_frames, n_features]`` at ``fs_hz``; returns the same shape.
    """
    from scipy import signal     # here, not at the top: SciPy's import costs command lines 0.6 s

    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs_hz, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


def resample(x: np.ndarray, factor: int) -> np.ndarray:
    """Keep every ``factor``-th sample starting with the first: ``ceil(n / factor)`` rows."""
    return x[::factor]


def znormalise(x: np.ndarray) -> np.ndarray:
    """Per-column zero mean, unit variance over this trial; constant columns become 0."""
    std = x.std(axis=0, keepdims=True)
    return (x - x.mean(axis=0, keepdims=True)) / np.where(std > 0, std, 1.0)


def preprocess(features: np.ndarray, labels: np.ndarray, config: PreprocessConfig
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply the configured steps to one trial.

    Args:
        features: ``[n_frames, F]`` float at 30 Hz.
        labels: ``[n_frames, L]`` int label channels (e.g. gesture and progress), each
            ``UNLABELLED`` (-1) on the frames no transcription segment covers.

    Returns:
        ``(features [T, F] float32, labels [T, L] int64, frames [T] int64)`` where ``frames`` holds
        the 1-based 30 Hz frame number each kept sample came from.
    """
    frames = np.arange(1, len(features) + 1)
    x = features.astype(np.float64)
    if config.lowpass:
        x = lowpass(x, config.cutoff_hz, config.filter_order)
    if config.drop_unlabelled:
        keep = (labels != UNLABELLED).all(axis=1)
        x, labels, frames = x[keep], labels[keep], frames[keep]
    x, labels, frames = (resample(a, config.resample_factor) for a in (x, labels, frames))
    if config.normalise:
        x = znormalise(x)
    return x.astype(np.float32), labels.astype(np.int64), frames.astype(np.int64)

"""The paper's kinematic preprocessing, one switchable step at a time.

Order (documented in docs/REPRODUCTION.md): (1) zero-phase low-pass filter on the continuous
30 Hz signal, (2) removal of unlabelled frames, (3) resampling 30 Hz -> 5 Hz by keeping every 6th
sample, (4) z-normalisation per trial. Filtering comes first because it needs the contiguous
signal; normalisation comes last so that the network sees exactly zero mean / unit variance.
A recording at another rate (``recording_format``) takes the same filter, its cut-off in Hz,
designed at its own rate, and keeps one sample in ``decimation(config, rate_hz)``, so that the
model sees 5 Hz samples of the same frequency band.

Unlabelled recordings (prediction) keep every frame: ``preprocess_recording``. Online use needs
causal steps: ``CausalLowpass`` (one forward pass, state carried between calls), normalisation
with statistics fixed in advance (``Normalisation``), and ``StreamingPreprocessor``, which feeds
frames one at a time through both and equals ``preprocess_recording(..., causal=True)``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

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

    def __post_init__(self):
        nyquist = KINEMATICS_HZ / 2
        for name in ("lowpass", "drop_unlabelled", "normalise"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"PreprocessConfig.{name} must be true or false "
                                 f"(got {getattr(self, name)!r})")
        if not (isinstance(self.cutoff_hz, (int, float)) and 0 < self.cutoff_hz < nyquist):
            raise ValueError(f"PreprocessConfig.cutoff_hz must be a number in (0, {nyquist:g}) Hz "
                             f"(got {self.cutoff_hz!r})")
        for name in ("filter_order", "resample_factor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"PreprocessConfig.{name} must be an integer >= 1 "
                                 f"(got {value!r})")

    @property
    def sample_hz(self) -> float:
        return KINEMATICS_HZ / self.resample_factor


def _scipy_signal():
    """``scipy.signal``, imported on first use: its import costs every command line 0.6 s."""
    from scipy import signal

    return signal


def butterworth(cutoff_hz: float, order: int, fs_hz: float = KINEMATICS_HZ) -> np.ndarray:
    """Second-order sections of a Butterworth low-pass.

    Args:
        cutoff_hz: cut-off frequency, in Hz.
        order: the filter's order (of one pass; ``lowpass``'s two passes double it).
        fs_hz: sampling rate of the signal, in Hz (the kinematics' 30 Hz by default).

    Returns:
        ``[n_sections, 6]`` float64 (``b0 b1 b2 1 a1 a2``), ``n_sections = ceil(order / 2)``.
    """
    return _scipy_signal().butter(order, cutoff_hz, btype="low", fs=fs_hz, output="sos")


def lowpass(x: np.ndarray, cutoff_hz: float, order: int, fs_hz: float = KINEMATICS_HZ
            ) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward-backward, second-order sections).

    Args:
        x: ``[n_frames, n_features]`` float at ``fs_hz``; needs more frames than scipy's edge
            padding (16 for order 4; a shorter ``x`` is refused, naming the minimum).
        cutoff_hz: cut-off frequency, in Hz.
        order: Butterworth order of one pass (the forward-backward filter doubles it).
        fs_hz: sampling rate of ``x``, in Hz (30 Hz frames by default).

    Returns:
        ``[n_frames, n_features]`` float64.

    Raises:
        ValueError: ``x`` has fewer frames than the filter needs (the message says how many).
    """
    sos = butterworth(cutoff_hz, order, fs_hz)
    needed = _min_frames(sos)
    if len(x) < needed:
        raise ValueError(f"{len(x)} frames, fewer than the {needed} the zero-phase low-pass "
                         f"filter (order {order}) needs")
    return _scipy_signal().sosfiltfilt(sos, x, axis=0)


def _min_frames(sos: np.ndarray) -> int:
    """``scipy.signal.sosfiltfilt``'s default ``padlen`` + 1 for ``sos``."""
    taps = 2 * len(sos) + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * taps + 1


class CausalLowpass:
    """The Butterworth low-pass run forward only (``scipy.signal.sosfilt``): each output depends on
    the frames up to it, so frames can be fed one at a time; the filter state is carried between
    calls. It starts in the steady state of a signal that stayed at the first frame's value (no
    start-up transient from zero). Order ``order`` (not doubled as in ``lowpass``), with the
    Butterworth's delay (at 1.5 Hz, order 4: 0.27 s for slow motion, 0.36 s at 1 Hz).
    """

    def __init__(self, cutoff_hz: float, order: int, fs_hz: float = KINEMATICS_HZ):
        self.sos = butterworth(cutoff_hz, order, fs_hz)
        self._state: np.ndarray | None = None        # [n_sections, 2, F]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Filter the next frames ``[n, F]`` (``n`` >= 1) of the signal; returns ``[n, F]``."""
        x = np.asarray(x, dtype=np.float64)
        if self._state is None:
            self._state = _scipy_signal().sosfilt_zi(self.sos)[:, :, None] * x[0]
        y, self._state = _scipy_signal().sosfilt(self.sos, x, axis=0, zi=self._state)
        return y


def causal_lowpass(x: np.ndarray, cutoff_hz: float, order: int, fs_hz: float = KINEMATICS_HZ
                   ) -> np.ndarray:
    """``CausalLowpass`` over a whole signal: what frame-by-frame use gives.

    Args:
        x: ``[n_frames, F]`` float at ``fs_hz``.
        cutoff_hz: cut-off frequency, in Hz.
        order: Butterworth order (one forward pass, not doubled).
        fs_hz: sampling rate of ``x``, in Hz (30 Hz frames by default).

    Returns:
        ``[n_frames, F]`` float64.
    """
    return CausalLowpass(cutoff_hz, order, fs_hz)(x)


def decimation(config: PreprocessConfig, rate_hz: float) -> int:
    """How many samples of a recording at ``rate_hz`` give one of the model's
    (``config.sample_hz``): ``config.resample_factor`` at the release's 30 Hz.

    Raises:
        ValueError: ``rate_hz`` is not a whole multiple of the model's rate (keeping every k-th
            sample would give another rate), or the low-pass cut-off is not below its Nyquist
            frequency (the message names the rate).
    """
    factor = rate_hz / config.sample_hz
    if round(factor) < 1 or abs(factor - round(factor)) > 1e-9 * factor:
        raise ValueError(f"sample rate {rate_hz:g} Hz is not a whole multiple of the model's "
                         f"{config.sample_hz:g} Hz (ratio {factor:g}); resample the recording "
                         f"to a multiple of {config.sample_hz:g} Hz first")
    if config.lowpass and not config.cutoff_hz < rate_hz / 2:
        raise ValueError(f"sample rate {rate_hz:g} Hz: the {config.cutoff_hz:g} Hz low-pass "
                         f"filter needs a rate above {2 * config.cutoff_hz:g} Hz")
    return round(factor)


def resample(x: np.ndarray, factor: int) -> np.ndarray:
    """Keep every ``factor``-th sample starting with the first: ``ceil(n / factor)`` rows."""
    return x[::factor]


def znormalise(x: np.ndarray) -> np.ndarray:
    """Per-column zero mean, unit variance over this trial; constant columns become 0."""
    return _standardise(x, x.mean(axis=0, keepdims=True), x.std(axis=0, keepdims=True))


def _standardise(x: np.ndarray, mean: np.ndarray, std: np.ndarray) -> np.ndarray:
    return (x - mean) / np.where(std > 0, std, 1.0)


@dataclass(frozen=True)
class Normalisation:
    """Per-feature statistics fixed in advance (e.g. from a run's training trials), for inputs
    that cannot be normalised over the whole recording (streaming): ``(x - mean) / std``, a zero
    ``std`` counting as 1."""

    mean: tuple[float, ...]
    std: tuple[float, ...]

    def __post_init__(self):
        if len(self.mean) != len(self.std):
            raise ValueError(f"{len(self.mean)} means but {len(self.std)} standard deviations")
        bad = next((i for i, (m, d) in enumerate(zip(self.mean, self.std))
                    if not (np.isfinite(m) and np.isfinite(d) and d >= 0)), None)
        if bad is not None:
            raise ValueError(f"feature {bad}: mean {self.mean[bad]}, std {self.std[bad]}: "
                             "expected finite values and a std >= 0")

    @classmethod
    def fit(cls, samples: Sequence[np.ndarray]) -> Normalisation:
        """Mean and (population) standard deviation per column, pooled over every row of
        ``samples`` (a list of ``[T_i, F]`` arrays)."""
        pooled = np.concatenate([np.asarray(s, dtype=np.float64) for s in samples])
        return cls(tuple(pooled.mean(axis=0).tolist()), tuple(pooled.std(axis=0).tolist()))

    def apply(self, x: np.ndarray) -> np.ndarray:
        """``[..., F]`` -> the same shape, standardised with these statistics."""
        if np.shape(x)[-1] != len(self.mean):
            raise ValueError(f"normalisation has {len(self.mean)} features, input "
                             f"{np.shape(x)[-1]}")
        return _standardise(x, np.asarray(self.mean), np.asarray(self.std))


def preprocess(features: np.ndarray, labels: np.ndarray, config: PreprocessConfig,
               rate_hz: float = KINEMATICS_HZ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Apply the configured steps to one trial.

    Args:
        features: ``[n_frames, F]`` float at ``rate_hz``.
        labels: ``[n_frames, L]`` int label channels (e.g. gesture and progress), each
            ``UNLABELLED`` (-1) on the frames no transcription segment covers.
        config: the switches.
        rate_hz: the recording's sample rate (the release's 30 Hz by default; ``decimation``).

    Returns:
        ``(features [T, F] float32, labels [T, L] int64, frames [T] int64)`` where ``frames`` holds
        the 1-based frame (row of the recording) each kept sample came from.
    """
    factor = decimation(config, rate_hz)
    frames = np.arange(1, len(features) + 1)
    x = features.astype(np.float64)
    if config.lowpass:
        x = lowpass(x, config.cutoff_hz, config.filter_order, rate_hz)
    if config.drop_unlabelled:
        keep = (labels != UNLABELLED).all(axis=1)
        x, labels, frames = x[keep], labels[keep], frames[keep]
    x, labels, frames = (resample(a, factor) for a in (x, labels, frames))
    if config.normalise:
        x = znormalise(x)
    return x.astype(np.float32), labels.astype(np.int64), frames.astype(np.int64)


def preprocess_recording(features: np.ndarray, config: PreprocessConfig, causal: bool = False,
                         normalisation: Normalisation | None = None,
                         rate_hz: float = KINEMATICS_HZ) -> tuple[np.ndarray, np.ndarray]:
    """Preprocess an unlabelled recording as ``preprocess`` does a trial, keeping every frame.

    Steps: low-pass on the whole recording, every ``decimation``-th frame from the first,
    normalisation over the recording's samples (``drop_unlabelled`` does not apply: there are no
    labels). With ``causal`` the filter is ``causal_lowpass`` and ``normalisation`` (required when
    ``config.normalise``) replaces the per-recording statistics, so each sample depends only on
    the frames up to it, as in ``StreamingPreprocessor``.

    Args:
        features: ``[n_frames, F]`` float at ``rate_hz``.
        config: the run's preprocessing switches.
        causal: forward-only filter and fixed statistics instead of the offline steps.
        normalisation: fixed statistics (with ``causal``; None = per-recording z-normalisation).
        rate_hz: the recording's sample rate (the release's 30 Hz by default; ``decimation``).

    Returns:
        ``(inputs [T, F] float32, frames [T] int64)``, ``T = ceil(n_frames / decimation)``,
        ``frames`` the 1-based frame (row of the recording) each sample came from.
    """
    if causal and config.normalise and normalisation is None:
        raise ValueError("causal preprocessing needs fixed normalisation statistics")
    factor = decimation(config, rate_hz)
    x = np.asarray(features, dtype=np.float64)
    if config.lowpass:
        x = (causal_lowpass if causal else lowpass)(x, config.cutoff_hz, config.filter_order,
                                                    rate_hz)
    x = resample(x, factor)
    if config.normalise:
        x = normalisation.apply(x) if normalisation is not None else znormalise(x)
    frames = resample(np.arange(1, len(features) + 1, dtype=np.int64), factor)
    return x.astype(np.float32), frames


class StreamingPreprocessor:
    """``preprocess_recording(..., causal=True)`` one frame at a time (30 Hz, or ``rate_hz``).

    ``push(frame)`` filters the frame (state carried over) and, on every ``decimation``-th
    frame from the first, returns the normalised 5 Hz sample ``[F]`` float32; otherwise None.
    """

    def __init__(self, config: PreprocessConfig, normalisation: Normalisation | None,
                 rate_hz: float = KINEMATICS_HZ):
        if config.normalise and normalisation is None:
            raise ValueError("streaming preprocessing needs fixed normalisation statistics")
        self.config, self.normalisation = config, normalisation
        self.factor = decimation(config, rate_hz)
        self.frames = 0                    # frames pushed so far
        self._filter = (CausalLowpass(config.cutoff_hz, config.filter_order, rate_hz)
                        if config.lowpass else None)

    def push(self, frame: np.ndarray) -> np.ndarray | None:
        """Next frame ``[F]`` -> its sample ``[F]`` float32 when it is kept, else None."""
        x = np.asarray(frame, dtype=np.float64)[None]
        if self._filter is not None:
            x = self._filter(x)
        self.frames += 1
        if (self.frames - 1) % self.factor:
            return None
        if self.config.normalise:
            x = self.normalisation.apply(x)
        return x[0].astype(np.float32)

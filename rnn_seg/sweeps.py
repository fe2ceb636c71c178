"""Sweeps: batches of sequences run together through time, short ones wrapped to the longest.

A sweep of ``B`` sequences has the duration of its longest member; every shorter sequence is
repeated (numpy ``wrap`` padding) to fill it, and a reset flag marks the first step of every copy
so the recurrent state restarts there. Sequences are drawn from an endless stream that visits all
of them in a fresh random order on each pass, as in DiPietro et al.'s code. Wrapped steps count in
the loss like any other, as they do there. A convolutional encoder's sweeps are padded with zeros
instead (``pad_sweep``), the padding outside every loss (``rnn_seg.encoders``).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np


def sweep_indices(num_seqs: int, batch_size: int, seed: int, sweep: int) -> list[int]:
    """Sequence indices of training sweep number ``sweep`` (0-based).

    The sweeps read consecutive ``batch_size`` positions of an endless stream that visits every
    sequence once per pass in a fresh random order; pass ``p``'s order depends only on ``(seed, p)``
    so any sweep can be rebuilt after a resume without replaying the ones before it.

    Args:
        num_seqs: number of training sequences.
        batch_size: sequences per sweep (``B``).
        seed: the run's seed (``TrainConfig.seed``).
        sweep: 0-based sweep number.

    Returns:
        ``batch_size`` indices into the training sequences.
    """
    positions = np.arange(sweep * batch_size, (sweep + 1) * batch_size)
    passes = positions // num_seqs
    orders = {p: np.random.default_rng([seed, int(p)]).permutation(num_seqs) for p in set(passes)}
    return [int(orders[p][i]) for p, i in zip(passes, positions % num_seqs)]


def wrap(seq: np.ndarray, duration: int) -> np.ndarray:
    """Repeat ``seq`` (time on axis 0) cyclically to ``duration`` steps."""
    return np.take(seq, np.arange(duration) % len(seq), axis=0)


def reset_flags(lengths: Sequence[int], duration: int) -> np.ndarray:
    """``[B, duration]`` bool: True at the first step of every (wrapped) copy of each sequence."""
    steps = np.arange(duration)[None, :]
    return steps % np.asarray(lengths)[:, None] == 0


def make_sweep(seqs: Sequence[np.ndarray], duration: int | None = None) -> np.ndarray:
    """Stack sequences ``[T_i, ...]`` into ``[B, duration, ...]``, wrapping shorter ones."""
    duration = duration or max(len(s) for s in seqs)
    return np.stack([wrap(s, duration) for s in seqs])


def pad_sweep(seqs: Sequence[np.ndarray], duration: int | None = None) -> np.ndarray:
    """Stack sequences ``[T_i, ...]`` into ``[B, duration, ...]``, zeros after each one's end
    (the sweeps of a convolutional encoder, ``rnn_seg.encoders``)."""
    duration = duration or max(len(s) for s in seqs)
    return np.stack([np.pad(s, [(0, duration - len(s))] + [(0, 0)] * (s.ndim - 1))
                     for s in seqs])


def sweeps_per_epoch(num_seqs: int, batch_size: int) -> int:
    """An epoch visits every training sequence at least once: ``ceil(num_seqs / batch_size)``."""
    return -(-num_seqs // batch_size)

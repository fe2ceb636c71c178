"""Deterministic synthetic JIGSAWS-format release of any defined task (the project's embedded
default data).

Writes the official layout (76-column kinematics at 30 Hz, transcriptions with CRLF line ends and
trailing spaces, meta file) for 8 users x 5 trials. Each trial follows the task's synthetic grammar
(``TaskDefinition.synthetic``): for Suturing, reach (G1, sometimes G5), several throws of position /
push / pull (G2, G3, G6) with adjustment gestures (G4, G8) and tightening (G9, G10) between them,
and a final drop (G11). Kinematics move each patient-side arm towards a gesture-specific pose with
a gesture-specific oscillation; users differ in speed, workspace offset and motion amplitude,
trials in pose jitter, and every signal carries noise: learnable from context, but not from one
sample.
"""
from __future__ import annotations

import hashlib
import json
import os
import secrets
import shutil
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .errors import JigsawsError
from .messages import cache_unwritable, data_logger
from .release import KINEMATICS_HZ, kinematics_dir, meta_path, trial_name, transcriptions_dir
from .task_definition import SUTURING, SynthGrammar, SynthStep, TaskDefinition

#: Beside a cached release (``ensure_release``): the SHA-256 of each of its files.
MANIFEST = "manifest.json"
#: Bump whenever the generator's output changes for the same ``SynthConfig`` and task.
GENERATOR_VERSION = 2
SYNTH_USERS = ("B", "C", "D", "E", "F", "G", "H", "I")
SYNTH_SKILLS = ("N", "I", "E", "E", "I", "N", "N", "N")
TRIALS_PER_USER = 5

log = data_logger(__name__)


@dataclass(frozen=True)
class SynthConfig:
    """Knobs of the generator; the defaults are the embedded demo release."""

    seed: int = 0
    users: tuple[str, ...] = SYNTH_USERS
    trials_per_user: int = TRIALS_PER_USER
    noise: float = 1.0           # measurement noise, in units of the typical pose separation
    pose_jitter: float = 0.8     # per-segment perturbation of the gesture poses, same units


def grammar(task: TaskDefinition) -> SynthGrammar:
    """``task``'s synthetic grammar, or a clear error when its definition has none."""
    if task.synthetic is None:
        raise JigsawsError(f"task {task.name} has no [synthetic] section in its definition: "
                           f"the generator cannot write it")
    return task.synthetic


def gesture_sequence(rng: np.random.Generator, task: TaskDefinition = SUTURING) -> list[str]:
    """Sample one trial's gesture sequence from ``task``'s synthetic grammar."""
    rules = grammar(task)
    seq = [g for step in rules.opening if (g := _sample(step, rng, 0))]
    for cycle in range(rng.integers(rules.cycles[0], rules.cycles[1] + 1)):
        seq += [g for step in rules.cycle if (g := _sample(step, rng, cycle))]
    seq += [g for step in rules.closing if (g := _sample(step, rng, 0))]
    return seq


def _sample(step: SynthStep, rng: np.random.Generator, cycle: int) -> str | None:
    """The gesture ``step`` produces in ``cycle`` (0-based), or None. Draws one uniform number for
    ``p < 1`` and one to choose among several gestures, none otherwise."""
    if step.cycles == "first" and cycle > 0 or step.cycles == "later" and cycle == 0:
        return None
    if step.p < 1.0 and not rng.random() < step.p:
        return None
    if len(step.gestures) == 1:
        return step.gestures[0]
    cumulative = np.cumsum(step.weights) / sum(step.weights)
    choice = int(np.searchsorted(cumulative, rng.random(), side="right"))
    return step.gestures[min(choice, len(step.gestures) - 1)]


def _prototypes(seed: int, task: TaskDefinition) -> dict[str, dict[str, np.ndarray]]:
    """Per-gesture motion prototype for both arms: pose [2, 3], gripper [2], wobble [2, 3], rate."""
    rng = np.random.default_rng([seed, 7919])
    protos = {}
    for g in task.gestures:
        protos[g] = {"pose": rng.normal(0.0, 1.0, (2, 3)), "grip": rng.uniform(-0.3, 1.2, 2),
                     "wobble": rng.normal(0.0, 0.6, (2, 3)), "rate": rng.uniform(0.3, 1.5),
                     "turn": rng.normal(0.0, 0.5, (2, 3))}
    # Related gestures look alike (Suturing: the two adjustments, tightening / loosening vs
    # pulling).
    for timing in grammar(task).gestures:
        if timing.like:
            for key in ("pose", "wobble", "turn"):
                protos[timing.gesture][key] = (0.6 * protos[timing.like][key]
                                               + 0.4 * protos[timing.gesture][key])
    return protos


def _segments(seq: list[str], rng: np.random.Generator, speed: float, rules: SynthGrammar
              ) -> list[tuple[str, int]]:
    return [(g, max(8, int(rng.integers(rules.timing(g).min_frames, rules.timing(g).max_frames)
                           * speed))) for g in seq]


def _arm_signals(segments: list[tuple[str, int]], protos, rng: np.random.Generator,
                 style: dict[str, np.ndarray], config: SynthConfig) -> np.ndarray:
    """``[n_frames, 2, 19]`` patient-side signals per arm (release column order within an arm)."""
    n = sum(d for _, d in segments)
    target = np.empty((n, 2, 3))
    grip = np.empty((n, 2))
    wobble = np.empty((n, 2, 3))
    turn = np.empty((n, 2, 3))
    start = 0
    for g, d in segments:
        p = protos[g]
        jitter = rng.normal(0.0, config.pose_jitter, (2, 3))
        phase = np.arange(d)[:, None, None] / KINEMATICS_HZ * 2 * np.pi * p["rate"] * style["tempo"]
        target[start:start + d] = p["pose"] + jitter
        grip[start:start + d] = p["grip"] + rng.normal(0.0, 0.1, 2)
        wobble[start:start + d] = p["wobble"] * np.sin(phase + rng.uniform(0, 2 * np.pi))
        turn[start:start + d] = p["turn"] + rng.normal(0.0, 0.2, (2, 3))
        start += d
    # The arms approach each gesture's pose smoothly (first-order lag, ~0.4 s time constant).
    alpha = 1.0 - np.exp(-1.0 / (0.4 * KINEMATICS_HZ))
    pos = np.empty_like(target)
    angles = np.empty_like(turn)
    pos[0], angles[0] = target[0], turn[0]
    for i in range(1, n):
        pos[i] = pos[i - 1] + alpha * (target[i] - pos[i - 1])
        angles[i] = angles[i - 1] + alpha * (turn[i] - angles[i - 1])
    pos = pos + wobble * style["amplitude"]
    pos = style["offset"] + 0.01 * pos + 0.01 * config.noise * rng.normal(0.0, 1.0, pos.shape)
    grip = grip + 0.15 * config.noise * rng.normal(0.0, 1.0, grip.shape)
    vel = np.gradient(pos, axis=0) * KINEMATICS_HZ + 0.002 * rng.normal(0.0, 1.0, pos.shape)
    ang_vel = np.gradient(angles, axis=0) * KINEMATICS_HZ + 0.05 * rng.normal(0.0, 1.0, pos.shape)
    rot = _rotation_matrices(angles).reshape(n, 2, 9)
    return np.concatenate([pos, rot, vel, ang_vel, grip[..., None]], axis=2)


def _rotation_matrices(angles: np.ndarray) -> np.ndarray:
    """Z-Y-X Euler angles ``[..., 3]`` -> rotation matrices ``[..., 3, 3]``."""
    a, b, c = (angles[..., i] for i in range(3))
    ca, sa, cb, sb, cc, sc = np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c), np.sin(c)
    return np.stack([
        np.stack([ca * cb, ca * sb * sc - sa * cc, ca * sb * cc + sa * sc], -1),
        np.stack([sa * cb, sa * sb * sc + ca * cc, sa * sb * cc - ca * sc], -1),
        np.stack([-sb, cb * sc, cb * cc], -1)], -2)


def synth_trial(config: SynthConfig, user_index: int, trial: int,
                task: TaskDefinition = SUTURING) -> tuple[np.ndarray, list[tuple[int, int, str]]]:
    """One trial of ``task``: kinematics ``[n_frames, 76]`` at 30 Hz and its
    ``(start, end, gesture)`` lines.

    Args:
        config: the generator's knobs (seed, users, noise).
        user_index: position of the user in ``config.users``.
        trial: 1-based trial number.
        task: whose grammar and vocabulary the trial follows.
    """
    rules = grammar(task)
    protos = _prototypes(config.seed, task)
    user_rng = np.random.default_rng([config.seed, 1, user_index])
    style = {"tempo": user_rng.uniform(0.7, 1.3), "amplitude": user_rng.uniform(0.6, 1.4),
             "offset": user_rng.normal(0.0, 0.02, (2, 3)), "speed": user_rng.uniform(0.75, 1.35)}
    rng = np.random.default_rng([config.seed, 2, user_index, trial])
    segments = _segments(gesture_sequence(rng, task), rng, style["speed"], rules)
    lead, tail = int(rng.integers(15, 90)), int(rng.integers(0, 40))
    slave = _arm_signals([(rules.lead_in, lead)] + segments + [(rules.tail, tail)], protos, rng,
                         style, config)
    master = slave.copy()
    master[..., 0:3] = slave[..., 0:3] * 3.0 + 0.002 * rng.normal(0.0, 1.0, slave[..., 0:3].shape)
    master[..., 12:15] *= 3.0
    kinematics = np.concatenate([master.reshape(len(slave), 38), slave.reshape(len(slave), 38)], 1)
    lines, frame = [], lead + 1
    for g, d in segments:
        lines.append((frame, frame + d - 1, g))
        frame += d
    return kinematics, lines


def write_release(out: Path | str, config: SynthConfig = SynthConfig(),
                  task: TaskDefinition = SUTURING) -> Path:
    """Write a complete synthetic release of ``task`` under ``out`` and return ``out``.

    The files are written into a hidden sibling folder (``.<name>.<random>.partial``) renamed to
    ``out`` once complete: an interrupted call never leaves a partial release where a reader
    would take it for one (only the hidden folder, which nothing reads).

    Args:
        out: the release folder (e.g. ``.../Suturing``); must not exist or be an empty folder:
            the generator never overwrites data.
        config: the generator's seed, users, trials per user and noise.
        task: the task written; its definition must have a synthetic grammar.

    Returns:
        ``out`` as a ``Path``.
    """
    out = Path(out)
    grammar(task)
    if out.is_symlink() or (out.exists() and (not out.is_dir() or any(out.iterdir()))):
        raise JigsawsError(f"{out} exists and is not an empty folder; the synthetic release is "
                           f"written only into a new or empty folder, so that no data is "
                           f"overwritten")
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = out.parent / f".{out.name}.{secrets.token_hex(4)}.partial"
    staging.mkdir()                            # with the umask's permissions, unlike mkdtemp
    try:
        _write_files(staging, config, task)
        os.replace(staging, out)               # onto a missing or empty folder
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return out


def _write_files(out: Path, config: SynthConfig, task: TaskDefinition) -> None:
    """The release's kinematics, transcriptions and meta file, into the folder ``out``."""
    kinematics_dir(out).mkdir(parents=True, exist_ok=True)
    transcriptions_dir(out).mkdir(parents=True, exist_ok=True)
    meta_lines = []
    for u, user in enumerate(config.users):
        skill = SYNTH_SKILLS[u % len(SYNTH_SKILLS)]
        grs_rng = np.random.default_rng([config.seed, 3, u])
        for trial in range(1, config.trials_per_user + 1):
            name = trial_name(user, trial, task)
            kinematics, lines = synth_trial(config, u, trial, task)
            np.savetxt(kinematics_dir(out) / f"{name}.txt", kinematics, fmt="%15.8f", delimiter=" ")
            with open(transcriptions_dir(out) / f"{name}.txt", "wb") as f:
                f.write("".join(f"{s} {e} {g} \r\n" for s, e, g in lines).encode())
            items = grs_rng.integers(1, 6, 6)
            meta_lines.append(f"{name}\t\t{skill}\t{items.sum()}\t\t" + "\t".join(map(str, items)))
    meta_path(out, task).write_bytes(("\r\n".join(meta_lines) + "\r\n").encode())


def ensure_release(cache_dir: Path | str, config: SynthConfig = SynthConfig(),
                   task: TaskDefinition = SUTURING) -> Path:
    """The synthetic release of ``task`` for ``config`` under ``cache_dir``, written once
    (atomically) and verified at each use.

    The folder name carries ``GENERATOR_VERSION`` and a hash of ``config`` and of the task's whole
    definition, so a changed generator, option or grammar never reuses an older release. Beside
    the release, ``manifest.json`` holds the SHA-256 of each of its files: a release edited,
    truncated or added to since (or cached without a manifest) is written again, with a warning.

    Args:
        cache_dir: the cache folder holding the synthetic releases.
        config: the generator's seed, users, trials per user and noise.
        task: the task written; its definition must have a synthetic grammar.

    A ``cache_dir`` that cannot be written is one warning (``messages.cache_unwritable``), and
    the release is written under ``fallback_cache_dir()`` instead.

    Returns:
        The release folder, ``<cache_dir>/synthetic-seed<seed>-<hash>/<task name>``.
    """
    definition = json.dumps(asdict(task), sort_keys=True)
    key = hashlib.sha256(repr((GENERATOR_VERSION, config, definition)).encode()).hexdigest()[:12]
    target = Path(cache_dir) / f"synthetic-seed{config.seed}-{key}" / task.name
    if target.is_dir():
        problem = _changed(target)
        if problem is None:
            return target
        log.warning("%s: %s; writing the synthetic release again", target, problem)
    try:
        target.parent.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=target.parent.parent, prefix=".synthetic-"))
    except OSError as error:
        fallback = fallback_cache_dir()
        if Path(cache_dir) == fallback:
            raise
        cache_unwritable(cache_dir, error, f"the synthetic release is written to {fallback} "
                                           "instead, and preprocessed data are not cached")
        return ensure_release(fallback, config, task)
    aside = staging.with_name(staging.name + "-old")      # an edited copy, removed at the end
    try:
        write_release(staging / task.name, config, task)
        (staging / MANIFEST).write_text(json.dumps(_digests(staging / task.name), indent=1))
        if target.is_dir():
            os.replace(target.parent, aside)
        staging.rename(target.parent)
    except OSError:
        if not target.is_dir():        # lost no race: a real failure
            raise
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(aside, ignore_errors=True)
    return target


def fallback_cache_dir() -> Path:
    """Where a synthetic release is written when the cache folder cannot be: this user's
    folder in the system's temporary folder (the same for every command, so that a grid's
    record names one release)."""
    user = os.getuid() if hasattr(os, "getuid") else os.getlogin()
    return Path(tempfile.gettempdir()) / f"mtrnn-jigsaws-{user}"


def _digests(release: Path) -> dict[str, str]:
    """SHA-256 of every file of ``release``, by path relative to it."""
    digests = {}
    for path in sorted(p for p in release.rglob("*") if p.is_file()):
        with open(path, "rb") as f:
            digest = hashlib.file_digest(f, "sha256").hexdigest()
        digests[path.relative_to(release).as_posix()] = digest
    return digests


def _changed(release: Path) -> str | None:
    """What differs between the cached ``release`` and its manifest; None when nothing does."""
    try:
        recorded = json.loads((release.parent / MANIFEST).read_text())
    except (OSError, ValueError):
        return f"no readable {MANIFEST} to verify it against"
    found = _digests(release)
    changed = sorted(set(recorded) ^ set(found)) or sorted(
        name for name in found if found[name] != recorded[name])
    return f"{changed[0]} changed since it was written" if changed else None

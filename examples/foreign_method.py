"""A gesture recogniser trained elsewhere: it reads a JIGSAWS-layout release with numpy alone
(it imports nothing of this project) and writes its leave-one-user-out test predictions in the
text layout ``multitask-tables score`` reads (docs/YOUR_METHOD.md).

Per held-out user: the kinematics of every frame, z-normalised per trial and averaged over a
moving window, are classified by the nearest gesture mean of the other users' labelled frames
(a random 80 % of their trials, drawn with ``--seed``), then smoothed by a majority vote in a
window. Output: ``<out>/<trial>.txt``, one gesture name per line, at ``--rate`` Hz (30: every
frame; 5: every 6th frame from the first).

    python examples/foreign_method.py --data-dir /path/to/Suturing --seed 0 --out my_method/seed0
"""
from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

RECORDING_HZ = 30
WINDOW = 15          # frames averaged into each frame's features
VOTE = 31            # frames of the majority vote


def read_release(root: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Trial name -> (kinematics [n, 76], gesture name per frame [n], "" where unlabelled), for
    every trial with both a kinematics file and a transcription."""
    trials = {}
    for path in sorted((root / "transcriptions").glob("*.txt")):
        kinematics = root / "kinematics" / "AllGestures" / path.name
        if not kinematics.is_file():
            continue
        x = np.loadtxt(kinematics, ndmin=2)
        labels = np.full(len(x), "", dtype=object)
        for line in path.read_text().split("\n"):
            if line.strip():
                start, end, gesture = line.split()[:3]
                labels[int(start) - 1:int(end)] = gesture
        trials[path.stem] = (x, labels)
    return trials


def features(x: np.ndarray) -> np.ndarray:
    """Per-trial z-normalised kinematics averaged over ``WINDOW`` frames: [n, 76]."""
    z = (x - x.mean(axis=0)) / np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
    kernel = np.ones(WINDOW) / WINDOW
    return np.stack([np.convolve(column, kernel, mode="same") for column in z.T], axis=1)


def majority(labels: np.ndarray, classes: int) -> np.ndarray:
    """The most frequent label in a window of ``VOTE`` frames around each frame."""
    counts = np.stack([np.convolve(labels == k, np.ones(VOTE), mode="same")
                       for k in range(classes)], axis=1)
    return counts.argmax(axis=1)


def predict(trials: dict, test_user: str, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Gesture names per frame of ``test_user``'s trials, from the others' class means."""
    user = {name: re.match(r".*_([A-Z])\d{3}$", name).group(1) for name in trials}
    train = [n for n in trials if user[n] != test_user]
    train = sorted(rng.choice(train, size=max(1, int(0.8 * len(train))), replace=False))
    x = np.concatenate([features(trials[n][0]) for n in train])
    y = np.concatenate([trials[n][1] for n in train])
    classes = sorted(set(y) - {""})
    means = np.stack([x[y == c].mean(axis=0) for c in classes])
    out = {}
    for name in (n for n in trials if user[n] == test_user):
        f = features(trials[name][0])
        nearest = ((f[:, None, :] - means[None]) ** 2).sum(axis=2).argmin(axis=1)
        out[name] = np.asarray(classes)[majority(nearest, len(classes))]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data-dir", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rate", type=int, default=RECORDING_HZ, choices=(30, 15, 10, 6, 5))
    args = parser.parse_args()
    trials = read_release(args.data_dir)
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    users = sorted({re.match(r".*_([A-Z])\d{3}$", n).group(1) for n in trials})
    for test_user in users:
        for name, labels in predict(trials, test_user, rng).items():
            kept = labels[::RECORDING_HZ // args.rate]
            (args.out / f"{name}.txt").write_text("\n".join(kept) + "\n")
    print(f"{args.out}: predictions of {len(trials)} trials at {args.rate} Hz")


if __name__ == "__main__":
    main()

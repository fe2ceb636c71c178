"""Lea et al.'s released ED-TCN predictions for JIGSAWS Suturing, scored by our metric code,
beside our ED-TCN model A (issue 64).

Lea et al. (CVPR 2017) released their test-fold predictions with their code
(github.com/colincsl/TemporalConvolutionalNetworks): ``predictions/JIGSAWS/<model>/<k>.mat``,
one file per split ``Split_<k>`` of ``splits/JIGSAWS/Suturing/``, holding per test trial (in the
order of the split's ``test.txt``) ``P`` (predicted class per sample), ``Y`` (their true class)
and ``S`` (class scores). The kinematic ("sensors") model is ``sensors_ED-TCN_L2_C15``. Nothing
of theirs is copied here or committed: the command reads a checkout the user gives.

Their samples are every ``r``-th labelled 30 Hz frame from a trial's first labelled one (``r`` is
not stored; it is found per trial as the stride whose original labels equal their ``Y``, and
printed). Each prediction is scored against **our original labels at the same frames**
(``jigsaws_tools``: the release's transcription, no amendments) with ``rnn_seg.metrics``: per
trial, then the mean over a split's trials, then over the 8 splits (users B-I), as our tables
average folds. Only the trials our release has (kinematics and transcription, as training
reads them) enter the main row; their other trials are scored in a note. A second note holds
their predictions held (each 30 Hz frame takes the prediction of the last sample at or before
it) at our 5 Hz samples, scored against our 5 Hz labels: the same frames our runs are scored on.

Ours: model A on the original labels from a per-fold table (``multitask-tables paper``'s
``per_fold.csv``; each fold's mean over its seeds), averaged over folds the same way.

    python bench/lea_predictions.py --reference PATH/TemporalConvolutionalNetworks \\
        [--model sensors_ED-TCN_L2_C15] [--data ../shared/jigsaws/Suturing] \\
        [--ours results/tcn/ed-tcn-tables/per_fold.csv] [--csv FILE]

Prints a table, the difference per metric and whether it is within 1.5 points on accuracy,
edit and F1@10 (issue 64's target); ``--csv FILE`` also writes that table, and nothing else.
Needs the JIGSAWS release (licensed; never committed).
"""
from __future__ import annotations

import argparse
import csv
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

METRICS = ("accuracy", "edit", "f1@10", "f1@25", "f1@50")
#: Our samples: one labelled 30 Hz frame in 6 (``PreprocessConfig.resample_factor``).
OUR_STRIDE = 6
KINEMATICS_HZ = 30.0
LONGEST_STRIDE = 30
#: Issue 64's target: ours within this many points of theirs on these metrics.
TOLERANCE = 1.5
TARGET_METRICS = ("accuracy", "edit", "f1@10")
#: The comparison's column saying whether a target metric is within ``TOLERANCE``.
WITHIN = f"within_{TOLERANCE:g}"


class UnusableFile(Exception):
    """A file of the reference or of ours that cannot be used; the message names it."""


@dataclass(frozen=True)
class ScoredTrial:
    """One test trial of the reference, aligned to our labels."""

    trial: str
    user: str
    stride: int                  # 30 Hz frames between two of their samples
    in_our_release: bool
    scores: dict[str, float]     # at their samples
    scores_5hz: dict[str, float]  # their predictions held at our 5 Hz samples


def labelled_frames(labels: np.ndarray) -> np.ndarray:
    """``[n]`` int64 labels of a trial's 30 Hz frames -> ``[m]`` those of its labelled frames
    (the frames no transcription segment covers, -1, dropped, as our preprocessing does)."""
    return labels[labels >= 0]


def stride_of(their_true: np.ndarray, labels: np.ndarray, where: str) -> int:
    """The stride ``r`` (30 Hz frames) at which ``their_true`` ``[T]`` equals ``labels[::r]``
    ``[m]`` (labelled frames), allowing their last sample to be missing (``ceil(m / r)`` or one
    fewer samples); ``where`` names the trial in the error."""
    for r in range(1, LONGEST_STRIDE + 1):
        ours = labels[::r]
        if len(ours) in (len(their_true), len(their_true) + 1) and \
                np.array_equal(ours[:len(their_true)], their_true):
            return r
    raise UnusableFile(f"{where}: their {len(their_true)} true labels equal our original "
                          f"labels ({len(labels)} labelled frames) at no stride of 1-"
                          f"{LONGEST_STRIDE} frames")


def held(pred: np.ndarray, stride: int, n_labelled: int, step: int = OUR_STRIDE) -> np.ndarray:
    """``[T]`` predictions at every ``stride``-th labelled frame -> ``[ceil(n_labelled / step)]``
    at every ``step``-th: each takes the last of their samples at or before its frame."""
    frames = np.arange(0, n_labelled, step)
    return pred[np.minimum(frames // stride, len(pred) - 1)]


def _metrics():
    from rnn_seg.metrics import segmentation_metrics
    return segmentation_metrics


def score_split(mat_path: Path, trials: list[str], user: str, labels_of, ours: set[str]
                ) -> list[ScoredTrial]:
    """Score one split's ``.mat`` file; ``labels_of(trial)`` gives the ``[n]`` original labels
    of its 30 Hz frames (-1 unlabelled), ``ours`` the trials our release holds."""
    from scipy.io import loadmat

    segmentation_metrics = _metrics()
    try:
        mat = loadmat(mat_path)
    except (OSError, ValueError) as e:
        raise UnusableFile(f"{mat_path}: not a readable .mat file ({e})") from None
    if "P" not in mat or "Y" not in mat:
        raise UnusableFile(f"{mat_path}: holds no 'P' and 'Y' (predicted and true labels)")
    preds, trues = mat["P"].ravel(), mat["Y"].ravel()
    if len(preds) != len(trials) or len(trues) != len(trials):
        raise UnusableFile(f"{mat_path}: {len(preds)} predicted sequences, but its split's "
                              f"test.txt names {len(trials)} trials")
    out = []
    for trial, p, y in zip(trials, preds, trues):
        p, y = np.ravel(p).astype(np.int64), np.ravel(y).astype(np.int64)
        labels = labelled_frames(labels_of(trial))
        r = stride_of(y, labels, f"{mat_path}: {trial}")
        at_theirs = labels[::r][:len(p)]
        at_ours = labels[::OUR_STRIDE]
        out.append(ScoredTrial(trial, user, r, trial in ours,
                               segmentation_metrics([p], [at_theirs]),
                               segmentation_metrics([held(p, r, len(labels))], [at_ours])))
    return out


def fold_means(trials: list[ScoredTrial], field: str = "scores") -> dict[str, dict[str, float]]:
    """Per user, the mean over its trials of each metric (``field``: ``scores`` or
    ``scores_5hz``)."""
    users = sorted({t.user for t in trials})
    return {u: {m: float(np.mean([getattr(t, field)[m] for t in trials if t.user == u]))
                for m in METRICS} for u in users}


def over_folds(per_fold: dict[str, dict[str, float]]) -> dict[str, tuple[float, float]]:
    """Per metric, ``(mean, sample std)`` over the folds."""
    return {m: (float(np.mean([f[m] for f in per_fold.values()])),
                float(np.std([f[m] for f in per_fold.values()], ddof=1)))
            for m in METRICS}


def read_ours(path: Path, annotations: str = "original", variant: str = "A"
              ) -> dict[str, dict[str, float]]:
    """Per fold, our ``variant``'s gesture metrics on ``annotations`` labels (fixed weighting,
    offline) from a ``per_fold.csv``."""
    try:
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f)
                    if r.get("annotations") == annotations and r.get("variant") == variant
                    and r.get("weighting") == "fixed" and r.get("direction") == "bidirectional"]
    except OSError as e:
        raise UnusableFile(f"{path}: cannot read ({e.strerror})") from None
    if not rows:
        raise UnusableFile(f"{path}: no row of model {variant} on the {annotations} labels")
    try:
        return {r["fold"]: {m: float(r[f"gesture_{m}"]) for m in METRICS} for r in rows}
    except (KeyError, ValueError) as e:
        raise UnusableFile(f"{path}: no usable gesture column ({e})") from None


def score_reference(reference: Path, model: str, data: Path, task_name: str = "Suturing"
                    ) -> list[ScoredTrial]:
    """Every test trial of the reference's 8 splits, scored (``score_split``)."""
    from jigsaws_tools.release import (discover, frame_labels, read_transcription,
                                       transcriptions_dir)

    index = discover(data)
    ours = {t.name for t in index.trials}
    transcriptions = {t.name: t.transcription for t in index.trials}
    folder = reference / "predictions" / "JIGSAWS" / model
    splits = reference / "splits" / "JIGSAWS" / task_name

    def labels_of(trial: str) -> np.ndarray:
        path = transcriptions.get(trial, transcriptions_dir(index.root) / f"{trial}.txt")
        if not path.is_file():
            raise UnusableFile(f"{path}: no transcription of {trial} in {data}")
        segments = read_transcription(path)
        return frame_labels(segments, segments[-1].end, index.task)

    out = []
    for k in range(1, 9):
        test = splits / f"Split_{k}" / "test.txt"
        if not test.is_file():
            raise UnusableFile(f"{test}: no such file (is --reference their repository?)")
        trials = [line.strip() for line in test.read_text().splitlines() if line.strip()]
        users = {t.rsplit("_", 1)[-1][0] for t in trials}
        if len(users) != 1:
            raise UnusableFile(f"{test}: trials of {len(users)} users, expected one")
        mat = folder / f"{k}.mat"
        if not mat.is_file():
            raise UnusableFile(f"{mat}: no such file (is --model one of their folders?)")
        out += score_split(mat, trials, users.pop(), labels_of, ours)
    return out


def their_folds(scored: list[ScoredTrial], ours: dict[str, dict[str, float]]
                ) -> dict[str, dict[str, float]]:
    """Per fold, the mean of their scores over the trials our release holds; the folds must be
    ours."""
    theirs = fold_means([t for t in scored if t.in_our_release])
    missing = sorted(set(theirs) ^ set(ours))
    if missing:
        raise UnusableFile(f"folds {', '.join(missing)}: in one of ours and theirs only")
    return theirs


def comparison(scored: list[ScoredTrial], ours: dict[str, dict[str, float]]) -> list[dict]:
    """Per metric (``METRICS``): the mean and sample std over the folds of ours and of theirs,
    ours - theirs, and for ``TARGET_METRICS`` whether the difference, to the 2 decimals shown,
    is within ``TOLERANCE`` points ("yes" / "no"; "" for the others)."""
    a, b = over_folds(ours), over_folds(their_folds(scored, ours))
    return [{"metric": m, "ours_mean": a[m][0], "ours_std": a[m][1],
             "theirs_mean": b[m][0], "theirs_std": b[m][1], "ours_minus_theirs": a[m][0] - b[m][0],
             WITHIN: _within(m, a[m][0] - b[m][0])} for m in METRICS]


def _within(metric: str, difference: float) -> str:
    """``yes`` / ``no``: ``difference``, to the 2 decimals shown, within ``TOLERANCE`` points;
    ``""`` for a metric not in ``TARGET_METRICS``."""
    if metric not in TARGET_METRICS:
        return ""
    return "yes" if abs(round(difference, 2)) <= TOLERANCE else "no"


def check_destination(path: Path) -> None:
    """An ``UnusableFile`` when ``path`` cannot name the CSV to write: no file name (``.``,
    ``/``, empty), a folder, or in a folder that does not exist; checked before the scoring."""
    if path.name in ("", ".", ".."):
        raise UnusableFile(f"{str(path)!r}: not a file name (give --csv FILE)")
    if path.is_dir():
        raise UnusableFile(f"{path}: a folder (give --csv FILE)")
    if not path.parent.is_dir():
        raise UnusableFile(f"{path}: no folder {path.parent} to write it in")


def write_csv(rows: list[dict], path: Path) -> None:
    """``rows`` as a CSV at ``path``, numbers to 2 decimals, whole or not at all (a temporary
    file beside it, renamed)."""
    check_destination(path)
    partial = path.with_name(f".{path.name}.partial")
    try:
        with open(partial, "w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
            writer.writeheader()
            writer.writerows({k: f"{v:.2f}" if isinstance(v, float) else v
                              for k, v in row.items()} for row in rows)
        partial.replace(path)
    except OSError as e:
        partial.unlink(missing_ok=True)
        raise UnusableFile(f"{path}: cannot write ({e.strerror})") from None


def report(scored: list[ScoredTrial], ours: dict[str, dict[str, float]]) -> str:
    """The table of ``comparison``, then the notes."""
    same = [t for t in scored if t.in_our_release]
    theirs_folds = their_folds(scored, ours)
    lines = ["Lea et al.'s ED-TCN (their released predictions) against our ED-TCN model A, "
             "original labels,", f"scored by rnn_seg.metrics; mean (std) over the "
             f"{len(ours)} folds of each fold's mean over its trials ({len(same)} trials):", "",
             f"{'metric':<10} {'ours (A)':>14} {'theirs':>14} {'ours - theirs':>14} {WITHIN:>10}"]
    for r in comparison(scored, ours):
        lines.append(f"{r['metric']:<10} {r['ours_mean']:>7.2f} ({r['ours_std']:4.1f}) "
                     f"{r['theirs_mean']:>7.2f} ({r['theirs_std']:4.1f}) "
                     f"{r['ours_minus_theirs']:>+14.2f} {r[WITHIN]:>10}")
    strides = {u: sorted({t.stride for t in same if t.user == u}) for u in theirs_folds}
    lines += ["", "their samples: " + ", ".join(
        f"{u} every {'/'.join(map(str, r))} frames ({'/'.join(f'{KINEMATICS_HZ / x:g}' for x in r)}"
        f" Hz)" for u, r in strides.items())]
    held_5 = over_folds(fold_means(same, "scores_5hz"))
    lines.append("theirs held at our 5 Hz samples: " + ", ".join(
        f"{m} {held_5[m][0]:.2f}" for m in METRICS))
    others = [t.trial for t in scored if not t.in_our_release]
    if others:
        every = over_folds(fold_means(scored))
        lines.append(f"theirs with {', '.join(others)} (not in our release): " + ", ".join(
            f"{m} {every[m][0]:.2f}" for m in METRICS))
    pooled = {m: float(np.mean([t.scores[m] for t in scored])) for m in METRICS}
    lines.append(f"theirs, mean over all {len(scored)} trials (their compare_predictions.py): "
                 + ", ".join(f"{m} {pooled[m]:.2f}" for m in METRICS))
    lines += ["", "per fold (ours / theirs):"]
    for u in sorted(theirs_folds):
        lines.append(f"  {u}: " + ", ".join(f"{m} {ours[u][m]:.1f} / {theirs_folds[u][m]:.1f}"
                                             for m in METRICS))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--reference", type=Path, required=True,
                        help="a checkout of colincsl/TemporalConvolutionalNetworks")
    parser.add_argument("--model", default="sensors_ED-TCN_L2_C15",
                        help="their predictions folder under predictions/JIGSAWS/")
    parser.add_argument("--data", type=Path, default=Path("../shared/jigsaws/Suturing"),
                        help="the JIGSAWS Suturing release")
    parser.add_argument("--ours", type=Path,
                        default=Path("results/tcn/ed-tcn-tables/per_fold.csv"))
    parser.add_argument("--csv", type=Path, metavar="FILE",
                        help="also write the table (per metric: ours, theirs, the difference, "
                             f"within {TOLERANCE:g} points) to FILE")
    args = parser.parse_args(argv)
    from jigsaws_tools.errors import JigsawsError
    try:
        if args.csv:
            check_destination(args.csv)
        ours = read_ours(args.ours)
        scored = score_reference(args.reference, args.model, args.data)
        print(report(scored, ours))
        if args.csv:
            write_csv(comparison(scored, ours), args.csv)
    except (UnusableFile, JigsawsError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

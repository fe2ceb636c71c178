"""A finished grid written without training: every file ``multitask-tables`` reads (grid.json,
config.json, metrics.json, predictions, history.csv, gradnorm.csv, finished.json), with made-up but
seeded
scores, so that tables, captions, curves and figures are tested in a second instead of a training
run per fold."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from jigsaws_tools.task_definition import SUTURING
from multitask.grid.spec import (PAPER_EXPERIMENTS, Experiment, GridSpec, RunKey, expand,
                                 run_config, spec_payload, with_budget)
from multitask.models.variants import get_variant
from rnn_seg.runs.folder import to_jsonable, write_json

GESTURES = SUTURING.gestures
STAGES = SUTURING.stage_names
FOLDS = ("B", "C", "D", "E", "F", "G", "H", "I")
#: Test trials per fold: user G has one trial fewer, as in the real release.
TRIALS = {fold: 4 if fold == "G" else 5 for fold in FOLDS}
#: Gestures that never occur in a fold's test trials (their accuracy is NaN there), and one that
#: occurs but is never recognised (accuracy 0).
ABSENT = {"G10"}
NEVER_RECOGNISED = "G9"
SAMPLES = 60                       # per test trial, at 5 Hz


def write_fake_grid(root: Path, seeds: tuple[int, ...] = (0, 1), hidden: int = 16,
                    epochs: int = 12,
                    experiments: tuple[Experiment, ...] = PAPER_EXPERIMENTS,
                    schedule_factors: dict[str, float] | None = None,
                    per_class: bool = False, fingerprint: str | None = None,
                    encoder: str = "lstm", seconds: float | None = None,
                    precision: str = "fp32", loops: str = "graph", scores_seed: int = 0,
                    data: Path | None = None) -> Path:
    """Every run of a grid (default: the paper's, 22 configurations) over 8 folds and ``seeds``
    under ``root``; every variant at the paper's relative length unless ``schedule_factors``.
    ``per_class``: metrics.json holds per-class precision, recall, F1 and the confusion matrices
    (as runs finished since they were saved); without it, as an older archive's runs.
    ``fingerprint``: every config.json records it as the data's, and grid.json records the spec,
    so that the tables check every run against it (fixed weightings and offline models only: a
    GradNorm or ordered head's settings are not written); without it, grid.json records no spec,
    as an early version's. ``encoder``: a TCN's grid (``hidden``, ``epochs`` and
    ``schedule_factors`` then unused: its reference schedule). ``seconds``: every run's
    ``timing.json`` records this many seconds (data loading and training). ``precision``,
    ``loops``: the LSTM's execution path every config.json records; ``scores_seed`` seeds the
    fake scores (another value: other scores). ``data``: a (synthetic) Suturing release the runs
    record as theirs, whose test trials (names and lengths) their predictions then follow, so that
    the example figures find their true labels there."""
    lstm = encoder == "lstm"
    path = {"precision": precision, "loops": loops} if lstm else {}
    spec = GridSpec(data_dir=str(data or root / "data" / "Suturing"), seeds=seeds,
                    hidden=hidden if lstm else None, epochs=epochs if lstm else None,
                    experiments=experiments, encoder=encoder,
                    schedule_factors=(schedule_factors or {}) if lstm else None, **path)
    rng = np.random.default_rng(scores_seed)
    keys = expand(spec, FOLDS)
    trials = _test_trials(data)
    for key in keys:
        run_dir = root / key.path()
        config = run_config(spec, key)
        tasks = (["gesture"] if key.variant.startswith("A") else []) + (
            ["progress"] if "P" in key.variant else [])
        record = {"run": to_jsonable(config), "tasks": tasks, "variant": key.variant,
                  "weighting": key.weighting}
        _write_json(run_dir / "config.json",
                    record if fingerprint is None else {**record, "data_fingerprint": fingerprint})
        point = config.train.eval_points[-1]
        predictions = run_dir / "eval" / f"epoch{point:04d}" / "predictions"
        predictions.mkdir(parents=True)
        for name, samples in trials[key.fold].items():
            _predictions(rng, tasks, key.variant, samples).to_csv(predictions / f"{name}.csv",
                                                                  index=False)
        _history(rng, tasks, config.optim.total).to_csv(run_dir / "history.csv", index=False)
        if key.weighting == "gradnorm":
            n = np.arange(1, config.optim.total + 1)
            w = 1 + 0.3 * np.tanh(n / 5)
            pd.DataFrame({"sweep": 7 * n, "unit": n, "w_end_gesture": w,
                          "w_end_progress": 2 - w}).to_csv(run_dir / "gradnorm.csv", index=False)
        mean = {task: _scores(rng, task, key.variant) for task in tasks}
        metrics = {"points": {str(point): mean}, "mean": mean, "unit": "epochs"}
        if per_class:
            metrics["confusion"] = {task: _confusion(rng, task) for task in tasks}
            for task in tasks:
                mean[task].update(_class_scores(metrics["confusion"][task]))
        _write_json(run_dir / "metrics.json", metrics)
        _write_json(run_dir / "finished.json", {"sweeps": 7 * config.optim.total})
        if seconds is not None:
            _write_json(run_dir / "timing.json", {"data": 0.5, "train": seconds - 0.5})
    runs = [str(key.path()) for key in keys]
    _write_json(root / "grid.json", {"runs": runs} if fingerprint is None
                else {"spec": spec_payload(with_budget(spec)), "runs": runs})
    return root


def write_fake_run(run_dir: Path, key: RunKey, mean: dict[str, dict[str, float | None]],
                   hidden: int = 16, epochs: int = 12) -> Path:
    """A finished run of ``key`` at ``hidden`` units, ``epochs`` long (the variant's relative
    length), without training: config.json, metrics.json of one evaluation point whose scores
    are ``mean`` (a task of the variant that ``mean`` lacks scores an accuracy of 50), and
    finished.json. Returns ``run_dir``."""
    spec = GridSpec(data_dir=str(run_dir), seeds=(key.seed,), hidden=hidden, epochs=epochs,
                    schedule_factors={})
    config = run_config(spec, key)
    tasks = list(get_variant(key.variant).task_names)
    _write_json(run_dir / "config.json", {"run": to_jsonable(config), "tasks": tasks,
                                          "variant": key.variant, "weighting": key.weighting})
    mean = {task: mean.get(task, {"accuracy": 50.0}) for task in tasks}
    _write_json(run_dir / "metrics.json", {"points": {str(config.train.eval_points[-1]): mean},
                                           "mean": mean, "unit": "epochs"})
    _write_json(run_dir / "finished.json", {"sweeps": 7 * config.optim.total})
    return run_dir


def _test_trials(data: Path | None) -> dict[str, dict[str, int]]:
    """Per fold, its test trials' names and lengths in samples: ``data``'s, else ``TRIALS``
    trials of ``SAMPLES`` samples."""
    if data is None:
        return {fold: {f"Suturing_{fold}{k:03d}": SAMPLES for k in range(1, TRIALS[fold] + 1)}
                for fold in FOLDS}
    from jigsaws_tools.dataset import DataConfig, load_dataset

    found: dict[str, dict[str, int]] = {fold: {} for fold in FOLDS}
    for trial in load_dataset(DataConfig(str(data))).trials:
        found[trial.user][trial.name] = len(trial)
    return found


def _write_json(path: Path, obj) -> None:
    """Strict JSON (NaN as null), as every file of a real run."""
    write_json(path, obj)


def _scores(rng: np.random.Generator, task: str, variant: str) -> dict[str, float]:
    scores = {name: float(rng.uniform(70, 95)) for name in ("accuracy", "edit", "f1@10")}
    if task == "gesture":
        for g in GESTURES:
            scores[f"accuracy_{g}"] = (float("nan") if g in ABSENT else
                                       0.0 if g == NEVER_RECOGNISED else float(rng.uniform(40, 99)))
    elif variant.endswith("Pr"):
        scores["mae_normalised"] = float(rng.uniform(4, 12))
        scores["mae_normalised_rounded"] = 0.8 * scores["mae_normalised"]   # no extra draw
    return scores


def _confusion(rng: np.random.Generator, task: str) -> dict:
    """A confusion matrix of ``task``'s classes with a heavy diagonal; ``ABSENT`` gestures never
    occur (an empty row) and ``NEVER_RECOGNISED`` is never predicted (an empty column)."""
    classes = GESTURES if task == "gesture" else STAGES
    counts = rng.integers(0, 5, size=(len(classes), len(classes))) + 40 * np.eye(len(classes),
                                                                                 dtype=int)
    for k, name in enumerate(classes):
        if name in ABSENT:
            counts[k] = 0
        if name == NEVER_RECOGNISED:
            counts[:, k] = 0
    return {"classes": list(classes), "counts": counts}


def _class_scores(confusion: dict) -> dict[str, float]:
    """The per-class precision, recall and F1 of a confusion matrix (rnn_seg.metrics)."""
    from rnn_seg.metrics import class_scores

    return {f"{kind}_{c}": float(v)
            for kind, values in zip(("precision", "recall", "f1"),
                                    class_scores(confusion["counts"]))
            for c, v in zip(confusion["classes"], values)}


def _labels(rng: np.random.Generator, classes: int, samples: int) -> np.ndarray:
    lengths = rng.integers(4, 12, size=samples)
    labels = np.repeat(rng.integers(0, classes, size=samples), lengths)
    return labels[:samples]


def _predictions(rng: np.random.Generator, tasks: list[str], variant: str,
                 samples: int = SAMPLES) -> pd.DataFrame:
    """One row per 5 Hz sample, in the format of ``rnn_seg.predictions``."""
    frames = 1 + 6 * np.arange(samples)
    columns: dict[str, np.ndarray] = {"frame": frames, "time_s": (frames - 1) / 30,
                                      "sample": np.arange(samples)}
    for task, names in (("gesture", GESTURES), ("progress", STAGES)):
        if task not in tasks:
            continue
        true = _labels(rng, len(names), samples)
        pred = np.where(rng.random(samples) < 0.8, true, _labels(rng, len(names), samples))
        columns[task], columns[f"{task}_true"] = np.asarray(names)[pred], np.asarray(names)[true]
        if task == "progress" and variant.endswith("Pr"):          # regression: the raw output
            columns["progress_value"] = true + rng.normal(0, 0.4, samples)
        elif task == "progress" and variant.endswith("oc"):        # ordinal: sigmoid outputs
            columns.update({f"progress_y_{n}": (pred >= k) * 0.9 for k, n in enumerate(names)})
        else:                                                       # softmax probabilities
            columns.update({f"{task}_p_{n}": (pred == k) * 0.9 + 0.01
                            for k, n in enumerate(names)})
    return pd.DataFrame(columns)


def _history(rng: np.random.Generator, tasks: list[str], epochs: int) -> pd.DataFrame:
    """One row per epoch; test scores only every third epoch and at the end (empty otherwise)."""
    n = np.arange(1, epochs + 1)
    table = pd.DataFrame({"unit": "epochs", "n": n.astype(float), "sweep": 7 * n, "lr": 1.0})
    for task in tasks:
        table[f"loss_{task}"] = 2.0 / n + rng.uniform(0, 0.1, epochs)
    table["seconds"] = rng.uniform(1.0, 1.5, epochs)
    scored = (n % 3 == 0) | (n == epochs)
    for task in tasks:
        table[f"test_{task}_acc"] = np.where(scored, 60 + 30 * (1 - 1 / n), np.nan)
    return table

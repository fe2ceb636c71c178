"""A finished run's ``metrics.json``, checked before any table uses it.

``rnn_seg.trainer.Trainer.finish`` writes it: ``points`` (per evaluation point, per task, each
metric; ``null`` for NaN), ``mean`` (their mean over the points, the value tables use),
``convergence`` and, since per-class scores were saved, ``confusion`` (per task, its ``classes``
and the ``[K, K]`` ``counts`` summed over the points, rows true, columns predicted). A file that
contradicts itself or its run is refused, one line naming the file and the field: the mean tasks
other than the run's (its config.json), a metric that is not a number, a mean that is not the
mean of its points (to ``TOLERANCE``: a file rounded by hand still agrees), a confusion matrix of
other classes than the run's task definition or whose counts are not a ``[K, K]`` table of
non-negative integers.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rnn_seg.runs.folder import RunFolderError, read_json

from ...models.run_record import RunRecord

METRICS_FILE = "metrics.json"
#: How far a mean may lie from the mean of its points (percent points, or normalised MAE).
TOLERANCE = 1e-3


def read_metrics(run_dir: Path, record: RunRecord) -> dict:
    """The checked ``metrics.json`` of the finished run ``run_dir`` whose config.json is
    ``record``.

    Raises:
        RunFolderError: one line naming the file and the field at fault.
    """
    path = Path(run_dir) / METRICS_FILE
    metrics = read_json(path)
    if not isinstance(metrics, dict):
        raise RunFolderError(f"{path}: not a run's metrics (value: {str(metrics)[:60]!r})")
    mean = _per_task(metrics.get("mean"), path, "mean")
    if set(mean) != set(record.tasks):
        raise RunFolderError(f"{path}: mean: tasks {sorted(mean)}, but the run's config.json "
                             f"records {sorted(record.tasks)}")
    points = metrics.get("points")
    if not isinstance(points, dict) or not points:
        raise RunFolderError(f"{path}: points: no metrics per evaluation point (value: "
                             f"{str(points)[:60]!r})")
    values = {point: _per_task(scores, path, f"points.{point}") for point, scores in points.items()}
    for task, names in mean.items():
        for name, value in names.items():
            _check_mean(path, f"{task}.{name}", value,
                        [scores.get(task, {}).get(name, math.nan) for scores in values.values()])
    if "confusion" in metrics:
        _check_confusion(path, metrics["confusion"], record)
    return metrics


def _per_task(value, path: Path, field: str) -> dict[str, dict[str, float]]:
    """``value`` as ``{task: {metric: number or NaN}}``, or a ``RunFolderError`` naming
    ``field``."""
    if not isinstance(value, dict) or not all(isinstance(v, dict) for v in value.values()):
        raise RunFolderError(f"{path}: {field}: no metrics per task (value: {str(value)[:60]!r})")
    for task, names in value.items():
        for name, number in names.items():
            if number is not None and (isinstance(number, bool)
                                       or not isinstance(number, (int, float))):
                raise RunFolderError(f"{path}: {field}.{task}.{name}: not a number "
                                     f"(value: {number!r})")
    return {task: {name: math.nan if number is None else float(number)
                   for name, number in names.items()} for task, names in value.items()}


def _check_mean(path: Path, field: str, mean: float, points: list[float]) -> None:
    """Raise unless ``mean`` is the mean of ``points`` (NaN when one of them is)."""
    expected = float(np.mean(points))
    if math.isnan(expected) and math.isnan(mean):
        return
    if math.isnan(expected) or math.isnan(mean) or abs(expected - mean) > TOLERANCE:
        raise RunFolderError(f"{path}: mean.{field}: {mean:g} is not the mean of its "
                             f"evaluation points ({expected:g})")


def _check_confusion(path: Path, confusion, record: RunRecord) -> None:
    """Raise unless ``confusion`` holds, per task of the run, a matrix of its classes."""
    if not isinstance(confusion, dict):
        raise RunFolderError(f"{path}: confusion: not a confusion matrix per task (value: "
                             f"{str(confusion)[:60]!r})")
    if set(confusion) != set(record.tasks):
        raise RunFolderError(f"{path}: confusion: tasks {sorted(confusion)}, but the run's "
                             f"config.json records {sorted(record.tasks)}")
    for task, matrix in confusion.items():
        field = f"confusion.{task}"
        if not isinstance(matrix, dict):
            raise RunFolderError(f"{path}: {field}: not a confusion matrix (value: "
                                 f"{str(matrix)[:60]!r})")
        classes = record.classes(task)
        if matrix.get("classes") != list(classes):
            raise RunFolderError(f"{path}: {field}.classes: {matrix.get('classes')!r} are not the "
                                 f"run's {task} classes {list(classes)}")
        counts = matrix.get("counts")
        square = isinstance(counts, list) and len(counts) == len(classes) and all(
            isinstance(row, list) and len(row) == len(classes) for row in counts)
        if not square or not all(isinstance(n, int) and not isinstance(n, bool) and n >= 0
                                 for row in counts for n in row):
            raise RunFolderError(f"{path}: {field}.counts: not a {len(classes)} x {len(classes)} "
                                 f"table of non-negative integers (value: {str(counts)[:60]!r})")

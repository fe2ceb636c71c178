"""Experiment tracking: finished run folders logged to MLflow (``pip install -e ".[mlflow]"``).

``--mlflow URI`` (``multitask-train``, ``multitask-grid``; ``multitask.train(mlflow=URI)``)
logs each run once it has finished, read from its folder, so that nothing but the process that
waits for the run needs MLflow (not a grid's local or Dask workers) and a run interrupted and
resumed is logged once, whole:

* its settings as parameters: config.json flattened (``run.encoder.hidden``,
  ``run.optim.learning_rate``, ``variant``, ``weighting``, ``gradnorm.alpha``, ``tasks``,
  ``data_fingerprint``, ``settings_hash``; a value longer than MLflow takes is cut);
* every ``history.csv`` row as metrics at step = its sweep count: ``epoch`` (or ``sweep``), the
  learning rate, each task's loss, the test scores where the row has them, seconds per unit;
  a GradNorm run's ``gradnorm.csv`` rows too, as ``gradnorm.<column>`` (``gradnorm.w_end_gesture``);
* its final scores (``metrics.json``'s mean over the evaluation points) as ``final.<task>.<score>``
  (``final.gesture.accuracy``, ``final.gesture.f1_10`` for F1@10: MLflow names take no ``@``).

The LSTM loops a run started on (config.json's ``provenance.loops``: ``fused`` or ``graph`` for
the parameter ``run.encoder.loops = auto``) are its tag ``mtrnn.loops``.

A grid is one parent MLflow run (its spec as parameters), its runs nested under it. Runs are
found again by their tags (``mtrnn.run_dir``, ``mtrnn.settings_hash``; a grid's
``mtrnn.grid_dir``): the same command again logs nothing twice. ``URI`` is any MLflow tracking
URI: ``sqlite:///mlflow.db``, ``http://host:5000``, or a folder (``file:./mlruns``; MLflow 3
refuses its file store unless ``MLFLOW_ALLOW_FILE_STORE=true``, and says so). The experiment is
``$MLFLOW_EXPERIMENT_NAME``, else ``mtrnn-jigsaws``.
"""
from __future__ import annotations

import csv
import math
import os
import re
import time
from datetime import datetime
from pathlib import Path
from typing import Any, Iterator

from .folder import CONFIG, GRADNORM_LOG, HISTORY, is_finished, read_json
from .provenance import started_loops

DEFAULT_EXPERIMENT = "mtrnn-jigsaws"
INSTALL = 'MLflow is not installed: pip install -e ".[mlflow]" (or pip install mlflow-skinny)'
#: MLflow's limits: characters of a parameter's value, entries of one ``log_batch`` call.
MAX_PARAM_CHARS, MAX_BATCH = 6000, 1000
#: history.csv columns that are the step's coordinates rather than metrics.
_STEP_COLUMNS = {"unit", "n", "sweep", "elapsed_seconds"}


class TrackingError(ValueError):
    """MLflow is missing, or the tracking URI cannot be used; the message says which and why (a
    user's error: the commands print it in one line)."""


class Tracker:
    """One MLflow experiment at ``uri``, checked at once (``TrackingError`` naming the URI and
    MLflow's reason), logging finished run folders (``log_run``), nested under a grid's parent
    run (``start_grid``) when one is open."""

    def __init__(self, uri: str):
        try:
            from mlflow.tracking import MlflowClient
        except ImportError:
            raise TrackingError(INSTALL) from None
        self.uri = uri
        name = os.environ.get("MLFLOW_EXPERIMENT_NAME") or DEFAULT_EXPERIMENT
        try:
            self.client = MlflowClient(tracking_uri=uri)
            found = self.client.get_experiment_by_name(name)
            self.experiment = (found.experiment_id if found is not None
                               else self.client.create_experiment(name))
        except Exception as error:                    # MLflow's own errors have no common base
            raise TrackingError(f"--mlflow {uri}: {_first_line(error)}") from None
        self.parent: str | None = None

    def start_grid(self, grid_dir: Path, spec: dict) -> str:
        """Open (or find again) the parent run of the grid in ``grid_dir``, its ``spec`` (plain
        data) as parameters; the runs logged from now on are nested under it. Returns its id."""
        key = str(Path(grid_dir).resolve())
        found = self._find("mtrnn.grid_dir", key)
        if found is None:
            run = self.client.create_run(self.experiment, run_name=f"grid {Path(key).name}",
                                         tags={"mtrnn.grid_dir": key})
            found = run.info.run_id
            self._log(found, params=_flat(spec))
        self.parent = found
        return found

    def end_grid(self, status: str = "FINISHED") -> None:
        """Close the grid's parent run: ``FINISHED``, ``FAILED`` or ``KILLED``."""
        if self.parent is not None:
            self.client.set_terminated(self.parent, status)
            self.parent = None

    def log_run(self, run_dir: Path) -> str | None:
        """Log the finished run in ``run_dir`` (settings, history, final scores) unless it was
        logged before; returns its MLflow run id, None for an unfinished run."""
        run_dir = Path(run_dir).resolve()
        if not is_finished(run_dir):
            return None
        config = read_json(run_dir / CONFIG)
        found = self._find("mtrnn.run_dir", str(run_dir), config.get("settings_hash"))
        if found is not None:
            return found
        tags = {"mtrnn.run_dir": str(run_dir), "mtrnn.settings_hash":
                str(config.get("settings_hash", ""))}
        if self.parent is not None:
            tags["mlflow.parentRunId"] = self.parent
        ran = started_loops(config)
        if ran is not None:                 # the parameter says what was asked, e.g. auto
            tags["mtrnn.loops"] = ran
        started = _started(config)
        run = self.client.create_run(self.experiment, run_name=_run_name(run_dir, config),
                                     tags=tags, start_time=started)
        run_id = run.info.run_id
        self._log(run_id, params={k: v for k, v in _flat(config).items()
                                  if not k.startswith("provenance.")})
        self._log(run_id, metrics=[*_csv_metrics(run_dir / HISTORY, started),
                                   *_csv_metrics(run_dir / GRADNORM_LOG, started, "gradnorm."),
                                   *_final_metrics(read_json(run_dir / "metrics.json"))])
        self.client.set_terminated(run_id, "FINISHED")
        return run_id

    def _find(self, tag: str, value: str, settings_hash: str | None = None) -> str | None:
        """The id of this experiment's run tagged ``tag = value`` (and with the settings hash,
        when given), None if there is none."""
        query = f"tags.`{tag}` = '{_quoted(value)}'"
        if settings_hash:
            query += f" and tags.`mtrnn.settings_hash` = '{_quoted(settings_hash)}'"
        runs = self.client.search_runs([self.experiment], filter_string=query, max_results=1)
        return runs[0].info.run_id if runs else None

    def _log(self, run_id: str, params: dict[str, str] | None = None,
             metrics: list | None = None) -> None:
        """``params`` and ``metrics`` (``mlflow.entities.Metric``) in batches MLflow takes."""
        from mlflow.entities import Param

        entries = [Param(k, v) for k, v in (params or {}).items()]
        for start in range(0, len(entries), 100):            # MLflow: 100 parameters a batch
            self.client.log_batch(run_id, params=entries[start:start + 100])
        metrics = metrics or []
        for start in range(0, len(metrics), MAX_BATCH):
            self.client.log_batch(run_id, metrics=metrics[start:start + MAX_BATCH])


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


def _quoted(value: str) -> str:
    return value.replace("\\", "\\\\").replace("'", "\\'")


def metric_name(name: str) -> str:
    """``name`` as MLflow takes it: characters other than letters, digits, ``_-. :/`` become
    ``_`` (``f1@10`` -> ``f1_10``)."""
    return re.sub(r"[^\w\-. :/]", "_", name)


def _flat(value: Any, prefix: str = "") -> dict[str, str]:
    """Nested plain data as ``{"a.b.c": "value"}``, lists as their JSON-like text, values cut to
    ``MAX_PARAM_CHARS``."""
    if isinstance(value, dict):
        out: dict[str, str] = {}
        for key, item in value.items():
            out.update(_flat(item, f"{prefix}{key}."))
        return out
    text = ", ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)
    return {metric_name(prefix.rstrip(".")): text[:MAX_PARAM_CHARS]}


def _started(config: dict) -> int:
    """The run's start (config.json's provenance) in ms since the epoch; now if not recorded."""
    stamp = config.get("provenance", {}).get("started")
    try:
        return int(datetime.fromisoformat(stamp).timestamp() * 1000)
    except (TypeError, ValueError):
        return int(time.time() * 1000)


def _run_name(run_dir: Path, config: dict) -> str:
    """``APoc-gradnorm B`` (variant, weighting, test user), else the folder's name."""
    variant, user = config.get("variant"), config.get("run", {}).get("test_user")
    if variant and user:
        return f"{variant}-{config.get('weighting', 'fixed')} {user}"
    return run_dir.name


def _csv_metrics(path: Path, started: int, prefix: str = "") -> Iterator:
    """One metric per filled cell of a CSV log (``history.csv``, ``gradnorm.csv``; none if the
    run has not this log): step = the row's sweep, time = the run's start plus the row's elapsed
    seconds where it has them; ``history.csv``'s ``epoch`` (or ``sweep``) = the row's units."""
    from mlflow.entities import Metric

    if not path.is_file():
        return
    with open(path, newline="") as file:
        for row in csv.DictReader(file):
            step = int(row["sweep"])
            stamp = started + int(1000 * float(row.get("elapsed_seconds") or 0))
            if "n" in row and not prefix:
                unit = "sweep" if row.get("unit") == "sweeps" else "epoch"
                yield Metric(unit, float(row["n"]), stamp, step)
            for column, cell in row.items():
                if column not in _STEP_COLUMNS and cell not in ("", None):
                    yield Metric(metric_name(prefix + column), float(cell), stamp, step)


def _final_metrics(saved: dict) -> list:
    """``final.<task>.<score>`` of ``metrics.json``'s mean, undefined scores left out."""
    from mlflow.entities import Metric

    now = int(time.time() * 1000)
    return [Metric(metric_name(f"final.{task}.{name}"), float(value), now, 0)
            for task, scores in saved.get("mean", {}).items() for name, value in scores.items()
            if isinstance(value, (int, float)) and math.isfinite(value)]

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

Beside them, its record and figures as artifacts: ``config.json``, ``metrics.json``,
``finished.json``, ``timing.json``, ``history.csv``, ``gradnorm.csv``, and per evaluation
point ``eval/<point>/metrics.json`` and ``eval/<point>/plots/*`` (never its weights or its
per-trial predictions, which carry the release's labels).

A grid is one parent MLflow run (its spec as parameters), its runs nested under it. Runs are
found again by their tags (``mtrnn.run_dir``, ``mtrnn.settings_hash``; a grid's
``mtrnn.grid_dir``), compared exactly whatever characters the folder's path holds: the same
command again logs nothing twice, and a run whose logging was cut short (a killed process, a
server gone) is logged again whole in place of the partial one.

``URI`` is any MLflow tracking URI:

* ``sqlite:///mlflow.db``: a database file (``pip install -e ".[mlflow]"`` brings the
  SQLAlchemy it needs); its artifacts go to MLflow's default place, ``./mlruns`` beside where
  the experiment was created. A file that cannot be opened or created (a missing or read-only
  folder, ``/proc``) is one line at once, where MLflow would retry it for two minutes;
* ``http://host:5000``: a tracking server. One that does not answer is reported within seconds
  (one try of at most ``CHECK_TIMEOUT`` seconds before any work; later, ``LOG_RETRIES`` retries
  of at most ``LOG_TIMEOUT`` seconds each, then a warning), unless ``MLFLOW_HTTP_REQUEST_*``
  in the environment say otherwise;
* a folder (``file:./mlruns``, ``./mlruns``): MLflow's file store, which MLflow 3 keeps in
  maintenance mode; named here, it is used as asked (``MLFLOW_ALLOW_FILE_STORE`` is set for
  it).

The experiment is ``$MLFLOW_EXPERIMENT_NAME``, else ``mtrnn-jigsaws``.
"""
from __future__ import annotations

import csv
import math
import os
import re
import sqlite3
import time
from contextlib import closing, contextmanager
from datetime import datetime
from pathlib import Path
from typing import Any, Iterator
from urllib.parse import urlparse

from .folder import CONFIG, FINISHED, GRADNORM_LOG, HISTORY, is_finished, read_json
from .provenance import started_loops

DEFAULT_EXPERIMENT = "mtrnn-jigsaws"
INSTALL = 'MLflow is not installed: pip install -e ".[mlflow]" (or pip install mlflow-skinny)'
#: MLflow's limits: characters of a parameter's value, entries of one ``log_batch`` call.
MAX_PARAM_CHARS, MAX_BATCH = 6000, 1000
#: history.csv columns that are the step's coordinates rather than metrics.
_STEP_COLUMNS = {"unit", "n", "sweep", "elapsed_seconds"}
#: A tracking server's limits: seconds of the one try that checks it before any work; retries
#: and seconds a try when a run is logged (MLflow's own: 7 retries, about 4 minutes).
CHECK_TIMEOUT, LOG_RETRIES, LOG_TIMEOUT = 10, 2, 30
#: A run's files logged as artifacts (those present), and per evaluation point, its scores and
#: figures (``eval/<point>/...``).
ARTIFACTS = (CONFIG, "metrics.json", FINISHED, "timing.json", HISTORY, GRADNORM_LOG)
POINT_ARTIFACTS = ("metrics.json", "plots")
#: The first bytes of every SQLite database file.
SQLITE_HEADER = b"SQLite format 3\x00"
#: Characters of a tag value a search filter cannot hold as they are (``_find``).
_UNQUOTABLE = re.compile(r"['\\%_]")


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
        problem = _scheme_problem(uri) or _database_problem(uri)
        if problem:
            raise TrackingError(f"--mlflow {uri}: {problem}")
        try:
            with self._limits(0, CHECK_TIMEOUT):
                self.client = MlflowClient(tracking_uri=uri)
                found = self.client.get_experiment_by_name(name)
                self.experiment = (found.experiment_id if found is not None
                                   else self.client.create_experiment(name))
        except Exception as error:                    # MLflow's own errors have no common base
            raise TrackingError(f"--mlflow {uri}: {_reason(error)}") from None
        self.parent: str | None = None

    @contextmanager
    def _limits(self, retries: int, timeout: int) -> Iterator[None]:
        """For the block, MLflow's settings this URI needs: a server's ``retries`` and
        ``timeout`` (unless the environment sets them), a folder's file store allowed."""
        scheme = urlparse(self.uri).scheme
        wanted = ({"MLFLOW_HTTP_REQUEST_MAX_RETRIES": str(retries),
                   "MLFLOW_HTTP_REQUEST_TIMEOUT": str(timeout)}
                  if scheme in ("http", "https") else
                  {"MLFLOW_ALLOW_FILE_STORE": "true"} if scheme in ("", "file") else {})
        added = {key: value for key, value in wanted.items() if key not in os.environ}
        os.environ.update(added)
        try:
            yield
        finally:
            for key in added:
                os.environ.pop(key, None)

    def start_grid(self, grid_dir: Path, spec: dict) -> str:
        """Open (or find again) the parent run of the grid in ``grid_dir``, its ``spec`` (plain
        data) as parameters; the runs logged from now on are nested under it. Returns its id."""
        key = str(Path(grid_dir).resolve())
        with self._limits(LOG_RETRIES, LOG_TIMEOUT):
            found = self._find({"mtrnn.grid_dir": key})
            if found is None:
                found = self.client.create_run(self.experiment,
                                               run_name=f"grid {Path(key).name}",
                                               tags={"mtrnn.grid_dir": key})
                self._log(found.info.run_id, params=_flat(spec))
        self.parent = found.info.run_id
        return self.parent

    def end_grid(self, status: str = "FINISHED") -> None:
        """Close the grid's parent run: ``FINISHED``, ``FAILED`` or ``KILLED``."""
        if self.parent is not None:
            with self._limits(LOG_RETRIES, LOG_TIMEOUT):
                self.client.set_terminated(self.parent, status)
            self.parent = None

    def log_run(self, run_dir: Path) -> str | None:
        """Log the finished run in ``run_dir`` (settings, history, final scores, its record and
        figures as artifacts) unless it was logged whole before; returns its MLflow run id, None
        for an unfinished run."""
        run_dir = Path(run_dir).resolve()
        if not is_finished(run_dir):
            return None
        config = read_json(run_dir / CONFIG)
        tags = {"mtrnn.run_dir": str(run_dir), "mtrnn.settings_hash":
                str(config.get("settings_hash", ""))}
        with self._limits(LOG_RETRIES, LOG_TIMEOUT):
            found = self._find(tags if config.get("settings_hash") else
                               {"mtrnn.run_dir": str(run_dir)})
            if found is not None and found.info.status == "FINISHED":
                return found.info.run_id
            if found is not None:                   # its logging was cut short: again, whole
                self.client.delete_run(found.info.run_id)
            return self._new_run(run_dir, config, tags)

    def _new_run(self, run_dir: Path, config: dict, tags: dict[str, str]) -> str:
        """Log the finished run in ``run_dir`` as a new MLflow run tagged ``tags``; it is
        marked finished last, once everything is logged."""
        if self.parent is not None:
            tags = {**tags, "mlflow.parentRunId": self.parent}
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
        for path, folder in _artifacts(run_dir):
            self.client.log_artifact(run_id, str(path), folder)
        self.client.set_terminated(run_id, "FINISHED")
        return run_id

    def _find(self, tags: dict[str, str]):
        """This experiment's run whose tags hold exactly ``tags``, None if there is none. The
        search matches a superset (each character MLflow's filter cannot quote, ``'`` and
        ``\\``, and the patterns' ``%`` and ``_``, stand for any one), then the tags are
        compared exactly."""
        query = " and ".join(f"tags.`{key}` LIKE '{_UNQUOTABLE.sub('_', value)}'"
                             for key, value in tags.items())
        token = None
        while True:
            page = self.client.search_runs([self.experiment], filter_string=query,
                                           max_results=100, page_token=token)
            for run in page:
                if all(run.data.tags.get(key) == value for key, value in tags.items()):
                    return run
            token = page.token
            if not token:
                return None

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


def _artifacts(run_dir: Path) -> list[tuple[Path, str | None]]:
    """The files of ``run_dir`` logged as artifacts (``ARTIFACTS``, ``POINT_ARTIFACTS``) that
    are there, each with the artifact folder it goes to (None: the top)."""
    found: list[tuple[Path, str | None]] = [(run_dir / name, None) for name in ARTIFACTS
                                            if (run_dir / name).is_file()]
    for point in sorted((run_dir / "eval").glob("*")):
        for name in POINT_ARTIFACTS:
            files = ([point / name] if (point / name).is_file()
                     else sorted((point / name).glob("*")))
            found += [(file, file.parent.relative_to(run_dir).as_posix())
                      for file in files if file.is_file() and not file.is_symlink()]
    return found


#: The URI schemes of MLflow's tracking stores ("": a folder).
SCHEMES = ("", "file", "http", "https", "sqlite", "postgresql", "mysql", "mssql", "databricks")


def _scheme_problem(uri: str) -> str | None:
    """Why ``uri``'s scheme names no MLflow tracking store, or None (MLflow's own message is a
    paragraph about its model registry)."""
    scheme = urlparse(uri).scheme.split("+")[0]            # postgresql+psycopg2 and the like
    if scheme in SCHEMES or len(scheme) == 1:              # or a Windows drive letter
        return None
    return (f"unsupported scheme {scheme!r}: give a folder, or a URI of "
            f"{', '.join(f'{name}:' for name in SCHEMES[1:])}")


def _database_problem(uri: str) -> str | None:
    """What keeps the SQLite database file of a ``sqlite:///`` URI from being opened or
    created, or None: MLflow would retry it for about two minutes, warning at each try."""
    if not uri.startswith("sqlite:///"):
        return None
    path = Path(uri[len("sqlite:///"):].split("?")[0])
    if path.is_dir() or (path.exists() and not path.is_file()):
        return f"{path} is not a database file (a folder, or not a regular file)"
    if path.is_file() and path.stat().st_size and _read_head(path) != SQLITE_HEADER:
        return f"{path} is not an SQLite database"
    blocked = next((parent for parent in path.parents if parent.exists()
                    and not parent.is_dir()), None)
    if blocked is not None:
        return f"cannot create {path}: {blocked} is a file, not a folder"
    return _unopenable(path)


def _unopenable(path: Path) -> str | None:
    """SQLite's reason it cannot open or create the database file ``path`` (a missing or
    read-only folder, a file system that holds no files), or None; a file this check created
    is removed again (MLflow creates it)."""
    existed = path.exists()
    try:
        with closing(sqlite3.connect(path, timeout=CHECK_TIMEOUT)) as database:
            database.execute("PRAGMA schema_version")
    except sqlite3.Error as error:
        return f"cannot open or create {path} ({error})"
    finally:
        if not existed:
            path.unlink(missing_ok=True)
    return None


def _read_head(path: Path) -> bytes:
    """The first bytes of the file ``path``, as many as an SQLite header has."""
    with open(path, "rb") as file:
        return file.read(len(SQLITE_HEADER))


def _reason(error: BaseException) -> str:
    """MLflow's reason, in one line; a server that cannot be reached said so plainly."""
    text = _first_line(error)
    if re.search(r"Connection refused|Failed to establish|Max retries exceeded|timed out", text):
        cause = re.search(r"Connection refused|timed out|Name or service not known", text)
        return (f"no MLflow tracking server answers there ("
                f"{cause.group() if cause else 'cannot connect'}); start one, or name another")
    return text


def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return text.splitlines()[0] if text else type(error).__name__


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

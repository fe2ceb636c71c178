"""One job of a grid, as a worker process runs it: a group of runs of one configuration.

A job takes and returns plain data (so process pools and Dask can ship it), trains its runs
together (``rnn_seg.stack``) and logs each run to ``<run dir>/train.log``. This module imports
TensorFlow only inside ``run_job``, after quieting it, so that a worker process that unpickles
the job prints none of TensorFlow's start-up lines.
"""
from __future__ import annotations

import logging
import time
import traceback
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Callable, Iterator, TextIO

from jigsaws_tools.cli.common import import_tensorflow
from jigsaws_tools.messages import new_command
from rnn_seg.runs.provenance import set_command

from .spec import RunKey, run_arguments, spec_from_dict

Log = Callable[[str], None]


class JobFailed(Exception):
    """A job's error as ``error_text`` words it: what a worker returns to the grid's process,
    where unpickling the original exception would import the module that defines it (the
    trainer's, TensorFlow's) and print TensorFlow's start-up lines."""


def error_text(error: BaseException) -> str:
    """``"<type>: <message>"`` of a job's error, as the grid reports a failed run."""
    return str(error) if isinstance(error, JobFailed) else f"{type(error).__name__}: {error}"


def run_job(spec: dict, keys: list[dict], out: str, cores: int, command: list[str] | None = None
            ) -> list[dict]:
    """Train a group of runs of one configuration (resuming interrupted ones) and return each
    one's ``metrics.json`` content; several runs train together in one vectorised step
    (``rnn_seg.stack``).

    Takes and returns plain data so that process pools and Dask workers can ship it; each run's
    log (and the traceback of a failure) goes to ``<run dir>/train.log``, and so do the warnings
    of the data layer (the submitting process has shown them once already). A failure raises
    ``JobFailed``.

    Args:
        spec: the grid's spec as plain data (``spec.spec_payload``).
        keys: the group's runs, each a ``RunKey`` as a dict (``dataclasses.asdict``).
        out: the grid's folder.
        cores: TensorFlow threads of the job (0 = all the cores this process may use).
        command: the grid's command line, recorded in each run's provenance; None = this
            process's.
    """
    import_tensorflow()
    from jigsaws_tools.dataset import load_dataset
    from rnn_seg.stack import train_together
    from rnn_seg.threads import configure_threads

    from ..models.fold_run import variant_trainer

    if command:
        set_command(command)
    grid, runs = spec_from_dict(spec), [RunKey(**key) for key in keys]
    configure_threads(cores, grid.budget.hidden, grid.precision,
                      bidirectional=runs[0].direction == "bidirectional")
    run_dirs = [Path(out) / run.path() for run in runs]
    with ExitStack() as files:
        logs = []
        for run_dir in run_dirs:
            run_dir.mkdir(parents=True, exist_ok=True)
            logs.append(_line_writer(files.enter_context(open(run_dir / "train.log", "a"))))
        files.enter_context(_warnings_to(logs))
        try:
            arguments = [run_arguments(grid, run) for run in runs]
            began = time.perf_counter()
            dataset = load_dataset(arguments[0]["config"].data)   # one configuration: one release
            loading = (time.perf_counter() - began) / len(runs)
            trainers = [variant_trainer(**args, run_dir=run_dir, dataset=dataset, log=log)
                        for args, run_dir, log in zip(arguments, run_dirs, logs)]
            for trainer in trainers:
                trainer.clock.add("data", loading)          # shared by the job's runs
            return train_together(trainers)
        except Exception as error:
            for log in logs:
                log(traceback.format_exc())
            raise JobFailed(error_text(error)) from None


def _line_writer(file: TextIO) -> Log:
    def write(message: str) -> None:
        file.write(message + "\n")
        file.flush()
    return write


class _ToLogs(logging.Handler):
    def __init__(self, logs: list[Log]):
        super().__init__(logging.WARNING)
        self.logs = logs

    def emit(self, record: logging.LogRecord) -> None:
        for log in self.logs:
            log(f"{record.levelname}: {record.getMessage()}")


@contextmanager
def _warnings_to(logs: list[Log]) -> Iterator[None]:
    """Send ``jigsaws_tools``' warnings to the runs' logs instead of the worker's terminal, each
    once per job (``jigsaws_tools.messages``: a worker runs many)."""
    new_command()
    logger = logging.getLogger("jigsaws_tools")
    handler, propagate = _ToLogs(logs), logger.propagate
    logger.addHandler(handler)
    logger.propagate = False
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.propagate = propagate

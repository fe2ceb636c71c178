"""One job of a grid, as a worker process runs it: a group of runs of one configuration.

A job takes and returns plain data (so process pools and Dask can ship it), trains its runs
together (``rnn_seg.stack``, which holds each run folder's lock) and logs each run to
``<run dir>/train.log``.
"""
from __future__ import annotations

import time
import traceback
from contextlib import ExitStack
from pathlib import Path
from typing import Callable, TextIO

from jigsaws_tools.dataset import load_dataset
from rnn_seg.provenance import set_command
from rnn_seg.stack import train_together
from rnn_seg.threads import configure_threads

from .fold_run import variant_trainer
from .grid_spec import RunKey, run_arguments, spec_from_dict


def run_job(spec: dict, keys: list[dict], out: str, cores: int, command: list[str] | None = None
            ) -> list[dict]:
    """Train a group of runs of one configuration (resuming interrupted ones) and return each
    one's ``metrics.json`` content; several runs train together in one vectorised step
    (``rnn_seg.stack``). ``command``: the grid's command line, recorded in each run's provenance.

    Takes and returns plain data so that process pools and Dask workers can ship it; each run's
    log (and the traceback of a failure) goes to ``<run dir>/train.log``.
    """
    if command:
        set_command(command)
    grid, runs = spec_from_dict(spec), [RunKey(**key) for key in keys]
    configure_threads(cores, grid.budget.hidden)
    run_dirs = [Path(out) / run.path() for run in runs]
    with ExitStack() as files:
        logs = []
        for run_dir in run_dirs:
            run_dir.mkdir(parents=True, exist_ok=True)
            logs.append(_line_writer(files.enter_context(open(run_dir / "train.log", "a"))))
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
        except Exception:
            for log in logs:
                log(traceback.format_exc())
            raise


def _line_writer(file: TextIO) -> Callable[[str], None]:
    def write(message: str) -> None:
        file.write(message + "\n")
        file.flush()
    return write

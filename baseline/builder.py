"""Model "A": DiPietro et al.'s BiLSTM gesture recogniser (and its forward-LSTM online twin)."""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable, Sequence

from jigsaws_tools.dataset import DataConfig, Dataset, Trial, data_fingerprint, load_dataset
from jigsaws_tools.task_definition import SUTURING, TaskDefinition
from rnn_seg.model import SegmentationModel
from rnn_seg.tasks import SoftmaxClassification, Task
from rnn_seg.trainer import SequenceSet, Trainer

from .config import RunConfig

#: Trial attribute holding each task's integer labels.
LABEL_FIELDS = {"gesture": "gestures", "progress": "progress"}


def gesture_task(task: TaskDefinition = SUTURING) -> Task:
    """Softmax over ``task``'s gestures (Suturing, the default: 10-way, G1-G6, G8-G11), mean
    cross-entropy."""
    return SoftmaxClassification("gesture", task.gestures)


def to_sequences(trials: Sequence[Trial], tasks: Sequence[Task], data: DataConfig
                 ) -> SequenceSet:
    """Trials -> the engine's named sequences with one label list per task; their frames at the
    rate of ``data``'s recording format (30 Hz for the release)."""
    return SequenceSet(
        names=[t.name for t in trials],
        inputs=[t.inputs for t in trials],
        labels={task.name: [getattr(t, LABEL_FIELDS[task.name]) for t in trials] for task in tasks},
        frames=[t.frames for t in trials], frame_hz=data.recording_format.rate_hz)


TrainerFactory = Callable[..., Trainer]


def run_configs(config: RunConfig, tasks: Sequence[Task], extra_configs: dict | None = None,
                fingerprint: str | None = None) -> dict:
    """What a run's config.json records and its folder is checked against.

    Args:
        config: the run's configuration.
        tasks: the model's tasks; their names are recorded.
        extra_configs: further entries (variant, weighting, ...); None = none.
        fingerprint: the data fingerprint (``data_fingerprint``); None = compute it, which
            reads the release files.
    """
    return {"run": config, "tasks": [t.name for t in tasks], **(extra_configs or {}),
            "data_fingerprint": fingerprint or data_fingerprint(config.data)}


def build_trainer(config: RunConfig, tasks: Sequence[Task], run_dir: Path,
                  dataset: Dataset | None = None, trainer: TrainerFactory = Trainer,
                  extra_configs: dict | None = None, log: Callable[[str], None] = print) -> Trainer:
    """Load the fold's data (unless ``dataset`` is given), build the model and return a ready
    ``Trainer`` for ``run_dir``; the loading time goes to the trainer's ``data`` phase.

    Args:
        config: the run's configuration (data, fold, encoder, schedule, training).
        tasks: one head per task, in this order.
        run_dir: the run folder.
        dataset: ``config.data``'s dataset, already loaded (config.json records its
            ``fingerprint``); None = load it.
        trainer: the class (or a factory with ``Trainer``'s parameters) to build, e.g.
            ``GradNormTrainer`` with its configuration bound.
        extra_configs: further entries of config.json (``run_configs``); None = none.
        log: where the trainer's progress lines go.
    """
    began = time.perf_counter()
    dataset = dataset or load_dataset(config.data)
    loading = time.perf_counter() - began
    train, test = dataset.louo_split(config.test_user, config.held_out_users)
    model = SegmentationModel(dataset.num_features, config.encoder, tasks, config.train.seed)
    built = trainer(model, tasks, config.optim, config.train,
                    to_sequences(train, tasks, config.data), to_sequences(test, tasks, config.data),
                    run_dir, run_configs(config, tasks, extra_configs, dataset.fingerprint),
                    config.data.preprocessing.sample_hz, log=log)
    built.clock.add("data", loading)
    return built


def train_baseline(config: RunConfig, run_dir: Path, dataset: Dataset | None = None,
                   log: Callable[[str], None] = print, restart: bool = False) -> dict:
    """Train model A on one fold.

    Args:
        config: the run's configuration.
        run_dir: the run folder; an unfinished run there resumes.
        dataset: ``config.data``'s dataset, already loaded; None = load it.
        log: where progress lines go.
        restart: delete a previous run's config and results in ``run_dir`` first.

    Returns:
        The run's metrics (``metrics.json``'s content, see ``rnn_seg.trainer``).
    """
    return build_trainer(config, [gesture_task(config.data.task)], run_dir, dataset,
                         log=log).run(restart)

"""What a table's caption states about the runs behind it: data, trials, folds, model width,
epochs and seeds, read from the runs themselves (their ``config.json`` and test predictions, or
the test trials a scores archive recorded), so that a caption never claims a budget the runs did
not have.
"""
from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from jigsaws_tools.task_definition import PAPER_TASK
from rnn_seg.runs.folder import read_json

from ...grid.archive import archived_test_trials
from ...grid.kept_predictions import kept_trials
from ...grid.spec import RunKey
from ...models.variants import VARIANTS

#: Folder name prefix of the synthetic releases ``jigsaws_tools.synth.ensure_release`` writes.
_SYNTHETIC_PREFIX = "synthetic-"


@dataclass(frozen=True)
class RunsDescription:
    """The common facts of a set of runs; what their files do not tell is left empty."""

    data: str                                # e.g. "JIGSAWS Suturing kinematics"
    trials: int                              # test trials over all folds (each trial once)
    folds: tuple[str, ...]                   # the test users
    seeds: tuple[int, ...]
    hidden: tuple[int, ...] = ()             # LSTM widths
    encoders: tuple[str, ...] = ()           # TCNs, users' encoders by path (rnn_seg.encoders)
    lengths: dict[int, tuple[str, ...]] = field(default_factory=dict)  # length -> its variants
    unit: str = "epochs"                     # of the lengths: "epochs" or "sweeps"
    selected: tuple[str, ...] = ()           # settings a nested selection chose per outer fold

    def sentence(self) -> str:
        """E.g. ``Data: JIGSAWS Suturing kinematics, 38 trials, leave-one-user-out over 8 folds
        (B, ..., I). Models: 128 hidden units, 30 epochs (20 for Pr, Pc, Poc), 1 seed (0).``"""
        data = [f"Data: {self.data}"] + ([f"{self.trials} trials"] if self.trials else [])
        data.append(f"leave-one-user-out over {len(self.folds)} fold{'s' * (len(self.folds) != 1)} "
                    f"({', '.join(self.folds)})")
        models = [f"{', '.join(map(str, self.hidden))} hidden units"] if self.hidden else []
        models += [f"{', '.join(self.encoders)} encoder"] if self.encoders else []
        models += [self._schedule()] if self.lengths else []
        models.append(f"{len(self.seeds)} seed{'s' * (len(self.seeds) != 1)} "
                      f"({', '.join(map(str, self.seeds))})")
        if self.selected:
            models.append(selection_phrase(self.selected))
        return f"{', '.join(data)}. Models: {', '.join(models)}."

    def _schedule(self) -> str:
        """``30 epochs (20 for Pr, Pc, Poc)``: the length most variants have, then the others."""
        common = Counter({n: len(v) for n, v in self.lengths.items()}).most_common(1)[0][0]
        others = "; ".join(f"{n} for {', '.join(v)}"
                           for n, v in sorted(self.lengths.items(), reverse=True) if n != common)
        return f"{common} {self.unit}" + (f" ({others})" if others else "")


def selection_phrase(selected: tuple[str, ...]) -> str:
    """``kernel, lowpass chosen per outer fold on its training users alone (a nested
    selection)``: what a caption or note says of the settings a nested selection chose."""
    return f"{', '.join(selected)} chosen per outer fold on its training users alone " \
           "(a nested selection)"


def selected_names(names: Iterable[str]) -> tuple[str, ...]:
    """The settings a nested selection chose, by the last part of each recorded name
    (``run.encoder.kernel`` -> ``kernel``), sorted and each once."""
    return tuple(sorted({name.rsplit(".", 1)[-1] for name in names}))


def describe_runs(grid_dir: Path | str, runs: pd.DataFrame) -> RunsDescription:
    """The description of ``runs`` (rows of ``collect.run_rows``: the run key columns) of the grid
    in ``grid_dir``, from their ``config.json`` and test predictions where present."""
    root = Path(grid_dir)
    keys = [RunKey(**{k: row[k] for k in RunKey.__dataclass_fields__})
            for row in runs.to_dict("records")]
    saved = {key: read_json(path) for key in keys
             if (path := root / key.path() / "config.json").is_file()}
    configs = {key: record["run"] for key, record in saved.items()}
    selected = selected_names(name for record in saved.values()
                              for name in (record.get("selection") or {}).get("common", {}))
    lengths: dict[int, list[str]] = {}
    for key, config in configs.items():
        variants = lengths.setdefault(config["optim"]["total"], [])
        if key.variant not in variants:
            variants.append(key.variant)
    first = next(iter(configs.values()), None)
    trials = _test_trials(root, keys)
    return RunsDescription(
        data=_data_name(first["data"] if first else {}),
        trials=len(trials),
        folds=tuple(sorted({key.fold for key in keys})),
        seeds=tuple(sorted({key.seed for key in keys})),
        hidden=tuple(sorted({c["encoder"]["hidden"] for c in configs.values()
                             if c["encoder"].get("kind", "lstm") == "lstm"})),
        encoders=tuple(sorted({c["encoder"].get("path") or c["encoder"]["kind"].upper()
                               for c in configs.values()
                               if c["encoder"].get("kind", "lstm") != "lstm"})),
        lengths={n: tuple(sorted(v, key=list(VARIANTS).index)) for n, v in lengths.items()},
        unit=first["optim"]["unit"] if first else "epochs",
        selected=selected)


def _test_trials(root: Path, keys: list[RunKey]) -> set[str]:
    """Names of the trials the runs were tested on: per fold, the predictions of the first of its
    runs that kept them, else the fold's trials as a scores archive recorded them."""
    archived = archived_test_trials(root)
    trials = set()
    for fold in {key.fold for key in keys}:
        runs = (root / key.path() for key in sorted(k for k in keys if k.fold == fold))
        kept = next((names for run in runs if (names := kept_trials(run))), None)
        trials.update(kept or archived.get(fold, ()))
    return trials


def _data_name(data: dict) -> str:
    """``JIGSAWS <Task> kinematics``, or the synthetic release's name, from a run's recorded data
    configuration (``config.json``'s ``run.data``; runs from before tasks were data: Suturing)."""
    task = task_name(data).replace("_", " ")
    return f"the synthetic {task} release" if is_synthetic(data) else f"JIGSAWS {task} kinematics"


def task_name(data: dict) -> str:
    """The task of a run's recorded data configuration (``config.json``'s ``run.data``); runs
    from before tasks were data: Suturing."""
    return data.get("task", {}).get("name", PAPER_TASK)


def is_synthetic(data: dict) -> bool:
    """Whether a run's recorded data configuration is a synthetic release's
    (``jigsaws_tools.synth.ensure_release``)."""
    return Path(data.get("data_dir", "")).parent.name.startswith(_SYNTHETIC_PREFIX)

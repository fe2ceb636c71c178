"""A grid's kept test predictions written out per configuration and seed, one file per trial at
the recording's rate: a release others pair their methods against (``multitask-tables
release``).

For each configuration (``<annotations>/<direction>/<variant>-<weighting>``) and seed of the grid,
a folder ``<annotations>/<direction>/<variant>-<weighting>/seed<k>/`` holds one ``<trial>.csv`` per
test trial of its folds (every trial of the release once), in the CSV format ``multitask-tables
score`` reads (``runs.method``): a header, then one row per frame of the recording (30 Hz in the
JIGSAWS release), columns ``frame`` (1-based), ``gesture`` (a gesture name) and, for a model with a
progress head, ``progress`` (a stage name). A run predicts at its model's samples (the labelled
frames, one in ``preprocessing.decimation`` from the first: every 6th of a 30 Hz recording, 5 Hz,
in the paper's protocol); frame ``f`` takes the prediction of the last sample at or before it
(``multitask-predict``'s rule), and the frames before the first sample take the first sample's.
Scoring such a folder at ``--rate`` the recording's rate reproduces, at every 5 Hz sample, the
run's own predictions of its last evaluation point (``grid.kept_predictions``), and so that point's
scores, for runs at 5 Hz; the grid's tables score a run as the mean over its evaluation points
(``LAST_POINT`` says how far apart the two are). Runs at another rate (a 3 Hz ED-TCN) are scored by
``score`` at other samples than their own (``OTHER_RATE``).

The frames come from the data (the kept predictions hold none): the grid's release, or
``data_dir``. ``README.md`` in the output says all this for readers without this project.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from jigsaws_tools.preprocessing import PreprocessConfig, decimation
from jigsaws_tools.recording_format import DEFAULT_FORMAT
from rnn_seg.runs.folder import write_atomic

from ...grid.kept_predictions import read_kept_predictions
from ...inference.run_record import recorded_data_dir
from ..runs.collect import LEFT_OUT, run_records
from ..runs.method import TrialTruth, truth

#: What scoring a release gives, beside the grid's own tables: in the release's README (the
#: note of ``multitask-tables score`` on a released folder says it in short); ``{frame_hz}``
#: (the recordings' rate) and ``{format}`` (``--format`` for recordings not in the release's
#: format) filled in.
#: Measured by scoring the release of ``results/reference/grid`` (18 configurations x 3 seeds x
#: 8 folds) at 30 Hz against the per-run scores its archive records.
LAST_POINT = """\
Scored with `multitask-tables score FOLDER --rate {frame_hz}`{format} (and `--annotations
original` for the `original/` folders), a folder gives exactly its runs' scores at their last
evaluation point. The grid's own tables, and `multitask-tables score --against GRID`, score each
run as the mean over its evaluation points (three near the end of training, the
paper's protocol), so a release scored and its archive differ a little. Measured on
`results/reference/grid` (gesture accuracy / edit score, points): per run 0.4 / 1.0 (median;
at most 2.8 / 6.7), per fold over its 3 seeds at most 1.5 / 2.9, and over the 8 folds by -0.35
to -0.15 / -0.13 to +0.25 (revised A-fixed: -0.24 / +0.04). To compare with the archived
numbers, pair with `--against GRID:CONFIG`; score a release to compare with what its models
predicted.
"""
#: The text of the release's ``README.md``; ``{grid}`` (its folder's last two names, never a
#: path of the machine), ``{folders}``, ``{frame_hz}``, ``{sampling}`` and ``{scoring}`` filled in
#: (``release_readme``).
README = """# Per-split test predictions of {grid}

Written by `multitask-tables release` (this project's evidence command line) from the grid's
scores archive. One folder per configuration and seed:

{folders}

Each holds one `<trial>.csv` per trial of the release: the predictions of the leave-one-user-out
run whose test user made the trial. Columns: `frame` (1-based frame of the {frame_hz} Hz
recording, every frame of it), `gesture` (the predicted gesture name) and, for models with a
progress head, `progress` (the predicted stage name).
{sampling}.
A frame holds the prediction of the last such sample at or before it (the first sample's before
it).

{scoring}"""
#: The ``{scoring}`` paragraph of a release whose runs predicted at other samples than those
#: ``multitask-tables score`` scores at (``{rate}``: theirs, ``{ours}``: the scoring rate;
#: ``{frame_hz}`` and ``{format}`` as in ``LAST_POINT``).
OTHER_RATE = """\
These runs predicted at {rate} samples, and their grid's tables score them there.
`multitask-tables score FOLDER --rate {frame_hz}`{format} scores at {ours} samples, each
taking the row of its frame: a folder so scored does not give its runs' scores, and `--against`
refuses their grid.
"""


@dataclass(frozen=True)
class Released:
    """What ``write_release`` wrote: the paths (``README.md`` first), the rates (Hz) its runs
    predicted at, and a line per run or configuration of the grid left out, saying why
    (unfinished, other settings, no kept predictions)."""

    paths: list[Path]
    sample_hz: list[float]
    left_out: list[str]


def write_release(grid: Path, out: Path, configs: Sequence[str] = (),
                  data_dir: Path | None = None) -> Released:
    """Write the release of ``grid``'s finished runs with kept predictions into ``out``: the
    folders and files of the module docstring, and ``README.md``.

    Args:
        grid: a grid folder or scores archive.
        out: the folder to write into (the publish's staging folder).
        configs: only these configurations (``A-fixed`` or ``original/A-fixed``; empty: all).
        data_dir: the release the runs read (None: the folder each run records).

    Raises:
        ValueError: a named configuration the grid lacks or has not finished, or no run that
            kept predictions.
    """
    grid = Path(grid)
    _, left_out, records = run_records(grid, allow_incomplete=True, finished_only=True)
    chosen = {Path(run): record for run, record in records.items()  # keyed by grid / run
              if _wanted(Path(run), grid, configs)}
    missing = [c for c in configs if not any(_wanted(r, grid, [c]) for r in chosen)]
    if missing:
        unfinished = [line.removeprefix(LEFT_OUT).strip() for line in left_out
                      if line.startswith(LEFT_OUT) and _names(line, missing[0])]
        if unfinished:
            raise ValueError(f"{grid}: configuration {missing[0]} has not finished all its runs "
                             f"({'; '.join(unfinished)}); a release holds complete "
                             "configurations only")
        held = sorted({"/".join(_folder(Path(r), grid).parts[::2][:2]) for r in records})
        raise ValueError(f"{grid}: no finished run of configuration {missing[0]}; it holds "
                         f"{', '.join(held) or 'none'}")
    written, folders, releases, samplings = [], set(), {}, set()
    for run_dir, record in sorted(chosen.items()):
        kept = read_kept_predictions(run_dir)
        if kept is None:
            left_out.append(f"{run_dir}: kept no predictions (archived before 2026-12-02), "
                            "left out")
            continue
        source = recorded_data_dir(record.config, run_dir) if data_dir is None else data_dir
        data = replace(record.config.data, data_dir=str(source))
        samplings.add((data.recording_format.rate_hz,
                       decimation(data.preprocessing, data.recording_format.rate_hz),
                       data.recording_format.name))
        key = repr(data)
        if key not in releases:
            releases[key] = {t.name: t for t in truth(data)}
        folder = _folder(run_dir, grid)
        folders.add(folder)
        for trial, predicted in kept.trials.items():
            if trial not in releases[key]:
                raise ValueError(f"{run_dir}: its test trial {trial} is not in {data.data_dir}")
            path = out / folder / f"{trial}.csv"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, trial_csv(releases[key][trial], predicted.labels, kept.classes))
            written.append(path)
    if not written:
        raise ValueError(f"{grid}: no finished run kept its predictions (archives written "
                         "before 2026-12-02 keep none); retrain, then archive")
    readme = out / "README.md"
    write_atomic(readme, release_readme(grid, sorted(folders), sorted(samplings)))
    return Released([readme, *written], _model_rates(samplings), left_out)


def release_readme(grid: Path, folders: Sequence[Path],
                   samplings: Sequence[tuple[float, int, str]]) -> str:
    """The release's ``README.md``: ``grid``'s name, its ``folders`` and how its runs sampled
    their recordings (``samplings``: per recording format, its rate in Hz, the recording frames
    per model sample and the format's name), with what scoring it gives (``LAST_POINT`` when
    every run predicted at the rate ``multitask-tables score`` scores at, else ``OTHER_RATE``).
    """
    ours = PreprocessConfig().sample_hz
    model_hz = _model_rates(samplings)
    frame_hz = " or ".join(sorted({f"{hz:g}" for hz, _, _ in samplings}))
    formats = sorted({name for _, _, name in samplings} - {DEFAULT_FORMAT})
    given = {"frame_hz": frame_hz,
             "format": f" with `--format` naming the {' or '.join(formats)} recording format's "
                       "file" if formats else ""}
    rates = " or ".join(f"every {_ordinal(step)} frame of a trial's labelled span "
                        f"({hz / step:g} Hz)" for hz, step, _ in samplings)
    scoring = (LAST_POINT.format(**given) if model_hz == [ours] else OTHER_RATE.format(
        rate=" or ".join(f"{hz:g} Hz" for hz in model_hz), ours=f"{ours:g} Hz", **given))
    return README.format(grid="/".join(grid.parts[-2:]), sampling=f"The models predict {rates}",
                         scoring=scoring, frame_hz=frame_hz,
                         folders="\n".join(f"- `{folder.as_posix()}/`" for folder in folders))


def _model_rates(samplings: Iterable[tuple[float, int, str]]) -> list[float]:
    """The rates (Hz) the models of ``samplings`` (``release_readme``'s) predicted at, sorted."""
    return sorted({hz / step for hz, step, _ in samplings})


def _ordinal(n: int) -> str:
    """``6th``, ``1st``, ``2nd``, ``3rd``, ``10th``."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def trial_csv(trial: TrialTruth, labels: dict[str, np.ndarray],
              classes: dict[str, tuple[str, ...]]) -> str:
    """One trial's predictions per frame (module docstring): ``labels`` per task ``[T]`` class
    indices at ``trial.frames`` ``[T]`` (5 Hz samples), written for frames 1..``n_frames``."""
    if len(trial.frames) != len(labels["gesture"]):
        raise ValueError(f"{trial.name}: {len(labels['gesture'])} kept predictions, "
                         f"{len(trial.frames)} samples in the data")
    frames = np.arange(1, trial.n_frames + 1)
    sample = np.maximum(np.searchsorted(trial.frames, frames, side="right") - 1, 0)
    tasks = [task for task in ("gesture", "progress") if task in labels]
    names = {task: np.asarray(classes[task])[labels[task][sample]] for task in tasks}
    lines = [",".join(["frame", *tasks])]
    lines += [",".join([str(f), *(names[task][i] for task in tasks)])
              for i, f in enumerate(frames)]
    return "\n".join(lines) + "\n"


def _folder(run_dir: Path, grid: Path) -> Path:
    """``<annotations>/<direction>/<config>/seed<k>`` of a run folder ``.../runs/.../<fold>``."""
    return run_dir.relative_to(grid).parent.relative_to("runs")


def _names(left_out: str, config: str) -> bool:
    """Whether a line of ``collect.run_records`` leaving out a configuration
    (``left out: <annotations>/<direction>/<config>, ...``) is about ``config`` (``A-fixed`` or
    ``original/A-fixed``, as ``--configs`` names it)."""
    label = left_out.removeprefix(LEFT_OUT).strip().split(",")[0].split("/")
    return len(label) == 3 and config in (label[2], f"{label[0]}/{label[2]}")


def _wanted(run_dir: Path, grid: Path, configs: Sequence[str]) -> bool:
    """Whether the run belongs to one of ``configs`` (all when empty)."""
    annotations, _, config = _folder(run_dir, grid).parts[:3]
    return not configs or any(c in (config, f"{annotations}/{config}") for c in configs)

"""``multitask-predict``: label new recordings with a trained run.

INPUT is a recording in the format the run trained on, offline or --stream (for a run trained on
the release, a JIGSAWS-layout kinematics file: 76 columns, one line per 30 Hz frame; no
transcription needed) or a folder of them; with --format, a recording in that format (e.g. a CSV at
100 Hz with its own column names) or a folder of them. For each recording NAME the output folder
gets NAME.csv (one row per frame of the recording: the predicted gesture name, its class
probabilities, the progress stage and scores when the model has a progress head) and NAME.png
(ribbons at 5 Hz); prediction.json records the run, the checkpoint, the inputs and the files
written. They are written together once every recording is predicted (``rnn_seg.runs.manifest``;
prediction.json is written last, so that it never describes the CSVs of another prediction):
``--overwrite`` replaces an earlier prediction in the folder whole, removing the files its record
lists that this one does not write, and any other file of an output's name; other files stay, and
an input recording is never written over. See docs/REPRODUCTION.md for how prediction treats every
frame.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from jigsaws_tools.cli.common import run_command
from jigsaws_tools.cli.format_options import add_format_option
from jigsaws_tools.recording_format import JIGSAWS_FORMAT, RecordingFormat
from rnn_seg.runs.manifest import listed, staged_outputs
from rnn_seg.runs.outputs import check_output_folder

from .options import load_for_command, trained_run_parser
from .run_record import STREAM_NORMALISATION_FILE, data_folder, read_run_config

if TYPE_CHECKING:
    from jigsaws_tools.preprocessing import Normalisation

    from .predictions import RecordingPrediction
    from .trained_run import TrainedRun

PROG = "multitask-predict"
RECORD_FILE = "prediction.json"


def build_parser() -> argparse.ArgumentParser:
    parser = trained_run_parser(PROG, __doc__)
    parser.add_argument("inputs", metavar="INPUT", nargs="+", type=Path,
                        help="kinematics files, or folders of them (their *.txt files; a release "
                             "folder's kinematics/AllGestures)")
    parser.add_argument("--out", type=Path, required=True, help="output folder (required)")
    parser.add_argument("--stream", action="store_true",
                        help="forward models only: feed the frames one at a time with causal "
                             "preprocessing and the LSTM state carried over, as online use "
                             "would (default: the run's offline preprocessing)")
    parser.add_argument("--data-dir", type=Path, default=None,
                        help="with --stream, when the run folder holds no "
                             "stream_normalisation.json yet: the release with the run's training "
                             "trials, whose statistics normalise the stream (default: the run's "
                             "data folder)")
    parser.add_argument("--no-plots", action="store_true",
                        help="write the CSVs only (default: CSVs and plots)")
    add_format_option(parser, "the INPUT recordings (default: the format the run trained on)")
    return parser


def kinematics_files(inputs: list[Path], recording_format: RecordingFormat = JIGSAWS_FORMAT
                     ) -> list[Path]:
    """The kinematics files named by INPUT arguments, in order; folders expand to their sorted
    files with the format's extension (``*.txt``; or those of a data folder's recordings folder,
    a release's ``kinematics/AllGestures``)."""
    files: list[Path] = []
    pattern = f"*{recording_format.extension}"
    for path in inputs:
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            recordings = path / recording_format.recordings
            folder = recordings if recordings.is_dir() else path
            found = sorted(p for p in folder.glob(pattern) if p.is_file())
            if not found:
                raise ValueError(f"{folder}: no kinematics files ({pattern})")
            files.extend(found)
        elif path.exists():
            raise ValueError(f"{path}: not a regular file or a folder (a FIFO, a socket or a "
                             "device); name kinematics files or folders of them")
        else:
            raise ValueError(f"{path}: no such file or folder")
    names: dict[str, Path] = {}
    for f in files:
        if f.stem in names:
            raise ValueError(f"two inputs would write {f.stem}.csv: {names[f.stem]} and {f}")
        names[f.stem] = f
    return files


def _predict(args: argparse.Namespace) -> None:
    from jigsaws_tools.recording_format import load_format

    if args.data_dir and not args.stream:
        raise ValueError("--data-dir only applies with --stream (offline prediction normalises "
                         "each recording by itself)")
    config = read_run_config(args.run_dir)[0]           # every check before TensorFlow loads
    recording_format = (load_format(args.format) if args.format
                        else config.data.recording_format)
    files = kinematics_files(args.inputs, recording_format)
    _check_outputs(args, files)
    if args.stream and not (args.run_dir / STREAM_NORMALISATION_FILE).is_file():
        data_folder(config, args.run_dir, args.data_dir)     # its training trials' statistics
    run = load_for_command(args)
    recording_format = run.recording_format(args.format)        # checked against the run
    predictions, normalisation = _predict_all(run, files, recording_format, args)
    mode = "stream" if args.stream else "offline"
    record = {"run_dir": str(args.run_dir.resolve()), "variant": run.variant,
              "checkpoint": run.checkpoint, "finished": run.finished, "mode": mode,
              "normalisation": normalisation,
              "recordings": {f.stem: {"input": str(f.resolve()), "frames": p.n_frames,
                                      "samples": len(p.sample_frames)}
                             for f, p in predictions.items()}}
    first = run.tasks[0]
    with staged_outputs(args.out, RECORD_FILE, PROG, args.overwrite, record) as staging:
        for f, prediction in predictions.items():
            prediction.write(staging, f.stem, f"{f.stem} - {run.variant} ({args.run_dir.name}, "
                                              f"sweep {run.checkpoint}, {mode})",
                             plot=not args.no_plots)
            labels = prediction.labels(first.name)
            print(f"{f.stem}: {prediction.n_frames} frames, most frequent {first.name} "
                  f"{first.class_names[np.bincount(labels).argmax()]}", flush=True)
    print(f"done: {len(files)} recording(s) predicted ({mode}) with {args.run_dir}, checkpoint "
          f"after sweep {run.checkpoint}; outputs in {args.out}")


def _check_outputs(args: argparse.Namespace, files: list[Path]) -> None:
    """Refuse a run or grid folder (``rnn_seg.runs.outputs``), an output that would replace an
    input recording (even with ``--overwrite``), and an earlier prediction or a file of an
    output's name unless ``--overwrite``; before any work."""
    check_output_folder(args.out, PROG)
    names = [RECORD_FILE] + [f"{f.stem}{ext}" for f in files for ext in (".csv", ".png")]
    inputs = {f.resolve() for f in files}
    for name in names:
        if (args.out / name).resolve() in inputs:
            raise ValueError(f"{args.out / name} is an input recording, and {PROG} would write "
                             "its prediction over it; choose another --out")
    existing = [args.out / name for name in names if (args.out / name).exists()]
    if existing and not args.overwrite:
        raise ValueError(f"{existing[0]} exists (from an earlier prediction?); use --overwrite "
                         "to replace that prediction, or another --out")
    listed(args.out, RECORD_FILE)                  # an unreadable record stops us before work


def _predict_all(run: TrainedRun, files: list[Path], recording_format: RecordingFormat,
                 args: argparse.Namespace
                 ) -> tuple[dict[Path, RecordingPrediction], Normalisation | None]:
    """Every recording's predictions (offline, or frame by frame with ``--stream``) and the fixed
    statistics a stream used; every input is read and checked before anything is written."""
    from .streaming import StreamingPredictor, stream_recording

    if not args.stream:
        return {f: run.predict(f, recording_format=recording_format) for f in files}, None
    run.require_online("--stream")
    recordings = {f: run.read_inputs(f, recording_format) for f in files}
    streamer = StreamingPredictor(run, run.stream_normalisation(args.data_dir), recording_format)
    return ({f: stream_recording(streamer, k, str(f)) for f, k in recordings.items()},
            streamer.normalisation)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return run_command(PROG, args.verbose, lambda: _predict(args), argv=argv)


if __name__ == "__main__":
    sys.exit(main())

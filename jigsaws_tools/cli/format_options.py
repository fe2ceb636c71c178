"""The ``--format`` command-line option of the commands that read recordings."""
from __future__ import annotations

import argparse

from ..recording_format import DEFAULT_FORMAT, RecordingFormat, load_format


def add_format_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup, what: str
                      ) -> argparse.Action:
    """``--format NAME|PATH``: the recordings' layout (``jigsaws_tools.recording_format``)."""
    return parser.add_argument("--format", metavar="PATH", default=None,
                               help=f"recording format of {what}: a TOML file naming the columns "
                                    "of the model's features, the sample rate and the file "
                                    "names (format in jigsaws_tools/recording_format.py; "
                                    f"default: {DEFAULT_FORMAT}, the JIGSAWS release's)")


def format_from_options(args: argparse.Namespace) -> RecordingFormat:
    """The format ``--format`` names (default: the JIGSAWS release's)."""
    return load_format(args.format)

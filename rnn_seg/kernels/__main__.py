"""``python -m rnn_seg.kernels``: build the fused LSTM loops now, or say why they cannot be."""
from __future__ import annotations

import argparse
import sys


def main(argv: list[str] | None = None) -> int:
    """Build (or verify) the library, print where it is and which product it runs; exit status 1
    with the reason when the loops cannot run here. A remembered failed build is tried again."""
    parser = argparse.ArgumentParser(
        prog="python -m rnn_seg.kernels",
        description="Build the fused LSTM loops now (they are otherwise built on first use, "
                    "about a minute once per TensorFlow version and processor), and print where "
                    "the library is and which product it runs; exit status 1, saying why, where "
                    "they cannot be built. $RNN_SEG_MARCH (e.g. haswell) builds for another "
                    "target than this processor; $CXX names the compiler (flags allowed). A build "
                    "that failed before is tried again here (training runs fall back to the "
                    "graph loops at once).")
    parser.parse_args(argv)
    from jigsaws_tools.cli.common import configure_output, import_tensorflow
    configure_output(verbose=False)
    import_tensorflow()
    from .build import KernelUnavailable, describe, forget_failure, library_path, loaded, \
        unavailable
    try:
        forget_failure(library_path())
    except KernelUnavailable:               # said by unavailable() below
        pass
    reason = unavailable("fp32")
    if reason:
        print(f"fused LSTM loops unavailable: {reason}", file=sys.stderr)
        return 1
    print(f"{loaded()[1]}: {describe()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

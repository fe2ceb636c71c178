"""Compile ``lstm_loops.cc`` once per TensorFlow version and CPU, cache it, load it.

The library is built for this CPU (``-march=native``: AVX-512 and, where the CPU has it,
AVX512_BF16 for ``bf16`` precision), so its cache key holds TensorFlow's version, the source, the
compiler command and the CPU's instruction-set flags. A build writes a temporary file and renames
it into place, so an interrupted or concurrent build never leaves a library a later run would load
half-written.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from functools import lru_cache
from pathlib import Path
from types import ModuleType

import tensorflow as tf
from tensorflow.python.framework import op_def_registry

from jigsaws_tools.dataset import default_cache_dir

from ..config import Precision, cpu_flags

SOURCE = Path(__file__).with_name("lstm_loops.cc")
FORWARD_OP = "MtrnnLstmForward"
BUILD_SECONDS = 600
#: Instruction sets ``-march=native`` may switch on that the loops never use and that TensorFlow's
#: bundled Eigen headers do not compile under with every compiler (AVX512-FP16, on Sapphire Rapids
#: and later Xeons: TensorFlow 2.21's Eigen with g++ 12), by the macro that shows one is on -> the
#: flag that switches it off again.
UNUSED_ISAS = {"__AVX512FP16__": "-mno-avx512fp16"}


class KernelUnavailable(RuntimeError):
    """The fused loops cannot be built or loaded here; the message says why."""


def library_dir() -> Path:
    """Where built libraries are cached: one folder per TensorFlow version."""
    return default_cache_dir() / "kernels" / f"tf-{tf.__version__}"


@lru_cache(maxsize=None)
def native_macros(compiler: str) -> frozenset[str]:
    """The macros ``compiler -march=native`` predefines (empty when it cannot say)."""
    try:
        done = subprocess.run([compiler, "-march=native", "-dM", "-E", "-x", "c++", os.devnull],
                              capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return frozenset()
    return frozenset(line.split()[1] for line in done.stdout.splitlines()
                     if line.startswith("#define "))


def compile_command(source: Path, target: Path) -> list[str]:
    """The compiler's command line for ``source`` -> shared library ``target``: this CPU's
    instruction sets (``-march=native``) but those in ``UNUSED_ISAS``."""
    compiler = os.environ.get("CXX") or "g++"
    unused = [flag for macro, flag in UNUSED_ISAS.items() if macro in native_macros(compiler)]
    return [compiler, "-shared", "-fPIC", "-O3", "-march=native", *unused, "-w",
            *tf.sysconfig.get_compile_flags(), str(source), "-o", str(target),
            *tf.sysconfig.get_link_flags()]


def library_path() -> Path:
    """The cached library's path for this source, TensorFlow, compiler command and CPU."""
    key = hashlib.sha256()
    key.update(SOURCE.read_bytes())
    key.update(" ".join(compile_command(Path("src"), Path("lib"))).encode())
    key.update(" ".join(sorted(cpu_flags())).encode())
    return library_dir() / f"lstm_loops-{key.hexdigest()[:16]}.so"


def build(path: Path) -> None:
    """Compile the library into ``path`` (through a temporary file renamed into place)."""
    command = compile_command(SOURCE, path)
    if shutil.which(command[0]) is None:
        raise KernelUnavailable(f"no C++ compiler: {command[0]!r} not found (install g++, or "
                                "set $CXX)")
    print(f"building the fused LSTM loops into {path} (once per TensorFlow version)",
          file=sys.stderr)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".build-") as work:
        target = Path(work) / path.name
        try:
            done = subprocess.run(compile_command(SOURCE, target), capture_output=True, text=True,
                                  timeout=BUILD_SECONDS)
        except subprocess.TimeoutExpired:
            raise KernelUnavailable(f"compiling {SOURCE.name} took over {BUILD_SECONDS} s") from None
        if done.returncode != 0:
            errors = [line for line in done.stderr.splitlines() if "error" in line]
            said = errors or done.stderr.splitlines() or [
                f"{command[0]} exited with status {done.returncode} and no message"]
            raise KernelUnavailable(f"compiling {SOURCE.name} failed: {said[0].strip()}")
        os.replace(target, path)


@lru_cache(maxsize=1)
def library() -> ModuleType:
    """The loaded ops (built first if not cached); raises ``KernelUnavailable`` saying why."""
    if not SOURCE.is_file():
        raise KernelUnavailable(f"{SOURCE} is missing from the installation")
    path = library_path()
    try:
        if not path.is_file():
            build(path)
        return tf.load_op_library(str(path))
    except OSError as error:
        raise KernelUnavailable(f"{path}: {error}") from None
    except tf.errors.NotFoundError as error:
        raise KernelUnavailable(f"loading {path} failed: {error.message.splitlines()[0]} "
                                "(delete it to rebuild)") from None


def weight_dtypes() -> set[tf.DType]:
    """The weight dtypes the loaded forward op accepts (bfloat16 only where the CPU has it)."""
    op = op_def_registry.get(FORWARD_OP)
    return {tf.as_dtype(t) for attr in op.attr if attr.name == "T"
            for t in attr.allowed_values.list.type}


def unavailable(precision: Precision) -> str | None:
    """Why the fused loops cannot run ``precision`` here, or None when they can."""
    try:
        library()
    except KernelUnavailable as error:
        return str(error)
    if precision == "bf16" and tf.bfloat16 not in weight_dtypes():
        return "the library was built without AVX512_BF16 (this CPU or compiler lacks it)"
    return None


def main() -> int:
    """``python -m rnn_seg.kernels``: build now, print the library's path or why not."""
    reason = unavailable("fp32")
    if reason:
        print(f"fused LSTM loops unavailable: {reason}", file=sys.stderr)
        return 1
    kinds = sorted(t.name for t in weight_dtypes())
    print(f"{library_path()} (weights: {', '.join(kinds)})")
    return 0

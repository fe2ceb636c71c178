"""Compile ``lstm_loops.cc`` once per TensorFlow version and CPU, cache it, verify it, load it.

The library is built for this CPU (``-march=native``, or the target ``$RNN_SEG_MARCH`` names,
e.g. ``haswell`` to build the AVX2 loops on an AVX-512 machine): the AVX-512 product where the
target has AVX-512 (and, where it has AVX512_BF16, bfloat16 for ``bf16`` precision), the AVX2
product elsewhere. Its cache key holds TensorFlow's version, the source, the compiler command and
the CPU's instruction-set flags.

A cached library is never loaded unchecked: a build records the library's size, SHA-256 and
instruction set beside it (``lstm_loops-<key>.json``), and a library whose bytes do not match its
record (truncated, replaced, or without one) or whose record names another TensorFlow version or
source is removed and rebuilt, with one line; a library that loads but holds no op is refused in
the same way. A folder, a FIFO or a device at the library's or the record's name is refused, left
as it is. So a damaged cache costs one rebuild, never a crash or a hang.

A build runs under a lock (one build at a time per library), writes into a temporary folder
(marked with its process id) renamed into place, record first. The compiler runs through
``tether.py``, in a session of its own: a compiler that runs over ``BUILD_SECONDS`` is stopped
with everything it started, and so is one whose process is killed (any signal, SIGKILL
included) or interrupted; a build folder left by a killed process is removed by the next build.
A failed build is remembered (``lstm_loops-<key>.failed.json`` beside the library: the reason,
the source, TensorFlow, the compiler command and the compiler's file), so every later process
falls back at once, in one line naming it, instead of compiling again; a changed source,
TensorFlow, compiler command or compiler retries, and so do ``python -m rnn_seg.kernels`` and
removing that file. ``$CXX`` may carry flags (``CXX="g++ -std=c++17"``).
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shlex
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from types import ModuleType
from typing import Iterator

import tensorflow as tf
from tensorflow.python.framework import op_def_registry

from jigsaws_tools.dataset import default_cache_dir
from jigsaws_tools.files import file_kind, read_regular

from ..config import Precision, cpu_flags

SOURCE = Path(__file__).with_name("lstm_loops.cc")
OPS = ("MtrnnLstmForward", "MtrnnLstmBackward")
FORWARD_OP = OPS[0]
#: The longest a build may take before it is stopped (a first build takes 25-60 s).
BUILD_SECONDS = 240
#: The longest the compiler may take to list a target's macros (it takes well under a second).
MACROS_SECONDS = 20
#: Seconds between the lines a build prints while the compiler works.
PROGRESS_SECONDS = 15
MARCH_ENV = "RNN_SEG_MARCH"
#: What a ``-march`` target's name may look like (``native``, ``haswell``, ``x86-64-v3``).
MARCH_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]*")
#: Instruction sets ``-march`` may switch on that the loops never use and that TensorFlow's
#: bundled Eigen headers do not compile under with every compiler (AVX512-FP16, on Sapphire Rapids
#: and later Xeons: TensorFlow 2.21's Eigen with g++ 12), by the macro that shows one is on -> the
#: flag that switches it off again.
UNUSED_ISAS = {"__AVX512FP16__": "-mno-avx512fp16"}
#: The predefined macros of the instruction sets a target's code may execute: one this processor
#: lacks stops the process at its first use (SIGILL), with no message.
VECTOR_ISA = re.compile(r"__(SSE|AVX|FMA|F16C|BMI|AMX|AES|VAES|GFNI|VPCLMULQDQ|SHA)\w*__")
BUILD_PREFIX = ".build-"
#: The most bytes a build record may hold (one is under a kilobyte).
RECORD_BYTES = 1 << 16
OWNER_FILE = "builder.pid"
FAILURE_SUFFIX = ".failed.json"
#: Runs a command in its process's group, ended when the process that started it ends.
TETHER = Path(__file__).with_name("tether.py")


class KernelUnavailable(RuntimeError):
    """The fused loops cannot be built or loaded here; the message says why."""


class BuildFailed(KernelUnavailable):
    """The compiler failed, wrote no library or ran over ``BUILD_SECONDS``: a build that would
    fail again the same way, so it is remembered (``remember_failure``)."""


def library_dir() -> Path:
    """Where built libraries are cached: one folder per TensorFlow version."""
    return default_cache_dir() / "kernels" / f"tf-{tf.__version__}"


def compiler() -> list[str]:
    """The C++ compiler's command and its own flags: ``$CXX`` split as a shell would (``g++``
    when unset).

    Raises:
        KernelUnavailable: ``$CXX`` is empty or unbalanced in its quotes.
    """
    given = os.environ.get("CXX")
    try:
        words = shlex.split(given) if given is not None else ["g++"]
    except ValueError as error:
        raise KernelUnavailable(f"CXX={given!r}: {error}") from None
    if not words:
        raise KernelUnavailable(f"CXX={given!r} names no compiler (unset it, or name one)")
    return words


def march() -> str:
    """The target the library is built for: ``$RNN_SEG_MARCH`` (a GCC ``-march`` value such as
    ``haswell``), else ``native``.

    Raises:
        KernelUnavailable: the value is not a plausible ``-march`` name.
    """
    value = os.environ.get(MARCH_ENV, "").strip() or "native"
    if not MARCH_NAME.fullmatch(value):
        raise KernelUnavailable(f"{MARCH_ENV}={value!r} is no -march target (e.g. native, "
                                "haswell, skylake-avx512)")
    return value


@lru_cache(maxsize=None)
def target_macros(command: tuple[str, ...], target: str = "native") -> frozenset[str]:
    """The macros ``command -march=target`` predefines (empty when it cannot say, or takes
    over ``MACROS_SECONDS``: then stopped with every process it started)."""
    try:
        process = _start([*command, f"-march={target}", "-dM", "-E", "-x", "c++", os.devnull],
                         stderr=subprocess.DEVNULL)
    except OSError:
        return frozenset()
    try:
        said, _ = process.communicate(timeout=MACROS_SECONDS)
    except subprocess.TimeoutExpired:
        _stop(process)
        process.stdout.close()
        return frozenset()
    return frozenset(line.split()[1] for line in said.splitlines()
                     if line.startswith("#define ") and len(line.split()) > 1)


def check_target() -> None:
    """Refuse a ``$RNN_SEG_MARCH`` target whose instruction sets this processor lacks (its
    library would be killed by an illegal instruction at the first step); nothing to check for
    ``native``, or where the compiler cannot say.

    Raises:
        KernelUnavailable: naming the instruction sets missing.
    """
    target = march()
    if target == "native":
        return
    words = tuple(compiler())
    here, there = target_macros(words, "native"), target_macros(words, target)
    missing = sorted(m.strip("_") for m in there - here if VECTOR_ISA.fullmatch(m))
    if here and missing:
        raise KernelUnavailable(f"{MARCH_ENV}={target}: this processor lacks "
                                f"{', '.join(missing)}, which that target's code runs (the "
                                "process would die of an illegal instruction)")


def native_macros(command: str) -> frozenset[str]:
    """The macros ``command -march=native`` predefines (``command`` one word or with flags)."""
    return target_macros(tuple(shlex.split(command)))


def compile_command(source: Path, target: Path) -> list[str]:
    """The compiler's command line for ``source`` -> shared library ``target``: the target's
    instruction sets (``march``) but those in ``UNUSED_ISAS``."""
    words, arch = compiler(), march()
    macros = target_macros(tuple(words), arch)
    unused = [flag for macro, flag in UNUSED_ISAS.items() if macro in macros]
    return [*words, "-shared", "-fPIC", "-O3", f"-march={arch}", *unused, "-w",
            *tf.sysconfig.get_compile_flags(), str(source), "-o", str(target),
            *tf.sysconfig.get_link_flags()]


def product_path(macros: frozenset[str]) -> dict:
    """Which float32 product the source compiles to for a target predefining ``macros``: its
    vector width in bits and a name (``lstm_loops.cc``'s header)."""
    if "__AVX512F__" in macros:
        return {"vector_bits": 512, "product": "AVX-512", "bf16": "__AVX512BF16__" in macros}
    if "__AVX2__" in macros and "__FMA__" in macros:
        return {"vector_bits": 256, "product": "AVX2", "bf16": False}
    return {"vector_bits": 256, "product": "generic (compiler vectors, no AVX2)", "bf16": False}


def library_path() -> Path:
    """The cached library's path for this source, TensorFlow, compiler command and CPU."""
    key = hashlib.sha256()
    key.update(SOURCE.read_bytes())
    key.update(" ".join(compile_command(Path("src"), Path("lib"))).encode())
    key.update(" ".join(sorted(cpu_flags())).encode())
    return library_dir() / f"lstm_loops-{key.hexdigest()[:16]}.so"


def record_path(library: Path) -> Path:
    """The build record beside ``library``."""
    return library.with_suffix(".json")


def digest(path: Path) -> str:
    """SHA-256 of a file's bytes, in hex."""
    sha = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            sha.update(block)
    return sha.hexdigest()


def damage(library: Path) -> str | None:
    """Why the cached ``library`` may not be loaded (its bytes differ from its build record, the
    record names another TensorFlow version or source, or it has none), or None when it
    matches."""
    try:
        record = json.loads(read_regular(record_path(library), RECORD_BYTES).decode())
        size, sha = int(record["size"]), str(record["sha256"])
        built_for = (str(record["tensorflow"]), str(record["source_sha256"]))
    except FileNotFoundError:
        return "no build record beside it"
    except (OSError, ValueError, TypeError, KeyError, RecursionError):
        return "its build record is unreadable"
    if built_for[0] != tf.__version__:
        return f"built for TensorFlow {built_for[0]}, not {tf.__version__}"
    if built_for[1] != hashlib.sha256(SOURCE.read_bytes()).hexdigest():
        return f"built from another {SOURCE.name}"
    try:
        found = library.stat().st_size
    except OSError as error:
        return f"unreadable ({error.strerror})"
    if found != size:
        return f"{found} bytes where its build recorded {size}"
    if digest(library) != sha:
        return "its bytes differ from those its build recorded"
    return None


def build(path: Path) -> None:
    """Compile the library into ``path`` and its record beside it (through a temporary folder
    renamed into place, the record first), saying so on standard error.

    Raises:
        KernelUnavailable: no compiler, the compiler failed or ran over ``BUILD_SECONDS``, or
            the folder cannot be written; the message says which.
    """
    command = compile_command(SOURCE, path)
    if shutil.which(command[0]) is None:
        raise KernelUnavailable(f"no C++ compiler: {command[0]!r} not found (install g++, or "
                                "set $CXX)")
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_abandoned_builds(path.parent)
    print(f"building the fused LSTM loops into {path} (once per TensorFlow version and "
          "processor; about a minute)", file=sys.stderr, flush=True)
    started = time.monotonic()
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=BUILD_PREFIX) as work:
        (Path(work) / OWNER_FILE).write_text(str(os.getpid()))
        target = Path(work) / path.name
        _compile(compile_command(SOURCE, target), command[0])
        if not target.is_file() or not target.stat().st_size:
            raise BuildFailed(f"{command[0]} exited without error but wrote no library "
                                    f"(CXX={os.environ.get('CXX', 'g++')!r})")
        macros = target_macros(tuple(compiler()), march())
        record = Path(work) / record_path(path).name
        record.write_text(json.dumps({
            "library": path.name, "size": target.stat().st_size, "sha256": digest(target),
            "source_sha256": hashlib.sha256(SOURCE.read_bytes()).hexdigest(),
            "march": march(), **product_path(macros), "tensorflow": tf.__version__,
            "compile_command": compile_command(SOURCE, path),
            "built_seconds": round(time.monotonic() - started, 1)}, indent=1) + "\n")
        os.replace(record, record_path(path))
        os.replace(target, path)
    print(f"  built in {time.monotonic() - started:.0f} s", file=sys.stderr, flush=True)


def _compile(command: list[str], name: str) -> None:
    """Run the compiler, a line every ``PROGRESS_SECONDS``; stop it and every process it started
    after ``BUILD_SECONDS``."""
    try:
        process = _start(command, stderr=subprocess.PIPE)
    except OSError as error:
        raise KernelUnavailable(f"{name}: {error.strerror}") from None
    started = time.monotonic()
    try:
        while True:
            try:
                _, stderr = process.communicate(timeout=PROGRESS_SECONDS)
                break
            except subprocess.TimeoutExpired:
                elapsed = time.monotonic() - started
                if elapsed > BUILD_SECONDS:
                    raise BuildFailed(f"compiling {SOURCE.name} took over {BUILD_SECONDS} s; "
                                            "stopped") from None
                print(f"  still compiling ({elapsed:.0f} s)", file=sys.stderr, flush=True)
    finally:
        if process.poll() is None:
            _stop(process)
    if process.returncode != 0:
        errors = [line for line in stderr.splitlines() if "error" in line]
        said = errors or stderr.splitlines() or [
            f"{name} exited with status {process.returncode} and no message"]
        raise BuildFailed(f"compiling {SOURCE.name} failed: {said[0].strip()}")


def _start(command: list[str], stderr: int) -> subprocess.Popen:
    """Start ``command`` through ``TETHER`` in a session of its own (its output piped as text):
    it ends, with everything it started, when this process ends or ``_stop`` ends it."""
    return subprocess.Popen([sys.executable, "-I", "-S", str(TETHER), str(os.getpid()), *command],
                            stdout=subprocess.PIPE, stderr=stderr, text=True,
                            start_new_session=True)


def _stop(process: subprocess.Popen) -> None:
    """End ``process`` and everything in its session (the compiler's own subprocesses)."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except OSError:
        process.kill()
    process.wait()


def remove_abandoned_builds(folder: Path) -> list[Path]:
    """Remove the build folders in ``folder`` that a build of this module made (its
    ``OWNER_FILE`` inside) and whose process is gone; returns them. Anything else is left."""
    removed = []
    for work in folder.glob(BUILD_PREFIX + "*"):
        try:
            owner = int((work / OWNER_FILE).read_text())
        except (OSError, ValueError):
            continue                         # not a build's folder (or not yet marked)
        if _alive(owner):
            continue
        shutil.rmtree(work, ignore_errors=True)
        removed.append(work)
    return removed


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


@contextmanager
def build_lock(path: Path) -> Iterator[None]:
    """Hold ``path``'s build lock (a lock file beside it), saying so in one line when another
    process holds it; where the folder cannot be written, no lock (and no build either)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path.with_suffix(".lock"), os.O_WRONLY | os.O_CREAT | os.O_NONBLOCK)
    except OSError:                        # also a FIFO of its name without a reader
        yield
        return
    with os.fdopen(fd, "w") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            print(f"waiting for another process's build of {path.name} (about a minute)",
                  file=sys.stderr, flush=True)
            fcntl.flock(handle, fcntl.LOCK_EX)
        yield


def failure_path(library: Path) -> Path:
    """The record of a failed build beside ``library``."""
    return library.with_name(library.stem + FAILURE_SUFFIX)


def _build_inputs() -> dict:
    """What a build's outcome depends on beyond the library's name: the source, TensorFlow, the
    compiler command and the compiler's file (its path, size and time, so an upgrade retries)."""
    words = compiler()
    found = shutil.which(words[0])
    try:
        status = os.stat(found) if found else None
    except OSError:
        status = None
    return {"source_sha256": hashlib.sha256(SOURCE.read_bytes()).hexdigest(),
            "tensorflow": tf.__version__,
            "compile_command": compile_command(Path("src"), Path("lib")),
            "compiler": None if status is None else {
                "path": os.path.realpath(found), "size": status.st_size,
                "mtime_ns": status.st_mtime_ns}}


def remember_failure(library: Path, error: BuildFailed) -> None:
    """Record that building ``library`` failed with ``error`` (nothing where the cache cannot be
    written: then every process tries again)."""
    record = {"library": library.name, "reason": str(error),
              "failed": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), **_build_inputs()}
    try:
        fd, name = tempfile.mkstemp(dir=library.parent, prefix=".failure-", suffix=".json")
    except OSError:
        return
    try:
        with os.fdopen(fd, "w") as f:
            f.write(json.dumps(record, indent=1) + "\n")
        os.replace(name, failure_path(library))
    except OSError:
        Path(name).unlink(missing_ok=True)


def known_failure(library: Path) -> str | None:
    """One line on the remembered failed build of ``library`` with today's inputs (source,
    TensorFlow, compiler command and file), naming how to retry it; None when there is none (or
    it was of other inputs, or is unreadable)."""
    where = failure_path(library)
    try:
        record = json.loads(read_regular(where, RECORD_BYTES).decode())
        reason, when = str(record["reason"]), str(record["failed"])
        same = all(record.get(key) == value for key, value in _build_inputs().items())
    except (OSError, ValueError, TypeError, KeyError, AttributeError, RecursionError):
        return None
    if not same:
        return None
    return (f"its build failed on {when} ({reason}); not tried again: `python -m rnn_seg.kernels` "
            f"retries it, or remove {where}")


def forget_failure(library: Path) -> None:
    """Remove the record of a failed build of ``library``, if any (a build retries)."""
    try:
        failure_path(library).unlink()
    except OSError:                     # none, or a read-only cache: the build says what it can
        pass


def ensure_built(path: Path) -> None:
    """Build the library into ``path`` where it is missing or damaged (``damage``: removed first,
    saying so in one line), under its build lock; unless a build with today's inputs failed
    before (``known_failure``). A failed build is remembered.

    Raises:
        KernelUnavailable: the build failed, now or before (see ``build``, ``known_failure``).
        OSError: the cache cannot be written.
    """
    blocked = next((folder for folder in path.parents if folder.exists()
                    and not folder.is_dir()), None)
    if blocked is not None:
        raise KernelUnavailable(f"the kernel cache {path.parent} cannot be made: {blocked} is "
                                "a file, not a folder")
    for part in (path, record_path(path)):
        kind = _not_a_file(part)
        if kind:
            raise KernelUnavailable(f"{part} is {kind}, not the cache's file: move it away and "
                                    "the library is built there")
    if path.is_file() and not damage(path):
        return
    _refuse_known_failure(path)
    with build_lock(path):
        _refuse_known_failure(path)                   # another process's build just failed
        problem = damage(path) if path.is_file() else None
        if problem:
            try:
                path.unlink()
            except OSError as error:
                raise KernelUnavailable(f"{path}: {problem}, and it cannot be removed "
                                        f"({error.strerror}): the cache is read-only") from None
            print(f"{path}: {problem}; removed, building it again", file=sys.stderr)
        if not path.is_file():
            try:
                build(path)
            except BuildFailed as error:
                remember_failure(path, error)
                raise
            forget_failure(path)


def _refuse_known_failure(path: Path) -> None:
    failed = known_failure(path)
    if failed:
        raise KernelUnavailable(f"{path.name}: {failed}")


def _not_a_file(path: Path) -> str | None:
    """What ``path`` is when it exists and is no regular file (``a folder``, ``a FIFO (named
    pipe)``, ...), else None."""
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        return None
    except OSError as error:
        return f"unreadable ({error.strerror})"
    return None if stat.S_ISREG(mode) else file_kind(mode)


def library() -> ModuleType:
    """The loaded ops, verified (built first where missing or damaged); raises
    ``KernelUnavailable`` saying why."""
    return loaded()[0]


@lru_cache(maxsize=1)
def loaded() -> tuple[ModuleType, Path]:
    """``library``'s ops and the path they were loaded from (once per process)."""
    if not SOURCE.is_file():
        raise KernelUnavailable(f"{SOURCE} is missing from the installation")
    check_target()
    path = library_path()
    try:
        ensure_built(path)
        ops = tf.load_op_library(str(path))
    except OSError as error:
        raise KernelUnavailable(f"{path}: {error}") from None
    except tf.errors.NotFoundError as error:
        _discard(path)
        raise KernelUnavailable(f"loading {path} failed: {error.message.splitlines()[0]} "
                                "(removed: the next process builds it again)") from None
    missing = [op for op in OPS if op_def_registry.get(op) is None]
    if missing:
        _discard(path)
        raise KernelUnavailable(f"{path} holds no {missing[0]} op (removed: the next process "
                                "builds it again)")
    return ops, path


def _discard(path: Path) -> None:
    """Remove a cached library (and its record) that failed to load."""
    for stale in (path, record_path(path)):
        try:
            stale.unlink()
        except OSError:
            pass


def built_record() -> dict:
    """The loaded library's build record (``{}`` when it cannot be read)."""
    try:
        return json.loads(record_path(loaded()[1]).read_text())
    except (OSError, ValueError, KernelUnavailable):
        return {}


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


def describe() -> str:
    """One line on the loaded library: its product and weight types, e.g. ``AVX2 product
    (256-bit vectors), weights float32``."""
    record = built_record()
    kinds = ", ".join(sorted(t.name for t in weight_dtypes()))
    return (f"{record.get('product', '?')} product ({record.get('vector_bits', '?')}-bit "
            f"vectors, -march={record.get('march', '?')}), weights {kinds}")

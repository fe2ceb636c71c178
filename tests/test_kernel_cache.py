"""The compiled kernel's cache can never take a run down: a damaged library is found before it is
loaded and rebuilt (or, where that fails, the graph loops run), a library that loads but holds no
op is refused, a hanging compiler is stopped with its children, a killed build ends its compiler
and leaves nothing a later build keeps, a failed build is remembered (not compiled again by every
process) until its inputs change, and ``$CXX`` may carry flags. Builds here go through a stand-in compiler that
copies the suite's own library, so no test compiles for a minute."""
from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from rnn_seg.kernels import build
from tests.fused_loops import needs_fused
from tests.test_archive_and_inputs import at_most

ROOT = Path(__file__).resolve().parents[1]


def _stand_in_compiler(folder: Path, library: Path, name: str = "cxx") -> Path:
    """A "compiler" that answers ``-E`` (the target's macros) as g++ does and otherwise writes a
    copy of ``library`` wherever ``-o`` points."""
    script = folder / name
    script.write_text(f"""#!/bin/sh
case " $* " in *" -E "*) exec g++ "$@";; esac
while [ $# -gt 0 ]; do
  if [ "$1" = -o ]; then cp "{library}" "$2"; exit 0; fi
  shift
done
exit 1
""")
    script.chmod(0o755)
    return script


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache folder and a stand-in compiler copying the suite's built library."""
    if build.unavailable("fp32") is not None or shutil.which("g++") is None:
        pytest.skip("no built library to copy")
    good = build.loaded()[1]
    folder = tmp_path / "cache"
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(folder))
    monkeypatch.setenv("CXX", str(_stand_in_compiler(tmp_path, good)))
    return folder


def _damaged(kind: str, path: Path) -> None:
    """Damage the library at ``path`` in one of several ways."""
    data = path.read_bytes()
    if kind == "truncated":
        path.write_bytes(data[: len(data) // 3])
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "same size, other bytes":
        path.write_bytes(data[:4096] + bytes(len(data) - 4096))
    elif kind == "no record":
        build.record_path(path).unlink()
    elif kind == "unreadable record":
        build.record_path(path).write_text("{not json")
    elif kind == "record nested too deeply":
        build.record_path(path).write_text("[" * 100_000 + "]" * 100_000)
    elif kind in ("another TensorFlow's", "another source's"):       # a cache copied across
        record = json.loads(build.record_path(path).read_text())
        key = "tensorflow" if kind == "another TensorFlow's" else "source_sha256"
        build.record_path(path).write_text(json.dumps({**record, key: "2.0.0"}))


@needs_fused
@pytest.mark.parametrize("kind", ["truncated", "empty", "same size, other bytes", "no record",
                                  "unreadable record", "record nested too deeply",
                                  "another TensorFlow's", "another source's"])
def test_a_damaged_library_is_found_and_rebuilt_before_it_is_loaded(cache, capsys, kind):
    path = build.library_path()
    build.ensure_built(path)
    good = path.read_bytes()
    capsys.readouterr()
    _damaged(kind, path)
    assert build.damage(path) is not None
    build.ensure_built(path)
    said = capsys.readouterr().err.splitlines()
    assert said[0].startswith(f"{path}: ") and said[0].endswith("removed, building it again")
    assert path.read_bytes() == good and build.damage(path) is None


@needs_fused
@pytest.mark.parametrize("which", ["library", "record"])
@pytest.mark.parametrize("kind", ["folder", "FIFO"])
def test_a_folder_or_fifo_in_the_caches_place_is_refused_and_left(cache, which, kind):
    """Neither waits for a writer (a FIFO record hung every process) nor costs the library (a
    folder as the record had it removed, then every build failed after compiling)."""
    path = build.library_path()
    build.ensure_built(path)
    taken = path if which == "library" else build.record_path(path)
    taken.unlink()
    taken.mkdir() if kind == "folder" else os.mkfifo(taken)
    with at_most(60), pytest.raises(build.KernelUnavailable,
                                    match=f"{taken} is a {kind}.*move it away"):
        build.ensure_built(path)
    assert taken.exists() and not taken.is_file()
    assert which == "library" or path.is_file()            # the library was not removed


@needs_fused
def test_a_damaged_library_in_a_read_only_cache_is_named_not_said_removed(cache, capsys,
                                                                          monkeypatch):
    path = build.library_path()
    build.ensure_built(path)
    capsys.readouterr()
    _damaged("truncated", path)

    def refuse(self, *args, **kwargs):
        raise PermissionError(1, "Operation not permitted", str(self))

    monkeypatch.setattr(Path, "unlink", refuse)
    with pytest.raises(build.KernelUnavailable, match="cannot be removed .*read-only"):
        build.ensure_built(path)
    assert "removed" not in capsys.readouterr().err


@needs_fused
def test_a_fifo_as_the_build_lock_is_no_lock_and_no_hang(cache):
    path = build.library_path()
    path.parent.mkdir(parents=True)
    os.mkfifo(path.with_suffix(".lock"))
    with at_most(60):
        build.ensure_built(path)
    assert build.damage(path) is None


@needs_fused
@pytest.mark.slow
def test_a_build_waiting_for_another_says_so_then_uses_its_library(cache, capsys):
    """A second process's first use during a build waited a minute without a word."""
    path = build.library_path()
    path.parent.mkdir(parents=True)
    with open(path.with_suffix(".lock"), "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        threading.Timer(2, lambda: fcntl.flock(held, fcntl.LOCK_UN)).start()
        with at_most(120):
            build.ensure_built(path)
    said = capsys.readouterr().err.splitlines()
    assert said[0] == f"waiting for another process's build of {path.name} (about a minute)"
    assert build.damage(path) is None


def test_a_compiler_that_writes_no_library_is_refused_for_it(tmp_path, monkeypatch):
    monkeypatch.setenv("CXX", "true")
    with pytest.raises(build.KernelUnavailable, match="exited without error but wrote no library"):
        build.build(tmp_path / "kernels" / "lstm_loops-x.so")
    assert list((tmp_path / "kernels").iterdir()) == []


@needs_fused
@pytest.mark.slow
def test_a_truncated_library_costs_a_training_one_line_and_a_rebuild(cache, tmp_path, synth_dir):
    """Today's crash (SIGBUS on loading a truncated library, in every later run too) cannot
    happen: the run rebuilds it and trains on the fused loops."""
    path = build.library_path()
    build.ensure_built(path)
    _damaged("truncated", path)
    done = _train(tmp_path / "run", synth_dir)
    assert done.returncode == 0, done.stderr
    assert f"{path}: " in done.stderr and "removed, building it again" in done.stderr
    assert "Traceback" not in done.stderr
    assert json.loads((tmp_path / "run" / "config.json").read_text())["provenance"]["loops"] \
        == "fused"


@needs_fused
@pytest.mark.slow
def test_a_library_that_holds_no_op_falls_back_to_the_graph_loops(cache, tmp_path, synth_dir):
    """A library whose bytes match its record but that registers no op (another program's, or a
    build gone wrong): one line, the graph loops, and the library removed for the next process."""
    path = build.library_path()
    build.ensure_built(path)
    empty = tmp_path / "empty.cc"
    empty.write_text("int nothing_here() { return 0; }\n")
    subprocess.run(["g++", "-shared", "-fPIC", str(empty), "-o", str(path)], check=True)
    record = json.loads(build.record_path(path).read_text())
    record.update(size=path.stat().st_size, sha256=build.digest(path))
    build.record_path(path).write_text(json.dumps(record))
    done = _train(tmp_path / "run", synth_dir)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if "fused LSTM loops unavailable" in line]
    assert len(lines) == 1 and "holds no MtrnnLstmForward op" in lines[0]
    assert "Traceback" not in done.stderr
    assert json.loads((tmp_path / "run" / "config.json").read_text())["provenance"]["loops"] \
        == "graph"
    assert not path.exists()


def _train(out: Path, data: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "multitask.train_cli", "--data-dir", str(data), "--variant", "A",
         "--hidden", "8", "--epochs", "1", "--test-user", "C", "--no-plots", "--out", str(out)],
        capture_output=True, text=True, env=env, timeout=600)


@pytest.mark.slow
def test_a_hanging_compiler_is_stopped_with_every_process_it_started(tmp_path, monkeypatch):
    pids = tmp_path / "pids"
    hang = tmp_path / "hang"
    hang.write_text(f"""#!/bin/sh
sleep 600 &
echo $! >> {pids}
echo $$ >> {pids}
wait
""")
    hang.chmod(0o755)
    monkeypatch.setenv("CXX", str(hang))
    monkeypatch.setattr(build, "BUILD_SECONDS", 2)
    monkeypatch.setattr(build, "PROGRESS_SECONDS", 1)
    monkeypatch.setattr(build, "MACROS_SECONDS", 2)
    started = time.monotonic()
    build.target_macros.cache_clear()
    with pytest.raises(build.KernelUnavailable, match="took over 2 s; stopped"):
        build.build(tmp_path / "kernels" / "lstm_loops-x.so")    # -E hangs too: stopped
    assert time.monotonic() - started < 60
    # a process sent SIGKILL ends when it is next scheduled: on a busy machine, not at once
    _wait_for(lambda: not any(_running(pid) for pid in map(int, pids.read_text().split())),
              seconds=30)
    assert list((tmp_path / "kernels").iterdir()) == []


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_a_killed_build_leaves_nothing_the_next_build_keeps(tmp_path):
    """A build folder whose builder is gone is removed; a folder the builder did not mark (a
    user's, or one being made) and a live builder's are left."""
    folder = tmp_path / "kernels"
    dead = subprocess.Popen(["true"])
    dead.wait()
    abandoned, live, unmarked = (folder / f"{build.BUILD_PREFIX}{n}" for n in ("a", "b", "c"))
    for work in (abandoned, live, unmarked):
        work.mkdir(parents=True)
        (work / "lstm_loops-x.so").write_bytes(b"half")
    (abandoned / build.OWNER_FILE).write_text(str(dead.pid))
    (live / build.OWNER_FILE).write_text(str(os.getpid()))
    assert build.remove_abandoned_builds(folder) == [abandoned]
    assert not abandoned.exists() and live.is_dir() and unmarked.is_dir()


@needs_fused
def test_a_compiler_given_with_flags_builds(cache, monkeypatch):
    """``CXX="g++ -std=c++17"``: the first word is the compiler, the rest its flags (not
    "compiler not found")."""
    stand_in = Path(os.environ["CXX"])
    monkeypatch.setenv("CXX", f"{stand_in} -std=c++17 -DFLAG='two words'")
    command = build.compile_command(Path("x.cc"), Path("x.so"))
    assert command[:3] == [str(stand_in), "-std=c++17", "-DFLAG=two words"]
    path = build.library_path()
    build.ensure_built(path)
    assert build.damage(path) is None


@pytest.mark.parametrize("value, message", [("", "names no compiler"),
                                            ("'g++", "No closing quotation")])
def test_a_compiler_variable_that_names_no_compiler_is_refused_for_what_it_is(
        monkeypatch, value, message):
    monkeypatch.setenv("CXX", value)
    with pytest.raises(build.KernelUnavailable, match=message):
        build.compiler()


def test_a_target_is_chosen_by_name_and_refused_when_it_is_no_name(monkeypatch):
    monkeypatch.setenv(build.MARCH_ENV, "haswell")
    assert "-march=haswell" in build.compile_command(Path("x.cc"), Path("x.so"))
    monkeypatch.setenv(build.MARCH_ENV, "haswell; rm -rf ~")
    with pytest.raises(build.KernelUnavailable, match="no -march target"):
        build.march()


def test_a_target_this_processor_cannot_run_is_refused_before_it_is_built(monkeypatch):
    """``RNN_SEG_MARCH=sapphirerapids`` on a processor without AMX built a library that killed
    the first step with SIGILL, no message; a subset of this processor's sets is allowed."""
    if shutil.which("g++") is None or not build.target_macros(("g++",), "native"):
        pytest.skip("no g++ to ask for a target's instruction sets")
    monkeypatch.setenv("CXX", "g++")
    native = build.target_macros(("g++",), "native")
    beyond = next((t for t, isa in (("sapphirerapids", "__AMXTILE__"),
                                    ("skylake-avx512", "__AVX512F__"), ("haswell", "__AVX2__"))
                   if isa not in native), None)
    if beyond is None:
        pytest.skip("this processor runs every target tried")
    monkeypatch.setenv(build.MARCH_ENV, beyond)
    with pytest.raises(build.KernelUnavailable, match=f"{beyond}: this processor lacks"):
        build.check_target()
    monkeypatch.setenv(build.MARCH_ENV, "x86-64")
    build.check_target()


def test_the_product_path_follows_the_targets_instruction_sets():
    assert build.product_path(frozenset({"__AVX512F__", "__AVX2__", "__FMA__"}))["vector_bits"] \
        == 512
    assert build.product_path(frozenset({"__AVX2__", "__FMA__"}))["product"] == "AVX2"
    assert "generic" in build.product_path(frozenset())["product"]


def _switchable_compiler(folder: Path, library: Path | None = None) -> Path:
    """A "compiler" run by the file ``mode`` beside it, so one command (one cache key) can
    succeed, fail or hang: ``hang`` starts a child and waits (writing both process ids to
    ``pids``), ``fail`` says an error, anything else (or no file) writes ``library`` (or a few
    bytes) wherever ``-o`` points; each compile (not ``-E``) adds a line to ``calls``."""
    script = folder / "cxx"
    copy = f'cp "{library}" "$2"' if library else 'echo built > "$2"'
    script.write_text(f"""#!/bin/sh
case " $* " in *" -E "*) exec g++ "$@";; esac
echo call >> "{folder}/calls"
mode=$(cat "{folder}/mode" 2>/dev/null)
if [ "$mode" = hang ]; then
  sleep 600 &
  echo $! >> "{folder}/pids"
  echo $$ >> "{folder}/pids"
  wait
fi
if [ "$mode" = fail ]; then echo "lstm_loops.cc:1:1: error: a test's failure" >&2; exit 1; fi
while [ $# -gt 0 ]; do
  if [ "$1" = -o ]; then {copy}; exit 0; fi
  shift
done
exit 1
""")
    script.chmod(0o755)
    return script


def _calls(folder: Path) -> int:
    try:
        return len((folder / "calls").read_text().split())
    except FileNotFoundError:
        return 0


def _wait_for(condition, seconds: float = 180) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "waited too long"
        time.sleep(0.2)


@pytest.mark.parametrize("how", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT],
                         ids=["SIGKILL", "SIGTERM", "SIGINT"])
@pytest.mark.slow
def test_a_killed_build_ends_its_compiler_and_the_next_use_rebuilds(tmp_path, monkeypatch,
                                                                     capsys, how):
    """The compiler ran in its own session to completion after its process was killed (SIGKILL,
    SIGTERM) or interrupted: now it dies with it, with what it started, and nothing the killed
    build left (no library, record or failure) is taken for finished: the next use builds."""
    tools = tmp_path / "tools"
    tools.mkdir()
    monkeypatch.setenv("CXX", str(_switchable_compiler(tools)))
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "cache"))
    (tools / "mode").write_text("hang")
    builder = subprocess.Popen(
        # Ctrl-C's handler set: an xdist worker (or a shell's background job) ignores SIGINT,
        # its children inherit that, and Python then installs no handler
        [sys.executable, "-c", "import signal; "
                               "signal.signal(signal.SIGINT, signal.default_int_handler); "
                               "from rnn_seg.kernels import build; "
                               "build.ensure_built(build.library_path())"],
        env={**os.environ, "PYTHONPATH": str(ROOT)}, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: (tools / "pids").is_file()
                  and len((tools / "pids").read_text().split()) == 2)
        builder.send_signal(how)
        builder.wait(timeout=60)
    finally:
        builder.kill()
        builder.communicate()
    pids = [int(pid) for pid in (tools / "pids").read_text().split()]
    _wait_for(lambda: not any(_running(pid) for pid in pids), seconds=30)

    path = build.library_path()
    left = {p.name for p in path.parent.iterdir()}
    assert not {path.name, build.record_path(path).name, build.failure_path(path).name} & left
    (tools / "mode").write_text("build")
    capsys.readouterr()
    build.ensure_built(path)
    assert "building the fused LSTM loops" in capsys.readouterr().err
    assert build.damage(path) is None and _calls(tools) == 2
    assert not [p for p in path.parent.iterdir() if p.name.startswith(build.BUILD_PREFIX)]


def test_a_failed_build_is_remembered_and_not_tried_again(tmp_path, monkeypatch):
    """Every process (every worker of a grid) compiled a known-failing build again, for up to a
    minute each: now the second and later fall back at once, naming the failure and the retry."""
    tools = tmp_path / "tools"
    tools.mkdir()
    monkeypatch.setenv("CXX", str(_switchable_compiler(tools)))
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "cache"))
    (tools / "mode").write_text("fail")
    path = build.library_path()
    with pytest.raises(build.BuildFailed, match="error: a test's failure"):
        build.ensure_built(path)
    for _ in range(2):
        with pytest.raises(build.KernelUnavailable) as refused:
            build.ensure_built(path)
        said = str(refused.value)
        assert "\n" not in said and "error: a test's failure" in said
        assert "python -m rnn_seg.kernels" in said and str(build.failure_path(path)) in said
    assert _calls(tools) == 1 and not path.exists()

    build.failure_path(path).unlink()                   # the documented retry
    (tools / "mode").write_text("build")
    build.ensure_built(path)
    assert _calls(tools) == 2 and build.damage(path) is None


@pytest.mark.parametrize("change", ["compiler replaced", "record of another TensorFlow",
                                    "record of another source", "record of another command",
                                    "record unreadable", "record a FIFO"])
def test_a_remembered_failure_of_other_inputs_is_tried_again(tmp_path, monkeypatch, change):
    tools = tmp_path / "tools"
    tools.mkdir()
    compiler = _switchable_compiler(tools)
    monkeypatch.setenv("CXX", str(compiler))
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "cache"))
    (tools / "mode").write_text("fail")
    path = build.library_path()
    with pytest.raises(build.BuildFailed):
        build.ensure_built(path)
    failed = build.failure_path(path)
    record = json.loads(failed.read_text())
    if change == "compiler replaced":                   # an upgrade: same name, other file
        compiler.write_text(compiler.read_text() + "\n")
        os.utime(compiler, ns=(0, record["compiler"]["mtime_ns"] + 10**9))
    elif change == "record unreadable":
        failed.write_text("{not json")
    elif change == "record a FIFO":
        failed.unlink()
        os.mkfifo(failed)
    else:
        key = {"record of another TensorFlow": "tensorflow",
               "record of another source": "source_sha256",
               "record of another command": "compile_command"}[change]
        failed.write_text(json.dumps({**record, key: "other"}))
    (tools / "mode").write_text("build")
    with at_most(60):
        build.ensure_built(path)
    assert _calls(tools) == 2 and build.damage(path) is None
    assert change == "record a FIFO" or not failed.exists()


@pytest.mark.slow
def test_a_build_that_fails_while_another_waits_is_not_tried_again_by_it(tmp_path, monkeypatch,
                                                                         capsys):
    """Two workers of a grid: the second waits on the first's build lock, then finds its failure
    and falls back without compiling."""
    tools = tmp_path / "tools"
    tools.mkdir()
    monkeypatch.setenv("CXX", str(_switchable_compiler(tools)))
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "cache"))
    path = build.library_path()
    path.parent.mkdir(parents=True)

    def fail_then_unlock(held) -> None:
        build.remember_failure(path, build.BuildFailed("compiling lstm_loops.cc failed: x"))
        fcntl.flock(held, fcntl.LOCK_UN)

    with open(path.with_suffix(".lock"), "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        threading.Timer(2, fail_then_unlock, args=(held,)).start()
        with at_most(120), pytest.raises(build.KernelUnavailable, match="not tried again"):
            build.ensure_built(path)
    assert _calls(tools) == 0


@needs_fused
@pytest.mark.slow
def test_a_remembered_failure_costs_a_training_one_line_and_the_kernels_command_retries(
        tmp_path, monkeypatch, synth_dir):
    tools = tmp_path / "tools"
    tools.mkdir()
    monkeypatch.setenv("CXX", str(_switchable_compiler(tools, build.loaded()[1])))
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path / "cache"))
    (tools / "mode").write_text("fail")
    path = build.library_path()
    with pytest.raises(build.BuildFailed):
        build.ensure_built(path)
    done = _train(tmp_path / "run", synth_dir)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if "fused LSTM loops" in line]
    assert len(lines) == 1 and "not tried again" in lines[0], done.stderr
    assert _calls(tools) == 1

    (tools / "mode").write_text("build")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    kernels = subprocess.run([sys.executable, "-m", "rnn_seg.kernels"], capture_output=True,
                             text=True, env=env, timeout=600)
    assert kernels.returncode == 0, kernels.stderr
    assert _calls(tools) == 2 and not build.failure_path(path).exists()


def test_a_cache_folder_that_is_a_file_is_named_as_such(tmp_path, monkeypatch):
    """``$JIGSAWS_CACHE_DIR`` naming a file: the library was said to be "unreadable (Not a
    directory), not the cache's file: move it away" — a file that does not exist."""
    taken = tmp_path / "notes.txt"
    taken.write_text("mine")
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(taken))
    path = build.library_path()
    with at_most(60), pytest.raises(build.KernelUnavailable,
                                    match=f"cannot be made: {taken} is a file, not a folder"):
        build.ensure_built(path)
    assert taken.read_text() == "mine"

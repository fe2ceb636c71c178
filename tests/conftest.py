"""Shared fixtures: the real release when present (``JIGSAWS_DIR`` overrides), a synthetic one always.

With pytest-xdist installed (the ``test`` extra), the suite runs on every core this process may
use, one worker process per core, each test file on one worker (``--dist loadfile``: a file's
module fixtures are made once); ``-n N`` chooses the count, ``-n 0`` or ``-p no:xdist`` runs in
this process.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from jigsaws_tools.cores import usable_cores
from jigsaws_tools.dataset import default_data_dir
from jigsaws_tools.synth import SynthConfig, write_release

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> None:
    """``-n <cores> --dist loadfile`` unless the command chose a count, debugs (``--pdb``), or
    this is already a worker. Runs before xdist's own hook, which turns the count into workers."""
    if (not config.pluginmanager.hasplugin("xdist") or config.option.numprocesses is not None
            or config.option.usepdb or "PYTEST_XDIST_WORKER" in os.environ):
        return
    cores = usable_cores()
    if cores > 1:
        config.option.numprocesses = cores
        if config.option.dist == "no":
            config.option.dist = "loadfile"


@pytest.fixture(scope="session")
def real_dir() -> Path:
    path = default_data_dir()
    if not (path / "transcriptions").is_dir():
        pytest.skip(f"real JIGSAWS Suturing not found at {path} (set JIGSAWS_DIR)")
    return path


@pytest.fixture(scope="session")
def synth_dir(tmp_path_factory) -> Path:
    return write_release(tmp_path_factory.mktemp("synth") / "Suturing", SynthConfig(seed=0))


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    """The suite's own cache folder (built kernels, synthetic releases, preprocessed data), one
    per process: each xdist worker builds its own kernel library at its start, beside the other's
    (one shared build would leave the other worker waiting on its lock)."""
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "cache"))


@pytest.fixture(autouse=True)
def _data_warnings_said_anew():
    """Each test is a command of its own: its data warnings are said once more
    (``jigsaws_tools.messages``)."""
    from jigsaws_tools.messages import new_command

    new_command()

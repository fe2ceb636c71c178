"""Shared fixtures: the real release when present (``JIGSAWS_DIR`` overrides), a synthetic one always."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from jigsaws_tools.dataset import default_data_dir
from jigsaws_tools.synth import SynthConfig, write_release

os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "2")


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
    monkeypatch.setenv("JIGSAWS_CACHE_DIR", str(tmp_path_factory.getbasetemp() / "cache"))


@pytest.fixture(autouse=True)
def _data_warnings_said_anew():
    """Each test is a command of its own: its data warnings are said once more
    (``jigsaws_tools.messages``)."""
    from jigsaws_tools.messages import new_command

    new_command()

"""The settings a run folder is checked against, so that a folder always matches its weights.

A run records its configuration in ``config.json``: a dict of configuration dataclasses and plain
values (``Trainer(configs=...)``: the run's ``RunConfig``, tasks, variant, weighting, GradNorm
configuration, a fingerprint of the data ...). Its *settings* are the flat leaves of that record,
``{"run.encoder.hidden": 1024, "tasks": ["gesture"], ...}``, less the fields that a configuration
dataclass names in its ``output_fields`` class attribute: what a run writes rather than what it
computes (plots, log and checkpoint intervals, which checkpoints are kept ...), how it computes
rather than what (the LSTM's loops: the same equations, equal to float32 rounding, like the
thread plan, which is no setting either), or where its input is rather than what it holds (the
release's folder: the data fingerprint hashes its files). Their
hash (``settings_hash``) is stored in config.json, in every checkpoint and in finished.json.

Launching a run into a folder whose config.json records other settings stops before any work with
a ``SettingsMismatchError`` naming each difference (old -> new).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any, Iterator

from .folder import CONFIG, RunFolderError, read_json, run_outputs, to_jsonable

#: Top-level config.json keys that describe the record rather than the run's configuration.
RECORD_KEYS = ("settings_hash", "provenance")


class SettingsMismatchError(RunFolderError):
    """A run folder holds a run of other settings (or outputs of an unknown run): ``details``
    says which, the message adds what to do."""

    HINT = "Use another folder, or restart (e.g. --restart) to delete its results and train afresh."

    def __init__(self, details: str, hint: str = HINT):
        super().__init__(f"{details}\n{hint}")
        self.details = details


def settings_of(configs: dict) -> dict[str, Any]:
    """Every training-relevant leaf of ``configs`` as ``{"dotted.path": JSON value}``."""
    skip = set(output_paths(configs))
    return {k: v for k, v in _leaves(to_jsonable(configs)) if k not in skip}


def settings_hash(configs: dict) -> str:
    """16 hex digits identifying ``settings_of(configs)``."""
    text = json.dumps(settings_of(configs), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def output_paths(obj: Any, prefix: str = "") -> Iterator[str]:
    """Dotted paths of the output-only fields (``output_fields``) of the dataclasses in ``obj``."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            path = f"{prefix}{f.name}"
            if f.name in getattr(type(obj), "output_fields", ()):
                yield path
            else:
                yield from output_paths(getattr(obj, f.name), path + ".")
    elif isinstance(obj, dict):
        for key, value in obj.items():
            yield from output_paths(value, f"{prefix}{key}.")


def differences(recorded: dict, configs: dict) -> list[str]:
    """``"path: old -> new"`` for every setting where config.json's content ``recorded`` and
    ``configs`` differ (a setting one side lacks shows as ``(not recorded)``)."""
    new = settings_of(configs)
    skip = set(output_paths(configs))
    old = {k: v for k, v in _leaves({k: v for k, v in recorded.items() if k not in RECORD_KEYS})
           if k not in skip}
    return [f"{key}: {_show(old.get(key, _MISSING))} -> {_show(new.get(key, _MISSING))}"
            for key in [*new, *(k for k in old if k not in new)]
            if old.get(key, _MISSING) != new.get(key, _MISSING)]


def check_run_dir(run_dir: Path, configs: dict) -> None:
    """Raise ``SettingsMismatchError`` unless ``run_dir`` is new, or holds a run of ``configs``'
    settings: its config.json records the same settings, or it has no config.json and no outputs.
    """
    run_dir = Path(run_dir)
    if not (run_dir / CONFIG).is_file():
        outputs = run_outputs(run_dir)
        if outputs:
            raise SettingsMismatchError(f"{run_dir} holds run outputs ({', '.join(outputs)}) but "
                                        f"no {CONFIG}: they cannot be checked against this run's "
                                        "settings.")
        return
    recorded = read_json(run_dir / CONFIG)
    if not isinstance(recorded, dict):
        raise RunFolderError(f"{run_dir / CONFIG}: not a run's record: expected a JSON object "
                             f"(value: {str(recorded)[:60]})")
    changed = differences(recorded, configs)
    if changed:
        raise SettingsMismatchError(f"{run_dir} holds a run with other settings (recorded -> "
                                    "requested):\n  " + "\n  ".join(changed))


def _leaves(obj: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """``(dotted path, value)`` of every non-dict value of nested dicts (lists are leaves)."""
    if isinstance(obj, dict) and obj:
        for key, value in obj.items():
            yield from _leaves(value, f"{prefix}{key}.")
    else:
        yield prefix.removesuffix("."), obj


_MISSING = object()


def _show(value: Any) -> str:
    return "(not recorded)" if value is _MISSING else json.dumps(value)

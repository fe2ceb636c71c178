"""What trained which sweeps of a run: its training segments.

A run trains in one or more sessions (each launch of an unfinished run starts one, from its newest
checkpoint). A segment records one session's sweeps and how they ran::

    {"from_sweep": 0, "to_sweep": 140, "loops": "fused", "precision": "fp32",
     "why": "auto: the fused loops build and load here (...)", "started": "...",
     "host": "...", "cpu": "AMD EPYC"}

``loops`` is the LSTM's loops (``graph``, ``xla``, ``fused``; None for an encoder without
loops), ``why`` how they were chosen (``rnn_seg.lstm.loops_reason``). The segments up to a
checkpoint are saved in its clock (``ckpt-<N>.clock.json``), so that a run resumed from it
continues the list; a finished run's ``finished.json`` holds them all. A run resumed from a
checkpoint saved before segments were recorded gets one segment for the sweeps before it, with
the loops its config.json's provenance names. ``ran_loops`` reads a run's loops from its
segments: one name, or ``mixed (...)`` when sessions ran on different loops.
"""
from __future__ import annotations

import socket
from typing import Any

from .provenance import cpu_model, now, started_loops

SEGMENTS = "segments"


def session_segment(encoder: Any, first_sweep: int) -> dict:
    """The segment this session trains from sweep ``first_sweep`` on (open: no ``to_sweep``),
    from ``encoder``'s configuration (its ``config.loops`` and ``config.precision``, where it has
    them) and ``loops_why``."""
    config = getattr(encoder, "config", None)
    return {"from_sweep": first_sweep, "loops": getattr(config, "loops", None),
            "precision": getattr(config, "precision", None),
            "why": getattr(encoder, "loops_why", None), "started": now(),
            "host": socket.gethostname(), "cpu": cpu_model()}


def earlier_segments(clock: dict | None, sweep: int, record: dict) -> list[dict]:
    """The segments before checkpoint ``sweep`` (0: none), as its ``clock`` saved them; for a
    checkpoint saved before segments were recorded, one segment with the loops config.json's
    ``record`` says the run started on."""
    if sweep == 0:
        return []
    saved = (clock or {}).get(SEGMENTS)
    if isinstance(saved, list) and all(isinstance(s, dict) for s in saved):
        return saved
    return [{"from_sweep": 0, "to_sweep": sweep, "loops": started_loops(record),
             "precision": None, "why": "read from config.json's provenance: checkpoint "
             f"ckpt-{sweep} predates segment records"}]


def closed(segments: list[dict], sweep: int) -> list[dict]:
    """``segments`` with the open last one ending at ``sweep``; a segment without sweeps (a
    session that trained none) is left out."""
    done = [*segments[:-1], {**segments[-1], "to_sweep": sweep}] if segments else []
    return [s for s in done if s.get("to_sweep") != s.get("from_sweep")]


def ran_loops(segments: list[dict]) -> str | None:
    """The loops that trained a run with these segments: one name, ``mixed (fused, graph)``
    when they differ, None when no segment names any."""
    ran = sorted({s.get("loops") for s in segments if isinstance(s.get("loops"), str)})
    if not ran:
        return None
    return ran[0] if len(ran) == 1 else f"mixed ({', '.join(ran)})"

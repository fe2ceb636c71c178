"""The cores this process may use: the bound of every thread and worker count of the project.

A cluster's batch job (Slurm, PBS), a container started with ``--cpuset-cpus`` and ``taskset``
give a process some of the machine's cores through its CPU affinity; ``os.cpu_count()`` counts
all of them. Thread pools sized by the machine would put tens of threads on the few cores a job
holds, and threads that wait for each other then collapse (docs/PERFORMANCE.md).
"""
from __future__ import annotations

import os


def usable_cores() -> int:
    """The number of cores this process may run on: its CPU affinity where the system reports
    one (Linux), else every core of the machine; at least 1."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1

"""Deterministic worker kills for the Dask tests.

A task announces itself (its process id in a flag file) and waits; the test kills
that worker process mid-task, then checks that nothing was lost. Module-level
functions: the workers import this module to run the hook.
"""

from __future__ import annotations

import concurrent.futures
import functools
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def announce_and_wait(flag: str, victim: int, index: int) -> None:
    """First attempt of task ``victim``: write this worker's pid, then wait to be killed."""
    if index != victim or os.path.exists(flag):
        return
    Path(flag).write_text(str(os.getpid()))
    time.sleep(60)
    raise RuntimeError("the test did not kill this worker")


def run_killing_one_task(start: Callable[[Callable[[int], None]], Any], flag: Path,
                         victim: int) -> Any:  # fmt: skip
    """``start(hook)`` in a thread, the worker running task ``victim`` killed mid-task.

    ``start`` passes ``hook`` to the job as its per-task testing hook (``before_shard``,
    ``before_part``); returns what ``start`` returns.
    """
    hook = functools.partial(announce_and_wait, str(flag), victim)
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        job = pool.submit(start, hook)
        deadline = time.monotonic() + 30
        while not flag.exists() or not flag.read_text():
            assert time.monotonic() < deadline and not job.done(), f"task {victim} never started"
            time.sleep(0.05)
        os.kill(int(flag.read_text()), signal.SIGKILL)  # the worker dies mid-task
        return job.result(timeout=60)

"""`stiffnet serve` as a real process on 127.0.0.1, for the tests that need one."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

ROOT = Path(__file__).resolve().parents[1]


def free_port() -> int:
    """A loopback port nobody listens on (at the time of asking)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextmanager
def serving(*args: str, stderr: IO[bytes], port: int | None = None) -> Iterator[int]:
    """Start ``stiffnet serve --port PORT *args``, wait for ``/health``, yield the port, stop.

    The server's stderr goes to `stderr` (an open binary file): a test reads it for the
    log lines, and a server that dies during start-up fails with its log.
    """
    import httpx

    port = port or free_port()
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "stiffnet", "serve", "--port", str(port), *args],
        stdout=subprocess.DEVNULL, stderr=stderr, env=env, cwd=ROOT,
    )  # fmt: skip
    try:
        for _ in range(300):
            try:
                if httpx.get(f"http://127.0.0.1:{port}/health", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                time.sleep(0.1)
            assert proc.poll() is None, f"stiffnet serve exited with {proc.returncode}"
        yield port
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

"""Bounded HTTP load test of ``stiffnet serve`` on loopback.

Starts ``stiffnet serve`` as a subprocess on 127.0.0.1 with a free port, waits for
``GET /health``, then ``--clients`` concurrent clients (httpx, asyncio) send
``--requests`` ``POST /predict`` requests in all, each the first ``--seconds``
of the shipped example recording as JSON samples. Reports latency percentiles
(p50, p90, p99, max), throughput, the status codes (5xx must be 0), and the
server's resident memory at start (after one warm-up request), at the middle
and at the end; then stops the server. Exit code 1 if any 5xx or transport error.

    python benchmarks/load_http.py            # 50 clients, 5,000 requests
    python benchmarks/load_http.py --quick    # 20 clients, 300 requests
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import socket
import statistics
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def rss_mb(pid: int) -> float:
    """Resident set size of a process in MB (psutil if installed, else /proc)."""
    try:
        import psutil

        return psutil.Process(pid).memory_info().rss / 2**20
    except ImportError:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def wait_healthy(base: str, proc: subprocess.Popen, timeout: float = 60.0) -> None:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if proc.poll() is not None:
            raise SystemExit(f"server exited with code {proc.returncode}")
        try:
            if httpx.get(f"{base}/health", timeout=1.0).status_code == 200:
                return
        except httpx.HTTPError:
            time.sleep(0.2)
    raise SystemExit("server did not become healthy")


async def run_load(base: str, body: bytes, n_requests: int, n_clients: int, pid: int) -> dict:
    latencies: list[float] = []
    codes: Counter = Counter()
    rss: dict[str, float] = {}
    issued = 0

    async def client(c: httpx.AsyncClient) -> None:
        nonlocal issued
        while issued < n_requests:
            issued += 1
            if issued == n_requests // 2:
                rss["middle"] = rss_mb(pid)
            t = time.perf_counter()
            try:
                r = await c.post(
                    "/predict", content=body, headers={"content-type": "application/json"}
                )
                codes[r.status_code] += 1
            except httpx.HTTPError as exc:
                codes[f"transport error {type(exc).__name__}"] += 1
            latencies.append(time.perf_counter() - t)

    limits = httpx.Limits(max_connections=n_clients, max_keepalive_connections=n_clients)
    async with httpx.AsyncClient(base_url=base, timeout=120.0, limits=limits) as c:
        t0 = time.perf_counter()
        await asyncio.gather(*(client(c) for _ in range(n_clients)))
        wall = time.perf_counter() - t0
    return {"latencies": latencies, "codes": codes, "wall_s": wall, "rss": rss}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="20 clients, 300 requests")
    ap.add_argument("--requests", type=int, default=5000)
    ap.add_argument("--clients", type=int, default=50)
    ap.add_argument("--seconds", type=float, default=5.0, help="recording length per request")
    ap.add_argument("--max-concurrency", type=int, default=2, help="server worker threads")
    args = ap.parse_args()
    if args.quick:
        args.requests, args.clients = 300, 20

    from stiffnet.recordings import read_recording

    rec = read_recording(EXAMPLE)
    samples = rec.accel[: int(args.seconds * rec.fs_hz)]
    body = json.dumps({"samples": np.round(samples, 6).tolist(), "fs_hz": rec.fs_hz}).encode()

    port = free_port()
    base = f"http://127.0.0.1:{port}"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    cmd = [
        sys.executable,
        "-m",
        "stiffnet",
        "serve",
        "--port",
        str(port),
        "--max-concurrency",
        str(args.max_concurrency),
        "--max-queue",
        str(4 * args.clients),
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_healthy(base, proc)
        warm = httpx.post(
            f"{base}/predict",
            content=body,
            headers={"content-type": "application/json"},
            timeout=60,
        )
        if warm.status_code != 200:
            raise SystemExit(f"warm-up request failed: {warm.status_code} {warm.text[:200]}")
        rss_start = rss_mb(proc.pid)
        res = asyncio.run(run_load(base, body, args.requests, args.clients, proc.pid))
        rss_end = rss_mb(proc.pid)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    lat = np.array(res["latencies"]) * 1e3
    codes = res["codes"]
    n5xx = sum(v for k, v in codes.items() if isinstance(k, int) and k >= 500)
    n_err = sum(v for k, v in codes.items() if isinstance(k, str))
    print(
        f"{args.requests} requests, {args.clients} concurrent clients, {len(body) / 1e3:.0f} kB "
        f"JSON each ({args.seconds:g} s at {rec.fs_hz:g} Hz), server --max-concurrency "
        f"{args.max_concurrency}"
    )
    print(f"wall {res['wall_s']:.1f} s, throughput {len(lat) / res['wall_s']:.1f} req/s")
    print(
        f"latency ms: p50 {np.percentile(lat, 50):.1f}, p90 {np.percentile(lat, 90):.1f}, "
        f"p99 {np.percentile(lat, 99):.1f}, max {lat.max():.1f} (mean {statistics.fmean(lat):.1f})"
    )
    print(f"status codes: {dict(sorted(codes.items(), key=str))}")
    mid = res["rss"].get("middle", float("nan"))
    print(f"server RSS MB: start {rss_start:.1f}, middle {mid:.1f}, end {rss_end:.1f}")
    print(f"5xx: {n5xx}")
    return 1 if n5xx or n_err else 0


if __name__ == "__main__":
    sys.exit(main())

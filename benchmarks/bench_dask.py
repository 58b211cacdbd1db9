"""Benchmark dataset generation in-process against Dask LocalClusters of 1 and 2 workers.

Measures, on one dataset job (default config, ``--trajectories`` trajectories in shards
of ``--shard-size``):

* windows/s in-process, on a LocalCluster of 1 worker and of 2 workers (clusters are
  started and warmed up first - numba's cached kernels loaded in every worker - so
  the figure is the job's throughput; the start-up is reported on its own line);
* the overhead of the Dask path on a small job (2 tiny shards): in-process, on a warm
  1-worker cluster, and cold (``workers=1``: start, run, stop - what
  ``stiffnet simulate --workers 1`` costs);
* the cost of one trivial task (``map_tasks`` of 200 no-ops on the warm cluster).

Fairness: every worker runs one task at a time on one thread (OMP/numba threads = 1,
see ``stiffnet.distributed.cluster.WORKER_ENV``), so the in-process run is limited to
one numba thread too (``stiffnet.simulator.compiled.limited_threads(1)``); without
that limit the in-process compiled simulator would use every core by itself. The
machine's load average is printed: on a shared machine, timings move with it.

Run: ``OMP_NUM_THREADS=1 python benchmarks/bench_dask.py [--quick]`` (the default job
takes ~10-30 s in-process on one core; ``--quick`` is ~8x smaller).
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from stiffnet.config import load_yaml, validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.generate import generate_dataset
from stiffnet.distributed import map_tasks
from stiffnet.distributed.cluster import local_cluster
from stiffnet.simulator.compiled import limited_threads

ROOT = Path(__file__).resolve().parents[1]


def config(n_trajectories: int, shard_size: int, seed: int = 0) -> SimulationConfig:
    data = load_yaml(ROOT / "configs" / "sim" / "ideal.yaml")
    data.update(seed=seed, n_trajectories=n_trajectories, shard_size=shard_size)
    return validate_config(SimulationConfig, data)


def timed(cfg: SimulationConfig, out: Path, **where) -> tuple[float, int]:
    """Seconds and windows of one generation into ``out`` (replaced)."""
    t0 = time.perf_counter()
    card = generate_dataset(cfg, out, overwrite=True, **where)
    return time.perf_counter() - t0, int(card["n_windows"])


def _noop(x: int) -> int:
    return x


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="A job ~8x smaller.")
    parser.add_argument("--trajectories", type=int, default=None)
    parser.add_argument("--shard-size", type=int, default=128)
    args = parser.parse_args()
    n = args.trajectories or (256 if args.quick else 2048)
    shard = min(args.shard_size, 32) if args.quick else args.shard_size
    job, small, warm = config(n, shard), config(8, 4, seed=1), config(4, 4, seed=2)
    tmp = Path(tempfile.mkdtemp(prefix="bench_dask-"))
    rows: dict[str, tuple[float, int]] = {}
    extra: dict[str, float] = {}
    load0 = os.getloadavg()[0]
    try:
        with limited_threads(1):
            timed(warm, tmp / "warm")  # numba kernels loaded from its cache
            rows["in-process (1 numba thread)"] = timed(job, tmp / "job")
            extra["small in-process"] = timed(small, tmp / "small")[0]
        for workers in (1, 2):
            t0 = time.perf_counter()
            with local_cluster(workers) as cluster:
                extra[f"start {workers}-worker cluster"] = time.perf_counter() - t0
                address = cluster.scheduler_address
                timed(warm, tmp / "warm", scheduler=address)  # warm every worker up
                if workers == 2:
                    timed(config(8, 4, seed=3), tmp / "warm", scheduler=address)
                rows[f"LocalCluster, {workers} worker(s)"] = timed(job, tmp / "job",
                                                                  scheduler=address)  # fmt: skip
                if workers == 1:
                    extra["small on warm 1-worker cluster"] = timed(
                        small, tmp / "small", scheduler=address
                    )[0]
                    t0 = time.perf_counter()
                    map_tasks(_noop, range(200), scheduler=address)
                    extra["per trivial task (ms)"] = (time.perf_counter() - t0) / 200 * 1e3
        extra["small, cold (workers=1: start+run+stop)"] = timed(small, tmp / "small",
                                                                 workers=1)[0]  # fmt: skip
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load1 = os.getloadavg()[0]

    print(f"\njob: {n} trajectories, shards of {shard} ({-(-n // shard)} shards); "
          f"load average {load0:.1f} -> {load1:.1f} on {os.cpu_count()} cores\n")  # fmt: skip
    print("| run | seconds | windows | windows/s |")
    print("| --- | ---: | ---: | ---: |")
    for name, (sec, win) in rows.items():
        print(f"| {name} | {sec:.2f} | {win} | {win / sec:.0f} |")
    base = rows["in-process (1 numba thread)"][0]
    one = rows["LocalCluster, 1 worker(s)"][0]
    two = rows["LocalCluster, 2 worker(s)"][0]
    print(f"\nspeed-up 2 workers / 1 worker: {one / two:.2f}x")
    print(f"speed-up 2 workers / in-process: {base / two:.2f}x")
    print(f"1 worker / in-process time: {one / base:.2f} (Dask overhead on the big job: "
          f"{100 * (one / base - 1):+.1f}%)\n")  # fmt: skip
    print("| small job (2 shards, 8 trajectories) and fixed costs | seconds |")
    print("| --- | ---: |")
    for name, value in extra.items():
        print(f"| {name} | {value:.3f} |")
    overhead = extra["small on warm 1-worker cluster"] - extra["small in-process"]
    print(f"\noverhead_small_warm_s: {overhead:.3f}")
    print(f"speedup_2_workers: {one / two:.2f}")


if __name__ == "__main__":
    main()

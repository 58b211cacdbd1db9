"""Dask: map_tasks, dataset generation and campaigns on a real LocalCluster (2 processes).

One cluster serves the module. Fault injection is deterministic: a shard task announces
itself (its process id in a flag file) and waits; the test kills that worker process,
then checks that nothing is lost, the dataset is byte-identical to an in-process run,
and the shard is reported as run again.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from fault_injection import run_killing_one_task  # noqa: E402

from stiffnet.config import validate_config  # noqa: E402
from stiffnet.config.sim import SimulationConfig  # noqa: E402
from stiffnet.dataset.generate import generate_dataset  # noqa: E402
from stiffnet.dataset.store import load_dataset  # noqa: E402
from stiffnet.distributed import map_tasks, run_tasks  # noqa: E402
from stiffnet.distributed.cluster import local_cluster  # noqa: E402
from stiffnet.errors import StiffnetError  # noqa: E402

SMALL = {
    "n_trajectories": 8,
    "shard_size": 2,
    "windows": {"duration_periods": 6, "per_trajectory": 2},
    "sweep": {"fs_ratio": [50, 80]},
    "solver": {"settle_tolerance": 0.1, "batch_size": 2},
}


@pytest.fixture(scope="module")
def cluster():
    with local_cluster(2) as c:
        yield c


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The dataset generated in-process: what every cluster run must reproduce."""
    out = tmp_path_factory.mktemp("ref") / "ds"
    generate_dataset(validate_config(SimulationConfig, SMALL), out)
    return out


def shard_bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted((folder / "shards").iterdir())}


# ----------------------------------------------------------------- fault injection
# module-level functions: the workers import this module to run them


def _flaky(flag_dir: str, x: int) -> int:
    """Fails the first time it sees ``x == 2``, then succeeds."""
    flag = Path(flag_dir) / f"seen-{x}"
    if x == 2 and not flag.exists():
        flag.write_text("1")
        raise RuntimeError("transient failure")
    return x * x


def _user_error(x: int) -> int:
    if x == 1:
        raise StiffnetError(f"item {x} is bad input")
    return x


@contextlib.contextmanager
def _record_limit(n: int):
    """A thread limit that leaves its ``n`` where the task can read it."""
    os.environ["STIFFNET_TEST_THREAD_LIMIT"] = str(n)
    try:
        yield
    finally:
        del os.environ["STIFFNET_TEST_THREAD_LIMIT"]


def _limit_seen(x: int) -> tuple[int, str | None]:
    return x, os.environ.get("STIFFNET_TEST_THREAD_LIMIT")


def _always_fails_on(victim: int, shard: int) -> None:
    if shard == victim:
        raise RuntimeError(f"shard {shard} cannot be simulated")


# ----------------------------------------------------------------------- map_tasks


def test_map_tasks_in_process_keeps_order_and_names_the_failure(tmp_path):
    assert map_tasks(abs, [-3, 1, -2]) == [3, 1, 2]
    seen = []
    assert map_tasks(abs, [1, -1], progress=lambda d, t: seen.append((d, t))) == [1, 1]
    assert seen == [(1, 2), (2, 2)]
    with pytest.raises(StiffnetError, match=r"^task _flaky\[1\] failed: RuntimeError: transient"):
        map_tasks(functools.partial(_flaky, str(tmp_path)), [1, 2, 3])


def test_map_tasks_on_the_cluster_retries_and_reports(cluster, tmp_path):
    fn = functools.partial(_flaky, str(tmp_path))
    report = run_tasks(fn, range(6), scheduler=cluster.scheduler_address, retries=2)
    assert report.results == [0, 1, 4, 9, 16, 25] and not report.failed
    assert list(report.rerun) == ["_flaky[2]"]
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    with pytest.raises(StiffnetError, match=r"task _flaky\[0\] failed: .*transient.*after 1 run"):
        map_tasks(functools.partial(_flaky, str(fresh)), [2], scheduler=cluster.scheduler_address,
                  retries=0)  # fmt: skip


def test_thread_limit_is_the_callers_and_applies_on_workers_only(cluster):
    # the runner imports no compute library: the caller's limit wraps each Dask task
    on_cluster = map_tasks(_limit_seen, [1, 2, 3], scheduler=cluster.scheduler_address,
                           thread_limit=_record_limit)  # fmt: skip
    assert on_cluster == [(1, "1"), (2, "1"), (3, "1")]
    plain = map_tasks(_limit_seen, [1], scheduler=cluster.scheduler_address)
    assert plain == [(1, None)]
    # in-process the task keeps every thread of the caller's process
    assert map_tasks(_limit_seen, [4], thread_limit=_record_limit) == [(4, None)]


#: What a worker process of a LocalCluster goes through: a script's imports load numba (its
#: thread count read from the environment then), the nanny's ``env`` sets the worker's count
#: after the process started, a task runs inside the simulator's thread limit, and then
#: something is compiled for the first time (a cold cache: a fresh install, changed code).
WORKER_FIRST_COMPILE = """
import os
os.environ["NUMBA_NUM_THREADS"] = "2"
from stiffnet.simulator import compiled
os.environ["NUMBA_NUM_THREADS"] = "1"
with compiled.limited_threads(1):
    pass
import numba
numba.njit(lambda x: x + 1)(1)
print(numba.config.NUMBA_NUM_THREADS)
"""


def test_a_workers_first_compile_after_its_thread_limit_does_not_fail():
    # numba re-reads NUMBA_NUM_THREADS only when it compiles, and refuses a changed value
    # once its pool is launched: the limit reads the environment before it launches the pool
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "NUMBA_NUM_THREADS"}
    run = subprocess.run([sys.executable, "-c", WORKER_FIRST_COMPILE], env=env,
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0, run.stderr.strip().splitlines()[-1:]
    assert run.stdout.strip() == "1"


def test_bad_input_is_not_retried(cluster):
    report = run_tasks(_user_error, [0, 1, 2], scheduler=cluster.scheduler_address, retries=2)
    assert report.results == [0, None, 2] and not report.rerun
    assert report.failed == {"_user_error[1]": "item 1 is bad input"}
    with pytest.raises(StiffnetError, match=r"^task _user_error\[1\] failed: item 1 is bad input$"):
        report.raise_failures()


def test_dask_options_are_checked(monkeypatch):
    import sys

    with pytest.raises(StiffnetError, match="either --scheduler .* or --workers"):
        map_tasks(abs, [1], scheduler="tcp://127.0.0.1:1", workers=2)
    with pytest.raises(StiffnetError, match=r"--workers must be 1\.\."):
        map_tasks(abs, [1], workers=0)
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if the extra were missing
    with pytest.raises(StiffnetError, match=r"pip install 'stiffnet\[dask\]'"):
        map_tasks(abs, [1], workers=1)
    assert map_tasks(abs, [-1]) == [1]  # in-process needs no Dask


# ------------------------------------------------------------------ dataset shards


def test_one_and_two_workers_write_the_same_dataset(cluster, reference, tmp_path):
    cfg = validate_config(SimulationConfig, SMALL)
    two = generate_dataset(cfg, tmp_path / "two", scheduler=cluster.scheduler_address)
    one = generate_dataset(cfg, tmp_path / "one", workers=1)  # its own LocalCluster
    assert shard_bytes(tmp_path / "two") == shard_bytes(reference)
    assert shard_bytes(tmp_path / "one") == shard_bytes(reference)
    assert one["shards"] == two["shards"] and two["run"]["backend"].startswith("tcp://")
    assert len(load_dataset(tmp_path / "two", verify=True)) == two["n_windows"] == 16


def test_killed_worker_loses_nothing(cluster, reference, tmp_path):
    cfg = validate_config(SimulationConfig, SMALL)
    card = run_killing_one_task(
        lambda hook: generate_dataset(cfg, tmp_path / "ds", scheduler=cluster.scheduler_address,
                                      before_shard=hook),
        tmp_path / "victim.pid", 1,
    )  # fmt: skip
    assert shard_bytes(tmp_path / "ds") == shard_bytes(reference)
    assert "shard-00001" in card["run"]["rerun"]
    saved = json.loads((tmp_path / "ds" / "card.json").read_text())
    assert saved["n_windows"] == 16 and saved["run"]["rerun"] == card["run"]["rerun"]
    cluster.wait_for_workers(2, timeout=30)  # the nanny restarted it


def test_failed_shard_is_named_and_the_rerun_resumes(cluster, reference, tmp_path):
    cfg = validate_config(SimulationConfig, SMALL)
    out = tmp_path / "ds"
    hook = functools.partial(_always_fails_on, 2)
    with pytest.raises(StiffnetError, match=r"^task shard-00002 failed: .*cannot be simulated.*"
                                            r"after 2 runs"):  # fmt: skip
        generate_dataset(cfg, out, scheduler=cluster.scheduler_address, retries=1,
                         before_shard=hook)  # fmt: skip
    assert not (out / "card.json").exists()
    done = {p.name: p.stat().st_mtime_ns for p in (out / "shards").iterdir()}
    assert sorted(done) == ["shard-00000.parquet", "shard-00001.parquet", "shard-00003.parquet"]
    card = generate_dataset(cfg, out, scheduler=cluster.scheduler_address)
    assert card["run"]["shards_kept"] == 3 and card["run"]["shards_run"] == 1
    assert {n: (out / "shards" / n).stat().st_mtime_ns for n in done} == done  # untouched
    assert shard_bytes(out) == shard_bytes(reference)


def test_dask_reads_the_shards(cluster, reference):
    import dask.dataframe as dd
    from distributed import Client

    with Client(cluster.scheduler_address) as client:
        frame = dd.read_parquet(str(reference / "shards"))
        assert frame.npartitions == 4
        n = client.compute(frame["beta"].count()).result()
    assert n == load_dataset(reference).card["n_windows"]


# ------------------------------------------------------------------------ campaigns

MANIFEST = """recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s
a.csv,500,1.05,1.9,2.8,0.02,12,0.4
sub/b.csv,800,0.95,1.0,0.5,0.02,40,0.3
c.npy,600,1.0,1.2,1.2,0.02,90,0.2
"""


def test_campaign_is_the_same_on_the_cluster(cluster, tmp_path):
    from stiffnet.campaign import simulate_campaign

    manifest = tmp_path / "m.csv"
    manifest.write_text(MANIFEST)
    effects = ["gap_drift:amplitude=0.1..0.3"]
    local = simulate_campaign(manifest, tmp_path / "local", effects, seed=7)
    remote = simulate_campaign(manifest, tmp_path / "remote", effects, seed=7,
                               scheduler=cluster.scheduler_address)  # fmt: skip
    files = sorted(p.relative_to(local) for p in local.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(remote) for p in remote.rglob("*") if p.is_file())
    for name in files:
        assert (local / name).read_bytes() == (remote / name).read_bytes(), name
    bad = tmp_path / "bad.csv"
    bad.write_text(MANIFEST.replace("c.npy,600", "c.npy,20"))
    with pytest.raises(StiffnetError, match=r"line 4 \(c\.npy\): fs_ratio"):
        simulate_campaign(bad, tmp_path / "bad", [], scheduler=cluster.scheduler_address)
    assert not (tmp_path / "bad").exists()


def test_restoring_force_evidence_is_the_same_on_the_cluster(cluster, tmp_path):
    """diagnose reads each recording's force map on its workers: same evidence as in-process."""
    from distributed import Client

    from stiffnet.campaign import load_campaign, simulate_campaign
    from stiffnet.measurement.evidence import restoring_force_evidence

    manifest = tmp_path / "m.csv"
    manifest.write_text(MANIFEST.replace(",0.4\n", ",2.0\n").replace(",0.3\n", ",2.0\n"))
    effects = ["contact_damping:damping_ratio=0.2"]
    camp = load_campaign(simulate_campaign(manifest, tmp_path / "c", effects, seed=3))
    local = restoring_force_evidence(camp, camp.rows)
    with Client(cluster.scheduler_address) as client:
        remote = restoring_force_evidence(camp, camp.rows, client)
    assert [p["recording"] for p in remote["per_recording"]] == ["a.csv", "sub/b.csv", "c.npy"]
    assert remote == local
    assert local["answered"] >= 1


# ------------------------------------------------------------------------------ CLI


def test_cli_simulate_runs_where_stiffnet_scheduler_says(cluster, reference, tmp_path):
    import yaml
    from typer.testing import CliRunner

    from stiffnet.cli import app

    cfg = tmp_path / "c.yaml"
    cfg.write_text(yaml.safe_dump(SMALL))
    args = ["simulate", "--config", str(cfg), "--out", str(tmp_path / "ds")]
    env = {"STIFFNET_SCHEDULER": cluster.scheduler_address}
    res = CliRunner().invoke(app, [*args, "--json", str(tmp_path / "r.json")], env=env)
    assert res.exit_code == 0, res.output
    assert json.loads((tmp_path / "r.json").read_text())["run"]["backend"].startswith("tcp://")
    assert shard_bytes(tmp_path / "ds") == shard_bytes(reference)
    res = CliRunner().invoke(app, [*args, "--overwrite", "--workers", "2"], env=env)
    assert res.exit_code == 2 and "not both" in res.output


def _worker_housekeeping() -> dict:
    import dask

    return {k: dask.config.get(k) for k in ("distributed.worker.profile.enabled",
                                            "distributed.admin.tick.interval")}  # fmt: skip


def test_local_cluster_runs_without_the_dashboards_housekeeping(cluster, tmp_path) -> None:
    """The shipped settings reach the scheduler (no work stealing) and every worker (no
    profiler, a slow tick); a typo in the file is one line."""
    from distributed import Client

    from stiffnet.config import load_config
    from stiffnet.distributed.cluster import LocalClusterSettings, local_cluster_settings
    from stiffnet.errors import ConfigError

    assert local_cluster_settings() == LocalClusterSettings()  # the file: the defaults
    with Client(cluster) as client:
        seen = client.run(_worker_housekeeping)
        stealing = client.run_on_scheduler(
            lambda dask_scheduler: "stealing" in dask_scheduler.extensions
        )  # fmt: skip
    assert len(seen) == 2
    for cfg in seen.values():
        assert cfg == {"distributed.worker.profile.enabled": False,
                       "distributed.admin.tick.interval": "1.0s"}  # fmt: skip
    assert stealing is False
    bad = tmp_path / "local_cluster.yaml"
    bad.write_text("profile: false\ntick_interval: 1.0\n")
    with pytest.raises(ConfigError, match="tick_interval"):
        load_config(LocalClusterSettings, bad)

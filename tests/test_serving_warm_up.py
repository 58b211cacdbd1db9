"""The server's start and its last guard: the warm-up (one small prediction per lane's code
path, bounded, one line; a server that cannot predict refuses to start) and a job that
cannot finish in time (refused at its start with 429, or 503 with Retry-After once it ran
past the timeout; never a 504)."""

from __future__ import annotations

import asyncio
import math
import threading
import time

import httpx
import numpy as np
import pytest

from serving.app import Admission, Limits, ShedAtStart, create_app
from serving.load_shedding import SHED_MARGIN
from serving.warm_up import (
    WARM_UP_BETA,
    WARM_UP_FN_HZ,
    WARM_UP_FS_HZ,
    WARM_UP_SECONDS,
    WarmUpFailed,
    warm_up,
    warm_up_recording,
)


@pytest.fixture(scope="module")
def predictor():
    from serving.predictor import Predictor

    return Predictor.load()


class _Stub:
    """Stand-in predictor: answers `beta` after `seconds`, or raises `fails`; counts calls."""

    name, sha256, kind = "stub", "0" * 64, "cnn"

    def __init__(self, seconds: float = 0.0, fails: Exception | None = None) -> None:
        self.seconds, self.fails, self.seen = seconds, fails, []

    def predict(self, accel, fs_hz, **kwargs):
        self.seen.append(len(accel))
        if self.fails is not None:
            raise self.fails
        time.sleep(self.seconds)
        return {"class": "hard", "beta": 40.0}

    def info(self):
        return {"name": self.name}


def test_the_warm_up_recording_is_the_impact_oscillator_it_says():
    """Between impacts the motion is the free forced oscillator's: a'' = -a - 2 zeta a' - F r^2
    cos(r t)... checked the simple way: the contact makes the largest |acceleration| about
    (1 + beta) times the gap's restoring force, and the record is steady (its two halves
    hold the same peaks within 5 %)."""
    a = warm_up_recording()
    assert a.shape == (int(WARM_UP_SECONDS * WARM_UP_FS_HZ),) and np.isfinite(a).all()
    first, second = np.split(a, 2)
    assert abs(first.min() - second.min()) < 0.05 * abs(first.min())
    # the free flight never accelerates beyond F + x + 2 zeta v: a few units; contact, tens
    assert a.min() < -5.0 and a.max() < 3.0
    assert np.array_equal(a, warm_up_recording())  # deterministic


def test_warm_up_runs_every_lane_and_reads_the_contact(predictor):
    """One line naming the three predictions; the small lane starts measured (its cost per
    sample is what load shedding prices), the large lane its slow-down only (a 6 s record
    says little of a 2 M-sample upload's cost per sample). The warm-up record goes through
    the restoring-force check, which reads the simulated beta (40) within 15 %."""
    admission = Admission(predictor, Limits())
    try:
        line = warm_up(admission)
    finally:
        admission.shutdown()
    assert line.startswith("warm-up: 3 predictions") and "\n" not in line
    assert "predict" in line and "log" in line and "large lane .npy" in line
    assert admission.cost["small"].measured == 1 and admission.cost["large"].measured == 0
    now = time.monotonic()
    assert admission.cost["large"].contention.factor(now) >= 1.0  # its slow-down, measured
    assert admission.cost["small"].contention.factor(now) >= 1.0
    result = predictor.predict(warm_up_recording(), WARM_UP_FS_HZ,
                               natural_frequency_hz=WARM_UP_FN_HZ)  # fmt: skip
    assert result["restoring_force_beta"] == pytest.approx(WARM_UP_BETA, rel=0.15)


def test_a_warm_up_that_fails_refuses_to_start_in_one_line():
    admission = Admission(_Stub(fails=RuntimeError("onnx\nsession broken")), Limits())
    try:
        with pytest.raises(WarmUpFailed) as info:
            warm_up(admission)
    finally:
        admission.shutdown()
    message = str(info.value)
    assert message.startswith("warm-up: the predict of a 6 s recording failed: RuntimeError")
    assert "session broken" in message and "\n" not in message
    assert info.value.exit_code == 1  # an environment failure, not the user's input


def test_a_warm_up_past_its_bound_refuses_to_start():
    stub = _Held()  # its prediction waits until released
    admission = Admission(stub, Limits(timeout_s=1.5))  # warm-up bound: 3 s
    t0 = time.monotonic()
    try:
        with pytest.raises(
            WarmUpFailed, match=r"predict .* did not finish within 3 s \(2 x --timeout-s\)"
        ):
            warm_up(admission)
        elapsed = time.monotonic() - t0
    finally:
        stub.release.set()
        admission.shutdown()
    assert elapsed < 20.0  # bounded: it did not wait for the prediction (released at 20 s)
    assert stub.seen == [int(WARM_UP_SECONDS * WARM_UP_FS_HZ)]  # the later steps never ran


def test_serve_refuses_to_start_when_its_warm_up_fails(monkeypatch):
    """``stiffnet serve``: one line, exit 1, before uvicorn serves anything."""
    from typer.testing import CliRunner

    import serving.warm_up
    from stiffnet.cli import app

    def broken(_admission):
        raise WarmUpFailed("warm-up: the predict of a 6 s recording failed: RuntimeError: x")

    monkeypatch.setattr(serving.warm_up, "warm_up", broken)
    served = []
    monkeypatch.setattr("uvicorn.Server.run", lambda *a, **k: served.append(1))
    result = CliRunner().invoke(app, ["serve", "--port", "0"])
    assert result.exit_code == 1, result.output
    assert "warm-up: the predict of a 6 s recording failed" in result.output
    assert "Traceback" not in result.output and not served


def test_short_jobs_measure_the_slow_down_together():
    """A 0.03 s job alone says nothing of the lane's slow-down; two of them (0.06 s of CPU
    in 0.3 s) say 5 times; summed short jobs older than a minute are dropped."""
    from serving.load_shedding import CONTENTION_FRESH_S, Contention

    c = Contention()
    c.measure(0.15, 0.03, 100.0)
    assert c.factor(100.0) is None
    c.measure(0.15, 0.03, 101.0)
    assert c.factor(101.0) == pytest.approx(5.0)
    c.measure(1.0, 0.03, 102.0)
    c.measure(0.03, 0.03, 103.0 + CONTENTION_FRESH_S)  # the first is stale: not summed
    assert c.factor(103.0 + CONTENTION_FRESH_S) is None
    c.measure(0.03, 0.03, 104.0 + CONTENTION_FRESH_S)
    assert c.factor(104.0 + CONTENTION_FRESH_S) == pytest.approx(1.0)  # stale mean replaced


def test_a_job_its_worker_takes_too_late_is_refused_before_any_work(monkeypatch):
    """At its start a job's wait is known: it runs only if that wait plus its cost on a
    free worker (CPU seconds per sample times the lane's slow-down) fits the budget."""
    limits = Limits(timeout_s=10.0)
    admission = Admission(_Stub(), limits)
    budget = SHED_MARGIN * limits.timeout_s
    try:
        assert admission._late_start("small", 1000, budget - 0.1, 0.0) is None  # no slow-down
        late = admission._late_start("small", 1000, budget + 0.1, 0.0)
        assert isinstance(late, ShedAtStart) and late.retry_after_s == 1
        assert "waited 8.1 s for a worker" in late.message
        assert "would not finish within the 10 s timeout" in late.message
        cost = admission.cost["small"]
        cost.measure(1000, 2.0, 1.0)  # 1 ms of CPU a sample, running at twice its CPU time
        now = time.monotonic()
        assert admission._late_start("small", 1000, budget - 2.1, now) is None  # 2 s fits
        late = admission._late_start("small", 1000, budget - 1.9, now)
        assert late is not None and late.retry_after_s == math.ceil(2.0)
        # the large lane has no slow-down of its own: it is priced at the machine's load,
        # never at the small lane's (patched: 1x, then 2x, whatever this machine's load)
        admission.cost["large"].cpu_s_per_sample = 1e-3
        monkeypatch.setattr("serving.app.machine_slow_down", lambda: 1.0)
        assert admission._late_start("large", 1000, budget - 1.9, now) is None  # 1 s fits
        monkeypatch.setattr("serving.app.machine_slow_down", lambda: 2.0)
        late = admission._late_start("large", 1000, budget - 1.9, now)
        assert late is not None and late.retry_after_s == 2
    finally:
        admission.shutdown()


class _Held:
    """Stand-in predictor whose predictions wait for `release`; records what it started."""

    name, sha256, kind = "held", "0" * 64, "cnn"

    def __init__(self) -> None:
        self.seen, self.release = [], threading.Event()

    def predict(self, accel, *args, **kwargs):
        self.seen.append(len(accel))
        assert self.release.wait(20)
        return {"class": "soft"}

    def info(self):
        return {"name": self.name}


def test_past_the_timeout_a_running_job_is_503_and_a_queued_one_429_never_started(server_log):
    """A running job past the timeout: 503 with Retry-After and a one-line log (overloaded,
    not broken); the job queued behind it: 429, and its worker never starts it."""
    held = _Held()
    app = create_app(held, Limits(max_concurrency=1, max_queue=8, timeout_s=1.0))
    lane = app.state.admission.cost["small"]

    async def scenario() -> tuple:
        transport = httpx.ASGITransport(app=app)
        body = {"samples": [0.5] * 100, "fs_hz": 1000.0}
        async with httpx.AsyncClient(transport=transport, base_url="http://t") as c:
            running = asyncio.ensure_future(c.post("/predict", json=body))
            for _ in range(500):  # until it holds the one worker
                if held.seen:
                    break
                await asyncio.sleep(0.01)
            queued = await c.post("/predict", json={**body, "samples": [0.5] * 50})
            answered = await running
        held.release.set()
        for _ in range(500):  # until the worker has refused the queued one
            if not lane.jobs:
                break
            await asyncio.sleep(0.01)
        return answered, queued

    running, queued = asyncio.run(scenario())
    assert running.status_code == 503 and set(running.json()) == {"error"}
    assert "did not finish within the 1 s timeout" in running.json()["error"]
    assert int(running.headers["retry-after"]) >= 1
    assert queued.status_code == 429 and "refused before any work" in queued.json()["error"]
    assert int(queued.headers["retry-after"]) >= 1
    assert held.seen == [100] and not lane.jobs  # the queued one never started
    lines = [r.getMessage() for r in server_log]
    assert any(
        ln.startswith("503 (overrun): server overloaded: this small prediction") for ln in lines
    ), lines
    assert not any("failed afterwards" in ln for ln in lines), lines

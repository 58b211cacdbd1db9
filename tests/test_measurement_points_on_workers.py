"""A fit whose design's points are scored on idle workers (``fitting._Evaluator.prefetch``,
a joint refit's block descent in a diagnosis with workers) ends where the fit that scores
them one by one ends, with the same numbers bit for bit: the points are the same
simulations, run elsewhere, and the search asks for them in the same order within the same
budget."""

from __future__ import annotations

import pickle
from types import SimpleNamespace

import numpy as np
import pytest

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows
from stiffnet.distributed import tasks
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.measurement import fitting
from stiffnet.measurement.fitting import fit_effect, fit_joint
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = ManifestRow(recording="r.csv", fs_hz=1250, natural_frequency_hz=9.48, frequency_ratio=1.0,
                  amplitude=1.2, gap=1.2, damping_ratio=0.02, beta=30, noise=0.02)  # fmt: skip
ROWS = [ROW, ROW.model_copy(update={"recording": "b.csv", "beta": 60.0, "fs_hz": 1500})]
LENGTHS = [2500, 3000]
#: The sensor fit's evaluations: its design, one sweep of the resonance and a few more.
BUDGET = 66
#: The rig the target was measured on: a mounted resonance at 180 Hz and a damped contact.
TRUTH = [SensorDynamics(resonance_hz=180.0, resonance_damping=0.05, highpass_hz=0.5, lowpass_hz=0)]


class _Workers:
    """Two single-threaded workers: each chunk travels pickled, as to a Dask worker."""

    def __init__(self) -> None:
        self.chunks: list[int] = []

    def nthreads(self) -> dict[str, int]:
        return {"w0": 1, "w1": 1}

    def run_tasks(self, fn, items, client=None, thread_limit=None, **_):
        assert client is self and thread_limit is not None
        results = []
        for item in items:
            self.chunks.append(len(item[3]))
            results.append(pickle.loads(pickle.dumps(fn(pickle.loads(pickle.dumps(item))))))
        return SimpleNamespace(results=results, raise_failures=lambda: None)


@pytest.fixture(scope="module")
def target_args():
    sims = simulate_rows(ROWS, TRUTH, LENGTHS, seed=3, settings=FIT_SETTINGS)
    measured = [signal_statistics(a, r.fs_hz, 9.48, 1.0, inclination=False)
                for a, r in zip(sims, ROWS, strict=True)]  # fmt: skip
    return measured


def _target(measured) -> CampaignTarget:
    return CampaignTarget(ROWS, measured, LENGTHS, [], seed=11, inclination=False)


def test_a_fit_scored_on_workers_is_the_fit_scored_here(target_args, monkeypatch):
    """The sensor's fit (its seeds read off the ringing and a design of 33 points, its
    resonance swept by the global stage, a Nelder-Mead): the same point, per-recording
    values and evaluations; the design's and each sweep's points went to the workers in two
    chunks each, the local search stayed here."""
    here = fit_effect(_target(target_args), "sensor_dynamics", budget=BUDGET)
    workers = _Workers()
    monkeypatch.setattr(tasks, "run_tasks", workers.run_tasks)
    target = _target(target_args)
    there = fit_effect(target, "sensor_dynamics", budget=BUDGET, client=workers)
    assert there["params"] == here["params"]
    assert there["per_recording"] == here["per_recording"]
    assert there["evaluations"] == here["evaluations"] <= BUDGET
    assert there["improves"] and here["improves"]
    # the design split over the two workers, then a sweep's new points; the search's
    # last evaluations (the Nelder-Mead) here
    pairs = list(zip(workers.chunks[::2], workers.chunks[1::2], strict=True))
    assert len(pairs) >= 2 and all(abs(a - b) <= 1 for a, b in pairs)
    assert sum(workers.chunks) < BUDGET
    # what the workers scored is known to the target as if scored here
    assert len(target.known) > sum(workers.chunks)
    # the fit found the rig's resonance within the design's reach (truth 180 Hz)
    assert here["params"]["resonance_hz"] == pytest.approx(180.0, rel=0.1)


def test_a_joint_refit_scored_on_workers_is_the_one_scored_here(target_args, monkeypatch):
    """A two-effect joint refit with its block descent (each effect's design): bitwise the
    same values; without a client nothing is sent anywhere."""
    names = ["sensor_dynamics", "contact_damping"]
    start = [{"resonance_hz": 200.0, "resonance_damping": 0.04, "highpass_hz": 0.8,
              "lowpass_hz": 0.0, "lowpass_order": 2.0}, {"damping_ratio": 0.1}]  # fmt: skip
    monkeypatch.setattr(fitting, "REFINE_EVALUATIONS_MANY", 4)  # short descents: a test
    here = fit_joint(_target(target_args), names, start, FIT_SETTINGS, rounds=1)
    workers = _Workers()
    monkeypatch.setattr(tasks, "run_tasks", workers.run_tasks)
    there = fit_joint(_target(target_args), names, start, FIT_SETTINGS, rounds=1, client=workers)
    assert workers.chunks
    assert there["params"] == here["params"]
    assert np.array_equal(there["per_recording"], here["per_recording"])
    assert there["evaluations"] == here["evaluations"]
    before = len(workers.chunks)
    fit_joint(_target(target_args), names, start, FIT_SETTINGS, rounds=1)
    assert len(workers.chunks) == before

"""This process's independent evaluations spread over a LocalCluster (evaluation_pool): the
same numbers, memo, fits and nuisances as the loop in-process, bit for bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("distributed")

from distributed import Client  # noqa: E402

from stiffnet.campaign import ManifestRow  # noqa: E402
from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows  # noqa: E402
from stiffnet.distributed.cluster import local_cluster  # noqa: E402
from stiffnet.effects.registry import effect_class  # noqa: E402
from stiffnet.measurement import evaluation_pool as pool  # noqa: E402
from stiffnet.measurement.fitting import fit_effect, fit_joint  # noqa: E402
from stiffnet.measurement.nuisance import Nuisance, profile_nuisances  # noqa: E402
from stiffnet.measurement.statistics import signal_statistics  # noqa: E402
from stiffnet.measurement.target import CampaignTarget  # noqa: E402

ROW = ManifestRow(
    recording="a.csv", fs_hz=1250, beta=30.0, gap=1.0, amplitude=1.0,
    frequency_ratio=1.0, damping_ratio=0.05,
)  # fmt: skip
ROWS = [
    ROW,
    ROW.model_copy(update={"recording": "b.csv", "beta": 60.0}),
    ROW.model_copy(update={"recording": "c.csv", "beta": 15.0, "frequency_ratio": 0.9}),
]
N = 2500


@pytest.fixture(scope="module")
def client():
    with local_cluster(2) as cluster, Client(cluster.scheduler_address) as c:
        yield c


@pytest.fixture(scope="module")
def measured():
    truth = [
        effect_class("contact_damping")(damping_ratio=0.3),
        effect_class("sensor_dynamics")(resonance_hz=180.0, resonance_damping=0.05, lowpass_hz=0),
    ]
    sims = simulate_rows(ROWS, truth, [N] * 3, seed=3, settings=FIT_SETTINGS)
    return [signal_statistics(a, r.fs_hz, 9.48, r.frequency_ratio)
            for a, r in zip(sims, ROWS, strict=True)]  # fmt: skip


def make(measured) -> CampaignTarget:
    return CampaignTarget(list(ROWS), measured, [N] * 3, [], seed=11, inclination=False)


def damping(z: float):
    return effect_class("contact_damping")(damping_ratio=z)


def calls():
    other_rows = [r.model_copy(update={"gap": 1.1}) for r in ROWS]
    return [
        ([damping(0.1)], FIT_SETTINGS, {}),
        ([damping(0.2)], FIT_SETTINGS, {"starts": [3, 1, 2]}),
        ([damping(0.2)], FIT_SETTINGS, {"rows": other_rows}),
        ([damping(0.1)], FIT_SETTINGS, {}),  # a repeat
        ([], FIT_SETTINGS, {"inclination": False}),
    ]


def test_a_batch_on_the_workers_equals_the_loop_and_fills_the_same_memo(measured, client):
    here, there = make(measured), make(measured)
    loop = [here.per_recording(e, s, **kw) for e, s, kw in calls()]
    with pool.evaluation_pool(client):
        spread = pool.per_recording_many(there, calls())
    for a, b in zip(loop, spread, strict=True):
        np.testing.assert_array_equal(a, b)
    assert here.known.keys() == there.known.keys()
    for k in here.known:
        np.testing.assert_array_equal(here.known[k], there.known[k])


def test_the_batch_ran_on_the_workers_and_small_ones_stay_here(measured, client, monkeypatch):
    seen = []
    real = pool._spread
    monkeypatch.setattr(pool, "_spread", lambda *a: seen.append(len(a[2])) or real(*a))
    t = make(measured)
    with pool.evaluation_pool(client):
        pool.per_recording_many(t, calls()[:1])  # under MIN_BATCH: here
        pool.per_recording_many(t, calls())  # the first and its repeat known: three left
        pool.per_recording_many(make(measured), calls()[1:3])  # under MIN_BATCH: here
        stand_in = _StandIn()  # a duck-typed target (as some tests fit): evaluated here
        assert pool.per_recording_many(stand_in, calls()) == [0.0] * len(calls())
    pool.per_recording_many(make(measured), calls())  # no pool: here
    assert seen == [pool.MIN_BATCH]


class _StandIn:
    def per_recording(self, effects, settings, **kw):
        return 0.0


def test_statistics_on_the_workers_equal_the_loop(measured, client):
    t = make(measured)
    loop = [t.simulated_statistics(e, s, **kw) for e, s, kw in calls()]
    with pool.evaluation_pool(client):
        spread = pool.statistics_many(t, calls())
    for a, b in zip(loop, spread, strict=True):
        for x, y in zip(a, b, strict=True):
            for f in dataclasses.fields(x):
                np.testing.assert_array_equal(getattr(x, f.name), getattr(y, f.name))


def test_fits_and_nuisances_in_a_pool_equal_those_in_process(measured, client, monkeypatch):
    """The searches that prefetch (a design, a global stage, a first simplex, the starts and
    grids of the nuisances) end where the in-process ones end, with the same evaluations."""

    def run(with_client):
        t = make(measured)
        info = {"nuisances": [Nuisance("gap", np.full(3, 0.9), np.full(3, 1.1), np.zeros(3))]}
        with pool.evaluation_pool(with_client):
            nuis = profile_nuisances(t, [], FIT_SETTINGS, info)
            single = fit_effect(t, "sensor_dynamics", [damping(0.3)])
            joint = fit_joint(
                t, ["contact_damping", "sensor_dynamics"],
                [{"damping_ratio": 0.25}, single["params"]], FIT_SETTINGS, rounds=1,
            )  # fmt: skip
        return nuis, single, joint

    spread = []
    real = pool._spread
    monkeypatch.setattr(pool, "_spread", lambda *a: spread.append(len(a[2])) or real(*a))
    (n0, s0, j0) = run(None)
    assert spread == []
    (n1, s1, j1) = run(client)
    assert len(spread) >= 4 and sum(spread) >= 30  # starts, grids, designs, simplices
    assert n0 == n1
    s0.pop("seconds"), s1.pop("seconds")
    assert s0 == s1
    assert j0["params"] == j1["params"]
    assert j0["evaluations"] == j1["evaluations"]
    np.testing.assert_array_equal(j0["per_recording"], j1["per_recording"])


def test_independent_batches_on_the_workers_equal_the_loop(measured, client):
    """The face's independent steps (a grid's screen per model, a point scored alone) as
    tasks on the workers: the same arrays as in order here, bit for bit."""
    from stiffnet.campaign.simulate import FIT_SETTINGS_NUMERICAL
    from stiffnet.measurement.face_by_simulation import _scored_alone, _screen_batch

    t = make(measured)
    face = {"exponent": 1.0, "reference_penetration": 0.5, "face_mass": 0.1,
            "face_stiffness": 20.0, "face_damping": 0.05}  # fmt: skip
    points = [face, {**face, "face_mass": 0.15}]
    screens = [(t, [], points, FIT_SETTINGS_NUMERICAL), (t, [damping(0.2)], points,
                                                         FIT_SETTINGS_NUMERICAL)]  # fmt: skip
    alone = [(t, [], p, FIT_SETTINGS_NUMERICAL) for p in points]
    here = [[_screen_batch(i) for i in screens], [_scored_alone(i) for i in alone]]
    with pool.evaluation_pool(client):
        there = [pool.map_independent(_screen_batch, screens),
                 pool.map_independent(_scored_alone, alone)]  # fmt: skip
    for a, b in zip(here[0], there[0], strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
    for x, y in zip(here[1], there[1], strict=True):
        np.testing.assert_array_equal(x, y)

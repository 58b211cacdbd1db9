"""The serial stages of a diagnosis hand independent work to its workers: a joint refit's
block-descent round refits every effect from the round's start (the refits depend on nothing
of one another, so they run as parallel tasks), and the nuisances' initial states are
simulated one task per start. Where the work runs changes no number."""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.fitting import fit_joint, objective_value
from stiffnet.measurement.nuisance import N_STARTS, profile_nuisances
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = ManifestRow(
    recording="a.csv", fs_hz=1250, beta=30.0, gap=1.0, amplitude=1.0,
    frequency_ratio=1.0, damping_ratio=0.05,
)  # fmt: skip
N = 3000


@pytest.fixture(scope="module")
def campaign():
    rows = [
        ROW.model_copy(update={"recording": f"{b}_{s}.csv", "beta": float(b), "frequency_ratio": s})
        for b, s in ((30, 0.98), (60, 1.02), (45, 1.0))
    ]
    damped = [effect_class("contact_damping")(damping_ratio=0.3)]
    sims = simulate_rows(rows, damped, [N] * 3, seed=3, settings=FIT_SETTINGS)
    measured = [
        signal_statistics(a, r.fs_hz, 9.48, r.frequency_ratio, inclination=False)
        for a, r in zip(sims, rows, strict=True)
    ]
    return rows, measured


def _target(campaign) -> CampaignTarget:
    rows, measured = campaign
    return CampaignTarget(list(rows), measured, [N] * 3, [], seed=11, inclination=False)


def test_a_block_round_refits_every_effect_from_the_rounds_start_as_independent_tasks(campaign):
    names = ["contact_damping", "gap_drift"]
    start = [{"damping_ratio": 0.15}, {"amplitude": 0.0, "period": 200.0, "phase": 0.0}]
    batches: list[list[tuple[str, list[tuple[str, dict]]]]] = []

    def tasks(fn, items):
        # what each refit holds fixed, then run in the reverse order: independent tasks
        batches.append([(it[1], [(e.name, e.params.model_dump()) for e in it[2]]) for it in items])
        return [fn(x) for x in reversed(items)][::-1]

    spread = fit_joint(_target(campaign), names, start, FIT_SETTINGS, budget=2, rounds=2,
                       refits=tasks)  # fmt: skip
    here = fit_joint(_target(campaign), names, start, FIT_SETTINGS, budget=2, rounds=2)
    assert batches, "the round's refits did not go through the tasks"
    first = batches[0]
    assert [name for name, _ in first] == names  # one task per effect, in one batch
    # each refit holds the other effects at the round's start, not at a sibling's result
    assert first[0][1] == [("gap_drift", start[1])]
    assert first[1][1][0][0] == "contact_damping"
    assert first[1][1][0][1]["damping_ratio"] == pytest.approx(0.15)
    # the same answer wherever the refits ran, and never worse than the start
    assert spread["params"] == here["params"]
    np.testing.assert_array_equal(spread["per_recording"], here["per_recording"])
    target = _target(campaign)
    model = [effect_class(n)(**p) for n, p in zip(names, start, strict=True)]
    before = target.per_recording(model, FIT_SETTINGS)
    w = target.weights
    assert objective_value(np.asarray(spread["per_recording"]), w) < objective_value(before, w)
    assert abs(spread["params"][0]["damping_ratio"] - 0.3) < abs(0.15 - 0.3)


def test_the_initial_states_profiled_as_tasks_equal_those_profiled_here(campaign):
    model = [effect_class("contact_damping")(damping_ratio=0.2)]
    seen: list[int] = []

    def tasks(fn, items):
        seen.append(len(items))
        return [fn(x) for x in reversed(items)][::-1]

    spread, here = _target(campaign), _target(campaign)
    a = profile_nuisances(spread, model, FIT_SETTINGS, {}, tasks)
    b = profile_nuisances(here, model, FIT_SETTINGS, {})
    assert seen == [N_STARTS]  # one task per initial state, one batch
    assert a == b and spread.starts == here.starts
    np.testing.assert_array_equal(
        spread.per_recording(model, FIT_SETTINGS), here.per_recording(model, FIT_SETTINGS)
    )

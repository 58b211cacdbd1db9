"""A diagnosis searches a closed-form effect on a subset of the recordings spread over the
campaign's operating points (``fitting.SUBSET_SEARCH``) and scores the point found on all of
them: the subset holds every operating point of a campaign that repeats them, the fit finds
the hidden value, and what it reports is the whole campaign's discrepancy at that value."""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import FIT_SETTINGS, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.fitting import fit_effect, spread_subset
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget

ROW = ManifestRow(
    recording="a.csv", fs_hz=1250, beta=30.0, gap=1.0, amplitude=1.0,
    frequency_ratio=1.0, damping_ratio=0.05,
)  # fmt: skip
N = 3000


def _shifted(betas, shifts):
    """One row per (shift, beta): a campaign that repeats its operating points."""
    return [
        ROW.model_copy(update={"recording": f"{s}_{b}.csv", "beta": float(b), "frequency_ratio": s})
        for s in shifts
        for b in betas
    ]


def test_the_subset_holds_every_operating_point_of_a_repeated_campaign():
    betas = [8, 14, 22, 30, 45, 65, 80, 95]
    rows = _shifted(betas, [0.98, 1.0, 1.02])
    idx = spread_subset(rows, 8)
    assert sorted(rows[i].beta for i in idx) == betas  # one recording of each point
    assert list(idx) == sorted(idx)
    np.testing.assert_array_equal(spread_subset(rows[:5], 8), np.arange(5))  # all of them


@pytest.fixture(scope="module")
def campaign():
    rows = _shifted([30, 60], [0.98, 1.02])
    damped = [effect_class("contact_damping")(damping_ratio=0.3)]
    sims = simulate_rows(rows, damped, [N] * 4, seed=3, settings=FIT_SETTINGS)
    measured = [
        signal_statistics(a, r.fs_hz, 9.48, r.frequency_ratio)
        for a, r in zip(sims, rows, strict=True)
    ]
    return rows, measured


def test_a_fit_searched_on_a_subset_finds_the_value_and_scores_it_on_every_recording(campaign):
    rows, measured = campaign

    def target() -> CampaignTarget:
        return CampaignTarget(list(rows), measured, [N] * 4, [], seed=11, inclination=True)

    sub = fit_effect(target(), "contact_damping", subset=2)
    full = fit_effect(target(), "contact_damping")
    assert sub["improves"] and full["improves"]
    # the hidden damping is 0.3; the whole campaign's search lands near it too
    assert abs(sub["params"]["damping_ratio"] - 0.3) < 0.06, sub["params"]
    assert abs(sub["params"]["damping_ratio"] - full["params"]["damping_ratio"]) < 0.05
    # reported: every recording, every statistic, at the value found (a fresh evaluation)
    fresh = target().per_recording([effect_class("contact_damping")(**sub["params"])], FIT_SETTINGS)
    np.testing.assert_array_equal(sub["per_recording"], fresh)
    assert len(sub["per_recording"]) == len(sub["off_per_recording"]) == 4
    assert np.mean(sub["per_recording"]) < 0.5 * np.mean(sub["off_per_recording"])

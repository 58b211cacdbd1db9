"""A linear contact read through an undone low-pass near its band is no stiffening law
(``stiffnet.uncertainty.unseen_law.lowpass_near_contact``).

The independent rig's linear contact behind a 90 Hz 2nd-order low-pass and a 0.5 Hz
high-pass: through that chain the restoring force reads beta within 1 %, yet the inverse of a
low-pass at 1.2 times the 76 Hz contact bends the map within each impact (curvature gain 0.37),
which the curvature rule took for a stiffening law on 9 of 24 such recordings and the campaign
law then for an unknown law on all 24.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from independent_rig import record
from test_independent_rig import F_N, rig_campaign_runs

from serving.restoring_force_check import restoring_force_check
from stiffnet.uncertainty.unseen_law import (
    lowpass_near_contact,
    unseen_law_reasons,
    unseen_law_thresholds,
    with_unseen_law_check,
)

CHAIN = {"lowpass_hz": 90.0, "lowpass_order": 2, "highpass_hz": 0.5}


def applied(lowpass_hz, contact_hz, applied=True) -> dict:
    """A restoring-force reading through an undone chain, as the check reports it."""
    return {"sensor": {"lowpass_hz": lowpass_hz, "lowpass_order": 2, "contact_hz": contact_hz,
                       "applied": applied},
            "law_shape": {"curvature": 0.35, "curvature_share": 0.18}}  # fmt: skip


@pytest.mark.parametrize(
    "rf, near",
    [
        (applied(87.5, 77.6), True),  # the rig's stiffest contacts: 0.67-1.03 of the corner
        (applied(87.5, 90.0), True),
        (applied(87.5, 48.5), False),  # 1.8 times the contact: the curvature is read
        (applied(250.0, 90.0), False),  # a power law behind a 250 Hz low-pass stays judged
        (applied(87.5, 77.6, applied=False), False),  # no chain undone: release_ring's case
        (applied(None, 77.6), False),
    ],
)
def test_the_curvature_is_unread_only_behind_an_undone_lowpass_near_the_contact(rf, near):
    t = unseen_law_thresholds()
    said = lowpass_near_contact(rf, t)
    assert bool(said) is near
    if near:
        assert "\n" not in said and "low-pass was undone within 1.5 times" in said


def test_a_linear_contact_behind_a_lowpass_near_its_band_reads_beta_and_no_unknown_law():
    run = rig_campaign_runs(3.0, 11)[7]  # p2_1: beta 64, a 76 Hz contact at 1250 Hz
    run = replace(run, duration_s=4.0, sensor=dict(CHAIN))
    _, accel = record(run, seed=3)
    rf = restoring_force_check(accel, run.fs_hz, F_N, sensor=dict(CHAIN), sensor_fitted=True)
    assert rf["beta"] == pytest.approx(run.beta, rel=0.10)
    t = unseen_law_thresholds()
    # the rule off, the inverse's bend reads as a stiffening law
    off = t.model_copy(update={"curvature_min_lowpass_over_contact": 0.0})
    assert any("stiffens within" in r for r in unseen_law_reasons(rf, off))
    assert unseen_law_reasons(rf, t) == []
    assert "contact_law" not in with_unseen_law_check(None, rf)["fired"]

"""A campaign's identified low-pass weighed against its contacts' own dissipation
(serving/campaign_chain.py, :func:`campaign_dissipation`), and a Hunt-Crossley reading's
interval read in that law's sense (stiffnet/restoring_force/estimate.py).

The readers here are stand-ins with the R² the independent rig's Hunt-Crossley campaign
behind a 4th-order 600 Hz low-pass and a 2 Hz high-pass gave (/work/scratch/s42 probes):
with the ``delta v`` term free and no low-pass its laws explain 0.994-0.9997 of the contact
force, through the 111 Hz order-1 low-pass its recordings' fits pooled 0.72-0.99.
"""

from __future__ import annotations

import numpy as np
import pytest

from serving.campaign_chain import campaign_dissipation, profiled_campaign_chain
from stiffnet.restoring_force.chain import HIGHPASS_FITTED, shared_chain_shortfall


def fitted_lowpass(hz: float, order: int) -> dict:
    """A chain as the check reports a fitted low-pass (no high-pass found)."""
    return {"resonance_hz": None, "resonance_damping": None, "lowpass_hz": hz,
            "lowpass_order": order, "highpass_hz": 0.0, "source": "fitted", "applied": True,
            "intervals": {"lowpass_hz": [0.9 * hz, 1.1 * hz]}}  # fmt: skip


#: The recordings' own fits of the rig's campaign: they disagree, so nothing is pooled.
SENSORS = [fitted_lowpass(f, o) for f, o in ((105.0, 1), (114.7, 2), (93.8, 1), (324.0, 3),
                                             (150.0, 2), (111.0, 1))]  # fmt: skip
UNPOOLED = {"pooled": False, "sensor": None, "n": 6, "n_identified": 6, "stages": {
    "lowpass_hz": {"value": 112.9, "agreeing": 2, "showing": 6}},
    "reason": "the recordings' identified chains disagree, not pooled",
    "unpooled_sheet": {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 0.0,
                       "lowpass_order": 0.0, "highpass_hz": HIGHPASS_FITTED}}  # fmt: skip


def readers(r2_none, r2_low, share):
    """Stand-in readers: R² and dissipation share per recording, by whether the sheet holds a
    low-pass; every sheet read is logged."""
    asked = []

    def contact_r2(i, sheet, refused_as_unexplained=False):
        asked.append(dict(sheet))
        return r2_low[i] if sheet.get("lowpass_hz") else r2_none[i]

    def dissipation_share(i, sheet):
        asked.append(dict(sheet))
        return None if share is None else share[i]

    return contact_r2, dissipation_share, asked


def test_a_low_pass_the_contacts_dissipation_explains_better_is_not_pooled():
    r2_none = [0.9995, 0.9939, 0.9951, 0.9805, 0.997, 0.996]
    r2_low = [0.991, 0.722, None, None, 0.95, 0.98]  # None: refused below the contact
    contact_r2, share, asked = readers(r2_none, r2_low, [1.0, 0.99, 1.0, 0.9, 0.95, 1.0])
    out = campaign_dissipation(UNPOOLED, SENSORS, contact_r2, share)
    assert out["pooled"] and out["contact_dissipation"]
    assert out["sensor"]["lowpass_hz"] == 0.0 and out["sensor"]["lowpass_order"] == 0.0
    assert out["sensor"]["highpass_hz"] == HIGHPASS_FITTED  # each record's, until profiled
    weighed = out["stages"]["lowpass_hz"]["dissipation"]
    assert out["stages"]["lowpass_hz"]["value"] is None
    # the candidate low-pass: the median of the fits' corners and orders
    assert weighed["lowpass_hz"] == pytest.approx(np.median([105, 114.7, 93.8, 324, 150, 111]))
    assert weighed["lowpass_order"] == 2.0
    assert weighed["median_r2_none"] == pytest.approx(np.median(r2_none))
    assert weighed["median_log_misfit_ratio"] < 0
    assert "contacts' dissipation" in out["reason"] and "unpooled_sheet" not in out


def test_a_real_low_pass_and_a_law_without_the_term_keep_the_stage():
    # a real low-pass: the law with the term free reads better through it
    contact_r2, share, _ = readers([0.985] * 6, [0.999] * 6, [0.5] * 6)
    out = campaign_dissipation(UNPOOLED, SENSORS, contact_r2, share)
    assert not out.get("contact_dissipation") and not out["pooled"]
    assert out["stages"] == UNPOOLED["stages"]  # the profiles after it read them as they were
    assert out["dissipation_weighed"]["median_log_misfit_ratio"] > 0
    # a power law fits no delta v term (share None): the low-pass is not even read
    contact_r2, share, asked = readers([0.999] * 6, [0.9999] * 6, None)
    out = campaign_dissipation(UNPOOLED, SENSORS, contact_r2, share)
    assert not out.get("contact_dissipation")
    assert not any(s.get("lowpass_hz") for s in asked)
    # a law that still needs a chain without the low-pass (median R² under the gate)
    contact_r2, share, _ = readers([0.97] * 6, [0.90] * 6, [1.0] * 6)
    assert not campaign_dissipation(UNPOOLED, SENSORS, contact_r2, share).get("contact_dissipation")


def test_a_mount_or_no_low_pass_is_returned_as_it_is():
    contact_r2, share, asked = readers([0.999] * 6, [0.9] * 6, [1.0] * 6)
    mount = {**UNPOOLED, "unpooled_sheet": {**UNPOOLED["unpooled_sheet"], "resonance_hz": 240.0,
                                            "resonance_damping": 0.04}}  # fmt: skip
    assert campaign_dissipation(mount, SENSORS, contact_r2, share) is mount
    bare = [{**s, "lowpass_hz": None, "lowpass_order": None, "resonance_hz": 300.0}
            for s in SENSORS]  # fmt: skip
    assert campaign_dissipation(UNPOOLED, bare, contact_r2, share) is UNPOOLED
    assert asked == []


def test_a_campaign_read_with_its_dissipation_profiles_no_low_pass_and_its_own_corner():
    """The low-pass profile (76 % of the rig campaign's evaluation) reads nothing once the
    low-pass is the contacts' dissipation; the high-pass corner, which the recordings' fits
    left to each (0 Hz: the Kelvin-Voigt law reads a Hunt-Crossley pulse best without one),
    is profiled by the dissipation law's R², which peaks at the rig's 2 Hz."""
    fn = [9.48] * 6

    def r2(i, sheet, refused_as_unexplained=False):
        if sheet.get("lowpass_hz"):
            return 0.9
        hp = sheet["highpass_hz"]
        return 0.99 if hp == HIGHPASS_FITTED else 0.9997 - 0.002 * np.log(hp / 2.0) ** 2

    plain = []  # the readers without the dissipation term: never asked

    def library(i, sheet, refused_as_unexplained=False):
        plain.append(sheet)
        return 0.95

    hc = (r2, lambda i, s: None, lambda i, s: 1.0)
    out = profiled_campaign_chain(UNPOOLED, SENSORS, library, lambda i, s: None, lambda: fn,
                                  [None] * 6, None, hc)  # fmt: skip
    assert plain == []
    assert out["contact_dissipation"] and out["sensor"]["lowpass_hz"] == 0.0
    assert out["sensor"]["highpass_hz"] == pytest.approx(2.0, rel=0.05)
    assert out["stages"]["highpass_hz"]["pooled_median"] is None
    assert "each recording's own" in out["reason"]


def test_the_shortfall_compares_the_laws_that_read_beta():
    # read alone with the library's law through its own low-pass (R² 0.954), again with the
    # dissipation free through the pooled chain (its law 0.9997, its library law 0.947)
    first = {"contact_r2": 0.954, "hunt_crossley": None}
    again = {"contact_r2": 0.947, "hunt_crossley": {"r2": 0.9997, "dissipation_share": 1.0}}
    assert shared_chain_shortfall([first], [again]) == pytest.approx(0.954 - 0.9997)
    assert shared_chain_shortfall([first], [{"contact_r2": 0.9}]) == pytest.approx(0.054)


@pytest.fixture(scope="module")
def hc_behind_highpass():
    """A 3-s independent-rig recording at 1 kHz of a Hunt-Crossley contact (lambda 6 s/m,
    beta 25) behind a 2 Hz high-pass."""
    from independent_rig import RigRun, record

    run = RigRun(recording="hc.csv", beta=25.0, forcing_frequency_hz=9.95,
                 base_acceleration_g=0.757, gap_mm=2.8, duration_s=3.0,
                 contact="hunt_crossley", hc_lambda_s_per_m=6.0,
                 sensor={"highpass_hz": 2.0})  # fmt: skip
    return record(run, seed=5)[1], run.fs_hz


def test_a_hunt_crossley_readings_interval_spans_the_corners_in_its_own_law(hc_behind_highpass):
    """The campaign's corner interval puts beta's readings at its ends into the interval: in
    the Hunt-Crossley law's sense, not the library's (which reads such a contact 1.3-1.6x
    high, and whose reading of the map itself joined the interval)."""
    from serving.restoring_force_check import restoring_force_check

    accel, fs = hc_behind_highpass
    sheet = {"highpass_hz": 2.0, "highpass_low_hz": 1.8, "highpass_high_hz": 2.2}
    hc = restoring_force_check(accel, fs, 9.48, sheet, sensor_fitted=True,
                               penetration_dissipation=True)  # fmt: skip
    library = restoring_force_check(accel, fs, 9.48, sheet, sensor_fitted=True)
    lo, hi = hc["beta_interval"]
    assert lo <= 25.0 <= hi and abs(hc["beta"] / 25.0 - 1) < 0.1, hc
    assert library["beta"] > 1.2 * hc["beta"]
    assert hi < library["beta"], (hc["beta_interval"], library["beta"])


def test_the_dissipation_readings_take_the_free_flights_corner(monkeypatch):
    """A sheet that leaves the corner to the record is read with the free flight's corner
    where the law's dissipation is free: the contact-law profile of the corner tunes it until
    the library's law fits (0 Hz on the rig's Hunt-Crossley records for 2 Hz) and was 91 %
    of the dissipation test's CPU. The library's readings keep their profile."""
    from types import SimpleNamespace

    import stiffnet.restoring_force as rf
    from serving.campaign_chain import read_through

    seen = []
    monkeypatch.setattr(rf, "restoring_force_estimate", lambda a, fs, **kw: seen.append(kw))
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    accel = np.sin(2 * np.pi * 9.95 * np.arange(8000) / 2000.0)
    sheet = {"highpass_hz": HIGHPASS_FITTED}
    read_through(accel, 2000.0, 9.48, pred, sheet, penetration_dissipation=True)
    read_through(accel, 2000.0, 9.48, pred, sheet)
    assert seen[0]["penetration_dissipation"] and seen[0]["profile_highpass_below_r2"] == -np.inf
    assert not seen[1]["penetration_dissipation"] and seen[1]["profile_highpass_below_r2"] is None

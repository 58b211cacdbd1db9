"""A campaign's one accelerometer: the chains identified on some recordings pooled and used
on all (serving/campaign_chain.py, ``evaluate`` and ``predict-batch`` on a campaign)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from serving.campaign_chain import (
    MIN_IDENTIFIED,
    campaign_chain,
    campaign_sheets,
    identified,
    identify_regardless,
    labelled,
    reads_alone,
)
from serving.restoring_force_check import check_sensor_sheet
from stiffnet.restoring_force.chain import HIGHPASS_FITTED


def fitted(resonance_hz=None, lowpass_hz=None, order=4, width=0.01, applied=True, highpass=1.0):
    """A chain as the restoring-force check reports a fit (intervals +-`width`)."""
    iv = {}
    if resonance_hz:
        iv["resonance_hz"] = [resonance_hz * (1 - width), resonance_hz * (1 + width)]
    if lowpass_hz:
        iv["lowpass_hz"] = [lowpass_hz * (1 - width), lowpass_hz * (1 + width)]
    return {"resonance_hz": resonance_hz, "resonance_damping": 0.05 if resonance_hz else None,
            "lowpass_hz": lowpass_hz, "lowpass_order": order if lowpass_hz else None,
            "highpass_hz": highpass, "source": "fitted", "applied": applied,
            "intervals": iv}  # fmt: skip


def test_one_sensor_is_pooled_as_the_median_of_the_recordings_that_identified_it():
    sensors = [fitted(300.0, 500.0), None, fitted(310.0, 480.0), fitted(290.0, 520.0), None,
               fitted(lowpass_hz=505.0)]  # fmt: skip
    names = [f"r{i}" for i in range(6)]
    chain = campaign_chain(sensors, names)
    assert chain["pooled"] and chain["n_identified"] == 4 and chain["n"] == 6
    assert chain["identified_on"] == ["r0", "r2", "r3", "r5"]
    # the median of the stage over the recordings showing it (3 resonances, 4 low-passes)
    assert chain["sensor"]["resonance_hz"] == pytest.approx(300.0)
    assert chain["sensor"]["lowpass_hz"] == pytest.approx(502.5)
    assert chain["sensor"]["lowpass_order"] == 4.0
    assert chain["stages"]["resonance_hz"]["agreeing"] == 3
    assert chain["sensor"]["highpass_hz"] == pytest.approx(1.0)  # pooled as the others
    # where fewer than half show a high-pass none is known, not "none": each recording fits
    # its own corner behind the pooled chain ("auto"), which the predictor's sheet check keeps
    bare = campaign_chain([fitted(300.0, highpass=0.0), fitted(305.0, highpass=0.0),
                           fitted(298.0, highpass=2.0)], list("abc"))  # fmt: skip
    assert bare["pooled"] and bare["sensor"]["highpass_hz"] == HIGHPASS_FITTED
    assert check_sensor_sheet(bare["sensor"], 2000.0) == bare["sensor"]
    # every recording without a sheet reads the pooled chain, whether it identified one or not
    assert campaign_sheets(chain, [None] * 6) == [chain["sensor"]] * 6


def test_chains_of_different_sensors_are_not_pooled_and_the_reason_says_so():
    # rig_chains' recordings each have their own chain: resonances 157-420 Hz, 1 % intervals
    sensors = [fitted(157.0), fitted(210.0), fitted(354.0), fitted(420.0), fitted(271.0)]
    chain = campaign_chain(sensors, list("abcde"))
    assert not chain["pooled"] and chain["sensor"] is None
    assert "disagree" in chain["reason"] and "resonance_hz" in chain["reason"]
    assert campaign_sheets(chain, [None] * 5) == [None] * 5


def test_an_odd_fit_is_outvoted_but_a_wide_interval_counts_as_agreeing():
    sensors = [fitted(300.0), fitted(305.0), fitted(296.0), fitted(150.0)]
    assert campaign_chain(sensors, list("abcd"))["pooled"]  # 3 of 4 agree
    # two apart, each pinned by its interval: 1 of 2 agree with their median... not pooled
    assert not campaign_chain([fitted(200.0), fitted(300.0)], ["a", "b"])["pooled"]
    # a resonance they agree on is pooled without the low-pass they disagree on
    mixed = [fitted(195.0, 326.0), fitted(202.0, 40.0), fitted(197.0, 276.0), fitted(192.0)]
    chain = campaign_chain(mixed, list("abcd"))
    assert chain["pooled"] and chain["sensor"]["resonance_hz"] == pytest.approx(196.0)
    assert chain["sensor"]["lowpass_hz"] == 0.0 and "lowpass_hz" in chain["reason"]
    # the same two with intervals that cannot tell them apart: pooled
    wide = [fitted(200.0, width=0.4), fitted(300.0, width=0.4)]
    assert campaign_chain(wide, ["a", "b"])["pooled"]


def test_an_ideal_campaign_or_a_single_fit_pools_nothing():
    # no resonance or low-pass anywhere (a high-pass alone is each record's own fit)
    ideal = [None, fitted(highpass=0.5), None, None]
    chain = campaign_chain(ideal, list("abcd"))
    assert not chain["pooled"] and chain["n_identified"] == 0
    one = [None, fitted(300.0), None]
    chain = campaign_chain(one, list("abc"))
    assert not chain["pooled"] and f"at least {MIN_IDENTIFIED}" in chain["reason"]
    # a rejected fit (applied False) or a data sheet is no identification
    assert identified(fitted(300.0, applied=False)) is None
    assert identified({**fitted(300.0), "source": "data sheet"}) is None


def test_a_campaign_whose_gated_checks_fit_no_chain_has_it_fitted_regardless_and_pooled():
    # every gated check read its law above the gate and fitted no chain (None), one fit ran
    # and was rejected, one recording has its own data sheet
    sensors = [None, None, fitted(lowpass_hz=110.0, order=2, applied=False), None, None]
    sheets = [None, None, None, {"lowpass_hz": 100.0, "lowpass_order": 2.0}, None]
    asked = []

    def identify(i):
        asked.append(i)
        return fitted(lowpass_hz=[104.0, 106.0, 0, 0, 105.0][i], order=2)

    chain, pooled_from = identify_regardless(sensors, list("abcde"), sheets, identify)
    # only the recordings without a sheet whose check fitted nothing are fitted again
    assert asked == [0, 1, 4] and chain["fitted_regardless"] == ["a", "b", "e"]
    assert chain["pooled"] and chain["sensor"]["lowpass_hz"] == pytest.approx(105.0)
    assert chain["sensor"]["lowpass_order"] == 2.0 and "regardless" in chain["reason"]
    assert pooled_from[2] is sensors[2] and pooled_from[3] is None
    # a campaign whose gated checks already pool a chain is not fitted again
    asked.clear()
    enough = [fitted(300.0), fitted(305.0), None]
    chain, _ = identify_regardless(enough, list("abc"), None, identify)
    assert chain["pooled"] and asked == [] and "fitted_regardless" not in chain


def test_a_large_campaign_has_its_chain_fitted_regardless_on_a_spread_few():
    """24 recordings whose gated checks fitted no chain: the chain is fitted again on
    MAX_FITTED_REGARDLESS of them, spread from the first to the last, and pooled from those."""
    from serving.campaign_chain import MAX_FITTED_REGARDLESS

    n = 24
    asked = []

    def identify(i):
        asked.append(i)
        return fitted(lowpass_hz=100.0 + 0.1 * i, order=2)

    chain, pooled_from = identify_regardless([None] * n, [f"r{i}" for i in range(n)], None,
                                             identify)  # fmt: skip
    assert len(asked) == MAX_FITTED_REGARDLESS < n and asked[0] == 0 and asked[-1] == n - 1
    assert len(chain["fitted_regardless"]) == MAX_FITTED_REGARDLESS
    assert chain["pooled"] and chain["sensor"]["lowpass_hz"] == pytest.approx(101.15, abs=0.5)
    assert sum(s is not None for s in pooled_from) == MAX_FITTED_REGARDLESS


def test_behind_a_second_order_lowpass_the_gate_fits_no_chain_and_the_fit_regardless_does():
    """The independent rig behind one campaign's chain (a 106 Hz order-2 low-pass, its mount
    above the Nyquist frequency; 2 % noise): the record's law reads R2 above the gate, so the
    gated check fits no chain and reads beta half the truth; fitted regardless of the gate
    (what a campaign that pools nothing asks for) the low-pass is found within 10 % and beta
    too."""
    from independent_rig import RigRun, record

    from serving.restoring_force_check import restoring_force_check

    sensor = {"resonance_hz": 1267.0, "resonance_damping": 0.057, "lowpass_hz": 106.0,
              "lowpass_order": 2, "highpass_hz": 2.76}  # fmt: skip
    run = RigRun(recording="r.csv", beta=38.9, fs_hz=1460.0, duration_s=3.0, gap_mm=1.5,
                 sensor=sensor, noise=0.02)  # fmt: skip
    accel = record(run, seed=3)[1]
    gated = restoring_force_check(accel, run.fs_hz, 9.48, None, None)
    assert gated["sensor"] is None and gated["contact_r2"] > 0.98
    assert gated["beta"] < 0.8 * run.beta
    got = restoring_force_check(accel, run.fs_hz, 9.48, None, None, fit_chain=True)
    chain = got["sensor"]
    assert chain["applied"] and chain["lowpass_order"] == 2
    assert chain["lowpass_hz"] == pytest.approx(106.0, rel=0.1)
    assert got["beta"] == pytest.approx(run.beta, rel=0.1)
    assert got["beta_interval"][0] <= run.beta <= got["beta_interval"][1]


def test_the_chain_fitted_regardless_is_the_whole_checks_chain():
    """The campaign's fit regardless of the gate keeps only the chain, read without beta's
    interval: on the independent rig behind a 3rd-order 145 Hz low-pass (bench_crosscheck's
    rig_chains #8) it is the chain the whole check fits (fit_chain), every field the same,
    the low-pass the impacts cannot exclude too (profiled without the interval)."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import chain_fitted_regardless
    from serving.checks import checked_recording
    from serving.restoring_force_check import restoring_force_check

    sensor = {"resonance_hz": 1597.73, "resonance_damping": 0.0832, "lowpass_hz": 144.685,
              "lowpass_order": 3, "highpass_hz": 0.3724}  # fmt: skip
    run = RigRun(recording="r.csv", beta=7.780985785073243, fs_hz=2078.9479613976932,
                 duration_s=3.0, gap_mm=2.1053183865925034, sensor=sensor)  # fmt: skip
    accel = record(run, seed=20261135)[1]
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None, penetration_dissipation=False)
    got = chain_fitted_regardless(accel, run.fs_hz, 9.48, pred)
    a = checked_recording(accel, run.fs_hz, 9.48, pred.window_periods, "recording")[0]
    whole = restoring_force_check(a, run.fs_hz, 9.48, None, None, fit_chain=True)["sensor"]
    assert got is not None and got["lowpass_hz"] == pytest.approx(144.685, rel=0.15)
    assert got["lowpass_not_excluded"]
    assert json.dumps(got, sort_keys=True) == json.dumps(whole, sort_keys=True)


def test_a_recording_is_read_once_per_sheet_within_a_campaign():
    """The profiles' repeats: a recording read through a sheet with the same entries (in any
    order) is read once; another recording or another corner is read again; each pooling
    keeps its own readings."""
    from serving.campaign_chain import read_once

    asked = []

    def read(i, sheet):
        asked.append((i, sheet["highpass_hz"]))
        return {"r": i, "corner": sheet["highpass_hz"]}

    once = read_once(read)
    sheet = {"lowpass_hz": 120.0, "lowpass_order": 4.0, "highpass_hz": 3.1}
    first = once(0, sheet)
    assert once(0, dict(reversed(sheet.items()))) is first
    assert once(1, sheet) == {"r": 1, "corner": 3.1}
    assert once(0, {**sheet, "highpass_hz": 3.2}) == {"r": 0, "corner": 3.2}
    assert once(0, {**sheet, "highpass_low_hz": 2.9}) == {"r": 0, "corner": 3.1}
    assert asked == [(0, 3.1), (1, 3.1), (0, 3.2), (0, 3.1)]
    read_once(read)(0, sheet)  # another campaign's pooling reads again
    assert len(asked) == 5


def test_the_profiles_readers_share_one_reading_per_sheet():
    """A campaign's contact-law R2 and free damping of one recording through one sheet come
    from a single reading (the free flight at the corner the high-pass profile chose)."""
    from types import SimpleNamespace

    from serving.campaign_chain import profile_readers

    asked = []

    def read(i, sheet):
        asked.append(i)
        return SimpleNamespace(law="linear", contact_r2=0.9, ok=i == 0,
                               free_damping_fitted=0.02, free_r2=0.99)  # fmt: skip

    contact_r2, free_damping = profile_readers(read)
    sheet = {"highpass_hz": 3.1}
    assert contact_r2(0, sheet) == 0.9 and free_damping(0, sheet) == 0.02
    assert contact_r2(1, sheet, refused_as_unexplained=True) == 0.0  # refused: unexplained
    assert free_damping(1, sheet) == 0.02
    assert asked == [0, 1]


def test_a_users_data_sheet_wins_and_does_not_vote():
    sheet = {"resonance_hz": 800.0, "resonance_damping": 0.03}
    sensors = [fitted(300.0), fitted(302.0), {**fitted(800.0), "source": "fitted"}]
    chain = campaign_chain(sensors, list("abc"), [None, None, sheet])
    assert chain["pooled"] and chain["n_identified"] == 2
    assert chain["sensor"]["resonance_hz"] == pytest.approx(301.0)
    assert campaign_sheets(chain, [None, None, sheet]) == [chain["sensor"], chain["sensor"], sheet]


def test_a_recording_whose_own_law_the_pooled_chain_reads_much_worse_reads_alone():
    # the rig's campaign: R2 0.998 alone, 0.54 through the pooled chain (refused there)
    assert reads_alone({"contact_r2": 0.998}, {"contact_r2": 0.541})
    assert reads_alone({"contact_r2": 0.96}, {"contact_r2": None})  # refused: explains nothing
    # within the confirmation's shortfall, or better, or a first reading that refused: pooled
    assert not reads_alone({"contact_r2": 0.981}, {"contact_r2": 0.960})
    assert not reads_alone({"contact_r2": 0.315}, {"contact_r2": 0.949})
    assert not reads_alone({"contact_r2": None}, {"contact_r2": 0.9})
    assert not reads_alone(None, {"contact_r2": 0.9})


def test_predict_batch_keeps_the_first_row_of_a_recording_that_reads_alone():
    import pyarrow as pa

    from serving.batch_prediction import _campaign_table

    paths = ["a", "b", "c", "d"]
    first = pa.table({"path": paths, "sensor_source": ["fitted", None, "data sheet", "fitted"],
                      "restoring_force_contact_r2": [0.998, 0.97, 0.99, None]})  # fmt: skip
    second = pa.table({"path": paths,
                       "sensor_source": ["campaign", "campaign", "data sheet", "campaign"],
                       "restoring_force_contact_r2": [0.541, 0.99, 0.99, 0.95]})  # fmt: skip
    # a (R2 0.998 -> 0.541) keeps its first row; b and d read through the pooled chain; c has
    # its own sheet (not flagged) and keeps its first row
    table = _campaign_table(first, second, (True, True, False, True))
    assert table.column("path").to_pylist() == ["a", "b", "c", "d"]
    assert table.column("sensor_source").to_pylist() == ["fitted", "campaign", "data sheet",
                                                         "campaign"]  # fmt: skip


def test_the_result_names_the_chain_it_was_read_through():
    res = {"restoring_force": {"sensor": {"source": "data sheet", "resonance_hz": 300.0}},
           "chain_undone": {"source": "data sheet", "resonance_hz": 300.0}}  # fmt: skip
    out = labelled(res, True)
    assert out["chain_source"] == "campaign"
    assert out["restoring_force"]["sensor"]["source"] == "campaign"
    assert out["chain_undone"]["source"] == "campaign"
    assert res["restoring_force"]["sensor"]["source"] == "data sheet"  # a copy
    assert labelled(res, False)["chain_source"] == "data sheet"
    assert labelled({"restoring_force": {"sensor": None}}, False)["chain_source"] is None


#: One accelerometer for the whole campaign: a mount resonance at 20 f_n (in the band of a
#: 2 kHz logger, near the bottom of the shipped CNN's prior) and a charge amplifier.
def test_the_pooled_highpass_corner_is_profiled_over_the_campaigns_contact_laws():
    """Three damped contacts of the independent rig behind one 120 Hz order-4 low-pass and a
    4 Hz high-pass (2 % noise), pooled with the corner 35 % low, as the median of corners
    fitted behind each recording's own chain reads it: profiled over the campaign's contact
    laws read through the pooled chain, the corner lands within 10 % of the truth and every
    beta reads closer to the truth than through the pooled corner."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import campaign_highpass, contact_r2_through
    from stiffnet.restoring_force import restoring_force_estimate

    sensor = {"lowpass_hz": 120.0, "lowpass_order": 4, "highpass_hz": 4.0}
    betas = (12.0, 30.0, 55.0)
    recs = [record(RigRun(recording="r.csv", beta=b, fs_hz=1250.0, duration_s=3.0, gap_mm=1.5,
                          contact="kelvin_voigt", contact_zeta=0.15, sensor=sensor),
                   seed=i)[1] for i, b in enumerate(betas)]  # fmt: skip
    pooled = {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 120.0,
              "lowpass_order": 4.0, "highpass_hz": 2.6}  # fmt: skip
    chain = {"pooled": True, "sensor": pooled, "reason": "pooled", "stages": {}}
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    got = campaign_highpass(chain, lambda i, s: contact_r2_through(recs[i], 1250.0, 9.48, pred, s),
                            [9.48] * 3)  # fmt: skip
    corner = got["sensor"]["highpass_hz"]
    assert corner == pytest.approx(4.0, rel=0.1)
    assert got["stages"]["highpass_hz"]["pooled_median"] == 2.6 and "2.60 Hz" in got["reason"]
    corners = ("highpass_hz", "highpass_low_hz", "highpass_high_hz")
    assert {k: v for k, v in got["sensor"].items() if k not in corners} == {
        k: v for k, v in pooled.items() if k != "highpass_hz"}  # fmt: skip
    low, high = got["sensor"]["highpass_low_hz"], got["sensor"]["highpass_high_hz"]
    assert low <= corner <= high and got["stages"]["highpass_hz"]["interval"] == [low, high]

    def errors(sheet):
        return [abs(restoring_force_estimate(a, 1250.0, natural_frequency_hz=9.48, sensor=sheet,
                                             max_periods=24.0, interval=False).beta / b - 1)
                for a, b in zip(recs, betas, strict=True)]  # fmt: skip

    assert all(e < e0 for e, e0 in zip(errors(got["sensor"]), errors(pooled), strict=True))
    # a corner none pooled stays each recording's own; nothing pooled stays nothing
    auto = {**chain, "sensor": {**pooled, "highpass_hz": HIGHPASS_FITTED}}
    assert campaign_highpass(auto, lambda *_: 1 / 0, [9.48] * 3) is auto
    assert campaign_highpass({"pooled": False, "sensor": None}, lambda *_: 1 / 0, [9.48]) == {
        "pooled": False, "sensor": None}  # fmt: skip


DAMPED_SENSOR = {"lowpass_hz": 120.0, "lowpass_order": 4, "highpass_hz": 4.5}
DAMPED_BETAS = (12.0, 30.0, 55.0)


@pytest.fixture(scope="module")
def damped_campaign():
    """Three Kelvin-Voigt contacts (zeta 0.2) of the independent rig (its damping ratio 0.02)
    behind one 120 Hz order-4 low-pass and a 4.5 Hz high-pass, 2 % noise; the pooled chain
    with the corner 30 % low, profiled over the contact laws (:func:`campaign_highpass`);
    each recording's reading through a sheet memoised."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import campaign_highpass, contact_r2_through, free_damping_through

    recs = [record(RigRun(recording="r.csv", beta=b, fs_hz=1250.0, duration_s=3.0, gap_mm=1.5,
                          contact="kelvin_voigt", contact_zeta=0.2, sensor=DAMPED_SENSOR),
                   seed=i)[1] for i, b in enumerate(DAMPED_BETAS)]  # fmt: skip
    pooled = {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 120.0,
              "lowpass_order": 4.0, "highpass_hz": 0.7 * DAMPED_SENSOR["highpass_hz"]}  # fmt: skip
    chain = {"pooled": True, "sensor": pooled, "reason": "pooled", "stages": {}}
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    calls = []

    def free_damping(i, sheet):
        calls.append(sheet["highpass_hz"])
        return free_damping_through(recs[i], 1250.0, 9.48, pred, sheet)

    profiled = campaign_highpass(
        chain, lambda i, s: contact_r2_through(recs[i], 1250.0, 9.48, pred, s), [9.48] * 3
    )
    return SimpleNamespace(recs=recs, profiled=profiled, free_damping=free_damping, calls=calls)


def test_a_damped_campaigns_highpass_corner_is_read_from_the_free_flight_at_the_rigs_damping(
    damped_campaign,
):
    """The rig's damping given (0.02, a manifest's ``damping_ratio``): the corner is where the
    recordings' free flights, read through the pooled chain, show that damping, within 5 % of
    the true 4.5 Hz, with an interval that holds it; the contact laws' profile, which main
    keeps, is further off (3.74 Hz). Every beta reads within 5 % (two do not through the
    profile's corner)."""
    from serving.campaign_chain import campaign_highpass_damped
    from stiffnet.restoring_force import restoring_force_estimate

    profiled = damped_campaign.profiled
    assert profiled["stages"]["highpass_hz"]["source"] == "contact_r2_profile"
    got = campaign_highpass_damped(profiled, damped_campaign.free_damping, [9.48] * 3,
                                   [0.02] * 3)  # fmt: skip
    stage, sheet = got["stages"]["highpass_hz"], got["sensor"]
    assert stage["source"] == "free_flight_damping", stage["free_flight"]
    corner, truth = sheet["highpass_hz"], DAMPED_SENSOR["highpass_hz"]
    assert corner == pytest.approx(truth, rel=0.05)
    assert abs(profiled["sensor"]["highpass_hz"] / truth - 1) > abs(corner / truth - 1)
    assert sheet["highpass_low_hz"] <= corner <= sheet["highpass_high_hz"]
    # the interval holds both readings of the corner: the free flight's and the profile's
    assert sheet["highpass_low_hz"] <= profiled["sensor"]["highpass_hz"]
    assert stage["interval"] == [sheet["highpass_low_hz"], sheet["highpass_high_hz"]]
    assert stage["profiled"] == profiled["sensor"]["highpass_hz"] and "free flight" in got["reason"]
    assert {k: v for k, v in sheet.items() if not k.startswith("highpass")} == {
        k: v for k, v in profiled["sensor"].items() if not k.startswith("highpass")}  # fmt: skip

    def errors(s):
        return [abs(restoring_force_estimate(a, 1250.0, natural_frequency_hz=9.48, sensor=s,
                                             max_periods=24.0, interval=False).beta / b - 1)
                for a, b in zip(damped_campaign.recs, DAMPED_BETAS, strict=True)]  # fmt: skip

    plain = {k: v for k, v in sheet.items() if k not in ("highpass_low_hz", "highpass_high_hz")}
    before = {**plain, "highpass_hz": profiled["sensor"]["highpass_hz"]}
    # through the true 4.5 Hz the betas read 0.984, 0.967, 1.018 of the truth; through the
    # profile's 3.74 Hz 1.065, 1.011, 1.056
    assert max(errors(plain)) < 0.05 < max(errors(before))


def test_a_wrong_given_damping_keeps_the_profiled_corner_and_says_why(damped_campaign):
    """A damping given ten times the rig's (0.2, a lab writing the contact's) implies a corner
    far outside the contact laws' range: the profile is kept, its sheet unchanged, and the
    reason asks whether the damping is right. A campaign whose rows give no damping is
    returned as it is, the free flight never read."""
    from serving.campaign_chain import campaign_highpass_damped

    profiled = damped_campaign.profiled
    got = campaign_highpass_damped(profiled, damped_campaign.free_damping, [9.48] * 3,
                                   [0.2] * 3)  # fmt: skip
    assert got["sensor"] == profiled["sensor"]
    stage = got["stages"]["highpass_hz"]
    assert stage["source"] == "contact_r2_profile"
    assert "damping right" in stage["free_flight"]["kept"]
    assert "the profiled corner kept" in got["reason"] and "0.2" in got["reason"]
    calls = len(damped_campaign.calls)
    assert campaign_highpass_damped(profiled, damped_campaign.free_damping, [9.48] * 3,
                                    [None] * 3) is profiled  # fmt: skip
    assert len(damped_campaign.calls) == calls
    # a chain whose corner was not profiled (none pooled: each recording's own) stays as it is
    auto = {"pooled": True, "sensor": {"highpass_hz": HIGHPASS_FITTED}, "stages": {}}
    assert campaign_highpass_damped(auto, lambda *_: 1 / 0, [9.48], [0.02]) is auto


def test_the_free_flight_corners_interval_spans_the_free_dampings_tolerance(damped_campaign):
    """The free flight's corner is read at a given damping taken as exact; an error the
    recordings share (a lab's damping off, a pooled band that reads the free damping high)
    moves it by about ``2 f_n`` times that error, which no bootstrap over the recordings sees.
    A damping given off by the tolerance reads a corner inside the interval read at the true
    one (main's interval, the bootstrap and the profile, [3.74, 4.68] Hz, misses the 4.70 Hz
    read at 0.01), and the interval spans ``2 f_n`` times the tolerance either side."""
    from serving.campaign_chain import FREE_DAMPING_TOLERANCE, campaign_highpass_damped

    profiled, free = damped_campaign.profiled, damped_campaign.free_damping
    got = campaign_highpass_damped(profiled, free, [9.48] * 3, [0.02] * 3)
    sheet = got["sensor"]
    corner, low, high = sheet["highpass_hz"], sheet["highpass_low_hz"], sheet["highpass_high_hz"]
    for given in (0.02 - FREE_DAMPING_TOLERANCE, 0.02 + FREE_DAMPING_TOLERANCE):
        other = campaign_highpass_damped(profiled, free, [9.48] * 3, [given] * 3)
        assert other["stages"]["highpass_hz"]["source"] == "free_flight_damping"
        assert low <= other["sensor"]["highpass_hz"] <= high, (given, other["sensor"])
    slack = 2 * 9.48 * FREE_DAMPING_TOLERANCE
    assert low <= corner - slack and corner + slack <= high
    assert got["stages"]["highpass_hz"]["free_flight"]["tolerance"] == FREE_DAMPING_TOLERANCE
    assert f"+-{FREE_DAMPING_TOLERANCE:g}" in got["reason"]


ELASTIC_SENSOR = {"lowpass_hz": 224.0, "lowpass_order": 2, "highpass_hz": 3.2}
ELASTIC_BETAS = (10.0, 24.0, 48.0)


@pytest.fixture(scope="module")
def elastic_campaign():
    """Three elastic contacts of the independent rig (its damping ratio 0.02) behind one
    224 Hz order-2 low-pass and a 3.2 Hz high-pass (rig_campaigns+1000's campaign 3 without
    its mount), 2 % noise, at 2900 Hz."""
    from independent_rig import RigRun, record

    return [record(RigRun(recording="r.csv", beta=b, fs_hz=2900.0, duration_s=3.0,
                          gap_mm=1.5, sensor=ELASTIC_SENSOR), seed=i)[1]
            for i, b in enumerate(ELASTIC_BETAS)]  # fmt: skip


@pytest.mark.slow
def test_an_elastic_campaigns_corner_is_read_from_the_free_flight_through_its_chain(
    elastic_campaign,
):
    """With the band stages pooled right, the elastic campaign's free flights read the rig's
    damping at the true corner, and the corner the free flight implies from 30 % low lies
    within 5 % of the truth (the contact being elastic is not what reads it high)."""
    from types import SimpleNamespace

    from serving.campaign_chain import campaign_highpass_damped, free_damping_through

    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    truth = ELASTIC_SENSOR["highpass_hz"]
    sheet = {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 224.0,
             "lowpass_order": 2.0, "highpass_hz": 0.7 * truth}  # fmt: skip
    chain = {"pooled": True, "sensor": sheet, "reason": "pooled",
             "stages": {"highpass_hz": {"value": 0.7 * truth, "interval": [0.5 * truth,
                                                                           1.2 * truth],
                                        "source": "contact_r2_profile"}}}  # fmt: skip

    def free(i, s):
        return free_damping_through(elastic_campaign[i], 2900.0, 9.48, pred, s)

    at_truth = [free(i, {**sheet, "highpass_hz": truth}) for i in range(3)]
    assert np.median(at_truth) == pytest.approx(0.02, abs=0.003)
    got = campaign_highpass_damped(chain, free, [9.48] * 3, [0.02] * 3)
    assert got["stages"]["highpass_hz"]["source"] == "free_flight_damping", got["reason"]
    assert got["sensor"]["highpass_hz"] == pytest.approx(truth, rel=0.05)


@pytest.mark.slow
def test_a_pooled_chain_that_misses_the_lowpass_reads_the_free_damping_high(elastic_campaign):
    """Why an elastic campaign's free-flight corner read high on the bench: read at the true
    corner through a chain that leaves the 224 Hz low-pass out (the pool missed it) or puts
    it 30 % high, the free flight's damping reads well above the rig's 0.02 (the pulses'
    tails lie beside the contacts, where the free damping is identified): the corner it
    implies is then high by ``2 f_n`` times the excess."""
    from types import SimpleNamespace

    from serving.campaign_chain import free_damping_through

    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    true = {"resonance_hz": 0.0, "resonance_damping": 0.0, "lowpass_hz": 224.0,
            "lowpass_order": 2.0, "highpass_hz": ELASTIC_SENSOR["highpass_hz"]}  # fmt: skip

    def median_free(sheet):
        return float(np.median([free_damping_through(a, 2900.0, 9.48, pred, sheet)
                                for a in elastic_campaign]))  # fmt: skip

    right = median_free(true)
    assert right == pytest.approx(0.02, abs=0.003)
    for off in ({"lowpass_hz": 0.0, "lowpass_order": 0.0}, {"lowpass_hz": 1.3 * 224.0}):
        assert median_free({**true, **off}) > right + 0.004


SENSOR = {"resonance_hz": 190.0, "resonance_damping": 0.05, "highpass_hz": 1.0}
BETAS = (8.0, 20.0, 30.0, 45.0, 70.0, 90.0)


def _rig_campaign(folder, sensor):
    from independent_rig import RigRun, write_campaign

    from stiffnet.campaign import load_campaign
    from stiffnet.campaign.loaded import LoadedCampaign

    runs = [RigRun(recording=f"r{i}.csv", beta=b, fs_hz=2000.0, duration_s=3.0, gap_mm=1.5,
                   sensor=sensor) for i, b in enumerate(BETAS)]  # fmt: skip
    write_campaign(folder, runs)
    return LoadedCampaign.of(load_campaign(folder))


def _mape(betas):
    return float(np.mean([abs(b / t - 1) for b, t in zip(betas, BETAS, strict=True)]))


@pytest.mark.slow
def test_evaluate_pools_one_known_chain_on_an_independent_rig_campaign(tmp_path):
    """Six recordings of the independent rig (solve_ivp, analog chain) behind one sensor:
    the pooled resonance within 10 % of the truth, every recording read through it, and the
    learned betas at least as close to the truth as each recording's own undo."""
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.nuisance import predicted

    campaign = _rig_campaign(tmp_path / "camp", SENSOR)
    res = evaluate_campaign(campaign)
    chain = res["sensor"]
    assert chain["pooled"], chain["reason"]
    assert chain["n_identified"] >= 2
    assert chain["sensor"]["resonance_hz"] == pytest.approx(SENSOR["resonance_hz"], rel=0.1)
    # every recording through the pooled chain, but one whose own contact law the pooled
    # chain reads much worse keeps its own reading (reads_alone: here beta 90, whose own fit
    # puts the high-pass at 3.4 Hz where the pool reads 0.9 Hz for the true 1 Hz)
    sources = [r["chain_source"] for r in res["recordings"]]
    assert sources.count("campaign") >= len(BETAS) - 1 and set(sources) <= {"campaign", "fitted"}
    # a pooled chain is a fit, not a data sheet: each recording read through it is also read
    # through the other chains the fit allows, and its interval spans those readings
    for r in res["recordings"]:
        readings = r["chain_readings"] or []
        if r["chain_source"] == "campaign":
            assert readings, r["recording"]
        low, high = r["beta_interval"]
        assert all(low <= x["beta"] <= high for x in readings), r["recording"]
    # the first reading (each recording's own chain, or none) is memoised on the campaign
    own = [predicted(campaign, i, row, None) for i, row in enumerate(campaign.rows)]
    pooled = [r["beta_estimate"] for r in res["recordings"]]
    assert _mape(pooled) <= _mape([r["beta"] for r in own]) + 1e-9
    # predict-batch on the campaign folder pools the same chain, in a second round of parts
    import pyarrow.parquet as pq

    from serving.batch_prediction import predict_batch

    summary = predict_batch(tmp_path / "camp", tmp_path / "out.parquet", part_size=4)
    assert summary["sensor"]["sensor"] == chain["sensor"] and summary["parts"] == 4
    table = pq.read_table(tmp_path / "out.parquet").to_pylist()
    assert [r["sensor_source"] for r in table] == sources
    assert [r["beta"] for r in table] == pytest.approx(pooled)
    assert [json.loads(r["chain_readings"] or "null") for r in table] == [
        r["chain_readings"] for r in res["recordings"]
    ]


@pytest.mark.slow
def test_an_ideal_campaign_gets_no_pooled_chain_and_the_same_predictions(tmp_path):
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.nuisance import predicted

    campaign = _rig_campaign(tmp_path / "ideal", None)
    res = evaluate_campaign(campaign)
    assert not res["sensor"]["pooled"] and res["sensor"]["sensor"] is None
    assert not res["campaign_law"]["flag"], res["campaign_law"]["message"]  # one rig's law
    own = [predicted(campaign, i, row, None) for i, row in enumerate(campaign.rows)]
    for r, o in zip(res["recordings"], own, strict=True):
        assert r["chain_source"] != "campaign"
        assert (r["class"], r["beta_estimate"], r["beta_interval"]) == (
            o["class"], o["beta"], o["beta_interval"])  # fmt: skip


def test_the_profiled_corner_carries_the_corners_the_recordings_cannot_tell_apart():
    """The profiled corner's interval is where the rule lands on the campaign's recordings
    drawn again: recordings that agree pin it; recordings split between two corners (three
    best at 3 Hz, three at 4.5 Hz, the other corner close behind) leave both open, and a
    corner every recording fits far worse stays out."""
    from serving.campaign_chain import corner_interval

    read = np.ones(6, dtype=bool)
    agree = {2.0: np.full(6, 0.05), 3.0: np.full(6, 0.01), 4.5: np.full(6, 0.04)}
    assert corner_interval(agree, read, 3.0) == (3.0, 3.0)
    split = {2.0: np.full(6, 0.2), 3.0: np.r_[[0.010] * 3, [0.012] * 3],
             4.5: np.r_[[0.012] * 3, [0.010] * 3]}  # fmt: skip
    assert corner_interval(split, read, 3.0) == (3.0, 4.5)
    # a recording with no say does not move it
    assert corner_interval(split, np.r_[[True] * 3, [False] * 3], 3.0) == (3.0, 3.0)


def _lowpass_table(truth):
    """A campaign's contact laws as an analytic table: recording i's share of force unexplained
    through a low-pass at corner c and order o is ``0.001 (i + 1) exp((ln(c / t_i) / 0.1)^2)``,
    three times more at another order than 4 (`truth`: each recording's best corner t_i)."""

    def contact_r2(i, sheet):
        order_cost = 1.0 if sheet["lowpass_order"] == 4.0 else 3.0
        shape = (np.log(sheet["lowpass_hz"] / truth[i]) / 0.1) ** 2
        return 1.0 - 0.001 * (i + 1) * order_cost * np.exp(shape)

    return contact_r2


def test_the_campaigns_lowpass_is_profiled_where_the_recordings_fits_disagree():
    """Four recordings fitted a low-pass 6-44 % above the campaign's 90 Hz order 4 (one at
    order 3), too scattered to pool: the stage left out is profiled over the campaign's
    contact laws (an analytic table whose laws all fit best at 90 Hz order 4), so the chain
    is pooled with 90 Hz order 4 within the refinement's 2 %, its interval holding it; where
    the recordings split between 85 and 100 Hz the interval spans both; a recording with its
    own sheet is not read; a campaign whose recordings agree on a low-pass, leave the
    high-pass to each recording, or show no low-pass is left as it is."""
    from serving.campaign_chain import campaign_lowpass

    sensors = [fitted(lowpass_hz=95.0), fitted(lowpass_hz=112.0), fitted(lowpass_hz=130.0),
               fitted(lowpass_hz=100.0, order=3), None]  # fmt: skip
    chain = campaign_chain(sensors, list("abcde"))
    assert not chain["pooled"] and "lowpass_hz" in chain["stages"]
    got = campaign_lowpass(chain, sensors, _lowpass_table([90.0] * 5))
    sheet = got["sensor"]
    assert got["pooled"] and sheet["lowpass_order"] == 4.0
    assert sheet["lowpass_hz"] == pytest.approx(90.0, rel=0.02)
    assert sheet["lowpass_low_hz"] <= sheet["lowpass_hz"] <= sheet["lowpass_high_hz"]
    assert sheet["lowpass_high_hz"] / sheet["lowpass_low_hz"] < 1.1
    assert got["stages"]["lowpass_hz"]["median"] == chain["stages"]["lowpass_hz"]["value"]
    assert "left out" in got["reason"]
    assert check_sensor_sheet(sheet, 1000.0) == sheet  # a data sheet the check accepts
    # recordings split between two corners: the interval spans both
    split = campaign_lowpass(chain, sensors, _lowpass_table([85.0, 85.0, 100.0, 100.0, 85.0]))
    assert split["sensor"]["lowpass_low_hz"] <= 85.0 * 1.03
    assert split["sensor"]["lowpass_high_hz"] >= 100.0 / 1.03
    # a recording read with its own data sheet is neither read nor voting
    own = [None, None, None, None, {"lowpass_hz": 50.0}]
    table = _lowpass_table([90.0] * 5)
    sure = campaign_lowpass(chain, sensors,
                            lambda i, s: 1 / 0 if i == 4 else table(i, s), own)  # fmt: skip
    assert sure["sensor"]["lowpass_hz"] == pytest.approx(90.0, rel=0.02)
    # a low-pass the recordings agree on is kept as pooled
    agreeing = [fitted(lowpass_hz=99.0), fitted(lowpass_hz=100.0), fitted(lowpass_hz=101.0)]
    pooled = campaign_chain(agreeing, list("abc"))
    assert campaign_lowpass(pooled, agreeing, lambda *_: 1 / 0) is pooled
    # a high-pass left to each recording: not profiled (each reading would profile its own)
    apart = [fitted(lowpass_hz=f, highpass=0.0) for f in (95.0, 112.0, 130.0)]
    auto = campaign_chain(apart, list("abc"))
    assert auto["unpooled_sheet"]["highpass_hz"] == HIGHPASS_FITTED
    assert campaign_lowpass(auto, apart, lambda *_: 1 / 0) is auto
    # no low-pass shown: nothing profiled
    resonant = [fitted(300.0), fitted(305.0), fitted(298.0)]
    plain = campaign_chain(resonant, list("abc"))
    assert campaign_lowpass(plain, resonant, lambda *_: 1 / 0) is plain


def test_a_large_campaigns_lowpass_profile_reads_a_bounded_spread_subset():
    """A 24-recording campaign whose fits scatter over three orders: the profile reads every
    candidate and refinement on an evenly spaced subset of the recordings, as many as
    MAX_PROFILE_READINGS allows but at least MIN_PROFILED_RECORDINGS (every recording on
    every candidate would be 24 x 56), and it still finds the 90 Hz order 4 the laws share;
    a six-recording campaign is read whole."""
    from serving.campaign_chain import (
        LOWPASS_REFINE_ITER,
        MAX_PROFILE_READINGS,
        MIN_PROFILED_RECORDINGS,
        campaign_lowpass,
        profiled_subset,
    )

    n = 24
    sensors = [fitted(lowpass_hz=95.0 + 3.0 * i, order=2 + i % 3) for i in range(n)]
    chain = campaign_chain(sensors, [f"r{i}" for i in range(n)])
    assert not chain["pooled"] and "lowpass_hz" in chain["stages"]
    table = _lowpass_table([90.0] * n)
    calls = []
    got = campaign_lowpass(chain, sensors, lambda i, s: calls.append(i) or table(i, s))
    assert got["sensor"]["lowpass_hz"] == pytest.approx(90.0, rel=0.02)
    assert got["sensor"]["lowpass_order"] == 4.0
    read = sorted(set(calls))
    # three orders of 16 corners and the refinement: far over the budget, so the floor
    assert len(read) == MIN_PROFILED_RECORDINGS < n
    assert MAX_PROFILE_READINGS // (3 * 16 + LOWPASS_REFINE_ITER) < MIN_PROFILED_RECORDINGS
    assert read[0] == 0 and read[-1] == n - 1  # spread over the campaign
    assert len(calls) <= (3 * 16 + LOWPASS_REFINE_ITER + 1) * len(read)
    assert got["stages"]["lowpass_hz"]["profiled_on"] == len(read)
    # the subset keeps the recordings it is asked to, and a small campaign whole
    assert {5, 23} <= set(profiled_subset(list(range(n)), 48, kept=[5, 23]))
    assert profiled_subset(list(range(6)), 48) == list(range(6))
    assert profiled_subset(list(range(n)), MAX_PROFILE_READINGS // n) == list(range(n))


def test_a_lowpass_the_recordings_fits_scatter_over_is_profiled_on_a_rig_campaign():
    """Three damped contacts of the independent rig behind one 120 Hz order-4 low-pass and a
    4 Hz high-pass (2 % noise), whose chain fits read the corner 8-46 % high and too scattered
    to pool (the corner traded against each contact's damping): the campaign's contact laws
    read through the chain with the corner held choose it within 10 % at order 4, the interval
    holds the truth, and every beta reads closer to the truth than through the chain the
    pool left without its low-pass."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import campaign_lowpass, contact_r2_through
    from stiffnet.restoring_force import restoring_force_estimate

    sensor = {"lowpass_hz": 120.0, "lowpass_order": 4, "highpass_hz": 4.0}
    betas = (12.0, 30.0, 55.0)
    recs = [record(RigRun(recording="r.csv", beta=b, fs_hz=1250.0, duration_s=3.0, gap_mm=1.5,
                          contact="kelvin_voigt", contact_zeta=0.15, sensor=sensor),
                   seed=i)[1] for i, b in enumerate(betas)]  # fmt: skip
    fits = [fitted(lowpass_hz=f, highpass=4.0) for f in (130.0, 150.0, 175.0)]
    chain = campaign_chain(fits, list("abc"))
    assert not chain["pooled"]  # the corners disagree: the stage is left out
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    got = campaign_lowpass(
        chain, fits, lambda i, s: contact_r2_through(recs[i], 1250.0, 9.48, pred, s)
    )
    sheet = got["sensor"]
    assert got["pooled"] and sheet["lowpass_order"] == 4.0
    assert sheet["lowpass_hz"] == pytest.approx(120.0, rel=0.1)
    assert sheet["lowpass_low_hz"] <= 120.0 * 1.02 and sheet["lowpass_high_hz"] >= 120.0 / 1.02

    def errors(at):
        return [abs(restoring_force_estimate(a, 1250.0, natural_frequency_hz=9.48, sensor=at,
                                             max_periods=24.0, interval=False).beta / b - 1)
                for a, b in zip(recs, betas, strict=True)]  # fmt: skip

    bare = {k: v for k, v in sheet.items() if not k.startswith("lowpass")}
    assert all(e < e0 for e, e0 in zip(errors(sheet), errors(bare), strict=True))


def _minority_table(truth_hz, truth_order=3, without=5.0):
    """A campaign's contact laws as an analytic table: recording i's share of force unexplained
    through a low-pass at corner c is ``0.001 (i + 1) exp((ln(c / truth_hz) / 0.1)^2)``, three
    times more at another order than `truth_order`, and `without` times its best with no
    low-pass (the chain the pool left without one)."""

    def contact_r2(i, sheet):
        if not sheet["lowpass_hz"]:
            return 1.0 - 0.001 * (i + 1) * without
        order_cost = 1.0 if sheet["lowpass_order"] == truth_order else 3.0
        shape = (np.log(sheet["lowpass_hz"] / truth_hz) / 0.1) ** 2
        return 1.0 - 0.001 * (i + 1) * order_cost * np.exp(shape)

    return contact_r2


def test_a_lowpass_fewer_than_half_the_chains_show_is_profiled_with_none_a_candidate():
    """Three recordings fitted the campaign's resonance, one of them also a 345 Hz order-2
    low-pass (rig_campaigns+1000's campaign 1: true 371 Hz order 3). The pool counts a stage
    only where half the chains show it, so it holds none, and :func:`campaign_lowpass` leaves
    it so. Where the campaign's contact laws (an analytic table) read best at 371 Hz order 3,
    and 5x worse without a low-pass, the profile adds it within 10 % at order 3, its interval
    holding it; where they read best without one, none is added and the reason says so; a
    pool that holds a low-pass, a chain none of whose fits shows one, or one that leaves the
    high-pass to each recording is left as it is."""
    from serving.campaign_chain import campaign_lowpass, campaign_lowpass_minority

    sensors = [fitted(216.0), fitted(221.0), fitted(227.0, lowpass_hz=345.0, order=2)]
    chain = campaign_chain(sensors, list("abc"))
    assert chain["pooled"] and not chain["sensor"]["lowpass_hz"]
    assert campaign_lowpass(chain, sensors, lambda *_: 1 / 0) is chain  # main: no low-pass
    got = campaign_lowpass_minority(chain, sensors, _minority_table(371.0))
    sheet = got["sensor"]
    assert sheet["lowpass_order"] == 3.0
    assert sheet["lowpass_hz"] == pytest.approx(371.0, rel=0.10)
    assert sheet["lowpass_low_hz"] <= 371.0 * 1.02 and sheet["lowpass_high_hz"] >= 371.0 / 1.02
    assert sheet["resonance_hz"] == chain["sensor"]["resonance_hz"]
    assert got["stages"]["lowpass_hz"]["showing"] == 1
    assert "shown by 1 of the 3 identified chains" in got["reason"]
    assert "at_grid_end" not in got["stages"]["lowpass_hz"]  # 371 Hz lies inside 259-380 Hz
    edge = campaign_lowpass_minority(chain, sensors, _minority_table(450.0, without=50.0))
    assert edge["stages"]["lowpass_hz"]["at_grid_end"] and "end of the corners" in edge["reason"]
    assert check_sensor_sheet(sheet, 2420.0) == sheet
    # the contact laws read best without a low-pass: none added, and the reason says so
    kept = campaign_lowpass_minority(chain, sensors, _minority_table(371.0, without=0.5))
    assert kept["sensor"] == chain["sensor"]
    assert kept["stages"]["lowpass_hz"]["value"] is None
    assert "not kept" in kept["reason"]
    # left as it is: a pooled low-pass, no fit showing one, a high-pass left to each recording
    agreeing = [fitted(lowpass_hz=99.0), fitted(lowpass_hz=100.0), fitted(lowpass_hz=101.0)]
    pooled = campaign_chain(agreeing, list("abc"))
    assert campaign_lowpass_minority(pooled, agreeing, lambda *_: 1 / 0) is pooled
    resonant = [fitted(300.0), fitted(305.0), fitted(298.0)]
    plain = campaign_chain(resonant, list("abc"))
    assert campaign_lowpass_minority(plain, resonant, lambda *_: 1 / 0) is plain
    auto_fits = [fitted(216.0, highpass=0.0), fitted(221.0, highpass=0.0),
                 fitted(227.0, lowpass_hz=345.0, order=2, highpass=0.0)]  # fmt: skip
    auto = campaign_chain(auto_fits, list("abc"))
    assert auto["sensor"]["highpass_hz"] == HIGHPASS_FITTED
    assert campaign_lowpass_minority(auto, auto_fits, lambda *_: 1 / 0) is auto


@pytest.mark.slow
def test_a_lowpass_one_fit_shows_is_recovered_on_a_rig_campaign():
    """Three elastic contacts of the independent rig behind rig_campaigns+1000's campaign-1
    chain (a 216.8 Hz mount of zeta 0.068, a 371 Hz order-3 low-pass, 1.12 Hz; 2 % noise at
    2420 Hz), the pool holding the mount and no low-pass (one fit of three showed one, at
    345 Hz order 2): the campaign's contact laws read through the pooled chain choose the
    low-pass within 10 % of the truth."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import campaign_lowpass_minority, contact_r2_through

    true = {"resonance_hz": 216.8, "resonance_damping": 0.068, "lowpass_hz": 371.0,
            "lowpass_order": 3.0, "highpass_hz": 1.12}  # fmt: skip
    betas = (46.0, 78.0, 52.0)
    recs = [record(RigRun(recording="r.csv", beta=b, fs_hz=2420.0, duration_s=3.0, gap_mm=1.5,
                          sensor=true), seed=i)[1] for i, b in enumerate(betas)]  # fmt: skip
    fits = [fitted(216.0, highpass=1.12), fitted(221.0, highpass=1.12),
            fitted(227.0, lowpass_hz=345.0, order=2, highpass=1.12)]  # fmt: skip
    chain = campaign_chain(fits, list("abc"))
    pool = {**true, "lowpass_hz": 0.0, "lowpass_order": 0.0}
    chain = {**chain, "sensor": pool}  # the resonance as profiled: at the truth
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)
    got = campaign_lowpass_minority(
        chain, fits, lambda i, s: contact_r2_through(recs[i], 2420.0, 9.48, pred, s)
    )
    assert got["sensor"]["lowpass_hz"] == pytest.approx(371.0, rel=0.10), got["reason"]


def _resonance_table(truth_hz, truth_damping=0.05, never_read=()):
    """A campaign's contact laws as an analytic table, read as :func:`contact_r2_through`
    reads them with ``refused_as_unexplained``: recording i's share of force unexplained
    through a resonance at f Hz, damping z is ``0.001 (i + 1) exp(shape)``, with
    ``shape = (ln(f / t_i) / 0.03)^2 + (ln(z / truth_damping) / 0.3)^2`` (`truth_hz`: each
    recording's best frequency t_i); a reading with shape above 3 is refused (R² 0), as the
    ringing a resonance off in frequency and damping leaves makes the contacts last too long;
    the recordings in `never_read` are refused everywhere."""

    def contact_read(i, sheet):
        shape = (np.log(sheet["resonance_hz"] / truth_hz[i]) / 0.03) ** 2
        shape += (np.log(sheet["resonance_damping"] / truth_damping) / 0.3) ** 2
        return 0.0 if shape > 3.0 or i in never_read else 1.0 - 0.001 * (i + 1) * np.exp(shape)

    return contact_read


RESONANCE_SHEET = {"resonance_hz": 208.0, "resonance_damping": 0.034, "lowpass_hz": 0.0,
                   "lowpass_order": 0.0, "highpass_hz": 1.0}  # fmt: skip


def _resonance_chain(resonance_hz=208.0, damping=0.034):
    sheet = {**RESONANCE_SHEET, "resonance_hz": resonance_hz, "resonance_damping": damping}
    return {"pooled": True, "sensor": sheet, "reason": "pooled",
            "stages": {"resonance_hz": {"value": resonance_hz}}}  # fmt: skip


def test_a_pooled_resonance_that_refuses_the_contacts_is_profiled_over_the_campaign():
    """A resonance pooled 4 % high in frequency and a third low in damping (as two or three
    fits pool it), near the contacts, refuses every recording of an analytic table whose laws
    all fit best at 200 Hz zeta 0.05: profiled, the sheet gets 200 Hz within 1 % and zeta 0.05
    within 10 %, every recording reads, its interval holds the frequency, the rest of the
    sheet is unchanged; recordings split between 196 and 204 Hz give an interval spanning
    both. Left as they are: a resonance far above the contacts, a high-pass left to each
    recording, no resonance, nothing pooled; a recording with its own sheet is not read."""
    from serving.campaign_chain import RESONANCE_NEAR_CONTACT, campaign_resonance

    chain, fns = _resonance_chain(), [9.48] * 5
    table = _resonance_table([200.0] * 5)
    assert all(table(i, chain["sensor"]) == 0.0 for i in range(5))  # the pool refuses them
    got = campaign_resonance(chain, table, fns)
    out = got["sensor"]
    assert out["resonance_hz"] == pytest.approx(200.0, rel=0.01)
    assert out["resonance_damping"] == pytest.approx(0.05, rel=0.1)
    assert all(table(i, out) > 0.99 for i in range(5))
    stage = got["stages"]["resonance_hz"]
    assert stage["pooled"] == 208.0 and stage["pooled_damping"] == 0.034
    assert (stage["read_pooled"], stage["read"], stage["profiled_on"]) == (0, 5, 5)
    assert stage["interval"][0] <= out["resonance_hz"] <= stage["interval"][1]
    assert "208.0 Hz" in got["reason"]
    assert {k: v for k, v in out.items() if not k.startswith("resonance")} == {
        k: v for k, v in RESONANCE_SHEET.items() if not k.startswith("resonance")}  # fmt: skip
    split = campaign_resonance(chain, _resonance_table([196.0, 196.0, 204.0, 204.0, 196.0]), fns)
    low, high = split["stages"]["resonance_hz"]["interval"]
    assert low <= 196.0 * 1.02 and high >= 204.0 / 1.02
    # a recording read with its own sheet is neither read nor voting
    own = [None, None, None, None, {"resonance_hz": 500.0}]
    sure = campaign_resonance(chain, lambda i, s: 1 / 0 if i == 4 else table(i, s), fns, own)
    assert sure["sensor"]["resonance_hz"] == pytest.approx(200.0, rel=0.01)
    # far above the stiffest contact (96 Hz at beta 100, f_n 9.48 Hz): not profiled
    far_hz = 1.05 * RESONANCE_NEAR_CONTACT * 9.48 * np.sqrt(101.0)
    far = {**chain, "sensor": {**chain["sensor"], "resonance_hz": far_hz}}
    assert campaign_resonance(far, lambda *_: 1 / 0, fns) is far
    auto = {**chain, "sensor": {**chain["sensor"], "highpass_hz": HIGHPASS_FITTED}}
    assert campaign_resonance(auto, lambda *_: 1 / 0, fns) is auto
    none = {**chain, "sensor": {**chain["sensor"], "resonance_hz": 0.0, "resonance_damping": 0.0}}
    assert campaign_resonance(none, lambda *_: 1 / 0, fns) is none
    assert campaign_resonance({"pooled": False, "sensor": None}, lambda *_: 1 / 0, fns) == {
        "pooled": False, "sensor": None}  # fmt: skip


def test_a_pooled_resonance_is_kept_unless_a_candidate_reads_more_recordings():
    """The guard: a pool that reads every recording is returned as it is after reading each
    once, though the contact laws' R² alone would move it (every law fits best 2 % lower,
    zeta 0.04); and a pool that refuses a recording no candidate reads is kept (reported),
    though every other law fits best elsewhere: the profile never trades readings for fit."""
    from serving.campaign_chain import campaign_resonance

    calls = []

    def counted(table):
        def read(i, sheet):
            calls.append(i)
            return table(i, sheet)

        return read

    right = _resonance_chain(200.0, 0.05)
    leaning = _resonance_table([196.0] * 5, truth_damping=0.04)
    assert all(leaning(i, right["sensor"]) > 0.0 for i in range(5))
    assert campaign_resonance(right, counted(leaning), [9.48] * 5) is right
    assert len(calls) == 5
    unread = _resonance_table([200.0] * 5, never_read=(4,))
    kept = campaign_resonance(_resonance_chain(203.0, 0.05), unread, [9.48] * 5)
    assert kept["sensor"]["resonance_hz"] == 203.0 and kept["sensor"]["resonance_damping"] == 0.05
    assert kept["stages"]["resonance_hz"]["kept"] and kept["stages"]["resonance_hz"]["read"] == 4


def test_a_pool_no_candidate_reads_any_recording_through_is_returned_as_it_is():
    """Where every candidate's readings are refused, nothing ranks the candidates: the chain
    comes back untouched, without the empty median's warning."""
    import warnings

    from serving.campaign_chain import campaign_resonance

    chain = _resonance_chain(200.0, 0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert campaign_resonance(chain, lambda i, sheet: 0.0, [9.48] * 3) is chain


@pytest.mark.slow
def test_a_mount_resonance_pooled_off_is_profiled_on_a_rig_campaign():
    """Three hard contacts of the independent rig behind a 200 Hz zeta 0.05 mount (about twice
    the stiffest contact's frequency) and a 1 Hz high-pass (2 % noise), read through the
    resonance as two or three fits pool it (208 Hz, zeta 0.034): the ringing left around each
    pulse refuses at least one (the contacts last too long, or the law explains too little).
    Profiled over the campaign's contact laws, the resonance lands within 3 % in frequency and
    25 % in damping, and every recording reads beta within 10 %. The true resonance, pooled,
    reads all three and is returned as it is."""
    from types import SimpleNamespace

    from independent_rig import RigRun, record

    from serving.campaign_chain import campaign_resonance, contact_r2_through
    from stiffnet.restoring_force import restoring_force_estimate

    sensor = {"resonance_hz": 200.0, "resonance_damping": 0.05, "highpass_hz": 1.0}
    betas = (50.0, 80.0, 95.0)
    recs = [record(RigRun(recording="r.csv", beta=b, fs_hz=2000.0, duration_s=3.0, gap_mm=1.5,
                          sensor=sensor), seed=i)[1] for i, b in enumerate(betas)]  # fmt: skip

    def readings(sheet):
        return [restoring_force_estimate(a, 2000.0, natural_frequency_hz=9.48, sensor=sheet,
                                         max_periods=24.0, interval=False)
                for a in recs]  # fmt: skip

    chain = _resonance_chain()
    assert not all(r.ok for r in readings(chain["sensor"]))
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)

    def read(i, s):
        return contact_r2_through(recs[i], 2000.0, 9.48, pred, s, refused_as_unexplained=True)

    got = campaign_resonance(chain, read, [9.48] * 3)
    sheet = got["sensor"]
    assert sheet["resonance_hz"] == pytest.approx(200.0, rel=0.03)
    assert sheet["resonance_damping"] == pytest.approx(0.05, rel=0.25)
    for r, b in zip(readings(sheet), betas, strict=True):
        assert r.ok and r.beta == pytest.approx(b, rel=0.1)
    right = _resonance_chain(200.0, 0.05)
    assert campaign_resonance(right, read, [9.48] * 3) is right

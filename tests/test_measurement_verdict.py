"""Verdicts per recording: each residual against its own split-half floor, a robust
campaign rule, non-repeatable recordings reported and weighted down, orbits named."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binom

from stiffnet.measurement.noise_floor import (
    CHANCE_ABOVE,
    NON_REPEATABLE_FACTOR,
    Floors,
    robust_summary,
    verdict,
)
from stiffnet.measurement.significance import significance

sys.path.insert(0, str(Path(__file__).parent))

FLOORS = np.array([0.1, 0.12, 0.08, 0.1, 0.09, 0.11, 0.1, 0.1, 2.5, 6.0])  # two wander


def test_non_repeatable_recordings_are_flagged_and_weighted_down():
    f = Floors(FLOORS)
    assert f.median == pytest.approx(0.1)
    assert f.non_repeatable().tolist() == [False] * 8 + [True, True]
    w = f.weights()
    assert np.all(w[:8] == 1.0)
    limit = NON_REPEATABLE_FACTOR * 0.1
    assert w[8:] == pytest.approx([limit / 2.5, limit / 6.0])


def test_judge_is_a_binomial_sign_test_on_the_repeatable_recordings():
    f = Floors(FLOORS)
    per = FLOORS * 0.8  # every recording within its own floor
    per[8:] = [20.0, 50.0]  # the wandering ones far above theirs: reported, not counted
    j = f.judge(per)
    assert j["n"] == 8 and j["n_above"] == 0 and j["at_floor"]
    per[:3] = FLOORS[:3] * 5  # three of eight repeatable recordings above 2x their floor
    j = f.judge(per)
    assert j["n_above"] == 3
    assert j["p_value"] == pytest.approx(binom.sf(2, 8, CHANCE_ABOVE))
    assert not j["at_floor"]  # p = 0.038
    per[1:3] = FLOORS[1:3]  # one above is what chance gives
    assert f.judge(per)["at_floor"]


def test_verdict_nothing_missing_despite_non_repeatable_outliers():
    """The old rule (mean residual vs median floor) called this campaign incomplete."""
    f = Floors(FLOORS)
    base = FLOORS * 0.5
    base[8:] = [4.0, 12.0]
    assert np.mean(base) > 2 * f.median  # what the mean-based verdict saw
    v = verdict(base, base, f, [], [None] * base.size)
    assert v["verdict"] == "nothing_missing", v["summary"]
    assert v["residual_summary"]["median"] == pytest.approx(np.median(base))


def test_verdict_explained_and_robust_explained_fraction():
    f = Floors(FLOORS)
    base = FLOORS * 20
    res = FLOORS * 1.2
    res[9] = 30.0  # a non-repeatable recording left far off weighs little
    where = [{"contact": 1.0, "free_flight": 0.0, "sensor_band": 0.0, "spectrum": 0.0}] * 10
    v = verdict(base, res, f, ["contact_damping"], where)
    assert v["verdict"] == "explained", v["summary"]
    assert v["explained_fraction"] > 0.9
    # the same residual on every repeatable recording: partially explained, where it lives
    res = FLOORS * 5
    v = verdict(base, res, f, ["contact_damping"], where)
    assert v["verdict"] == "partially_explained"
    assert v["unexplained_where"]["contact"] == pytest.approx(1.0)
    assert 0.5 < v["explained_fraction"] < 0.95


def test_significance_counts_excess_over_each_recordings_own_floor():
    f = Floors(FLOORS)
    before = FLOORS * 10
    after = before.copy()
    after[9] = 0.0  # only the non-repeatable recording improves: carried by one, tiny weight
    sig = significance(before, after, 1, f)
    assert not sig["significant"]
    after = FLOORS * 1.0
    sig = significance(before, after, 1, f)
    assert sig["significant"] and sig["excess_reduction"] == pytest.approx(1.0)


def test_robust_summary():
    s = robust_summary(np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 100.0]))
    assert s["median"] == 1.0 and s["trimmed_mean"] == pytest.approx(1.0)
    assert s["mean"] == pytest.approx(10.9)


@pytest.mark.slow
def test_ideal_independent_rig_with_non_repeatable_recordings_is_nothing_missing(tmp_path):
    """An ideal campaign from the independent solve_ivp rig holding a wandering
    near-grazing recording (β 40 at 1.6 f_n, gap 0.6 mm: its halves differ ~500x the
    campaign's median floor) and orbits of 5 impacts every 4 and 3 every 4 periods."""
    from independent_rig import write_campaign
    from test_independent_rig import POINTS, _runs

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.diagnose import diagnose_campaign

    points = [POINTS[0], POINTS[4], POINTS[6], POINTS[7]]
    points += [(40, 1.6, 1.9, 0.6, 1000), (60, 0.6, 1.9, 1.0, 1000), (25, 2.2, 1.9, 0.3, 1000)]
    runs = _runs(points, duration_s=4.0)
    for i, r in enumerate(runs):
        r.recording = f"rec/r{i:02d}_b{r.beta}.csv"
    d = diagnose_campaign(load_campaign(write_campaign(tmp_path / "ideal", runs)), effects=[])
    assert d["verdict"] == "nothing_missing", d["summary"]
    recs = {r["recording"]: r for r in d["per_recording"]}
    assert recs["rec/r04_b40.csv"]["non_repeatable"]
    assert "non-repeatable" in recs["rec/r04_b40.csv"]["note"]
    assert "non-repeatable" in d["summary"]
    assert recs["rec/r05_b60.csv"]["measured_orbit"] == "5 impacts every 4 forcing periods"
    assert all(r["orbit_matched"] in (True, None) for r in d["per_recording"])


@pytest.mark.slow
def test_recording_on_a_coexisting_orbit_is_named_and_nothing_missing(tmp_path):
    """β 55 at 1.05 f_n settles, from rest, on the coexisting orbit of two impacts every
    three forcing periods (the rig's solve_ivp); the starts reach it, the diagnosis names
    it for the measurement and the chosen simulation, and finds nothing missing."""
    from independent_rig import write_campaign
    from test_independent_rig import POINTS, _runs

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.diagnose import diagnose_campaign

    runs = _runs([POINTS[i] for i in (0, 4, 5, 7)], duration_s=3.0)
    d = diagnose_campaign(load_campaign(write_campaign(tmp_path / "orbit", runs)), effects=[])
    assert d["verdict"] == "nothing_missing", d["summary"]
    rec = next(r for r in d["per_recording"] if r["recording"].endswith("beta055.csv"))
    assert rec["measured_orbit"] == "2 impacts every 3 forcing periods"
    assert rec["simulated_orbit"] == rec["measured_orbit"] and rec["orbit_matched"]
    assert rec["distinct_orbits"] >= 2 and rec["starts_on_measured_orbit"] >= 1
    assert "No start reached" not in d["summary"]


def test_a_measured_orbit_no_start_reached_is_said_plainly():
    from stiffnet.measurement.diagnose import _orbit_warning

    recs = [{"recording": "a.csv", "starts_on_measured_orbit": 0},
            {"recording": "b.csv", "starts_on_measured_orbit": 3},
            {"recording": "c.csv", "starts_on_measured_orbit": None}]  # fmt: skip
    text = _orbit_warning(recs)
    assert "No start reached the measured orbit of a.csv" in text
    assert "b.csv" not in text and "c.csv" not in text
    assert "before concluding anything about physics" in text
    assert _orbit_warning(recs[1:]) == ""


@pytest.mark.slow
def test_damped_contact_and_sensor_resonance_at_three_operating_points_is_explained(tmp_path):
    """Contact damping 0.25 and a mounted resonance at 237 Hz (25 f_n) on the independent
    rig, whose sensor chain is analog, at three operating points logged at 2 kHz. One
    operating point (forcing at f_n, the cleanest orbit) used to stay at 50-160x its floor:
    the fitted 1-Hz high-pass started from rest at the first sample (power below the
    forcing the recording lacks) and a filter run at the logger's rate. Measured after the
    fix: explained, 0.253 and 235.8 Hz (3 recordings per point; 2 here)."""
    from independent_rig import write_campaign
    from test_independent_rig import _runs

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.diagnose import diagnose_campaign

    ops = [(1.05, 1.9, 2.8, 2000), (1.0, 1.2, 1.2, 2000), (0.98, 1.5, 1.6, 2000)]
    points = [(b, w, a, e, fs) for (w, a, e, fs) in ops for b in (30, 70)]
    sensor = {"resonance_hz": 237.0, "resonance_damping": 0.03}
    runs = _runs(points, 3.0, contact="kelvin_voigt", contact_zeta=0.25, sensor=sensor)
    for i, r in enumerate(runs):
        r.recording = f"rec/op{i // 2}_b{r.beta:03d}.csv"
    d = diagnose_campaign(
        load_campaign(write_campaign(tmp_path / "ops", runs)),
        effects=["contact_damping", "sensor_dynamics"], inclination=False,
    )  # fmt: skip
    # measured: explained (2 of 4 repeatable recordings above 2x their floors, p = 0.052),
    # the sensor's high-pass corner fitted at 0.14 Hz (the rig has none: a 0.8 degree lead
    # at the forcing); with a 1-Hz high-pass assumed in the fit the verdict was
    # partially_explained (median 0.21). Borderline for a reason outside the sensor: the
    # corner mostly buys the comparisons' longer lead-in (3 s against 0.1 s at no corner),
    # and op0/op1's simulated orbits depend on where the record starts (truth model, no
    # corner: op0 0.196/0.172 at a 0.1 s lead-in, 0.077/0.073 at 3 s; one op1 recording
    # 0.036 at 3.0 s, 3.5 at 3.3 s). With the free-run rule on every map the mount damping
    # read 0.0281, the fit ended at no corner and the verdict partially_explained.
    assert d["verdict"] == "explained", d["summary"]
    assert d["explained_fraction"] > 0.9, d["summary"]
    assert d["residual_summary"]["median"] < 0.15, d["summary"]  # measured 0.072
    fit = d["fitted_params"]
    # measured 0.262 and 236.6 Hz
    assert fit["contact_damping"]["damping_ratio"] == pytest.approx(0.25, rel=0.15)
    assert fit["sensor_dynamics"]["resonance_hz"] == pytest.approx(237.0, rel=0.05)
    assert fit["sensor_dynamics"]["highpass_hz"] < 0.5
    by_op = {}
    for r in d["per_recording"]:
        by_op.setdefault(r["recording"][4:7], []).append(r["residual"])
    worst = {op: max(v) for op, v in by_op.items()}
    # before the fixes op1 reached 1.5-3.2 with the others at 0.2-1.2; 0.35 / 1.29 / 0.88
    # with the assumed 1-Hz high-pass; measured with the corner fitted: 0.04 / 0.08 / 0.14
    assert max(worst.values()) < 0.5, worst

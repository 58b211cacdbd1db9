"""The sensor chain: identified from the impacts, given by a data sheet, undone, refused.

Recordings come from stiffnet's simulator and from the independent solve_ivp rig
(tests/independent_rig.py) whose chain is scipy.signal's, run on an oversampled motion
(the analog chain before the converter).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from serving.restoring_force_check import sensor_outside_priors, with_sensor_check
from stiffnet.errors import ConfigError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.chain import (
    MAX_GAIN,
    SensorChain,
    chain_response,
    contact_pulse,
    deconvolve,
    identifiability,
    inverse_noise_sigma,
    sensor_from_mapping,
    shared_chain,
)
from tests.independent_rig import RigRun, record

FN = 9.48


# --- analytic pieces --------------------------------------------------------------------


def test_deconvolve_inverts_a_known_chain_within_its_band():
    fs, n = 2000.0, 4000
    t = np.arange(n) / fs
    x = (
        np.sin(2 * np.pi * 10 * t)
        + 0.3 * np.cos(2 * np.pi * 150 * t)
        + 0.1 * np.sin(2 * np.pi * 400 * t)
    )
    chain = SensorChain(resonance_hz=300.0, resonance_damping=0.05, lowpass_hz=250.0,
                        lowpass_order=4)  # fmt: skip
    freqs = np.fft.rfftfreq(n, 1 / fs)
    y = np.fft.irfft(np.fft.rfft(x) * chain_response(chain, freqs), n)  # exact, periodic
    assert np.max(np.abs(y - x)) > 0.1  # the chain does change the record
    np.testing.assert_allclose(deconvolve(y, fs, chain, noise_sigma=1e-9), x, atol=1e-6)


def test_deconvolve_leaves_bands_of_pure_noise_alone():
    rng = np.random.default_rng(0)
    fs, n = 2000.0, 8000
    y = rng.standard_normal(n)  # nothing but white noise of unit variance
    chain = SensorChain(lowpass_hz=50.0, lowpass_order=4)
    out = deconvolve(y, fs, chain, noise_sigma=1.0)
    freqs = np.fft.rfftfreq(n, 1 / fs)
    plain = np.fft.irfft(np.fft.rfft(y) / chain_response(chain, freqs), n)
    assert np.std(plain) > 1e4  # the plain inverse: up to (f / 50)^4 = 1e8 at Nyquist
    assert np.std(out) < 0.25 * MAX_GAIN  # the Wiener weight: bounded, mostly switched off


def test_a_known_chains_inverse_is_weighted_by_the_lower_of_the_scatter_and_the_band_top():
    """White noise of 0.03 under a 100 Hz sinusoid: behind a known mount the top of the band
    reads the noise, and a free-flight scatter above it (the mount's ringing) gives way to it,
    one below it stands; a fitted chain, a sheet fitted to recordings (a campaign's pooled
    chain), and a known low-pass alone keep the scatter."""
    rng = np.random.default_rng(1)
    fs, n = 2000.0, 8000
    y = np.sin(2 * np.pi * 100 * np.arange(n) / fs) + rng.normal(0.0, 0.03, n)
    sheet = SensorChain(resonance_hz=300.0, resonance_damping=0.05, source="data sheet")
    assert inverse_noise_sigma(y, fs, sheet, 1.0) == pytest.approx(0.03, rel=0.1)
    assert inverse_noise_sigma(y, fs, sheet, 0.01) == 0.01
    fitted = dataclasses.replace(sheet, source="fitted")
    assert inverse_noise_sigma(y, fs, fitted, 1.0) == 1.0
    pooled = sensor_from_mapping({"resonance_hz": 300.0, "resonance_damping": 0.05}, fs,
                                 fitted_sheet=True)  # fmt: skip
    assert pooled.source == "data sheet" and pooled.fitted_sheet
    assert inverse_noise_sigma(y, fs, pooled, 1.0) == 1.0
    lowpass = SensorChain(lowpass_hz=300.0, lowpass_order=4, source="data sheet")
    assert inverse_noise_sigma(y, fs, lowpass, 1.0) == 1.0  # no ringing: the scatter stands


def test_contact_pulse_is_a_half_sine_for_an_elastic_contact():
    w_hz = 50.0
    t = np.linspace(-0.002, 0.02, 2000)
    f = contact_pulse(t, w_hz, 1e-6)
    w = 2 * np.pi * w_hz
    inside = (t >= 0) & (t < np.pi / w)
    np.testing.assert_allclose(f[inside], w * np.sin(w * t[inside]), rtol=1e-4, atol=1e-3)
    assert np.all(f[~inside] == 0)


def test_refusal_names_the_lowpass_and_the_contact_frequency():
    chain = SensorChain(lowpass_hz=30.0, lowpass_order=4, contact_hz=52.8)
    assert identifiability(chain) == (
        "the low-pass at 30 Hz is below the contact's frequency 53 Hz: beta is not "
        "identifiable from this sensor"
    )
    assert identifiability(SensorChain(lowpass_hz=120.0, lowpass_order=2, contact_hz=52.8)) == ""


def test_the_contact_law_fitted_through_a_band_reads_the_law_the_band_smeared():
    """A linear contact's force (K 400 beyond an onset of 0.9) through a 4th-order low-pass and
    a cut-off above 150 Hz (what an inverse keeps of it): fitted through that band the law is
    read exactly; fitted as it is, the smeared and delayed pulses fit no law."""
    from stiffnet.restoring_force.contact_law import (
        contact_force,
        fit_contact_law,
        linear_contact_start,
    )

    fs, n = 1000.0, 2000
    t = np.arange(n) / fs
    x, v = np.sin(2 * np.pi * 10.0 * t), 2 * np.pi * 10.0 * np.cos(2 * np.pi * 10.0 * t)
    freqs = np.fft.rfftfreq(n, 1 / fs)
    band = chain_response(SensorChain(lowpass_hz=60.0, lowpass_order=4), freqs) * (freqs < 150)
    seen = np.fft.irfft(np.fft.rfft(contact_force(x, v, 400.0, 0.9, 0.0)) * band, n)
    start = linear_contact_start(seen, x, v, seen > 0.1 * seen.max())
    near = x > 0.6
    through = fit_contact_law(seen, x, v, near, start, 0.1, 1.0, band=band)
    assert through.stiffness == pytest.approx(400.0, rel=0.01)
    assert through.onset == pytest.approx(0.9, abs=0.01) and through.r2 > 0.99
    plain = fit_contact_law(seen, x, v, near, start, 0.1, 1.0)
    assert plain.r2 < 0.5 and not plain.stiffness == pytest.approx(400.0, rel=0.1)


def test_data_sheet_mapping_checks_its_keys():
    c = sensor_from_mapping({"resonance_hz": 1500, "lowpass_hz": 400, "highpass_hz": 1}, 2000.0)
    assert (c.resonance_hz, c.resonance_damping, c.lowpass_order) == (None, None, 2)
    assert c.lowpass_hz == 400 and c.highpass_hz == 1 and c.source == "data sheet"
    with pytest.raises(ValueError, match="unknown sensor key"):
        sensor_from_mapping({"resonance": 1500}, 2000.0)
    with pytest.raises(ValueError, match="lowpass_order must be an integer"):
        sensor_from_mapping({"lowpass_hz": 400, "lowpass_order": 2.5}, 2000.0)
    with pytest.raises(ValueError, match="resonance_damping"):
        sensor_from_mapping({"resonance_hz": 500, "resonance_damping": 3}, 2000.0)
    with pytest.raises(ConfigError, match="unknown sensor key"):
        restoring_force_estimate(np.sin(np.arange(4000) * 0.03), 2000.0, sensor={"f": 1})


def test_shared_chain_is_the_median_of_the_recordings_that_show_a_stage():
    chains = [
        {"resonance_hz": 400.0, "resonance_damping": 0.04, "lowpass_hz": None, "highpass_hz": 1.0},
        {"resonance_hz": 420.0, "resonance_damping": 0.06, "lowpass_hz": 900.0, "highpass_hz": 1.2},
        {"resonance_hz": 410.0, "resonance_damping": 0.05, "lowpass_hz": None, "highpass_hz": 0.0},
        None,
    ]
    out = shared_chain(chains)
    assert out["n"] == 3 and out["resonance_hz"] == 410.0 and out["resonance_damping"] == 0.05
    assert out["lowpass_hz"] is None  # one recording of three: noise, not the shared sensor
    assert out["highpass_hz"] == pytest.approx(1.1)
    assert shared_chain([None, None]) is None


# --- the alarm's check against the training priors --------------------------------------

PRIORS = {
    "effects": [
        {
            "name": "sensor_dynamics",
            "params": {"resonance_damping": [0.01, 0.1], "highpass_hz": [0.0, 2.0]},
            "relative": {
                "resonance_hz": {"per": "natural_frequency", "range": [15.0, 300.0]},
                "lowpass_hz": {"per": "sampling_rate", "range": [0.15, 0.45]},
            },
        }
    ]
}


def test_sensor_outside_priors_says_which_stage():
    fs = 2000.0
    inside = {"resonance_hz": 40 * FN, "lowpass_hz": 0.3 * fs, "highpass_hz": 1.0}
    assert sensor_outside_priors(inside, PRIORS, fs, FN) is None
    score, words = sensor_outside_priors({"lowpass_hz": 0.05 * fs}, PRIORS, fs, FN)
    assert score == pytest.approx(np.log(3.0)) and "anti-alias low-pass at 100 Hz" in words
    score, words = sensor_outside_priors({"resonance_hz": 5 * FN}, PRIORS, fs, FN)
    assert "mount resonance" in words and score == pytest.approx(np.log(3.0))
    assert "high-pass" in sensor_outside_priors({"highpass_hz": 5.0}, PRIORS, fs, FN)[1]
    # a model trained without any chain: every chain is new to it; no card: nothing said
    assert sensor_outside_priors({"lowpass_hz": 900.0}, {"effects": []}, fs, FN) is not None
    assert sensor_outside_priors({"lowpass_hz": 90.0}, None, fs, FN) is None
    rejected = {"lowpass_hz": 0.05 * fs, "applied": False}  # the contact law said no
    assert sensor_outside_priors(rejected, PRIORS, fs, FN) is None


def test_sensor_check_fires_the_alarm():
    alarm = {"flag": False, "fired": [], "scores": {"embedding": 0.5},
             "thresholds": {"embedding": 1.0}, "message": "no alarm"}  # fmt: skip
    out = with_sensor_check(alarm, (1.1, "anti-alias low-pass at 100 Hz"))
    assert out["flag"] and out["fired"] == ["sensor"] and "100 Hz" in out["message"]
    assert with_sensor_check(alarm, None) is alarm


# --- recordings through known chains -----------------------------------------------------


def rig(sensor: dict, contact: str | None, fs: float = 2000.0, beta: float = 30.0):
    run = RigRun(recording="r.csv", beta=beta, fs_hz=fs, duration_s=3.0, contact=contact,
                 contact_zeta=0.15, sensor={**sensor, "oversample": 8})  # fmt: skip
    return record(run, seed=3)[1], fs


@pytest.mark.slow
@pytest.mark.parametrize("contact", [None, "kelvin_voigt"])
def test_a_mount_resonance_is_identified_and_undone(contact):
    """Independent rig, a resonance at 40 f_n (zeta 0.05): alone and with a damped contact."""
    accel, fs = rig({"resonance_hz": 40 * FN, "resonance_damping": 0.05}, contact)
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24)
    assert r.ok, r.reason
    assert r.sensor.source == "fitted" and r.sensor.applied
    assert r.sensor.resonance_hz == pytest.approx(40 * FN, rel=0.1)
    assert r.sensor.resonance_damping == pytest.approx(0.05, rel=0.5)
    lo, hi = r.sensor.intervals["resonance_hz"]
    assert lo < r.sensor.resonance_hz < hi
    assert r.beta == pytest.approx(30.0, rel=0.1)
    assert r.to_dict()["sensor"]["resonance_hz"] == pytest.approx(r.sensor.resonance_hz)
    json.dumps(r.to_dict(), allow_nan=False)  # JSON-safe (an unbounded interval is left out)


@pytest.mark.slow
def test_a_lowpass_and_highpass_are_identified_with_a_damped_contact():
    """Independent rig: low-pass at 0.25 fs (2nd order), 1 Hz high-pass, damped contact."""
    accel, fs = rig({"lowpass_hz": 500.0, "lowpass_order": 2, "highpass_hz": 1.0},
                    "kelvin_voigt")  # fmt: skip
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24)
    assert r.ok, r.reason
    assert r.sensor.lowpass_hz == pytest.approx(500.0, rel=0.1)
    assert r.beta == pytest.approx(30.0, rel=0.1)


@pytest.mark.slow
def test_data_sheet_chain_is_undone_as_given():
    """A 4th-order low-pass at 2 contact frequencies: read from its data sheet, beta within 10 %
    (stiffnet's own chain here), and a low-pass below the contact refused in one line
    (the independent rig)."""
    from tests.test_restoring_force import simulate

    sheet = {"resonance_hz": 50000.0, "highpass_hz": 0.0, "lowpass_hz": 0.1 * 300 * FN,
             "lowpass_order": 4}  # fmt: skip
    accel, fs = simulate(30.0, [("sensor_dynamics", sheet)], fs_ratio=300.0, noise=0.02,
                         periods=24, omega=1.05)  # fmt: skip
    given = {k: v for k, v in sheet.items() if k != "resonance_hz"}
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, sensor=given)
    assert r.ok, r.reason
    assert r.sensor.source == "data sheet" and r.beta == pytest.approx(30.0, rel=0.1)
    accel, fs = rig({"lowpass_hz": 30.0, "lowpass_order": 4}, "kelvin_voigt")
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                 sensor={"lowpass_hz": 30.0, "lowpass_order": 4})  # fmt: skip
    assert not r.ok and r.restoring_force_class is None  # refused, not "no contact"
    assert r.reason.startswith("the low-pass at 30 Hz is below the contact's frequency")
    assert "\n" not in r.reason


# --- the data sheet through the CLI and HTTP ---------------------------------------------


@pytest.fixture(scope="module")
def lowpassed_csv(tmp_path_factory):
    """A recording through a 4th-order low-pass at 0.1 fs (stiffnet's chain), as a CSV."""
    from tests.test_restoring_force import simulate

    chain = {"resonance_hz": 50000.0, "highpass_hz": 0.0, "lowpass_hz": 0.1 * 300 * FN,
             "lowpass_order": 4}  # fmt: skip
    accel, fs = simulate(30.0, [("sensor_dynamics", chain)], fs_ratio=300.0, noise=0.02,
                         periods=40, omega=1.05)  # fmt: skip
    path = tmp_path_factory.mktemp("rec") / "run.csv"
    t = np.arange(accel.size) / fs
    np.savetxt(path, np.column_stack([t, accel]), delimiter=",", header="t,accel", comments="")
    return path, accel, fs


@pytest.mark.slow
def test_cli_reads_a_data_sheet_and_refuses_a_bad_one(lowpassed_csv, tmp_path):
    from typer.testing import CliRunner

    from stiffnet.cli import app

    path, _, fs = lowpassed_csv
    out = tmp_path / "a.json"
    sheet = f"lowpass_hz={0.1 * fs},lowpass_order=4"
    res = CliRunner().invoke(
        app, ["analyze", str(path), "--fn", str(FN), "--sensor", sheet, "--json", str(out)]
    )
    assert res.exit_code == 0, res.output
    rf = json.loads(out.read_text())["restoring_force"]
    assert rf["sensor"]["source"] == "data sheet" and rf["sensor"]["lowpass_order"] == 4
    assert rf["beta"] == pytest.approx(30.0, rel=0.1)
    for bad, words in (("lowpass=3", "unknown sensor key"), ("lowpass_hz", "not KEY=VALUE"),
                       ("lowpass_hz=x", "is not a number")):  # fmt: skip
        res = CliRunner().invoke(app, ["analyze", str(path), "--sensor", bad])
        assert res.exit_code == 2 and words in res.output, res.output
        assert "Traceback" not in res.output


@pytest.mark.slow
def test_http_predict_takes_a_sensor_field(lowpassed_csv):
    from fastapi.testclient import TestClient

    from serving.app import Limits, create_app
    from serving.predictor import Predictor

    _, accel, fs = lowpassed_csv
    body = {"samples": accel.tolist(), "fs_hz": fs, "natural_frequency_hz": FN,
            "sensor": {"lowpass_hz": 0.1 * fs, "lowpass_order": 4}}  # fmt: skip
    with TestClient(create_app(Predictor.load(), Limits(max_upload_mb=4.0))) as client:
        r = client.post("/predict", json=body)
        assert r.status_code == 200, r.text
        restoring_force = r.json()["restoring_force"]
        assert restoring_force["sensor"]["source"] == "data sheet"
        assert restoring_force["beta"] == pytest.approx(30.0, rel=0.1)
        r = client.post("/predict", json={**body, "sensor": {"lowpass_hz": 100.0, "order": 2}})
        assert 400 <= r.status_code < 500 and "sensor" in r.json()["error"], r.text


@pytest.mark.slow
def test_identify_sensor_chain_gives_the_chain_alone():
    """diagnose's starting point for sensor_dynamics: stiffnet's chain, a 60 f_n mount."""
    from stiffnet.restoring_force import identify_sensor_chain
    from tests.test_restoring_force import simulate

    chain = {"resonance_hz": 60 * FN, "resonance_damping": 0.05, "highpass_hz": 0.0,
             "lowpass_hz": 0.0}  # fmt: skip
    accel, fs = simulate(30.0, [("sensor_dynamics", chain)], fs_ratio=300.0, noise=0.02,
                         periods=24, omega=1.05)  # fmt: skip
    got = identify_sensor_chain(accel, fs, FN)
    assert got is not None and got.source == "fitted"
    assert got.resonance_hz == pytest.approx(60 * FN, rel=0.1)
    assert identify_sensor_chain(np.zeros(5000), fs, FN) is None  # unreadable: nothing


def test_a_mount_resonance_at_three_contact_frequencies_is_not_read_as_a_lowpass():
    """Independent rig, a 187 Hz mount (zeta 0.076) over a 62 Hz contact at 2 % noise: its ring
    makes the record as recorded map a 152 Hz contact, which must not bound the fit's contact
    (a low-pass of order 3 at 106 Hz was read instead)."""
    from stiffnet.restoring_force import identify_sensor_chain

    mount = {"resonance_hz": 187.0, "resonance_damping": 0.076}
    run = RigRun(recording="r.csv", beta=41.6, fs_hz=1248.0, duration_s=3.0, gap_mm=1.7,
                 sensor=mount, noise=0.02)  # fmt: skip
    got = identify_sensor_chain(record(run, seed=3)[1], run.fs_hz, FN)
    assert got is not None and got.lowpass_hz is None
    assert got.resonance_hz == pytest.approx(187.0, rel=0.1)
    assert got.resonance_damping == pytest.approx(0.076, rel=0.5)


def test_a_fourth_order_lowpass_near_the_contact_is_recovered_with_its_order():
    """Independent rig, an elastic 62 Hz contact behind an 84.6 Hz 4th-order low-pass at 2 %
    noise (a campaign of rig_campaigns): the free-flight law reads the filtered pulses' tails
    as free damping, and the chain fit, not modelling the velocity step that leaves in each
    impact's window, read the corner at 96.9 Hz (14.5 % high) with a damped contact."""
    from stiffnet.restoring_force import identify_sensor_chain

    run = RigRun(recording="r.csv", beta=41.6, fs_hz=1248.0, duration_s=3.0, gap_mm=1.7,
                 sensor={"lowpass_hz": 84.6, "lowpass_order": 4}, noise=0.02)  # fmt: skip
    got = identify_sensor_chain(record(run, seed=3)[1], run.fs_hz, FN)
    assert got is not None and got.resonance_hz is None
    assert got.lowpass_order == 4
    assert got.lowpass_hz == pytest.approx(84.6, rel=0.1)


def test_a_mounts_highpass_is_the_corner_of_the_map_that_was_read():
    """Independent rig, a lab mount (237 Hz, zeta 0.05) with a 1 Hz high-pass, beta 36: the
    chain reported the corner fitted on the record as recorded, its ring not yet divided out
    (here none; 3-4 Hz on 4 of bench_alarm's 24 such records, above the model's 2 Hz prior:
    the sensor check fired on right answers), not that of the map beta was read from."""
    from serving.restoring_force_check import restoring_force_check

    mount = {"resonance_hz": 237.0, "resonance_damping": 0.05, "highpass_hz": 1.0}
    run = RigRun(recording="r.csv", beta=36.32, noise=0.0255, forcing_frequency_hz=10.28,
                 duration_s=8.0, sensor=mount)  # fmt: skip
    check = restoring_force_check(record(run, seed=7)[1], run.fs_hz, FN, None, None)
    sensor = check["sensor"]
    assert sensor["resonance_hz"] == pytest.approx(237.0, rel=0.02)
    assert 0.5 < sensor["highpass_hz"] < 2.0
    assert check["beta"] == pytest.approx(36.32, rel=0.1)


# --- lab chains (all three stages) through the independent rig ---------------------------


@pytest.mark.slow
def test_a_steep_lowpass_near_the_contact_is_not_read_as_a_resonance():
    """A lab chain: 4th-order low-pass at 0.068 fs (3 contact frequencies), a 4 Hz high-pass
    and a mount above Nyquist. A lightly damped resonance mimics the low-pass's overshoot
    within the pulse's window; the low-pass structure must win, and beta is right or
    refused (never a silent half of it)."""
    sensor = {"resonance_hz": 1035.8, "resonance_damping": 0.042, "lowpass_hz": 100.94,
              "lowpass_order": 4, "highpass_hz": 3.96, "oversample": 8}  # fmt: skip
    run = RigRun(recording="r.csv", beta=22.38, fs_hz=1490.9, duration_s=3.0,
                 forcing_frequency_hz=9.803, base_acceleration_g=0.81, gap_mm=2.078,
                 sensor=sensor)  # fmt: skip
    accel = record(run, seed=11)[1]
    r = restoring_force_estimate(accel, run.fs_hz, natural_frequency_hz=FN, max_periods=24)
    assert r.sensor.resonance_hz is None
    assert r.sensor.lowpass_hz == pytest.approx(100.94, rel=0.1)
    assert (not r.ok and "\n" not in r.reason) or r.beta == pytest.approx(22.38, rel=0.1)


@pytest.mark.slow
@pytest.mark.parametrize("highpass_hz", [0.0, 3.0])
def test_a_charge_amplifier_highpass_is_found_and_none_is_invented(highpass_hz):
    """Independent rig, elastic contact, beta 30: a 3 Hz high-pass (the analog chain in its
    steady state) is found within 10 % and beta within 10 %; without one, none is reported."""
    sensor = {"highpass_hz": highpass_hz, "oversample": 4} if highpass_hz else None
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=1000.0, duration_s=3.0, sensor=sensor)
    accel = record(run, seed=3)[1]
    r = restoring_force_estimate(accel, run.fs_hz, natural_frequency_hz=FN, max_periods=24)
    assert r.ok, r.reason
    assert r.highpass_hz == pytest.approx(highpass_hz, rel=0.1, abs=0.05)
    assert r.beta == pytest.approx(30.0, rel=0.1)


@pytest.mark.slow
def test_a_sheet_that_leaves_the_highpass_to_the_record_fits_its_corner():
    """Independent rig, elastic contact, beta 30, a mount resonance at 20 f_n and a 3.5 Hz
    charge amplifier: a sheet with the resonance and ``highpass_hz: "auto"`` (a campaign's
    pooled chain) finds the corner within 10 % and beta within 10 %, as the true sheet does.
    The same sheet with the high-pass held at 0 drifts the map below the softest class (beta
    3.2): the joint soft-contact fit, with the sheet's resonance applied to its model, reads it
    (30.9 [23.9, 39.9]; through no chain it read 25.5 with an interval of 5.6-116)."""
    from serving.restoring_force_check import check_sensor_sheet
    from stiffnet.restoring_force.chain import HIGHPASS_FITTED

    chain = {"resonance_hz": 20 * FN, "resonance_damping": 0.06, "highpass_hz": 3.5}
    accel, fs = rig(chain, None, fs=1500.0)
    sheet = {**chain, "highpass_hz": HIGHPASS_FITTED}
    assert check_sensor_sheet(sheet, fs) == sheet  # the predictor's check keeps "auto"
    auto = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                    sensor=sheet)  # fmt: skip
    assert auto.ok, auto.reason
    assert auto.sensor.source == "data sheet"
    assert auto.sensor.highpass_hz == pytest.approx(3.5, rel=0.1) == auto.highpass_hz
    assert auto.beta == pytest.approx(30.0, rel=0.1)
    held = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                    sensor={**chain, "highpass_hz": 0.0})  # fmt: skip
    assert held.highpass_hz == 0.0
    assert held.ok, held.reason
    assert "fitted jointly" in held.reason
    lo, hi = held.beta_interval
    assert lo <= 30.0 <= hi and hi / lo < 2.0


# --- "no contact" behind a low-pass ------------------------------------------------------


@pytest.mark.parametrize("contact", [None, "kelvin_voigt"])
def test_contacts_a_lowpass_smooths_away_are_refused_not_read_as_no_contact(contact):
    """Independent rig, beta 30 (contact 53 Hz) behind a 4th-order low-pass at 30 Hz and no
    data sheet: no impact stands out of the free flight, yet the impacts' harmonics 4-8
    do (a free flight has none beyond the shaker's 3rd): refused in one line, not "no
    contact" (which would be a silent wrong answer)."""
    accel, fs = rig({"lowpass_hz": 30.0, "lowpass_order": 4}, contact)
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24)
    assert not r.ok and r.restoring_force_class is None
    assert "low-pass below the contact's frequency" in r.reason
    assert "beta is not identifiable from this sensor" in r.reason and "\n" not in r.reason


@pytest.mark.parametrize("effect", ["forcing_harmonics", "sensor_dynamics"])
def test_a_free_flight_with_harmonics_of_its_own_is_still_no_contact(effect):
    """No contact (gap 30): the shaker's 2nd and 3rd harmonics (the free-flight law's) or the
    default sensor chain leave "no contact" as it was."""
    from tests.test_restoring_force import simulate

    accel, fs = simulate(30.0, [(effect, {})], gap=30.0, noise=0.02)
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN)
    assert r.restoring_force_class == "no_contact" and r.reason.startswith("no contact")


def test_excess_harmonics_reads_a_pulse_train_and_not_a_sinusoid():
    """Analytic: 20 periods of a sinusoid at harmonic 1 plus its 3rd carry no harmonic beyond
    the 3rd; a train of half-sine pulses (one per period) carries every one up to its band
    and refuses; a symmetric force (a rounded square wave, dry friction's odd harmonics
    only) does not."""
    from stiffnet.restoring_force.band import excess_harmonics, smoothed_contact_refusal

    period, n = 200, 4000
    t = np.arange(n) / period
    rng = np.random.default_rng(0)
    smooth = np.sin(2 * np.pi * t) + 0.1 * np.sin(6 * np.pi * t) + 0.01 * rng.standard_normal(n)
    assert excess_harmonics(smooth, period).size == 0
    phase = (t % 1.0) * period
    pulses = np.where(phase < 10, np.sin(np.pi * phase / 10), 0.0) + 0.01 * rng.standard_normal(n)
    found = excess_harmonics(pulses, period)
    assert {4, 5, 6, 7} <= set(found.tolist())
    assert "not identifiable" in smoothed_contact_refusal(pulses, period, 2000.0, 10.0, 5.0)
    square = np.tanh(5 * np.sin(2 * np.pi * t)) + 0.01 * rng.standard_normal(n)
    odd = excess_harmonics(square, period)
    assert odd.size >= 2 and np.all(odd % 2 == 1)
    assert smoothed_contact_refusal(square, period, 2000.0, 10.0, 5.0) == ""


def test_the_smoothed_contact_refusal_names_the_low_pass_only_where_it_may_be_the_cause():
    """Analytic pulse train (contacts at 100 Hz, f_n 10 Hz, 2 kHz): with no chain known the
    reason names both causes, a low-pass or contacts too soft to stand out ("this sensor",
    the chain_refusal alarm's words); a known chain whose low-pass passes every contact up
    to beta 100 (100.5 Hz), or has none, leaves the contacts alone ("this record"); a known
    low-pass below that is still named."""
    from stiffnet.restoring_force.band import smoothed_contact_refusal

    period, n = 200, 4000
    phase = (np.arange(n) % period).astype(float)
    rng = np.random.default_rng(0)
    pulses = np.where(phase < 10, np.sin(np.pi * phase / 10), 0.0) + 0.01 * rng.standard_normal(n)
    unknown = smoothed_contact_refusal(pulses, period, 2000.0, 10.0, 5.0, 100.0)
    assert "too soft or shallow" in unknown and "low-pass below the contact's frequency" in unknown
    assert unknown.endswith("from this sensor")
    for corner, words in ((284.0, "(284 Hz)"), (np.inf, "(none in the band)")):
        known = smoothed_contact_refusal(pulses, period, 2000.0, 10.0, 5.0, 100.0, corner)
        assert words in known and "beta 100 (100 Hz)" in known
        assert known.endswith("from this record") and "this sensor" not in known
    low = smoothed_contact_refusal(pulses, period, 2000.0, 10.0, 5.0, 100.0, 60.0)
    assert low == unknown


def test_the_softest_contact_behind_a_known_sensor_is_read_not_blamed_on_the_sensor():
    """Independent rig, beta 5.8 (contact 25 Hz) behind the rig campaign's 284 Hz order-4
    low-pass and 610 Hz resonance, its data sheet given: no impact stands out of the free
    flight (as on the ideal rig without noise), and the sheet's low-pass passes every
    contact, so the free flight and the contact are fitted jointly
    (:mod:`~stiffnet.restoring_force.soft_contact`): the soft class, an interval covering
    5.8, and the chain_refusal alarm, which judges the sensor's band, stays quiet."""
    from stiffnet.uncertainty.alarm_verdict import chain_refusal_excess

    sheet = {"resonance_hz": 609.6, "resonance_damping": 0.062, "lowpass_hz": 283.8,
             "lowpass_order": 4, "highpass_hz": 3.62}  # fmt: skip
    run = RigRun(recording="r.csv", beta=5.8, fs_hz=3257.0, duration_s=3.0, gap_mm=1.0,
                 sensor=sheet)  # fmt: skip
    accel = record(run, seed=1)[1]
    r = restoring_force_estimate(accel, 3257.0, natural_frequency_hz=FN, max_periods=24,
                                 sensor=sheet)  # fmt: skip
    assert r.ok and r.restoring_force_class == "soft", r.reason
    assert r.beta_interval[0] <= 5.8 <= r.beta_interval[1]
    assert "too soft to stand out" in r.reason and "\n" not in r.reason
    priors = {"effects": [{"name": "sensor_dynamics",
                           "relative": {"lowpass_hz": {"per": "sampling_rate",
                                                       "range": [0.15, 0.45]}}}]}  # fmt: skip
    assert chain_refusal_excess(r.to_dict(), priors, 3257.0) is None


@pytest.mark.parametrize("engine", ["stiffnet", "rig"])
def test_a_data_sheet_lowpass_at_three_contact_frequencies_reads_beta(engine):
    """A 4th-order low-pass at 160 Hz (3 contact frequencies, 0.056 fs) from its data sheet:
    the inverse's ripple around each pulse split one or two free samples off the contact,
    each flight's own displacement line then rested on them and beta was refused ("the
    contact force does not grow with the displacement"); within 10 % now, on stiffnet's
    chain and on the independent rig's analog one."""
    from tests.test_restoring_force import simulate

    sheet = {"lowpass_hz": 160.0, "lowpass_order": 4}
    if engine == "rig":
        accel, fs = rig(sheet, None, fs=300 * FN)
    else:
        accel, fs = simulate(30.0, [("sensor_dynamics", {**sheet, "resonance_hz": 5e4,
                                                         "highpass_hz": 0.0})],
                             fs_ratio=300.0, noise=0.02, periods=24, omega=1.05)  # fmt: skip
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24, sensor=sheet)
    assert r.ok, r.reason
    assert r.beta == pytest.approx(30.0, rel=0.1)


# --- the low-pass the impacts cannot exclude -----------------------------------------------


def _pulse_train(noise_sigma: float, lowpass_order: int | None = None, fs: float = 2000.0):
    """Residual force of 56 elastic 50 Hz contacts (unit impact velocity, peak ~300) at
    sub-sample onsets, optionally through a Butterworth low-pass at 2 contact frequencies,
    plus white noise: what :func:`fit_chain` reads."""
    from scipy import signal

    from stiffnet.restoring_force.chain import OVERSAMPLE, chain_sos

    fine = fs * OVERSAMPLE
    pulse = contact_pulse(np.arange(int(0.1 * fine)) / fine, 50.0, 0.0, 0.0, FN)
    if lowpass_order:
        sos = chain_sos(SensorChain(lowpass_hz=100.0, lowpass_order=lowpass_order), fine)
        pulse = signal.sosfilt(sos, pulse)
    force = np.zeros(12000)
    for k, t0 in enumerate(np.arange(0.2, 5.8, 0.1)):
        i0 = int(t0 * fs)
        force[i0 : i0 + 200] += np.interp(np.arange(200) + (0.37 * k) % 1,
                                          np.arange(pulse.size) / OVERSAMPLE, pulse)  # fmt: skip
    force += noise_sigma * np.random.default_rng(0).standard_normal(force.size)
    return force, force > 4 * max(noise_sigma, 0.025), fs


@pytest.mark.slow
def test_an_identified_lowpass_leaves_no_lower_one_open():
    """A 4th-order low-pass at 2 contact frequencies, nearly noise-free: identified within
    10 % (order 4), and no lower corner of either profiled order fits as well."""
    from stiffnet.restoring_force.chain import fit_chain

    force, core, fs = _pulse_train(0.02, lowpass_order=4)
    c = fit_chain(force, core, fs, FN, fs / 100.0, noise_sigma=0.02)
    assert c.lowpass_hz == pytest.approx(100.0, rel=0.1) and c.lowpass_order == 4
    assert c.lowpass_not_excluded == ()


def test_noise_leaves_lower_lowpass_corners_open():
    """Chain-free pulses: nearly noise-free, no low-pass up to 12 contact frequencies fits as
    well as none; the noisier the record, the lower the corner (per order) it cannot exclude,
    and a 2nd-order one always lower than a 4th-order one (gentler, so less visible)."""
    from stiffnet.restoring_force.chain import fit_chain

    lowest = []
    for sigma in (0.02, 3.0, 40.0):
        force, core, fs = _pulse_train(sigma)
        c = fit_chain(force, core, fs, FN, fs / 100.0, noise_sigma=sigma)
        assert not c.has_dynamics
        lowest.append(dict(c.lowpass_not_excluded))
        assert c.to_dict()["lowpass_not_excluded"] == [
            {"order": o, "hz": f} for o, f in c.lowpass_not_excluded
        ]
    assert lowest[0] == {}
    assert set(lowest[1]) == set(lowest[2]) == {2, 4}
    for order in (2, 4):
        assert lowest[2][order] < lowest[1][order]
    assert lowest[1][2] < lowest[1][4] and lowest[2][2] < lowest[2][4]


@pytest.mark.slow
def test_a_lowpass_the_fit_cannot_see_still_bounds_beta():
    """Independent rig (bench_crosscheck's rig_chains #8): beta 7.78 behind a 3rd-order
    145 Hz low-pass (5 contact frequencies), a 0.37 Hz high-pass and a mount above Nyquist.
    The chain-free pulses fit within the noise floor, so no chain is fitted, and the map
    reads 8.4; the interval used to be the bootstrap's alone (8.0-8.8). The low-passes the
    impacts cannot exclude (2nd order near 107 Hz, 4th order near 207 Hz) now bound it."""
    sensor = {"resonance_hz": 1597.73, "resonance_damping": 0.0832, "lowpass_hz": 144.685,
              "lowpass_order": 3, "highpass_hz": 0.3724}  # fmt: skip
    run = RigRun(recording="r.csv", beta=7.780985785073243, fs_hz=2078.9479613976932,
                 duration_s=3.0, gap_mm=2.1053183865925034, sensor=sensor)  # fmt: skip
    accel = record(run, seed=20261135)[1]
    r = restoring_force_estimate(accel, run.fs_hz, natural_frequency_hz=FN)
    assert r.ok, r.reason
    assert not r.sensor.has_dynamics
    corners = dict(r.sensor.lowpass_not_excluded)
    assert set(corners) == {2, 4}
    assert corners[2] < corners[4] < 2 * 144.685
    assert r.beta > 7.78 * 1.05  # still read high: the interval, not beta, tells
    assert r.beta_interval[0] <= 7.78 <= r.beta_interval[1]


# --- a chain that starts from rest with the logger -----------------------------------------


@pytest.mark.parametrize("order", [2, 4])
def test_settling_samples_are_a_few_group_delays_of_the_lowpass(order):
    """A Butterworth low-pass's DC group delay is sum_k sin((2k-1) pi / 2N) / w_c (analog;
    sqrt(2)/w_c for N = 2); the record is read from SETTLE_DELAYS of them on. A resonance
    alone (its start-up ring carries almost no area) and no chain skip nothing."""
    from stiffnet.restoring_force.chain import SETTLE_DELAYS, settling_samples

    fs, fc = 2000.0, 100.0
    k = np.arange(1, order + 1)
    delay = np.sum(np.sin((2 * k - 1) * np.pi / (2 * order))) / (2 * np.pi * fc / fs)
    chain = SensorChain(lowpass_hz=fc, lowpass_order=order)
    assert settling_samples(chain, fs) == pytest.approx(SETTLE_DELAYS * delay, abs=1.5)
    # a slower low-pass the impacts cannot exclude sets the skip
    slower = SensorChain(lowpass_hz=fc, lowpass_order=order, lowpass_not_excluded=((2, fc / 2),))
    assert settling_samples(slower, fs) > settling_samples(chain, fs)
    assert settling_samples(SensorChain(resonance_hz=300.0, resonance_damping=0.05), fs) == 0
    assert settling_samples(None, fs) == 0


@pytest.mark.slow
def test_a_highpass_behind_a_lowpass_from_rest_is_read_where_the_chain_has_settled():
    """Independent rig (bench_crosscheck's rig_chains #4): a 4.98 Hz high-pass, a 2nd-order
    212 Hz low-pass and a 187 Hz mount, all starting from rest with the logger. Read from the
    first sample, the low-pass's rise made the corner 4.34 Hz (0.87) and beta 7.47 [6.64,
    8.41] for 6.27: a silent miss. Read from where the low-pass has settled, both are right."""
    sensor = {"resonance_hz": 187.31787666406078, "resonance_damping": 0.03444806091186811,
              "lowpass_hz": 212.0826588011561, "lowpass_order": 2,
              "highpass_hz": 4.977502016046865}  # fmt: skip
    run = RigRun(recording="rig_chains_4.csv", beta=6.266298871802806, fs_hz=1008.6533219375192,
                 duration_s=3.0, gap_mm=1.3766664110123255, sensor=sensor)  # fmt: skip
    accel = record(run, seed=20261135)[1]
    r = restoring_force_estimate(accel, run.fs_hz, natural_frequency_hz=FN)
    assert r.ok, r.reason
    assert r.highpass_hz == pytest.approx(4.98, rel=0.1)
    assert r.beta == pytest.approx(6.27, rel=0.1)
    assert r.beta_interval[0] <= 6.27 <= r.beta_interval[1]


# --- the contact law fitted through the band the inverse keeps -------------------------------


@pytest.mark.parametrize("contact", [None, "kelvin_voigt"])
def test_a_data_sheet_lowpass_near_the_contact_reads_beta_through_the_kept_band(contact):
    """Independent rig, beta 30 (contact at 52.8 Hz) behind a 4th-order low-pass at 1.5 contact
    frequencies, 2 % noise, read from its data sheet. The inverse keeps only the band the
    record carries above its noise, and the map of the band-limited pulses read beta 20.6
    [18.8, 22.5] (elastic): wrong, its interval missing the truth. Fitted forward through that
    band the contact law reads beta within 10 %, its interval covering the truth."""
    fc = FN * np.sqrt(31.0)
    sheet = {"lowpass_hz": round(1.5 * fc, 2), "lowpass_order": 4}
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=1248.0, duration_s=3.0, gap_mm=1.7,
                 contact=contact, contact_zeta=0.15, sensor=sheet, noise=0.02)  # fmt: skip
    accel = record(run, seed=3)[1]
    r = restoring_force_estimate(accel, 1248.0, natural_frequency_hz=FN, max_periods=24,
                                 sensor=sheet)  # fmt: skip
    assert r.ok, r.reason
    assert r.beta == pytest.approx(30.0, rel=0.1)
    assert r.beta_interval[0] <= 30.0 <= r.beta_interval[1]


# --- a known mount near the contact: the inverse's noise floor --------------------------------


@pytest.mark.parametrize(
    ("ratio", "zeta", "samples", "beta"),
    [(2.0, 0.0, 8, 30.0), (2.0, 0.25, 12, 60.0), (6.0, 0.0, 8, 30.0)],
)
def test_a_data_sheet_mount_near_the_contact_reads_beta(ratio, zeta, samples, beta):
    """Independent rig, 2 % noise, a mount (zeta 0.05) at `ratio` contact frequencies, the contact
    spanning about `samples` samples, read through its true chain (the data sheet). At twice
    the contact's frequency each impact sets the mount ringing through the flight after it,
    and the free flight's scatter, which weighted the inverse as the record's noise, was that
    ringing: the inverse was off over much of the band, and beta read 1.26x [1.17, 1.37] for
    the elastic contact and was refused for the damped one ("the contacts last 2.0x").
    Weighted by the top of the band's noise floor both read within 10 %, their intervals
    covering; the guard (a mount at 6 contact frequencies, where the scatter is the noise)
    reads within 2 % as before."""
    fc = FN * np.sqrt(1.0 + beta)
    fs = 2.0 * fc * samples
    mount = {"resonance_hz": ratio * fc, "resonance_damping": 0.05}
    run = RigRun(recording=f"g_{ratio}_{zeta}_{samples}_{beta}.csv", beta=beta, fs_hz=fs,
                 duration_s=3.0, gap_mm=1.7, contact="kelvin_voigt" if zeta else None,
                 contact_zeta=zeta, sensor={**mount, "oversample": 8}, noise=0.02)  # fmt: skip
    accel = record(run, seed=3)[1]
    r = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                 sensor={**mount, "highpass_hz": 0.0})  # fmt: skip
    assert r.ok, r.reason
    assert r.beta == pytest.approx(beta, rel=0.1 if ratio < 6 else 0.02)
    assert r.beta_interval[0] <= beta <= r.beta_interval[1]


def test_a_sheet_fitted_to_recordings_keeps_the_scatter_weighting(monkeypatch):
    """The rig behind a mount at twice the contact's frequency (elastic, 8 samples, beta 30),
    its true chain given as a sheet fitted to recordings (a campaign's pooled chain: the
    estimate's ``sensor_fitted``, the corner profile's :func:`contact_r2_through`, the
    predictor's check): each reads exactly as with the inverse weighted by the free flight's
    scatter (the band top's floor switched off), and differs from the user's sheet, which the
    floor moves. The campaign's corner profile is read through these R²s: the floor there
    flattened a damped campaign's profile (high-pass 4.07 -> 1.41 Hz for a true 4.48)."""
    from types import SimpleNamespace

    import stiffnet.restoring_force.estimate as estimate_module
    from serving.campaign_chain import contact_r2_through
    from serving.restoring_force_check import restoring_force_check

    fc = FN * np.sqrt(31.0)
    fs = 2.0 * fc * 8
    mount = {"resonance_hz": 2.0 * fc, "resonance_damping": 0.05}
    run = RigRun(recording="pooled.csv", beta=30.0, fs_hz=fs, duration_s=3.0, gap_mm=1.7,
                 sensor={**mount, "oversample": 8}, noise=0.02)  # fmt: skip
    accel = record(run, seed=3)[1]
    sheet = {**mount, "highpass_hz": 0.0}
    pred = SimpleNamespace(window_periods=16.0, stage_ratio=None)

    def readings():
        est = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                       sensor=sheet, sensor_fitted=True)  # fmt: skip
        check = restoring_force_check(accel, fs, FN, sheet, sensor_fitted=True)
        return est.beta, est.contact_r2, check["beta"], contact_r2_through(accel, fs, FN, pred,
                                                                           sheet)  # fmt: skip

    user = restoring_force_estimate(accel, fs, natural_frequency_hz=FN, max_periods=24,
                                    sensor=sheet)  # fmt: skip
    pooled = readings()
    monkeypatch.setattr(estimate_module, "inverse_noise_sigma", lambda y, f, c, scatter: scatter)
    assert readings() == pooled  # the floor never reaches a fitted sheet
    assert user.beta == pytest.approx(30.0, rel=0.1)
    assert abs(pooled[0] / user.beta - 1) > 0.05  # the floor matters on this record

"""A known chain's low-pass below the contact's frequency: read where the reading's interval
reaches a contact the band passes, refused where even its low end lies beyond the corner.

Recordings from the independent solve_ivp rig (tests/independent_rig.py), its analog chain
run on the oversampled motion, each read through its true chain as a data sheet.
"""

from __future__ import annotations

import numpy as np
import pytest

from serving.restoring_force_check import restoring_force_check
from stiffnet.effects.registry import build_effect
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.band import lowpass_refusal, smoothed_away_refusal
from stiffnet.restoring_force.chain import SensorChain
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator
from tests.independent_rig import RigRun, record

FN = 9.48


def _read_through_sheet(beta: float, ratio: float, order: int, seed: int, **sensor_extra):
    """The check of a 3 s record behind a low-pass at `ratio` contact frequencies, read
    through its true chain."""
    sensor = {"lowpass_hz": round(ratio * FN * np.sqrt(1 + beta), 2), "lowpass_order": order,
              **sensor_extra}  # fmt: skip
    run = RigRun(recording="r.csv", beta=beta, fs_hz=1000.0, duration_s=3.0, sensor=sensor)
    return restoring_force_check(record(run, seed=seed)[1], run.fs_hz, FN, sensor, None)


def test_the_rule_refuses_only_where_the_whole_interval_is_beyond_the_corner():
    chain = SensorChain(lowpass_hz=80.0, lowpass_order=4, contact_hz=88.0)
    reaching = (79.0 / FN) ** 2 - 1  # the interval's low end: a contact at 79 Hz
    beyond = (81.0 / FN) ** 2 - 1
    assert lowpass_refusal(chain, FN, reaching) == ""
    assert lowpass_refusal(chain, FN, beyond) == (
        "the low-pass at 80 Hz is below the contact's frequency 88 Hz (at least 81 Hz): beta "
        "is not identifiable from this sensor"
    )
    above = SensorChain(lowpass_hz=90.0, lowpass_order=4, contact_hz=88.0)
    assert lowpass_refusal(above, FN, beyond) == ""  # the low-pass passes the contact


def test_a_contact_just_above_a_known_lowpass_is_read_within_ten_percent():
    """Beta 86 (contact 88 Hz) behind a 4th-order low-pass at 0.9 of it: read through the
    band the inverse keeps, 83.0 [69.2, 99.1]; the contact frequency alone (86.9 Hz read,
    above the 79.7 Hz corner) refused it."""
    got = _read_through_sheet(86.0, 0.9, 4, seed=5)
    assert got["beta"] is not None, got["reason"]
    assert got["beta"] == pytest.approx(86.0, rel=0.10)
    lo, hi = got["beta_interval"]
    assert lo <= 86.0 <= hi and got["class"] == "very_hard"


def test_a_lowpass_far_below_the_contact_is_still_refused():
    """Beta 20 (contact 43 Hz) behind a 2nd-order low-pass at 0.4 of it (17 Hz), 2 % noise:
    without the refusal the law through the band reads 25.3 [22.0, 27.1], wrong and silent."""
    got = _read_through_sheet(20.0, 0.4, 2, seed=3, highpass_hz=1.0)
    assert got["beta"] is None and got["class"] is None
    assert got["reason"].startswith("the low-pass at 17 Hz is below the contact's frequency")
    assert got["reason"].endswith("beta is not identifiable from this sensor")


def _rig_beta30_reader():
    """The rig's beta 30 behind a 120 Hz order-4 low-pass and a 4 Hz high-pass (a damped
    contact, zeta 0.15), read through a data sheet by the restoring-force estimate."""
    from stiffnet.restoring_force import restoring_force_estimate

    sensor = {"lowpass_hz": 120.0, "lowpass_order": 4, "highpass_hz": 4.0}
    run = RigRun(recording="r.csv", beta=30.0, fs_hz=1250.0, duration_s=3.0, gap_mm=1.5,
                 contact="kelvin_voigt", contact_zeta=0.15, sensor=sensor)  # fmt: skip
    a = record(run, seed=1)[1]

    def read(sheet):
        return restoring_force_estimate(a, 1250.0, natural_frequency_hz=9.48, sensor=sheet,
                                        max_periods=24.0)  # fmt: skip

    return read


def test_a_sheets_highpass_interval_is_carried_into_betas():
    """A campaign's profiled corner comes with the corners its laws cannot tell apart
    (``highpass_low_hz``, ``highpass_high_hz``): beta's interval spans the reading at each
    end (beta 30 behind a 120 Hz order-4 low-pass and a 4 Hz high-pass read through a sheet at
    2.6 Hz whose interval reaches 4.4 Hz: [29.0, 34.5] alone, 28.5 at 4.4 Hz); a corner
    outside its own ends is refused in one line."""
    from stiffnet.restoring_force.chain import sensor_from_mapping

    sheet = {"lowpass_hz": 120.0, "lowpass_order": 4.0, "highpass_hz": 2.6}
    ends = {"highpass_low_hz": 2.6, "highpass_high_hz": 4.4}
    read = _rig_beta30_reader()
    alone, spanned = read(sheet), read({**sheet, **ends})
    far = read({**sheet, "highpass_hz": 4.4}).beta
    assert spanned.beta == alone.beta and not alone.beta_interval[0] <= far
    assert spanned.beta_interval[0] <= far <= spanned.beta_interval[1]
    with pytest.raises(ValueError, match="must hold highpass_hz between them"):
        sensor_from_mapping({**sheet, "highpass_low_hz": 3.0, "highpass_high_hz": 4.4}, 1250.0)


def test_a_sheets_lowpass_interval_is_carried_into_betas():
    """A campaign's profiled low-pass comes with the corners its laws cannot tell apart
    (``lowpass_low_hz``, ``lowpass_high_hz``): beta's interval spans the reading at each end
    (beta 30 behind a 120 Hz order-4 low-pass and a 4 Hz high-pass, read through a sheet at
    135 Hz: 27.8, its interval short of the 30.7 read at 110 Hz; with the interval reaching
    110 Hz it holds that reading, and the truth); ends that do not hold the corner are
    refused. Through the 135 Hz sheet the map bends into a power law (exponent 1.82), whose
    interval spans its equivalent linear springs (x0.71-1.82) and so reaches 30.7 alone too:
    the ends' readings are what must be in the interval whatever the law."""
    from stiffnet.restoring_force.chain import sensor_from_mapping

    sheet = {"lowpass_hz": 135.0, "lowpass_order": 4.0, "highpass_hz": 4.0}
    ends = {"lowpass_low_hz": 110.0, "lowpass_high_hz": 135.0}
    read = _rig_beta30_reader()
    alone, spanned = read(sheet), read({**sheet, **ends})
    far = read({**sheet, "lowpass_hz": 110.0}).beta
    assert spanned.beta == alone.beta
    assert spanned.beta_interval[0] <= min(far, alone.beta_interval[0])
    assert spanned.beta_interval[1] >= max(far, alone.beta_interval[1])
    assert spanned.beta_interval[0] <= 30.0 <= spanned.beta_interval[1]
    assert spanned.sensor.intervals["lowpass_hz"] == [110.0, 135.0]
    with pytest.raises(ValueError, match="must hold lowpass_hz between them"):
        sensor_from_mapping({**sheet, "lowpass_low_hz": 140.0, "lowpass_high_hz": 150.0}, 1250.0)


def test_no_contact_behind_a_lowpass_is_refused_against_the_stiffest_contact_only():
    # contact frequency at beta 100: 9.48 sqrt(101) = 95.3 Hz
    assert smoothed_away_refusal(None, FN, 100.0) == ""
    assert smoothed_away_refusal(96.0, FN, 100.0) == ""
    assert smoothed_away_refusal(93.0, FN, 100.0) == (
        "the low-pass at 93 Hz is below the contact's frequency 95 Hz (beta 100): no contact "
        "cannot be told from a contact this sensor smooths away"
    )


def test_soft_contacts_behind_a_known_lowpass_that_passes_them_are_read_not_refused():
    """Stiffnet's engine, beta 5.53 (contact 23.6 Hz), zeta_c 0.12, behind a 2nd-order
    low-pass at 68 Hz, a 240 Hz mount and a 1.15 Hz high-pass given as the sheet, 1 % noise:
    no impact stands out, the harmonics show contacts. Refused before against beta 100's
    contact (95 Hz) rather than the record's own; read by the joint fit through the chain,
    4.57 [3.72, 5.63]."""
    chain = {"resonance_hz": 240.5, "resonance_damping": 0.04, "highpass_hz": 1.15,
             "lowpass_hz": 68.3, "lowpass_order": 2}  # fmt: skip
    batch = OscillatorBatch.single(beta=5.53, gap=2.96, amplitude=1.5, omega=1.137, damping=0.0146)
    effects = [build_effect("contact_damping", {"damping_ratio": 0.117}),
               build_effect("sensor_dynamics", chain)]  # fmt: skip
    accel = Simulator(effects).simulate(batch, 67.67, 2165, noise=0.01, rng=1).accel[0]
    got = restoring_force_estimate(accel, 67.67 * FN, natural_frequency_hz=FN, sensor=chain)
    assert got.ok, got.reason
    assert got.beta_interval[0] <= 5.53 <= got.beta_interval[1]
    assert "behind the known low-pass" in got.reason

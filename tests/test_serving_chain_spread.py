"""The learned model's interval behind a fitted sensor chain spans the chains the fit allows."""

from __future__ import annotations

import numpy as np
import pytest

from serving.chain_spread import (
    ChainSpreadConfig,
    chain_class_share,
    chain_spread_config,
    contact_frequencies,
    plausible_chains,
    resonance_rings_clear,
    spread_interval,
)
from stiffnet.errors import ConfigError

FS = 2000.0
FN = 9.48

FITTED = {"resonance_hz": 190.0, "resonance_damping": 0.07, "lowpass_hz": 100.0,
          "lowpass_order": 4, "highpass_hz": 3.0, "source": "fitted", "applied": True,
          "intervals": {"resonance_hz": [185.0, 196.0], "lowpass_hz": [97.0, 103.0]}}  # fmt: skip
UNDONE = {"resonance_hz": 190.0, "resonance_damping": 0.07, "lowpass_hz": 100.0,
          "lowpass_order": 4, "source": "fitted"}  # fmt: skip


def test_a_fitted_chain_stands_for_the_record_as_recorded_and_lower_corners():
    config = ChainSpreadConfig(as_recorded=True, lowpass_factors=[0.8, 0.9],
                               resonance_interval=True)  # fmt: skip
    chains = plausible_chains(FITTED, UNDONE, config)
    assert list(chains) == ["as recorded", "low-pass 80 Hz", "low-pass 90 Hz",
                            "resonance 185 Hz", "resonance 196 Hz"]  # fmt: skip
    assert chains["as recorded"] is None
    assert chains["low-pass 80 Hz"]["lowpass_hz"] == pytest.approx(80.0)
    assert chains["low-pass 80 Hz"]["resonance_hz"] == 190.0  # the other stages as fitted
    assert chains["resonance 196 Hz"]["lowpass_hz"] == 100.0
    # a campaign's pooled fits are fitted too
    assert plausible_chains(FITTED, {**UNDONE, "source": "campaign"}, config) == chains
    # a resonance alone: no corner to move
    only = plausible_chains(FITTED, {**UNDONE, "lowpass_hz": None}, config)
    assert list(only) == ["as recorded", "resonance 185 Hz", "resonance 196 Hz"]


def test_a_fitted_high_pass_undone_stands_for_the_record_with_it_left_in():
    config = ChainSpreadConfig(as_recorded=False, highpass_kept=True)
    chains = plausible_chains(FITTED, {**UNDONE, "highpass_hz": 3.0}, config)
    assert list(chains) == ["high-pass 3 Hz kept"]
    kept = chains["high-pass 3 Hz kept"]
    assert kept["highpass_hz"] == 0.0  # left in: not divided out
    assert (kept["resonance_hz"], kept["lowpass_hz"]) == (190.0, 100.0)  # still undone
    assert plausible_chains(FITTED, UNDONE, config) == {}  # no corner undone: nothing
    assert chain_spread_config().highpass_kept  # shipped on


def test_a_data_sheet_no_chain_or_the_switch_off_read_once():
    config = ChainSpreadConfig(lowpass_factors=[0.8])
    assert plausible_chains(FITTED, {**UNDONE, "source": "data sheet"}, config) == {}
    assert plausible_chains(FITTED, None, config) == {}  # nothing undone (ideal record)
    assert plausible_chains(None, None, config) == {}
    assert plausible_chains(FITTED, UNDONE, ChainSpreadConfig(enabled=False)) == {}


#: A lab's mount the fit identified: 237 Hz (25 f_n), damping 0.05, over a 66 Hz contact.
MOUNT = {"resonance_hz": 237.0, "resonance_damping": 0.05, "lowpass_hz": None,
         "highpass_hz": 1.0, "source": "fitted", "applied": True, "contact_hz": 66.0,
         "intervals": {"resonance_hz": [236.7, 237.3], "contact_hz": [65.3, 66.8]}}  # fmt: skip
MOUNT_UNDONE = {"resonance_hz": 237.0, "resonance_damping": 0.05, "lowpass_hz": None,
                "highpass_hz": 1.0, "source": "fitted"}  # fmt: skip
#: ... and the model's reading through it: beta 48 in [35, 66] (the rig's f_n 9.48 Hz).
READ = contact_frequencies(48.0, [35.0, 66.0], FN)


def test_the_contact_the_model_reads_in_hz():
    low, at_beta, high = READ
    assert at_beta == pytest.approx(FN * 7.0)  # sqrt(1 + 48)
    assert low == pytest.approx(FN * 6.0) and high == pytest.approx(FN * np.sqrt(67.0))
    assert contact_frequencies(None, [35.0, 66.0], FN) is None
    assert contact_frequencies(48.0, None, FN) is None


def test_a_resonance_ringing_clear_of_the_contact_is_not_read_away():
    # a light resonance 3.5 times the fastest contact, the fit's contact the one the model
    # reads: it rings after every impact, the record went through it, so "as recorded" is
    # no reading; the corner left in still is
    config = ChainSpreadConfig(as_recorded=True, highpass_kept=True)
    assert resonance_rings_clear(MOUNT, MOUNT_UNDONE, READ)
    assert list(plausible_chains(MOUNT, MOUNT_UNDONE, config, READ)) == ["high-pass 1 Hz kept"]
    # without the model's reading (the stiffness log's choice): read as before
    assert not resonance_rings_clear(MOUNT, MOUNT_UNDONE)
    assert "as recorded" in plausible_chains(MOUNT, MOUNT_UNDONE, config)
    # the same resonance where the pulse could take it: near the fit's contact (its
    # interval's top 80 Hz, a third of 237), heavily damped, undone with a low-pass
    near = {**MOUNT, "intervals": {**MOUNT["intervals"], "contact_hz": [65.0, 80.0]}}
    damped = {**MOUNT, "resonance_damping": 0.3}
    lowpass = {**MOUNT_UNDONE, "lowpass_hz": 300.0, "lowpass_order": 4}
    for sensor, undone in ((near, MOUNT_UNDONE), (damped, MOUNT_UNDONE), (MOUNT, lowpass)):
        assert not resonance_rings_clear(sensor, undone, READ)
        assert "as recorded" in plausible_chains(sensor, undone, config, READ)
    # near the model's contact: it reads beta 70 (80 Hz); its interval still holds 66 Hz
    assert not resonance_rings_clear(MOUNT, MOUNT_UNDONE, contact_frequencies(70, [40, 90], FN))
    # the fit's contact bent away from the model's: a 93 Hz "mount" over an 18 Hz contact
    # (beta 2.6) where the model reads beta 13 [9, 18] through it (30-42 Hz)
    bent = {**MOUNT, "resonance_hz": 93.0, "contact_hz": 18.0,
            "intervals": {"resonance_hz": [92.0, 94.0], "contact_hz": [17.5, 18.5]}}  # fmt: skip
    assert not resonance_rings_clear(bent, {**MOUNT_UNDONE, "resonance_hz": 93.0},
                                     contact_frequencies(13.0, [9.0, 18.0], FN))  # fmt: skip
    # the resonance's own interval reaching down near the contact; no contact fitted; no
    # resonance undone (a high-pass alone)
    wide = {**MOUNT, "intervals": {**MOUNT["intervals"], "resonance_hz": [190.0, 280.0]}}
    assert not resonance_rings_clear(wide, MOUNT_UNDONE, READ)
    assert not resonance_rings_clear({**MOUNT, "contact_hz": None}, MOUNT_UNDONE, READ)
    assert not resonance_rings_clear(MOUNT, {**MOUNT_UNDONE, "resonance_hz": None}, READ)


def test_the_interval_spans_the_readings_and_the_alarm_counts_other_classes():
    readings = [{"chain": "as recorded", "class": "medium", "beta_interval": [18.0, 30.0]},
                {"chain": "low-pass 80 Hz", "class": "hard", "beta_interval": [30.0, 52.0]},
                {"chain": "odd", "class": None, "beta_interval": None}]  # fmt: skip
    assert spread_interval([25.0, 45.0], readings) == [18.0, 52.0]
    assert spread_interval([25.0, 45.0], []) == [25.0, 45.0]  # no chain: as it was
    assert spread_interval(None, readings) is None
    # two of three readings land outside "hard": the chain_class alarm's score
    assert chain_class_share("hard", readings) == pytest.approx(2 / 3)
    assert chain_class_share("hard", readings[1:2]) == 0.0
    assert chain_class_share("hard", []) is None


def test_the_shipped_settings_load_and_bad_ones_are_one_line(tmp_path):
    from stiffnet.config import load_yaml, validate_config

    shipped = chain_spread_config()
    assert shipped.enabled and all(0 < f < 1 for f in shipped.lowpass_factors)
    bad = tmp_path / "spread.yaml"
    bad.write_text("lowpass_factors: [0.01]\n")
    with pytest.raises(ConfigError, match="lowpass_factors"):
        validate_config(ChainSpreadConfig, load_yaml(bad), str(bad))
    bad.write_text("as_recorded: true\nlowpass_factor: [0.8]\n")
    with pytest.raises(ConfigError, match="lowpass_factor"):
        validate_config(ChainSpreadConfig, load_yaml(bad), str(bad))


@pytest.fixture(scope="module")
def predictor():
    from serving.predictor import Predictor

    # as recorded only: the mechanism, whatever the shipped corners
    return Predictor.load(chain_spread=ChainSpreadConfig(as_recorded=True, lowpass_factors=[]))


def test_a_fitted_chain_whose_readings_straddle_classes_widens_and_alarms(predictor):
    # the rig behind a mount resonance at 12 f_n and a 4th-order low-pass at 0.1 fs, both
    # outside the chains the model saw: read through the chain undone the CNN says hard
    # (beta 40), read as recorded it blows up (test_serving_chain_undo). Given as a data
    # sheet the chain is known: one reading, the calibrated interval. The same chain as a
    # campaign's pooled fits: the as-recorded reading lands in another class, the alarm
    # says so and the interval spans it
    from test_serving_chain_undo import rig_record

    sheet = {"resonance_hz": 12 * FN, "resonance_damping": 0.05, "lowpass_hz": 0.1 * FS,
             "lowpass_order": 4, "highpass_hz": 1.0}  # fmt: skip
    a = rig_record(40.0, sheet)
    known = predictor.predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    fitted = predictor.predict(a, FS, natural_frequency_hz=FN, sensor=sheet, sensor_fitted=True)
    assert known["chain_readings"] is None
    assert "chain_class" not in known["alarm"]["fired"]
    assert fitted["chain_undone"]["source"] == "campaign"
    (raw,) = fitted["chain_readings"]
    assert raw["chain"] == "as recorded" and raw["class"] != fitted["class"] == "hard"
    assert fitted["beta"] == known["beta"] and fitted["class"] == known["class"]
    assert "chain_class" in fitted["alarm"]["fired"] and fitted["ood_flag"]
    assert "another class" in fitted["alarm"]["message"]
    lo, hi = fitted["beta_interval"]
    assert lo <= known["beta_interval"][0] and hi >= known["beta_interval"][1]
    assert lo <= raw["beta_interval"][0] and hi >= raw["beta_interval"][1]
    assert hi > 1.5 * known["beta_interval"][1]


def test_an_ideal_record_reads_once(predictor):
    from test_serving_chain_undo import rig_record

    res = predictor.predict(rig_record(40.0, None), FS, natural_frequency_hz=FN)
    assert res["chain_undone"] is None and res["chain_readings"] is None
    assert "chain_class" not in ((res["alarm"] or {}).get("scores") or {})
    assert np.isfinite(res["beta"])


@pytest.fixture(scope="module")
def shipped():
    from serving.predictor import Predictor

    return Predictor.load()


def test_a_mount_ringing_clear_of_the_contact_reads_one_class_and_a_near_one_two(shipped):
    # the independent rig behind a lab's mount, its chain fitted on the record (no sheet).
    # At 25 f_n (237 Hz, 3.5 times the 67 Hz contact) the record rings after every impact:
    # read as recorded the CNN says very hard (72 for 49, a mount it was not trained
    # behind) and chain_class fired on a right answer; it is now not read. At 18 f_n
    # (170 Hz, 2.6 times) the resonance could shape the pulse: the reading stays
    from test_serving_chain_undo import rig_record

    for factor, as_recorded in ((25, False), (18, True)):
        mount = {"resonance_hz": factor * FN, "resonance_damping": 0.05, "highpass_hz": 1.0}
        res = shipped.predict(rig_record(49.0, mount), FS, natural_frequency_hz=FN)
        assert res["chain_undone"]["resonance_hz"] == pytest.approx(factor * FN, rel=0.02)
        assert res["chain_undone"]["source"] == "fitted" and res["class"] == "hard"
        names = [r["chain"] for r in res["chain_readings"]]
        assert ("as recorded" in names) is as_recorded
        if not as_recorded:
            assert "chain_class" not in res["alarm"]["fired"]
            assert all(r["class"] == "hard" for r in res["chain_readings"])

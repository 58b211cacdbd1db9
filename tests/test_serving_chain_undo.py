"""The record the learned model reads with the identified sensor chain undone."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

# the shipped card's sensor prior (resonance 15-300 f_n, low-pass 0.15-0.45 fs)
from test_sensor_chain import PRIORS

from serving.chain_undo import (
    chain_to_undo,
    model_record,
    record_noise_sigma,
    undone_record,
    undone_windows,
)
from serving.restoring_force_check import sensor_prior_lows
from stiffnet.restoring_force.chain import SensorChain, chain_sos

FS = 2000.0
FN = 9.48


def pulse_train(n: int, fs: float, contact_hz: float, every_s: float) -> np.ndarray:
    """Half-sine contact pulses (the shape of a linear contact's force) every `every_s`."""
    t = np.arange(n) / fs
    phase = np.mod(t, every_s)
    half = 0.5 / contact_hz
    return np.where(phase < half, np.sin(np.pi * phase / half), 0.0)


def sensor(**stages) -> dict:
    base = {"resonance_hz": None, "resonance_damping": None, "lowpass_hz": None,
            "lowpass_order": None, "highpass_hz": 0.0, "source": "fitted", "applied": True,
            "contact_hz": 60.0}  # fmt: skip
    return {**base, **stages}


def _behind_mount_and_low_pass(n: int, seed: int) -> tuple[np.ndarray, SensorChain, np.ndarray]:
    """Contact pulses at 60 Hz, the chain (a mount resonance at 10 f_n, below the prior, and a
    3rd-order low-pass at 0.06 fs), and the pulses recorded through it with white noise."""
    rng = np.random.default_rng(seed)
    clean = pulse_train(n, FS, 60.0, 0.105)
    chain = SensorChain(resonance_hz=10 * FN, resonance_damping=0.05, lowpass_hz=0.06 * FS,
                        lowpass_order=3)  # fmt: skip
    recorded = signal.sosfilt(chain_sos(chain, FS), clean) + 0.005 * rng.standard_normal(n)
    return clean, chain, recorded


def test_a_known_chain_is_undone_within_the_band_the_record_passes():
    # contact pulses at 60 Hz behind a mount resonance at 10 f_n (below the prior) and a
    # 3rd-order low-pass at 0.06 fs: the record's error against the pulses is most of their
    # size; undone, what is left is the noise the inverse amplifies in the band it passes
    clean, chain, recorded = _behind_mount_and_low_pass(8000, seed=3)
    mid = slice(1000, 7000)  # away from the filter's start-up from rest
    before = np.sqrt(np.mean((recorded[mid] - clean[mid]) ** 2))
    after = np.sqrt(np.mean((undone_record(recorded, FS, chain)[mid] - clean[mid]) ** 2))
    assert before > 0.3
    assert after < 0.1 * before  # measured 0.50 -> 0.022


def test_windows_undone_one_by_one_undo_the_chain_wherever_the_record_is_cut():
    # each window read with record either side (reflected at the record's start) is close
    # to the pulses behind the chain, and the same window cut out of a shorter buffer (a
    # stream's) reads exactly the same
    clean, chain, recorded = _behind_mount_and_low_pass(12000, seed=4)
    starts = np.array([0, 3000, 5500, 9000])
    windows = undone_windows(recorded, starts, 2000, FS, chain)
    for s, w in zip(starts, windows, strict=True):
        c = clean[s : s + 2000]
        before = np.sqrt(np.mean((recorded[s : s + 2000] - c) ** 2))
        after = np.sqrt(np.mean((w - c) ** 2))
        assert after < 0.15 * before  # measured 2.5 -> 0.21-0.33 of the pulses' rms
    cut = undone_windows(recorded[2800:], starts[1:2] - 2800, 2000, FS, chain)
    assert cut[0] == pytest.approx(windows[1], abs=1e-12)


def test_a_high_pass_is_undone_exactly():
    # a tone at f_n and contact pulses through a 1st-order high-pass at 4 Hz (the charge
    # amplifier's, started from rest): the tone's phase turns by 23 degrees; undone, the
    # whole record is back, its start included (measured 0.26 -> 0.005 of the tone)
    t = np.arange(12000) / FS
    clean = np.sin(2 * np.pi * FN * t) + pulse_train(t.size, FS, 60.0, 0.105)
    clean -= clean.mean()
    recorded = signal.sosfilt(signal.butter(1, 4.0, "high", fs=FS, output="sos"), clean)
    before = np.sqrt(np.mean((recorded - clean) ** 2))
    after = np.sqrt(
        np.mean((undone_record(recorded, FS, SensorChain(highpass_hz=4.0)) - clean) ** 2)
    )
    assert before > 0.2
    assert after < 0.05 * before


def test_the_noise_floor_is_read_from_the_top_of_the_band():
    rng = np.random.default_rng(0)
    t = np.arange(20000) / FS
    y = np.sin(2 * np.pi * 10.0 * t) + 0.03 * rng.standard_normal(t.size)
    assert record_noise_sigma(y, FS) == pytest.approx(0.03, rel=0.1)


def test_prior_lows_are_the_cards_lowest_resonance_and_low_pass():
    lows = sensor_prior_lows(PRIORS, FS, FN)
    assert lows == {"resonance_hz": pytest.approx(15 * FN), "lowpass_hz": pytest.approx(0.15 * FS)}
    assert sensor_prior_lows(None, FS, FN) == {}


def test_which_stages_are_undone():
    both = sensor(resonance_hz=10 * FN, resonance_damping=0.05, lowpass_hz=0.3 * FS,
                  lowpass_order=2)  # fmt: skip
    full = chain_to_undo(both, PRIORS, FS, FN, "chain")
    assert (full.resonance_hz, full.lowpass_hz, full.lowpass_order) == (10 * FN, 0.3 * FS, 2)
    # the low-pass at 0.3 fs is inside the prior (0.15 fs and up): only the resonance goes
    outside = chain_to_undo(both, PRIORS, FS, FN, "outside_priors")
    assert (outside.resonance_hz, outside.lowpass_hz) == (10 * FN, None)
    assert chain_to_undo(both, PRIORS, FS, FN, "resonance").lowpass_hz is None
    # a chain the check did not apply, an off switch, a chain with no dynamics: nothing
    assert chain_to_undo({**both, "applied": False}, PRIORS, FS, FN, "chain") is None
    assert chain_to_undo(both, PRIORS, FS, FN, "off") is None
    # a high-pass alone is undone; outside_priors only above the prior's 2 Hz top
    assert chain_to_undo(sensor(highpass_hz=1.0), PRIORS, FS, FN, "chain").highpass_hz == 1.0
    assert chain_to_undo(sensor(highpass_hz=1.0), PRIORS, FS, FN, "outside_priors") is None
    assert (
        chain_to_undo(sensor(highpass_hz=4.0), PRIORS, FS, FN, "outside_priors").highpass_hz == 4.0
    )
    assert chain_to_undo(sensor(highpass_hz=4.0), PRIORS, FS, FN, "resonance") is None
    # a low-pass below the contact's frequency has smoothed the contact away: not inverted
    low = sensor(lowpass_hz=50.0, lowpass_order=2, contact_hz=90.0)
    assert chain_to_undo(low, PRIORS, FS, FN, "chain") is None
    with pytest.raises(ValueError, match="undo mode"):
        chain_to_undo(both, PRIORS, FS, FN, "all")


def test_an_ideal_record_is_read_as_recorded():
    y = pulse_train(4000, FS, 60.0, 0.105)
    for check in ({"sensor": None}, {"sensor": sensor()}, None):
        read, undone = model_record(y, FS, FN, check, PRIORS, "chain")
        assert read is y and undone is None
    read, undone = model_record(y, FS, FN, {"sensor": sensor(resonance_hz=90.0,
                                                             resonance_damping=0.05)},
                                PRIORS, "chain")  # fmt: skip
    assert read.shape == y.shape and undone["resonance_hz"] == 90.0


@pytest.fixture(scope="module")
def predictors():
    from serving.predictor import Predictor

    return {mode: Predictor.load(undo_chain=mode) for mode in ("off", "chain")}


def rig_record(beta: float, sensor: dict | None) -> np.ndarray:
    """3 s of the independent rig (solve_ivp, SI units, the analog chain), in g."""
    from independent_rig import RigRun, record

    run = RigRun(recording="chain.csv", beta=beta, fs_hz=FS, duration_s=3.0, gap_mm=1.5,
                 sensor=sensor)  # fmt: skip
    return record(run, seed=1)[1]


def test_a_record_behind_a_known_chain_is_read_closer_to_the_truth_undone(predictors):
    # a mount resonance at 12 f_n (the model saw 15 and up) and a 4th-order low-pass at 0.1 fs
    # (it saw 0.15 fs and up): read as recorded, the CNN's beta blows up (measured 3e5);
    # with the data sheet's chain undone it reads 43 for 40, inside its interval, no alarm
    sheet = {"resonance_hz": 12 * FN, "resonance_damping": 0.05, "lowpass_hz": 0.1 * FS,
             "lowpass_order": 4, "highpass_hz": 1.0}  # fmt: skip
    a = rig_record(40.0, sheet)
    raw = predictors["off"].predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    undone = predictors["chain"].predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    assert raw["chain_undone"] is None
    assert undone["chain_undone"]["resonance_hz"] == pytest.approx(12 * FN)
    assert undone["chain_undone"]["source"] == "data sheet"
    assert abs(np.log(undone["beta"] / 40.0)) < 0.15 < abs(np.log(raw["beta"] / 40.0))
    assert undone["class"] == "hard" != raw["class"]
    lo, hi = undone["beta_interval"]
    assert lo <= 40.0 <= hi
    # the chain itself is reported as the cross-check identified (here: read) it
    assert undone["restoring_force"]["sensor"] == raw["restoring_force"]["sensor"]


def test_a_charge_amplifiers_high_pass_is_undone_before_the_model_reads(predictors):
    # the independent rig through a 4 Hz high-pass alone (a data sheet's charge amplifier,
    # above the prior's 2 Hz): left in, it turns the phase of the motion at f_n and the CNN
    # reads beta 36 about 40 % high (measured 51.5, `sensor` alarm); undone, it reads what
    # the record without any chain reads (36.5 both)
    sheet = {"highpass_hz": 4.0}
    a = rig_record(36.0, sheet)
    got = predictors["chain"].predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    plain = predictors["chain"].predict(rig_record(36.0, None), FS, natural_frequency_hz=FN)
    assert got["chain_undone"]["highpass_hz"] == 4.0
    assert abs(np.log(got["beta"] / plain["beta"])) < 0.05
    assert abs(np.log(got["beta"] / 36.0)) < 0.12
    assert got["class"] == "hard"


def test_an_ideal_rig_record_reads_the_same_with_the_undo_on(predictors):
    a = rig_record(40.0, None)
    raw = predictors["off"].predict(a, FS, natural_frequency_hz=FN)
    undone = predictors["chain"].predict(a, FS, natural_frequency_hz=FN)
    assert undone["chain_undone"] is None
    assert undone["beta"] == raw["beta"] and undone["beta_interval"] == raw["beta_interval"]
    assert undone["class"] == raw["class"] == "hard"


def test_the_default_undoes_the_chain_and_a_bad_mode_is_one_line():
    from serving.predictor import UNDO_CHAIN, Predictor
    from stiffnet.errors import StiffnetError

    assert UNDO_CHAIN == "chain"
    with pytest.raises(StiffnetError, match="^undo_chain must be one of off, chain,"):
        Predictor.load(undo_chain="everything")


def test_a_model_whose_card_names_its_undo_mode_is_read_that_way():
    # a model trained behind the campaign's own fitted chain (the loop's card says
    # undo_chain: outside_priors) reads a chain inside its priors as recorded; a card
    # naming nothing keeps the predictor's default, and the caller's mode wins over both
    import dataclasses

    from serving.model import load_model
    from serving.predictor import Predictor

    model = load_model()
    card = {**model.card, "config": {**model.card["config"], "undo_chain": "outside_priors"}}
    own = dataclasses.replace(model, card=card)
    sheet = {"resonance_hz": 20 * FN, "resonance_damping": 0.05}  # the model saw 15 f_n and up
    a = rig_record(40.0, sheet)
    as_card = Predictor(own, None).predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    default = Predictor(model, None).predict(a, FS, natural_frequency_hz=FN, sensor=sheet)
    assert as_card["chain_undone"] is None
    assert default["chain_undone"]["resonance_hz"] == pytest.approx(20 * FN)
    assert Predictor(own, None, undo_chain="chain").undo_chain == "chain"

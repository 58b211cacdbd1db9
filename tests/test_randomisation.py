"""The randomised training world: effects present on a fraction of rigs, relative priors."""

import numpy as np
import pytest

from stiffnet.config import validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.generate import generate_dataset
from stiffnet.dataset.sampling import sample_plan
from stiffnet.dataset.store import load_dataset
from stiffnet.effects.registry import build_effect
from stiffnet.errors import ConfigError
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

SMALL = {
    "n_trajectories": 24,
    "shard_size": 12,
    "windows": {"duration_periods": 6, "per_trajectory": 2},
    "sweep": {"fs_ratio": [50, 80]},
    "solver": {"settle_tolerance": 0.1, "batch_size": 12, "substeps": 4},
}


def _batch(n=4):
    return OscillatorBatch(
        np.full(n, 40.0), np.full(n, 0.5), np.full(n, 1.0), np.full(n, 1.0), np.full(n, 0.03),
        np.full(n, 9.48),
    )  # fmt: skip


def test_an_effect_switched_off_on_a_row_leaves_that_row_ideal():
    batch = _batch()
    on = np.array([True, False, True, False])
    x0, v0 = np.zeros(4), np.ones(4)
    ideal = Simulator().simulate(batch, 60.0, 400, rng=1, x0=x0, v0=v0)
    effects = [
        build_effect("contact_damping", {"damping_ratio": 0.4}),
        build_effect("sensor_dynamics", {"resonance_hz": 150.0, "lowpass_hz": 200.0}),
    ]
    mixed = Simulator(effects).simulate(
        batch, 60.0, 400, rng=1, x0=x0, v0=v0,
        active={"contact_damping": on, "sensor_dynamics": on},
    )  # fmt: skip
    np.testing.assert_allclose(mixed.accel[~on], ideal.accel[~on], rtol=0, atol=1e-9)
    # rows with the effects differ: lower, smoother spikes
    assert np.max(np.abs(mixed.accel[on] - ideal.accel[on])) > 0.1 * np.max(np.abs(ideal.accel))


def test_an_effect_without_neutral_values_cannot_be_off_inside_a_batch():
    sim = Simulator([build_effect("hertz_contact")])
    with pytest.raises(ConfigError, match="declares no neutral parameters"):
        sim.simulate(_batch(2), 60.0, 50, rng=0, active={"hertz_contact": [True, False]})


def test_relative_priors_follow_each_rig():
    cfg = validate_config(SimulationConfig, {**SMALL, "effects": [{
        "name": "sensor_dynamics", "probability": 0.5,
        "relative": {"resonance_hz": {"per": "natural_frequency", "range": [20, 40]},
                     "lowpass_hz": {"per": "sampling_rate", "range": [0.2, 0.3]}}}]})  # fmt: skip
    plan = sample_plan(cfg, 400, np.random.default_rng(0))
    fn = plan.batch.natural_frequency_hz
    p = plan.effect_params["sensor_dynamics"]
    r = p["resonance_hz"] / fn
    lp = p["lowpass_hz"] / (fn * plan.fs_ratio)
    assert 20 <= r.min() and r.max() <= 40 and 0.2 <= lp.min() and lp.max() <= 0.3
    # log-uniform: the geometric mean sits at the middle
    assert np.exp(np.mean(np.log(r))) == pytest.approx(np.sqrt(20 * 40), rel=0.05)
    assert 0.4 < plan.active["sensor_dynamics"].mean() < 0.6


def test_randomised_dataset_records_which_rigs_had_what(tmp_path):
    cfg = validate_config(SimulationConfig, {**SMALL, "effects": [
        {"name": "contact_damping", "probability": 0.5, "params": {"damping_ratio": [0.2, 0.4]}},
        {"name": "hertz_contact", "probability": 0.25},
        {"name": "adc", "probability": 0.5, "params": {"bits": [10, 12]}},
    ]})  # fmt: skip
    generate_dataset(cfg, tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds", verify=True)
    on = ds.column("effect.contact_damping.active").astype(bool)
    zeta = ds.column("effect.contact_damping.damping_ratio")
    assert on.any() and (~on).any()
    assert np.all(zeta[~on] == 0.0) and np.all((zeta[on] >= 0.2) & (zeta[on] <= 0.4))
    hertz = ds.column("effect.hertz_contact.active").astype(bool)
    assert hertz.any() and (~hertz).any()  # both engines ran in one shard
    assert np.all(np.isfinite(np.concatenate(ds.windows())))
    # the same config and seed give the same dataset (groups are deterministic)
    generate_dataset(cfg, tmp_path / "ds2")
    again = load_dataset(tmp_path / "ds2")
    np.testing.assert_array_equal(np.concatenate(again.windows()), np.concatenate(ds.windows()))


def test_ideal_fraction_keeps_rigs_without_any_effect():
    cfg = validate_config(SimulationConfig, {**SMALL, "ideal_fraction": 0.5, "effects": [
        {"name": "contact_damping", "params": {"damping_ratio": [0.1, 0.2]}},
        {"name": "adc"},
    ]})  # fmt: skip
    plan = sample_plan(cfg, 2000, np.random.default_rng(3))
    damped, adc = plan.active["contact_damping"], plan.active["adc"]
    assert np.array_equal(damped, adc)  # probability 1: only the ideal rigs lack them
    assert 0.45 < 1 - damped.mean() < 0.55

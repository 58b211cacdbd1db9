"""One home for campaign simulation: a manifest row becomes the same simulation for
``simulate-campaign`` (one row per task) and for ``compare``/``diagnose`` (one batch),
with one solver-settings model behind the simulator, the dataset config and both."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

import stiffnet.campaign as campaign
from stiffnet.campaign import ManifestRow, load_campaign, sensor_gain, simulate_campaign
from stiffnet.campaign.simulate import (
    FIT_SETTINGS,
    FIT_SETTINGS_NUMERICAL,
    CampaignSolverSettings,
    RowJob,
    simulate_row,
    simulate_rows,
)
from stiffnet.config import validate_config
from stiffnet.config.sim import SimulationConfig, SolverConfig
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.errors import ConfigError, StiffnetError
from stiffnet.measurement.compare import config_settings
from stiffnet.recordings import write_recording_csv
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.settings import SolverSettings
from stiffnet.simulator.simulator import Simulator

ROW = ManifestRow(recording="r.csv", fs_hz=400.0, beta=20.0, gap=0.8, amplitude=1.2,
                  frequency_ratio=1.02, damping_ratio=0.03, noise=0.0)  # fmt: skip


@pytest.mark.parametrize("effects", [[], [ContactDamping(damping_ratio=0.2)]])
def test_a_row_is_the_same_simulation_for_both_callers(effects):
    # simulate-campaign's task and the comparisons' batch share the row -> simulator
    # mapping (f_n, fs ratio, initial state from (seed, crc32), transient, gain): with
    # no noise the two give the same samples, bit for bit
    accel, entry = simulate_row(RowJob(ROW, effects, 7, 1.5, "m.csv: line 2 (r.csv)"))
    (batch,) = simulate_rows([ROW], effects, [accel.size], seed=7)
    assert accel.size == 600 and entry["n_impacts"] > 0
    np.testing.assert_array_equal(batch, accel)
    # another seed starts elsewhere: the equality above is not a coincidence of the orbit
    (other,) = simulate_rows([ROW], effects, [accel.size], seed=8)
    assert not np.array_equal(other[:20], accel[:20])
    assert entry["sensor_gain"] == sensor_gain(9.48)


def test_missing_simulation_column_reads_the_same_for_both_callers(tmp_path):
    text = "recording,fs_hz,beta,gap,amplitude,damping_ratio\nx.csv,500,10,1,1.5,0.02\n"
    folder = tmp_path / "camp"
    folder.mkdir()
    (folder / "manifest.csv").write_text(text)
    write_recording_csv(folder / "x.csv", np.sin(np.arange(2000) / 5.0), 500.0)
    expected = r"line 2 \(x\.csv\): column frequency_ratio is required for simulation"
    with pytest.raises(StiffnetError, match=r"manifest\.csv: " + expected):
        simulate_campaign(folder / "manifest.csv", tmp_path / "out", [])
    with pytest.raises(StiffnetError, match=r"manifest\.csv: " + expected):
        simulate_rows(load_campaign(folder).rows, [], [1000])


def test_the_old_import_path_keeps_its_public_names():
    for name in ("ManifestRow", "read_manifest", "write_manifest", "load_campaign", "Campaign",
                 "simulate_campaign", "sensor_gain", "MANIFEST_NAME", "CARD_NAME",
                 "SIMULATION_COLUMNS", "DEFAULT_NOISE", "READ_COLUMNS", "COLUMNS"):  # fmt: skip
        assert name in campaign.__all__ and getattr(campaign, name) is not None


# ------------------------------------------------------------------ solver settings


def test_solver_defaults_and_ranges_have_one_source():
    base = SolverSettings()
    assert Simulator().settings == base
    assert SolverConfig().solver_settings() == base
    assert CampaignSolverSettings().solver_settings() == base
    for model in (SolverConfig, CampaignSolverSettings):
        assert issubclass(model, SolverSettings)
        for name, field in SolverSettings.model_fields.items():
            assert name not in model.__dict__.get("__annotations__", {})  # not restated
            assert repr(model.model_fields[name]) == repr(field), (model.__name__, name)
    # the same range refuses the same value wherever it comes in
    with pytest.raises(ConfigError, match="settle_tolerance"):
        Simulator(settle_tolerance=1.5)
    with pytest.raises(ConfigError, match="settle_tolerance"):
        validate_config(SimulationConfig, {"solver": {"settle_tolerance": 1.5}})
    with pytest.raises(ValidationError, match="settle_tolerance"):
        CampaignSolverSettings(settle_tolerance=1.5)
    with pytest.raises(ConfigError, match="substep"):
        Simulator(substep=2)  # a misspelt setting is named, not ignored


def test_the_simulator_takes_the_settings_model():
    batch = OscillatorBatch.single(20.0, 0.5, 1.0, 1.0, 0.02)
    cfg = validate_config(SimulationConfig, {"solver": {"settle_tolerance": 0.1,
                                                        "min_transient_periods": 3}})  # fmt: skip
    sim = Simulator([], cfg.solver)
    assert sim.settings == SolverSettings(settle_tolerance=0.1, min_transient_periods=3)
    # t = max(-ln(tol) / xi, periods * 2 pi / w)
    assert sim.transient_time(batch)[0] == pytest.approx(-np.log(0.1) / 0.02)
    # keyword overrides change one field of the given settings
    assert Simulator([], cfg.solver, substeps=3).settings.substeps == 3
    assert Simulator([], FIT_SETTINGS).settings == FIT_SETTINGS.solver_settings()
    # the comparisons built from a config keep its solver settings and add their length
    settings = config_settings(cfg, periods=12.0)
    assert settings.solver_settings() == cfg.solver.solver_settings() and settings.periods == 12
    # frozen and hashable: the diagnosis keys its noise floors by settings
    floors = {FIT_SETTINGS: 1.0, FIT_SETTINGS_NUMERICAL: 2.0}
    assert floors[CampaignSolverSettings(periods=40.0, min_transient_periods=10.0, substeps=2)] == 1
    with pytest.raises(ValidationError):
        FIT_SETTINGS.periods = 3.0


def test_example_manifest_rows_simulate_in_one_batch():
    rows = campaign.read_manifest(Path(__file__).resolve().parents[1] / "examples"
                                  / "campaign_manifest.csv")[:3]  # fmt: skip
    sims = simulate_rows(rows, [], [500] * len(rows), settings=FIT_SETTINGS)
    for row, a in zip(rows, sims, strict=True):
        # capped at FIT_SETTINGS.periods natural periods of the row
        f_n = row.natural_frequency_hz or 9.48
        assert a.size == min(500, int(np.ceil(40.0 * row.fs_hz / f_n)))
        assert np.isfinite(a).all() and np.std(a) > 0

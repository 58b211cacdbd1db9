"""Labelled datasets: labels, class balance, reproducibility, atomic writing."""

import json

import numpy as np
import pytest

from stiffnet.config import validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.dataset.generate import generate_dataset, simulate_shard
from stiffnet.dataset.labels import beta_class_index, window_labels
from stiffnet.dataset.store import load_dataset
from stiffnet.errors import StiffnetError

SMALL = {
    "n_trajectories": 12,
    "shard_size": 6,
    "windows": {"duration_periods": 6, "per_trajectory": 2},
    "sweep": {"fs_ratio": [50, 80]},
    "solver": {"settle_tolerance": 0.1, "batch_size": 6},
}


def small_config(**over):
    return validate_config(SimulationConfig, {**SMALL, **over})


def test_class_index_edges():
    edges = [5, 15, 35, 60, 100]
    beta = np.array([5, 14.99, 15, 34.9, 35, 59, 60, 99, 100])
    np.testing.assert_array_equal(beta_class_index(beta, edges), [1, 1, 2, 2, 3, 3, 4, 4, 4])
    labels = window_labels(beta[:3], np.array([True, False, True]), edges)
    np.testing.assert_array_equal(labels, [1, 0, 2])


def test_dataset_round_trip_labels_and_card(tmp_path):
    cfg = small_config()
    card = generate_dataset(cfg, tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds", verify=True)
    assert len(ds) == card["n_windows"] == 12 * 2
    assert sum(card["class_balance"].values()) == len(ds)
    # windows: 6 natural periods at the row's fs, a whole number of samples
    lengths = np.array([w.size for w in ds.windows()])
    np.testing.assert_array_equal(lengths, np.round(6 * ds.column("fs_ratio")).astype(int))
    # labels agree with beta and with impacts seen in the window
    beta, label = ds.column("beta"), ds.column("label")
    contact = (ds.column("n_impacts") > 0) | (ds.column("contact_fraction") > 0)
    np.testing.assert_array_equal(label == 0, ~contact)
    np.testing.assert_array_equal(
        label[contact], beta_class_index(beta[contact], [5, 15, 35, 60, 100])
    )
    assert set(ds.column("class")) <= set(card["class_names"])
    # stratified beta: every beta class has trajectories
    traj_beta = beta[ds.column("window") == 0]
    assert len(set(beta_class_index(traj_beta, [5, 15, 35, 60, 100]))) == 4
    saved = json.loads((tmp_path / "ds" / "card.json").read_text())
    assert saved["seed"] == 0 and saved["config"]["n_trajectories"] == 12
    assert saved["engine"] == "closed_form" and len(saved["shards"]) == 2


def test_shards_depend_only_on_seed_and_index():
    cfg = small_config()
    a = simulate_shard(cfg, 1, 6)
    b = simulate_shard(cfg, 1, 6)
    assert a.equals(b)
    other = simulate_shard(small_config(seed=1), 1, 6)
    assert not np.allclose(a.column("beta").to_numpy(), other.column("beta").to_numpy())


def test_gain_free_noise_level_recorded(tmp_path):
    cfg = small_config(sweep={"fs_ratio": [50, 80], "noise_levels": [0.0, 0.05]})
    generate_dataset(cfg, tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    assert set(np.round(ds.column("noise"), 6)) <= {0.0, 0.05}


def test_effect_parameters_are_columns(tmp_path):
    cfg = small_config(
        effects=[{"name": "contact_damping", "params": {"damping_ratio": [0.05, 0.2]}}]
    )
    generate_dataset(cfg, tmp_path / "ds")
    ds = load_dataset(tmp_path / "ds")
    zeta = ds.column("effect.contact_damping.damping_ratio")
    assert zeta.min() >= 0.05 and zeta.max() <= 0.2 and np.ptp(zeta) > 0


def test_interrupted_run_is_refused_then_resumed(tmp_path, monkeypatch):
    import stiffnet.dataset.generate as gen

    calls = []
    real = gen.simulate_shard

    def failing(cfg, shard, n):
        calls.append(shard)
        if shard == 1 and calls.count(1) == 1:
            raise KeyboardInterrupt
        return real(cfg, shard, n)

    monkeypatch.setattr(gen, "simulate_shard", failing)
    cfg = small_config()
    with pytest.raises(KeyboardInterrupt):
        generate_dataset(cfg, tmp_path / "ds")
    # an unfinished folder: shard 0 is in place, but nothing declares a dataset
    assert (tmp_path / "ds" / "shards" / "shard-00000.parquet").is_file()
    assert not (tmp_path / "ds" / "card.json").exists()
    with pytest.raises(StiffnetError, match="not a finished stiffnet dataset.*resume"):
        load_dataset(tmp_path / "ds")
    first = (tmp_path / "ds" / "shards" / "shard-00000.parquet").stat().st_mtime_ns
    seen = []
    card = generate_dataset(cfg, tmp_path / "ds", progress=lambda d, t: seen.append((d, t)))
    assert calls == [0, 1, 1]  # shard 0 was not simulated again
    assert (tmp_path / "ds" / "shards" / "shard-00000.parquet").stat().st_mtime_ns == first
    assert card["run"]["shards_kept"] == 1 and seen == [(1, 2), (2, 2)]
    fresh = generate_dataset(cfg, tmp_path / "fresh")
    assert card["shards"] == fresh["shards"] and card["class_balance"] == fresh["class_balance"]
    assert len(load_dataset(tmp_path / "ds", verify=True)) == 24


def test_resume_recomputes_a_corrupt_shard_and_refuses_another_config(tmp_path, monkeypatch):
    import stiffnet.dataset.generate as gen

    cfg = small_config()
    card = generate_dataset(cfg, tmp_path / "ds")
    (tmp_path / "ds" / "card.json").unlink()  # as if interrupted before the card
    (tmp_path / "ds" / "shards" / "shard-00001.parquet").write_bytes(b"garbage")
    calls = []
    real = gen.simulate_shard
    monkeypatch.setattr(gen, "simulate_shard", lambda c, s, n: calls.append(s) or real(c, s, n))
    again = generate_dataset(cfg, tmp_path / "ds")
    assert calls == [1] and again["shards"] == card["shards"]
    (tmp_path / "ds" / "card.json").unlink()
    with pytest.raises(StiffnetError, match="unfinished run of another config"):
        generate_dataset(small_config(seed=3), tmp_path / "ds")
    calls.clear()
    generate_dataset(small_config(seed=3), tmp_path / "ds", resume=False)  # starts over
    assert calls == [0, 1]
    with pytest.raises(StiffnetError, match="exists and is not empty"):
        generate_dataset(small_config(seed=3), tmp_path / "ds", resume=False)  # finished
    calls.clear()
    generate_dataset(small_config(seed=3), tmp_path / "ds", overwrite=True)
    assert calls == [0, 1]
    assert load_dataset(tmp_path / "ds").card["seed"] == 3
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # old folder gone


def test_finished_dataset_needs_overwrite(tmp_path):
    cfg = small_config()
    generate_dataset(cfg, tmp_path / "ds")
    with pytest.raises(StiffnetError, match="exists and is not empty"):
        generate_dataset(cfg, tmp_path / "ds")
    card = generate_dataset(cfg, tmp_path / "ds", overwrite=True)
    assert card["run"]["shards_run"] == 2


def test_shards_folder_reads_as_one_parquet_dataset(tmp_path):
    """Other tools read the shards directly: pyarrow, and Dask when installed."""
    import pyarrow.dataset as pds

    card = generate_dataset(small_config(), tmp_path / "ds")
    table = pds.dataset(tmp_path / "ds" / "shards", format="parquet").to_table()
    assert table.num_rows == card["n_windows"]
    assert str(table.schema.field("accel").type) == "list<element: float>"
    dd = pytest.importorskip("dask.dataframe")
    frame = dd.read_parquet(str(tmp_path / "ds" / "shards")).compute(scheduler="sync")
    assert len(frame) == card["n_windows"]
    assert frame["accel"].iloc[0].dtype == np.float32 or len(frame["accel"].iloc[0]) > 0


def test_existing_output_refused_before_work(tmp_path, monkeypatch):
    import stiffnet.dataset.generate as gen

    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "keep.txt").write_text("x")
    monkeypatch.setattr(gen, "simulate_shard", lambda *a: pytest.fail("simulated before refusing"))
    with pytest.raises(StiffnetError, match="exists and is not empty"):
        generate_dataset(small_config(), tmp_path / "ds")
    assert (tmp_path / "ds" / "keep.txt").read_text() == "x"


def test_atomic_writes_honour_the_umask(tmp_path):
    import os

    from stiffnet.io_utils import atomic_directory, write_bytes_atomic

    old = os.umask(0o022)
    try:
        write_bytes_atomic(tmp_path / "f.bin", b"x")
        with atomic_directory(tmp_path / "d") as d:
            (d / "a").write_text("a")
    finally:
        os.umask(old)
    assert (tmp_path / "f.bin").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "d").stat().st_mode & 0o777 == 0o755


def test_shards_simulated_together_keep_their_own_draws():
    # two configs that differ in their sweep only (two operating points), simulated in
    # shared batches: each shard's trajectories are those its own generator draws
    from stiffnet.dataset.generate import simulate_shards

    a = small_config(n_trajectories=4, shard_size=4, sweep={"gap": [0.5, 0.6]})
    b = small_config(n_trajectories=3, shard_size=4, sweep={"gap": [2.0, 2.2]})
    ta, tb = simulate_shards([a, b], [0, 1])
    for t, cfg, shard in ((ta, a, 0), (tb, b, 1)):
        # the closed form's rows do not depend on their batch: the shard, bit for bit
        assert t.equals(simulate_shard(cfg, shard, cfg.n_trajectories))
    assert set(tb.column("trajectory").to_pylist()) == {4, 5, 6}
    gap = tb.column("gap").to_numpy()
    assert np.all((gap >= 2.0) & (gap <= 2.2))
    with pytest.raises(StiffnetError, match="must share.*windows"):
        simulate_shards([a, small_config(windows={"duration_periods": 8, "per_trajectory": 2})],
                        [0, 1])  # fmt: skip


def _shared_and_alone(effects: list[dict]) -> list[tuple]:
    """Two operating points' shards in shared batches of 3 rows and each alone (batches of
    4 + 3 rows compose otherwise): pairs of tables."""
    from stiffnet.dataset.generate import simulate_shards

    solver = {"settle_tolerance": 0.1, "min_transient_periods": 5, "batch_size": 3,
              "substeps": 4, "record_substeps": "transient"}  # fmt: skip
    sweep = {"noise": [0.02, 0.05], "damping": [0.04, 0.05]}
    cfgs = [
        small_config(
            n_trajectories=n,
            shard_size=4,
            sweep={"gap": gap, **sweep},
            effects=effects,
            solver=solver,
        )  # fmt: skip
        for n, gap in ((4, [0.5, 0.6]), (3, [2.0, 2.2]))
    ]
    shared = simulate_shards(cfgs, [0, 1])
    return [(t, simulate_shard(c, i, c.n_trajectories))
            for i, (c, t) in enumerate(zip(cfgs, shared, strict=True))]  # fmt: skip


def test_a_shard_in_shared_batches_has_its_own_initial_states_and_noise():
    # a contact law for half the rigs (two groups, one on the numerical engine), measurement
    # effects that draw their own noise, on for half the rigs: every draw is the shard's
    effects = [{"name": "hertz_contact", "probability": 0.5},
               {"name": "colored_noise", "probability": 0.5},
               {"name": "adc", "probability": 0.5}]  # fmt: skip
    numerical_rows = 0
    for shared, alone in _shared_and_alone(effects):
        for col in set(alone.column_names) - {"accel", "contact_fraction"}:
            assert shared.column(col).equals(alone.column(col)), col  # impact counts included
        noise_std = (shared.column("noise").to_numpy() * shared.column("amplitude").to_numpy()
                     * shared.column("omega").to_numpy() ** 2)  # fmt: skip
        numerical = shared.column("effect.hertz_contact.active").to_numpy() == 1
        fraction = [t.column("contact_fraction").to_numpy() for t in (shared, alone)]
        impacts = shared.column("n_impacts").to_numpy()
        pairs = zip(shared.column("accel").to_pylist(), alone.column("accel").to_pylist(),
                    strict=True)  # fmt: skip
        for k, (a, b) in enumerate(pairs):
            a, b = np.asarray(a), np.asarray(b)
            if numerical[k]:  # the batch's steps: the integrator's error, within the noise
                assert np.sqrt(np.mean((a - b) ** 2)) < 0.5 * noise_std[k]
                # a contact's first or last sample may move: at most two per impact
                assert abs(fraction[0][k] - fraction[1][k]) * a.size <= 2 * impacts[k] + 1e-9
            else:  # the closed form: the same initial state and noise, bit for bit
                np.testing.assert_array_equal(a, b)
                assert fraction[0][k] == fraction[1][k]
        numerical_rows += int(numerical.sum())
    assert 0 < numerical_rows < 14


def test_shared_batches_refuse_a_measurement_chain_that_draws_by_the_signal(monkeypatch):
    from stiffnet.simulator.simulator import Simulator

    measure = Simulator.measure

    def drawing_by_value(self, accel, batch, fs_ratio, noise, draws, rng):
        rng.standard_normal(int(np.any(accel != 0)))  # zeros draw nothing, motion one number
        return measure(self, accel, batch, fs_ratio, noise, draws, rng)

    monkeypatch.setattr(Simulator, "measure", drawing_by_value)
    with pytest.raises(StiffnetError, match="drew by the signal's values"):
        _shared_and_alone([])


def _analog_world(oversampled: int) -> SimulationConfig:
    """A quiet world logged at 113.8 Hz (f_n 9.48 Hz, 12 x f_n) behind a lightly damped 60 Hz
    mount: at the logger's rate the stage lies above 0.45 fs and is skipped."""
    chain = {"resonance_hz": 60.0, "resonance_damping": 0.02, "highpass_hz": 0.0,
             "lowpass_hz": 0.0}  # fmt: skip
    effects = [{"name": "sensor_dynamics", "probability": 1.0, "params": chain}]
    return small_config(
        n_trajectories=4, shard_size=4,
        sweep={"fs_ratio": [12.0, 12.0], "noise": [0.0, 0.0], "gap": [0.3, 0.5]},
        windows={"duration_periods": 16, "per_trajectory": 2},
        effects=effects,
        solver={"settle_tolerance": 0.1, "batch_size": 4, "oversampled": oversampled},
    )  # fmt: skip


def test_an_oversampled_world_samples_its_analog_chain_output():
    # the hardware filters the continuous motion and the logger samples its output, the chain
    # running long before the record: the world's records approach that (the chain run 32
    # times faster than the logger, as long before) when it is oversampled, not when the
    # chain runs on the logger's samples
    from stiffnet.dataset.generate import build_simulator, lead_samples, shard_rng
    from stiffnet.dataset.sampling import sample_plan

    def accel(cfg):
        return np.stack(simulate_shard(cfg, 0, 4).column("accel").to_pylist())

    cfg = _analog_world(1)
    rng = shard_rng(cfg.seed, 0)
    plan = sample_plan(cfg, 4, rng)
    sim = build_simulator(cfg)
    draws = sim.draw_inputs(plan.batch, rng)
    w = int(plan.window_samples[0])
    lead = int(lead_samples(build_simulator(_analog_world(8)), plan)[0])
    assert lead > 0
    fine = sim.motion_of(plan.batch, plan.fs_ratio * 32, (lead + 2 * w) * 32, draws).accel
    analog = sim.measure(fine, plan.batch, plan.fs_ratio * 32, np.zeros(4), draws, rng)
    analog = analog[:, lead * 32 :: 32].reshape(8, w)  # two windows a trajectory, in order
    scale = np.sqrt(np.mean(analog**2))
    logger, oversampled = (np.sqrt(np.mean((accel(_analog_world(k)) - analog) ** 2)) / scale
                           for k in (1, 8))  # fmt: skip
    assert oversampled < 0.1 * logger
    assert oversampled < 0.05
    # in shared batches (operating points together) each shard is still the shard alone
    from stiffnet.dataset.generate import simulate_shards

    world = _analog_world(8)
    other = world.model_copy(update={"sweep": world.sweep.model_copy(update={"gap": [1.0, 1.2]})})
    shared = simulate_shards([world, other], [0, 1])
    for shard, (c, t) in enumerate(zip((world, other), shared, strict=True)):
        assert t.equals(simulate_shard(c, shard, c.n_trajectories))

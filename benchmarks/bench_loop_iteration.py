"""Speed of a measurement-loop iteration with a learned contact law (target: GBM <= 3 min).

Part 1b (``--shared``): the loop's operating-point dataset (the rig's two-stage campaign
of part 4, its first points) one batch per point against shared batches. Part 1c
(``--solvers``): the same dataset with other solver settings (substeps, warm start), CPU and
how far the windows move against the noise. Part 1d (``--zero-chain``): what the shared
batches' pass of the measurement chain on zeros (to move each shard's generator) costs.
Part 1 (ratio, same run): the iteration's dataset, the part that dominated (the learned law
needs the numerical engine). The config is the one ``loop`` writes: the ideal world
(``configs/sim/ideal.yaml``: fs/f_n 50-500, four 16-period windows per trajectory) plus
``learned_contact`` with a two-stage prior (knee 0.2 +-25 %, ratio 3 +-25 %). Old path:
every row of a batch integrated for the batch's longest record,
``substeps`` RK4 steps per sample at any rate. New path: each row integrated at its own
rate up to its own record (``row_samples``, :func:`stiffnet.simulator.numerical.
recording_substeps`). Part 2 (``--loop``): one whole GBM loop iteration on the example
manifest's eight points simulated with a two-stage user law, with its phases' seconds.
Part 3 (``--seeds``): how much the retrained model's campaign accuracy hangs on the
dataset's seed. The loop test's iteration (``--operating-points``, the law as discovered,
its prior inside the discovery's intervals) is run once; its dataset and GBM are then
drawn again at each seed, without and with a share of trajectories near the class edges
(``--edge-share``, :func:`stiffnet.measurement.operating_points.edge_configs`); each row lists the
recordings classed wrong with their β read. Part 4 (``--rig``): the issue's held-out test as
a user runs it, on campaigns of the independent rig (``tests/independent_rig.py``: 24
recordings, the eight operating points of ``tests/test_independent_rig.POINTS`` with three
betas each across the classes, 3 s at 2 % noise) with contact laws the library lacks
(``RIG_LAWS``; ``beam``: the stop at a cantilever's tip, two modes) or the ideal one:
``stiffnet diagnose`` (the rig candidates of the tests) and, where it proposes a law,
the plain ``stiffnet loop CAMPAIGN --diagnosis D --family F --iterations 1`` (GBM, or
``--rig-family``; no world option: the loop's ``auto`` world moves to the campaign's
operating points when the learned law is added; ``--rig-trajectories`` passes
``--n-trajectories``, default the loop's own; tracking into ``--rig-dir``'s
``mlflow.db``); the CLI's CPU seconds are its processes'. After the table, each loop's
last iteration: its world and why, trajectories, the misses (β: read, class, point and
gap) and the CPU seconds of its phases. Part 4b (``--rig-seeds``): that loop's iteration 1 on the
two-stage rig campaign without the diagnosis (the law's prior as discovered), drawn at each
dataset seed and near-edge share, with the accuracy the class read from the beta head
would give; ``--rig-families gbm,cnn`` trains each family on the same dataset (the CNN is
the loop's default family), ``--rig-weights none,small_gaps`` draws the dataset with each
per-point rule (:func:`stiffnet.measurement.operating_points.point_weights`), and
``--rig-per-shard`` simulates it one batch per shard (the loop shares batches). Part 4c
(``--rig-iteration STATE --rig-diagnosis D``): the plain loop's iteration 1 alone on that
campaign (or ``--rig-campaign``), resumed from STATE's iteration 0 with the diagnosis D, at
each dataset size (``--rig-sizes``) and seed (``--rig-dataset-seeds``): the model alone, the
reported reading and the CPU seconds of every phase (world simulation, features, GBM fit,
calibration, the predictor's evaluation, β by simulation, candidate chains, ...;
``--rig-repeats`` runs). Part 4d (``--rig-orbits ROWS``): the orbits (impacts per
forcing period) the loop's training windows reach at those campaign rows against the
recording's, by β band. Prints Markdown with the machine's load.

    OMP_NUM_THREADS=1 PYTHONPATH=.:tests python benchmarks/bench_loop_iteration.py \
        --trajectories 48 [--loop 120] [--seeds 0,1,7 --seed-trajectories 400 --edge-share 0.5]
    ... benchmarks/bench_loop_iteration.py --shared 6,24
    ... benchmarks/bench_loop_iteration.py --solvers '6,24;{"substeps": 8};{"substeps": 4}'
    ... benchmarks/bench_loop_iteration.py --zero-chain 24,400 --rig-dir /tmp/rig
    ... benchmarks/bench_loop_iteration.py --rig hunt_crossley,ideal,beam --rig-dir /tmp/rig
    ... benchmarks/bench_loop_iteration.py --rig-seeds 0,1 --rig-shares 0,0.5 --rig-dir /tmp/rig
    ... benchmarks/bench_loop_iteration.py --rig-iteration /tmp/rig/two_stage-loop \
        --rig-diagnosis d.json --rig-dir /tmp/rig [--rig-campaign C --rig-sizes 400,1600]
    ... benchmarks/bench_loop_iteration.py --rig-seeds 0,1 --rig-shares 0 --rig-per-shard \
        --rig-families gbm,cnn --rig-weights none,small_gaps --rig-dir /tmp/rig
    ... benchmarks/bench_loop_iteration.py --rig-orbits 3,6 --rig-seeds 0,1 --rig-dir /tmp/rig
    ... benchmarks/bench_loop_iteration.py --rig-seeds 0 --rig-shares 0 --rig-hold none,orbit \
        --rig-families gbm,cnn --rig-dir /tmp/rig   [--rig-jitter 0.02] [--rig-law 0.25,2.5]
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from stiffnet.config import load_config  # noqa: E402
from stiffnet.config.sim import SimulationConfig  # noqa: E402
from stiffnet.dataset import generate  # noqa: E402
from stiffnet.shipped import default_config  # noqa: E402
from stiffnet.simulator.simulator import Simulator  # noqa: E402

LAW = {"name": "learned_contact", "probability": 1.0,
       "params": {"knee": [0.15, 0.25], "knee_ratio": [2.25, 3.75]}}  # fmt: skip


def loop_config(n: int) -> SimulationConfig:
    """The ideal config with the learned law's prior, as a loop iteration writes it."""
    d = load_config(SimulationConfig, default_config("sim/ideal.yaml")).model_dump(mode="json")
    d.update(n_trajectories=n, effects=[LAW])
    return SimulationConfig.model_validate(d)


class _OldPath(Simulator):
    """The simulator before per-row records: ``row_samples`` ignored."""

    def simulate(self, *args, row_samples=None, **kwargs):  # noqa: ARG002
        return super().simulate(*args, **kwargs)


def time_dataset(cfg: SimulationConfig, old: bool) -> tuple[float, float, np.ndarray]:
    build = generate.build_simulator
    if old:

        def build_old(c, off=frozenset()):
            s = build(c, off)
            s.__class__ = _OldPath
            return s

        generate.build_simulator = build_old
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        table = generate.simulate_shard(cfg, 0, cfg.n_trajectories)
        accel = np.concatenate(table.column("accel").to_numpy(False))
        return time.perf_counter() - t0, time.process_time() - c0, accel
    finally:
        generate.build_simulator = build


def dataset_ratio(n: int) -> None:
    cfg = loop_config(n)
    new_s, new_c, new_a = time_dataset(cfg, old=False)
    old_s, old_c, old_a = time_dataset(cfg, old=True)
    # the same windows up to the integration error of the coarser substeps
    err = np.max(np.abs(new_a - old_a)) / np.max(np.abs(old_a))
    print(f"| dataset, {n} trajectories, learned two-stage law | {old_s:.1f} (CPU {old_c:.1f}) "
          f"| {new_s:.1f} (CPU {new_c:.1f}) | {old_c / new_c:.1f}x CPU | {err:.2e} | "
          f"{os.getloadavg()[0]:.1f} |")  # fmt: skip


#: The rig two-stage campaign's law as discovered (part 4), its prior the discovery's +-5 %.
RIG_LAW_PRIOR = {"name": "learned_contact", "probability": 1.0,
                 "params": {"knee": [0.2366, 0.2615], "knee_ratio": [2.314, 2.558],
                            "reference_penetration": 0.54}}  # fmt: skip


def rig_point_configs(
    points: int, n: int, solvers: list[dict], folder: Path | None = None
) -> list[list[SimulationConfig]]:
    """The loop's operating-point configs (``n`` trajectories, the discovered law's prior),
    one list per ``solvers`` entry (settings over the ideal config's), at the first
    ``points`` rows of the rig's two-stage campaign (part 4, simulated once, kept in
    ``folder`` when given)."""
    from independent_rig import write_campaign

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.operating_points import operating_point_configs

    d = load_config(SimulationConfig, default_config("sim/ideal.yaml")).model_dump(mode="json")
    d.update(n_trajectories=n, effects=[RIG_LAW_PRIOR])
    with tempfile.TemporaryDirectory() as tmp:
        camp_dir = (folder or Path(tmp)) / "two_stage"
        if not (camp_dir / "manifest.csv").is_file():
            write_campaign(camp_dir, rig_runs("two_stage"))
        rows = load_campaign(camp_dir).rows[:points]
    return [
        operating_point_configs(
            SimulationConfig.model_validate({**d, "solver": {**d["solver"], **solver}}), rows
        )
        for solver in solvers
    ]


def window_difference(new, ref) -> tuple[np.ndarray, float]:
    """Each window's RMS difference over its noise std (the same draws either way), and the
    share of windows whose impact counts are equal, between two tables of the same rows."""
    noise = (ref.column("noise").to_numpy() * ref.column("amplitude").to_numpy()
             * ref.column("omega").to_numpy() ** 2)  # fmt: skip
    old = [np.asarray(a) for a in ref.column("accel").to_pylist()]
    now = [np.asarray(a) for a in new.column("accel").to_pylist()]
    rel = np.array([np.sqrt(np.mean((a - b) ** 2)) for a, b in zip(now, old, strict=True)])
    same = np.mean(new.column("n_impacts").to_numpy() == ref.column("n_impacts").to_numpy())
    return rel / noise, float(same)


def shared_batches_ratio(points: int, n: int, warm: float = 0.0, folder: Path | None = None):
    """The loop's operating-point dataset, one batch per point (:func:`stiffnet.dataset.
    generate.simulate_shard`) against shared batches (:func:`stiffnet.dataset.generate.
    simulate_shards`), back to back on the first ``points`` of the rig's two-stage campaign
    (part 4), ``n`` trajectories; the loop's config with the discovered law's prior (knee
    0.249, ratio 2.436, +-5 %), warm start ``warm``. Both draw the same trajectories,
    initial states and noise: the windows differ by the integrator's error only (RMS over
    the noise std: median / 90 % / max, the share above 1; impact counts equal)."""
    import pyarrow as pa

    (configs,) = rig_point_configs(points, n, [{"warm_start": warm}], folder)
    c0 = time.process_time()
    alone = [generate.simulate_shard(c, i, c.n_trajectories) for i, c in enumerate(configs)]
    c1 = time.process_time()
    shared = generate.simulate_shards(configs, list(range(len(configs))))
    c2 = time.process_time()
    a, b = pa.concat_tables(alone), pa.concat_tables(shared)
    same = a.num_rows == b.num_rows and all(
        a.column(c).equals(b.column(c)) for c in ("trajectory", "window", "beta", "gap", "noise")
    )
    rel, impacts = window_difference(b, a)
    print(f"| operating-point dataset, {len(configs)} points, {n} trajectories, warm start "
          f"{warm} | CPU {c1 - c0:.1f} | CPU {c2 - c1:.1f} | {(c1 - c0) / (c2 - c1):.1f}x CPU "
          f"| same rows: {same} | {np.median(rel):.3f} / {np.quantile(rel, 0.9):.3f} / "
          f"{rel.max():.2f}, {np.mean(rel > 1):.1%} above | {impacts:.1%} | "
          f"{os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


def _orbit_kind(stats) -> str:
    """``1/1``, ``2/2`` (2 impacts every 2 forcing periods) or ``other`` for a window."""
    from stiffnet.measurement.orbits import orbit_pattern

    pattern = orbit_pattern(stats)
    return {(1, 1): "1/1", (2, 2): "2/2"}.get(pattern, "other") if pattern else "other"


def rig_orbits(rows: list[int], seed: int, n: int, folder: Path) -> None:
    """Part 4d (``--rig-orbits ROWS``): which orbit the loop's training windows at the rig's
    two-stage campaign rows ``rows`` settle on, against the recording's. The rows' shards
    of the loop's operating-point dataset (``n`` trajectories, the discovered law's prior,
    dataset seed ``seed``, shared batches) are simulated and every window (16 natural
    periods, like the recording's first 16) named as ``diagnose`` names an orbit
    (:func:`stiffnet.measurement.orbits.orbit_pattern` on the window's statistics), with
    counts by β band; the impacts per forcing period are the simulation's own."""
    from collections import Counter

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.statistics import signal_statistics

    (configs,) = rig_point_configs(24, n, [{}], folder)
    configs = [c.model_copy(update={"seed": seed}) for c in configs]
    camp_dir = folder / "two_stage"
    camp = load_campaign(camp_dir)
    c0 = time.process_time()
    tables = generate.simulate_shards([configs[i] for i in rows], rows)
    cpu = time.process_time() - c0
    bands = [(5.0, 35.0), (35.0, 60.0), (60.0, 100.0)]
    for i, table in zip(rows, tables, strict=True):
        r = camp.rows[i]
        rec = np.loadtxt(camp_dir / r.recording, delimiter=",", skiprows=1)[:, 1]
        stats = signal_statistics(rec, r.fs_hz, r.natural_frequency_hz, r.frequency_ratio,
                                  inclination=False)  # fmt: skip
        kinds, per_period = Counter(), []
        by_band = {b: Counter() for b in bands}
        for w in table.to_pylist():
            a = np.asarray(w["accel"], dtype=float)
            ws = signal_statistics(a, w["fs_hz"], w["natural_frequency_hz"], w["omega"],
                                   inclination=False)  # fmt: skip
            kind = _orbit_kind(ws)
            kinds[kind] += 1
            per_period.append(w["n_impacts"] * w["fs_ratio"] / (a.size * w["omega"]))
            band = next((b for b in bands if b[0] <= w["beta"] < b[1]), None)
            if band:
                by_band[band][kind] += 1
        cells = "; ".join(f"β {lo:g}-{hi:g}: " + ", ".join(f"{k} {c[k]}" for k in sorted(c))
                          for (lo, hi), c in by_band.items())  # fmt: skip
        print(f"| {i} ({Path(r.recording).stem}) | {r.gap:g} | {_orbit_kind(stats)} | "
              f"{sum(kinds.values())} | {', '.join(f'{k} {kinds[k]}' for k in sorted(kinds))} | "
              f"{cells} | {np.median(per_period):.2f} |", flush=True)  # fmt: skip
    print(f"\n{len(rows)} shards simulated in {cpu:.1f} s CPU, load {os.getloadavg()[0]:.1f}")


def zero_chain(points: int, n: int, folder: Path | None = None, repeats: int = 3) -> None:
    """Part 1d (``--zero-chain``): what the shared batches' first pass through each group's
    measurement chain costs. :func:`stiffnet.dataset.generate.simulate_shards` draws every
    shard's inputs first (``_shard_pieces``), running the chain on zeros to move the
    shard's generator past its draws, and runs it again on the motion; here the draws'
    CPU with the chain and with ``Simulator.measure`` replaced by a pass-through (the least
    of ``repeats`` runs each, the motion not simulated), at the first ``points`` rows of the
    rig's two-stage campaign, ``n`` trajectories, the discovered law's prior."""
    (configs,) = rig_point_configs(points, n, [{}], folder)

    def draws() -> list:
        sim = generate.build_simulator(configs[0])
        sims = {frozenset(): sim}
        return [p for i, c in enumerate(configs) for p in generate._shard_pieces(c, i, sim, sims)]

    def least_cpu() -> tuple[float, list]:
        runs = []
        for _ in range(repeats):
            c0 = time.process_time()
            out = draws()
            runs.append(time.process_time() - c0)
        return min(runs), out

    real = Simulator.measure
    with_chain, pieces = least_cpu()
    Simulator.measure = lambda self, accel, *a, **k: accel
    try:
        without, _ = least_cpu()
    finally:
        Simulator.measure = real
    samples = sum(len(p.plan) * p.n_samples for p in pieces)
    print(f"| {len(configs)} points, {n} trajectories, {len(pieces)} groups | {samples:,} | "
          f"{with_chain:.3f} | {without:.3f} | {with_chain - without:.3f} | "
          f"{os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


def solver_ratio(points: int, n: int, solvers: list[dict]) -> None:
    """The operating-point dataset of part 1b in shared batches with each solver setting
    (``substeps``, ``warm_start``) against the first: CPU and how far the windows move, as
    the RMS difference over the window's noise std (the same draws and noise either way)."""
    import pyarrow as pa

    runs = []
    for configs in rig_point_configs(points, n, solvers):
        c0 = time.process_time()
        table = pa.concat_tables(generate.simulate_shards(configs, list(range(len(configs)))))
        runs.append((time.process_time() - c0, table))
    cpu0, ref = runs[0]
    for solver, (cpu, t) in zip(solvers, runs, strict=True):
        rel, same = window_difference(t, ref)
        print(f"| {solver} | {cpu:.1f} | {cpu0 / cpu:.2f}x | {np.median(rel):.3f} / "
              f"{np.quantile(rel, 0.9):.3f} / {rel.max():.2f} | {np.mean(rel > 1):.0%} | "
              f"{same:.0%} | {os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


def time_campaign(camp, effects, old: bool) -> tuple[float, float, list[np.ndarray]]:
    """Wall and CPU seconds of one simulation of the campaign's rows (what compare, evaluate
    and every diagnose evaluation run), old or new path."""
    from stiffnet.campaign import simulate as csim

    real = csim.Simulator
    if old:
        csim.Simulator = _OldPath
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        lengths = [camp.recording(i).accel.size for i in range(len(camp.rows))]
        out = csim.simulate_rows(camp.rows, effects, lengths)
        return time.perf_counter() - t0, time.process_time() - c0, out
    finally:
        csim.Simulator = real


def campaign_ratio() -> None:
    import unknown_contact_laws as laws
    from test_learned_law_diagnose import batch_campaign

    from stiffnet.effects.learned_contact import LearnedContact

    with tempfile.TemporaryDirectory() as tmp:
        camp = batch_campaign(Path(tmp) / "two", [laws.TwoStageContact(knee=0.2, ratio=3.0)])
        law = [LearnedContact(knee=0.2, knee_ratio=3.0)]
        new_s, new_c, new_a = time_campaign(camp, law, old=False)
        old_s, old_c, old_a = time_campaign(camp, law, old=True)
    err = max(np.max(np.abs(a - b)) / np.max(np.abs(b)) for a, b in zip(new_a, old_a, strict=True))
    print(f"| campaign simulation (8 recordings, 3 s, learned two-stage law) | {old_s:.1f} "
          f"(CPU {old_c:.1f}) | {new_s:.1f} (CPU {new_c:.1f}) | {old_c / new_c:.1f}x CPU | "
          f"{err:.2e} | {os.getloadavg()[0]:.1f} |")  # fmt: skip


def loop_iteration(n: int) -> None:
    import unknown_contact_laws as laws
    from test_learned_law_diagnose import batch_campaign

    from stiffnet.measurement.loop import run_loop

    with tempfile.TemporaryDirectory() as tmp:
        camp = batch_campaign(Path(tmp) / "two", [laws.TwoStageContact(knee=0.2, ratio=3.0)])
        start = load_config(SimulationConfig, default_config("sim/ideal.yaml"))
        t0, c0 = time.perf_counter(), time.process_time()
        res = run_loop(camp, start, Path(tmp) / "state", iterations=1, family="gbm",
                       n_trajectories=n, tracking_uri=None,
                       candidates=["contact_damping"])  # fmt: skip
        total, cpu = time.perf_counter() - t0, time.process_time() - c0
    for it in res["iterations"]:
        sec = it["seconds"]
        print(f"| {it['label']} | {n} | {it['metrics']['discrepancy']:.3g} | "
              f"{it['metrics'].get('accuracy')} | {sec} | {os.getloadavg()[0]:.1f} |")  # fmt: skip
    print(f"\nwhole run (iterations 0 and 1, diagnosis included): {total:.0f} s wall, "
          f"{cpu:.0f} s CPU (one process)")  # fmt: skip


def _retrained(
    camp,
    cfg,
    work: Path,
    edge_share: float,
    shared: bool = False,
    effects=None,
    families: tuple[str, ...] = ("gbm",),
    weights: str = "none",
    hold: str = "none",
    jitter: float | None = None,
    eval_ratio: bool = False,
) -> dict[str, tuple]:
    """The iteration's dataset at the campaign's points and each family's model on it, at
    ``cfg``'s seed (evaluated with ``effects``, default ``cfg``'s, as the campaign's
    dynamics; ``weights`` the per-point rule of
    :func:`stiffnet.measurement.operating_points.point_weights`; ``hold`` ``orbit``: each
    row's windows held on its recording's orbit, :func:`stiffnet.measurement.
    operating_points.hold_orbit`; ``jitter`` each row's relative jitter, default the
    loop's). The dataset is drawn once:
    each family's row is (evaluation, wall s, CPU s), the dataset's seconds in every row
    (and apart under the key ``"dataset"``: wall s, CPU s). The evaluation is the learned
    model's alone: the reading by simulation, which does not depend on the model's dataset
    and is not printed here, is not run (35-40 s CPU per evaluation at load 10-16). With
    ``eval_ratio``, each model is evaluated again by the old and this code's estimate
    (:func:`evaluation_ratio`), outside the row's seconds."""
    from stiffnet.measurement import operating_points as ops
    from stiffnet.measurement.compare import config_effects
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.loop import _train_config
    from stiffnet.measurement.simulated_beta import SimulatedBetaConfig
    from training.train import train

    t0, c0 = time.perf_counter(), time.process_time()
    orbits = ops.measured_orbits(camp) if hold == "orbit" else None
    card = ops.operating_point_dataset(
        cfg, camp.rows, work / "data", edge_share=edge_share, shared_batches=shared,
        weights=weights, orbits=orbits, jitter=ops.JITTER if jitter is None else jitter,
    )  # fmt: skip
    data_wall, data_cpu = time.perf_counter() - t0, time.process_time() - c0
    for h in card["operating_points"]["orbit_hold"] or []:
        if h["orbit"] is not None and h["on_orbit"] < h["windows"]:
            print(f"  orbit hold, row {h['row']} ({Path(camp.rows[h['row']].recording).stem}): "
                  f"orbit {h['orbit']}, {h['on_orbit']} of {h['windows']} windows on it, "
                  f"{'held' if h['held'] else 'kept whole'}", flush=True)  # fmt: skip
    dyn = config_effects(cfg) if effects is None else effects
    out: dict = {"dataset": (data_wall, data_cpu)}
    for family in families:
        t1, c1 = time.perf_counter(), time.process_time()
        model = train(work / "data", _train_config(family, None), work / family, progress=None)
        ev = evaluate_campaign(camp, model["paths"]["onnx"], dyn, require_beta=False,
                               simulation=SimulatedBetaConfig(enabled=False))  # fmt: skip
        out[family] = (ev, data_wall + time.perf_counter() - t1,
                       data_cpu + time.process_time() - c1)  # fmt: skip
        if eval_ratio:
            evaluation_ratio(camp.folder, model["paths"]["onnx"], dyn)
    return out


def _old_estimate(estimate):
    """The restoring-force estimate as it was (``--rig-eval-ratio``'s old path): the
    record-as-recorded map behind a known chain fitted with its contact law too (``contact``
    ignored); returns the undo."""
    fit_map = estimate._fit_map

    def with_law(*args, contact=True, **kwargs):  # noqa: ARG001
        return fit_map(*args, **kwargs)

    estimate._fit_map = with_law

    def undo() -> None:
        estimate._fit_map = fit_map

    return undo


def evaluation_ratio(folder: Path, onnx: str, effects) -> None:
    """Part 4b's ``--rig-eval-ratio``: the campaign's evaluation (the learned model's, as
    :func:`_retrained` runs it) by the old estimate (:func:`_old_estimate`) and by this
    code's, back to back on the same model, each on the campaign loaded afresh (nothing
    memoised between them): CPU seconds, the readings the chain's pooling made, the profiled
    high-pass corner and its interval, the metrics, and whether the recordings' answers are
    the same (each recording's row of the report, compared whole)."""
    import serving.campaign_chain as cc
    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.evaluate import evaluate_campaign
    from stiffnet.measurement.simulated_beta import SimulatedBetaConfig
    from stiffnet.restoring_force import estimate

    runs, real_read, reads = {}, cc.read_through, {"old": 0, "new": 0}
    for name in ("old", "new"):

        def counted(*args, _name=name, **kwargs):
            reads[_name] += 1
            return real_read(*args, **kwargs)

        undo = _old_estimate(estimate) if name == "old" else (lambda: None)
        cc.read_through = counted
        try:
            c0, load = time.process_time(), os.getloadavg()[0]
            ev = evaluate_campaign(load_campaign(folder), onnx, effects, require_beta=False,
                                   simulation=SimulatedBetaConfig(enabled=False))  # fmt: skip
            runs[name] = (ev, time.process_time() - c0, reads[name], load)
        finally:
            undo()
            cc.read_through = real_read

    def row(name: str) -> str:
        ev, cpu, n_reads, load = runs[name]
        hp = (ev["sensor"].get("stages") or {}).get("highpass_hz") or {}
        m = ev["metrics"]
        corner = (f"{hp['value']:.4f} [{hp['interval'][0]:.4f}, {hp['interval'][1]:.4f}]"
                  if hp else "-")  # fmt: skip
        return (f"| {name} | {cpu:.1f} | {n_reads} | {corner} | "
                f"{_pair(m['learned']['accuracy'], m['learned']['beta_mape'])} | "
                f"{_pair(m['restoring_force']['accuracy'], m['restoring_force']['beta_mape'])} "
                f"| {load:.1f} |")  # fmt: skip

    print("\n| estimate | evaluation CPU s | pooling readings | profiled high-pass corner "
          "[interval] Hz | learned accuracy / MAPE | restoring force accuracy / MAPE "
          "| load |")  # fmt: skip
    print("|---" * 7 + "|")
    print(row("old"))
    print(row("new"))
    old, new = runs["old"][0], runs["new"][0]
    same = sum(a == b for a, b in zip(old["recordings"], new["recordings"], strict=True))
    print(f"\nevaluation CPU ×{runs['old'][1] / runs['new'][1]:.3f}; recordings' rows equal: "
          f"{same} of {len(new['recordings'])}; the pooled chain equal: "
          f"{old['sensor'] == new['sensor']}\n", flush=True)  # fmt: skip


def seed_spread(seeds: list[int], n: int, edge_share: float) -> None:
    import unknown_contact_laws as laws
    from test_learned_law_diagnose import batch_campaign

    from stiffnet.measurement.loop import run_loop

    print("\n| dataset seed | near-edge share | accuracy | beta MAPE | wrong (beta: read) "
          "| wall s | CPU s | load |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        camp = batch_campaign(Path(tmp) / "two", [laws.TwoStageContact(knee=0.2, ratio=3.0)])
        d = load_config(SimulationConfig, default_config("sim/ideal.yaml")).model_dump(mode="json")
        d["sweep"].update(fs_ratio=[60, 120], noise=[0.0, 0.05])  # the loop test's settings
        d["solver"].update(settle_tolerance=0.05, min_transient_periods=10, substeps=4)
        d["windows"]["per_trajectory"] = 2
        run_loop(camp, SimulationConfig.model_validate(d), Path(tmp) / "state", iterations=1,
                 family="gbm", n_trajectories=50, tracking_uri=None,
                 candidates=["contact_damping"], world="operating_points")  # fmt: skip
        law = load_config(SimulationConfig, Path(tmp) / "state" / "iter-001" / "config.yaml")
        for seed in seeds:
            for share in (0.0, edge_share):
                cfg = law.model_copy(update={"seed": seed, "n_trajectories": n})
                work = Path(tmp) / f"seed{seed}-{share}"
                ev, wall, cpu = _retrained(camp, cfg, work, share)["gbm"]
                m = ev["metrics"]["learned"]
                bad = [r for r in ev["recordings"] if r["class"] != r["true_class"]]
                wrong = ", ".join(f"{r['beta']:g}: {r['beta_estimate']:.1f}" for r in bad)
                print(f"| {seed} | {share} | {m['accuracy']:.3f} | {m['beta_mape']:.3f} | "
                      f"{wrong or '-'} | {wall:.0f} | {cpu:.0f} | {os.getloadavg()[0]:.1f} |",
                      flush=True)  # fmt: skip


#: Part 4's laws: the rig's own parametrisation, at levels the tests do not use.
RIG_LAWS: dict[str, dict] = {
    "ideal": {},
    "two_stage": {"contact": "two_stage", "knee_mm": 0.25, "stage_ratio": 2.5},
    "hunt_crossley": {"contact": "hunt_crossley", "hc_lambda_s_per_m": 6.0},
    "power_law": {"contact": "power_law", "power_exponent": 1.8, "power_d0_mm": 0.4},
    # the stop at a cantilever's tip (tests/test_discovery_independent_rig.BEAM)
    "beam": {
        "contact": "beam",
        "beam_mass_ratio": 0.4,
        "beam_f1_ratio": 10.0,
        "beam_modes": 2,
        "beam_damping": 0.02,
    },
}
RIG_CANDIDATES = ["contact_damping", "forcing_harmonics", "gap_drift", "sensor_dynamics"]


def rig_runs(law: str, seed: int = 11) -> list:
    """The 24 recordings of part 4: three betas (integers, classes in turn) per point."""
    from test_independent_rig import rig_campaign_runs

    return rig_campaign_runs(3.0, seed, **RIG_LAWS[law])


def simulate_once(module) -> None:
    """``module.simulate_shards`` answering a repeat of the same configs and shards from
    memory: the settings that differ only after the simulation (the orbit hold filters the
    simulated windows) share one dataset's simulation, its CPU counted in the first."""
    real = module.simulate_shards
    memo: dict = {}

    def once(cfgs, shards):
        key = (tuple(generate.config_fingerprint(c) for c in cfgs), tuple(shards))
        if key not in memo:
            memo.clear()  # one dataset at a time
            memo[key] = real(cfgs, shards)
        return memo[key]

    module.simulate_shards = once


def rig_seeds(
    folder: Path,
    seeds: list[int],
    shares: list[float],
    shared: bool,
    n: int,
    families: tuple[str, ...] = ("gbm",),
    weights: tuple[str, ...] = ("none",),
    holds: tuple[str, ...] = ("none",),
    centre: tuple[float, float] | None = None,
    jitters: tuple[float | None, ...] = (None,),
    eval_ratio: bool = False,
) -> None:
    """Part 4b (``--rig-seeds``): the loop's iteration 1 on the rig's two-stage campaign
    without its diagnosis (the law's prior as discovered, :data:`RIG_LAW_PRIOR`; evaluated
    with the law at its fit; ``--rig-law KNEE,RATIO``: the prior, as wide, and the law of
    the evaluation centred there instead, e.g. the rig's truth 0.25,2.5), the dataset drawn
    at each seed, near-edge share and per-point
    weighting rule (``--rig-weights``) and orbit hold (``--rig-hold none,orbit``), each
    family (``--rig-families``) trained on it, at each jitter of the rows' values
    (``--rig-jitter``, default the loop's).
    Besides the model's accuracy: what it would be with the class read from the beta head
    (``from beta``), and the misses (β: read, class). CPU and wall seconds: the dataset's
    plus the family's training and evaluation."""
    from independent_rig import write_campaign

    from stiffnet.campaign import load_campaign
    from stiffnet.effects.learned_contact import LearnedContact
    from stiffnet.measurement.metrics import true_class

    camp_dir = folder / "two_stage"
    if not (camp_dir / "manifest.csv").is_file():
        write_campaign(camp_dir, rig_runs("two_stage"))
    camp = load_campaign(camp_dir)
    d = load_config(SimulationConfig, default_config("sim/ideal.yaml")).model_dump(mode="json")
    knee, ratio = centre or (0.249, 2.436)
    around = {"knee": [0.95 * knee, 1.05 * knee], "knee_ratio": [0.95 * ratio, 1.05 * ratio]}
    prior = {**RIG_LAW_PRIOR, "params": {**RIG_LAW_PRIOR["params"], **around}}
    d.update(effects=[prior if centre else RIG_LAW_PRIOR])
    law = SimulationConfig.model_validate(d)
    fit = [LearnedContact(knee=knee, knee_ratio=ratio, reference_penetration=0.54)]
    print("| family | dataset seed | near-edge share | point weights | orbit hold | shared "
          "batches | accuracy | from beta | β MAPE | wrong (β: read, class) | wall s | CPU s "
          "| load |")  # fmt: skip
    print("|---" * 13 + "|")
    simulate_once(generate)
    for seed, share, rule, jit, hold in itertools.product(seeds, shares, weights, jitters, holds):
        cfg = law.model_copy(update={"seed": seed, "n_trajectories": n})
        with tempfile.TemporaryDirectory() as tmp:
            runs = _retrained(camp, cfg, Path(tmp), share, shared, fit, families, rule, hold, jit,
                              eval_ratio)  # fmt: skip
        data_wall, data_cpu = runs.pop("dataset")
        rule = rule if jit is None else f"{rule}, jitter {jit:g}"
        print(f"| dataset | {seed} | {share} | {rule} | {hold} | {shared} | | | | | "
              f"{data_wall:.0f} | {data_cpu:.0f} | {os.getloadavg()[0]:.1f} |")  # fmt: skip
        for family, (ev, wall, cpu) in runs.items():
            rows, m = ev["recordings"], ev["metrics"]["learned"]
            by_beta = np.mean([true_class(r["beta_estimate"], True) == r["true_class"]
                               for r in rows])  # fmt: skip
            bad = [r for r in rows if r["class"] != r["true_class"]]
            wrong = ", ".join(f"{r['beta']:g}: {r['beta_estimate']:.1f} {r['class']} "
                              f"({Path(r['recording']).stem.split('_b')[0]})"
                              for r in bad)  # fmt: skip
            print(f"| {family} | {seed} | {share} | {rule} | {hold} | {shared} | "
                  f"{m['accuracy']:.3f} | {by_beta:.3f} | {m['beta_mape']:.3f} | "
                  f"{wrong or '-'} | {wall:.0f} | {cpu:.0f} | "
                  f"{os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


#: The phases of a loop iteration the profile (``--rig-iteration``) times, innermost first
#: wins: (module, attribute, phase). Each attribute is looked up in its module at call time.
PHASES = (
    ("stiffnet.measurement.loop", "chain_discrepancy", "candidate chains"),
    ("stiffnet.measurement.operating_points", "operating_point_dataset", "dataset: writing"),
    ("stiffnet.dataset.generate", "simulate_shards", "dataset: world simulation"),
    ("stiffnet.dataset.generate", "run_shard_job", "dataset: world simulation"),
    ("stiffnet.dataset.generate", "generate_dataset", "dataset: world simulation"),
    ("training.train", "load_training_data", "training: load"),
    ("training.families.gbm.train", "gbm_inputs", "training: features"),
    ("training.families.gbm.train", "fit_gbm_family", "training: GBM fit"),
    ("training.finish", "calibrate", "training: calibration"),
    ("training.finish", "evaluate_test", "training: own test (+ geometric)"),
    ("training.finish", "export_model", "training: export"),
    ("stiffnet.measurement.loop", "compare_campaign", "evaluation: campaign simulation"),
    ("stiffnet.measurement.evaluate", "campaign_predictions", "evaluation: predictor"),
    ("stiffnet.measurement.evaluate", "with_simulation", "evaluation: beta by simulation"),
)

#: Phases that keep what they call (the candidate chains' campaign simulations are theirs).
ABSORBING = ("candidate chains",)


class PhaseClock:
    """CPU seconds (this process and its finished children) by phase, exclusive: a phase
    called inside another is charged to itself only (a stack of open phases)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._stack: list[str] = []
        self._last = 0.0
        self._undo: list = []

    @staticmethod
    def now() -> float:
        import resource

        own = resource.getrusage(resource.RUSAGE_SELF)
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime

    def _charge(self) -> None:
        t = self.now()
        top = self._stack[-1] if self._stack else "other"
        self.seconds[top] = self.seconds.get(top, 0.0) + t - self._last
        self._last = t

    def wrap(self, fn, phase: str):
        def timed(*args, **kwargs):
            if self._stack and self._stack[-1] in ABSORBING:
                return fn(*args, **kwargs)
            self._charge()
            self._stack.append(phase)
            try:
                return fn(*args, **kwargs)
            finally:
                self._charge()
                self._stack.pop()

        return timed

    def __enter__(self) -> PhaseClock:
        import importlib

        for mod_name, attr, phase in PHASES:
            mod = importlib.import_module(mod_name)
            real = getattr(mod, attr)
            setattr(mod, attr, self.wrap(real, phase))
            self._undo.append((mod, attr, real))
        self._last = self.now()
        return self

    def __exit__(self, *exc) -> None:
        self._charge()
        for mod, attr, real in reversed(self._undo):
            setattr(mod, attr, real)


def rig_iteration(
    state: Path,
    diagnosis: Path,
    campaign: Path,
    repeats: int = 1,
    sizes: tuple[int | None, ...] = (None,),
    seeds: tuple[int | None, ...] = (None,),
) -> None:
    """Part 4c (``--rig-iteration STATE --rig-diagnosis D``): the plain loop's iteration 1 on
    ``campaign`` (``--rig-campaign``, default ``--rig-dir``'s ``two_stage``), resumed from
    a copy of STATE (a loop state folder of that campaign) cut to its iteration 0, with the
    given diagnosis, in this process without tracking, at each dataset size
    (``--rig-sizes``, ``loop --n-trajectories``; ``default``: the loop's own) and dataset
    seed (``--rig-dataset-seeds``: the starting config's seed; default the state's):
    the model alone (accuracy / β MAPE), what the loop reports, and the CPU seconds of
    every phase (:class:`PhaseClock`; the candidate chains the diagnosis's chain is chosen
    among are part of the iteration, before its own clock starts), ``repeats`` times. A STATE
    of iteration 0 alone hands on the restoring-force fits it kept
    (:data:`~stiffnet.measurement.loop.KEPT_FITS_FILE`), as the loop resumed from it does."""
    import json
    import shutil

    from stiffnet.campaign import load_campaign
    from stiffnet.measurement.loop import KEPT_FITS_FILE, run_loop

    camp = load_campaign(campaign)
    diag = json.loads(diagnosis.read_text())
    names = list(dict.fromkeys(p for _, _, p in PHASES)) + ["other"]
    print("| trajectories | dataset seed | run | model alone: accuracy / β MAPE | reported "
          "reading: accuracy / β MAPE | own test accuracy | discrepancy | " + " | ".join(names)
          + " | CPU s, total | wall s | load |")  # fmt: skip
    print("|---" * (10 + len(names)) + "|")
    for n, seed, k in itertools.product(sizes, seeds, range(repeats)):
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp) / "loop"
            st = json.loads((state / "state.json").read_text())
            st_all = st["iterations"]
            st.update(iterations=st["iterations"][:1], campaign=str(campaign.resolve()),
                      tracking_uri=None)  # fmt: skip
            if n is not None:
                st["n_trajectories"] = n
            if seed is not None:
                st["start_config"]["seed"] = seed
            shutil.copytree(state / "iter-000", folder / "iter-000")
            shutil.copy(state / "stiffnet-run.json", folder / "stiffnet-run.json")
            if (state / KEPT_FITS_FILE).is_file() and len(st_all) == 1:
                # the restoring-force fits iteration 0 kept, as a resumed loop reads them (a
                # state with later iterations would hand iteration 1 its own fits)
                shutil.copy(state / KEPT_FITS_FILE, folder / KEPT_FITS_FILE)
            (folder / "state.json").write_text(json.dumps(st))
            cfg = SimulationConfig.model_validate(st["start_config"])
            load0 = os.getloadavg()[0]
            t0 = time.perf_counter()
            with PhaseClock() as clock:
                res = run_loop(camp, cfg, folder, iterations=1, diagnosis=diag,
                               tracking_uri=None)  # fmt: skip
            it, wall = res["iterations"][-1], time.perf_counter() - t0
        m = it["metrics"]
        cells = " | ".join(f"{clock.seconds.get(p, 0.0):.1f}" for p in names)
        print(
            f"| {it['n_trajectories']} | {cfg.seed} | {k} | {m['accuracy']:.3f} / "
            f"{m['beta_mape']:.3f} | "
            f"{_pair(m.get('reading_accuracy'), m.get('reading_beta_mape'))} | "
            f"{it['train_metrics'].get('train/accuracy', float('nan')):.3f} | "
            f"{m['discrepancy']:.3g} | {cells} | {sum(clock.seconds.values()):.1f} | "
            f"{wall:.0f} | {load0:.1f} -> {os.getloadavg()[0]:.1f} |",
            flush=True,
        )


def _pair(accuracy: float | None, mape: float | None) -> str:
    """``accuracy / MAPE``, or a dash where the evaluation has no such reading."""
    return "-" if accuracy is None else f"{accuracy:.3f} / {mape:.4f}"


def _cli(args: list[str]) -> tuple[float, float]:
    """``python -m stiffnet ARGS``: wall and CPU seconds (its processes and their children)."""
    import resource
    import subprocess

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "stiffnet", *args], check=True, cwd=ROOT,
                   stdout=subprocess.DEVNULL)  # fmt: skip
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return time.perf_counter() - t0, cpu


def iteration_detail(law: str, it: dict, folder: Path) -> str:
    """A loop iteration in one line: world (why), trajectories, accuracy, β MAPE, misses
    (β: read, class; point, gap mm from the campaign ``folder``'s manifest) and the CPU
    seconds of its phases."""
    import csv

    with open(folder / "manifest.csv", newline="") as f:
        gaps = {r["recording"]: r.get("gap_mm", "?") for r in csv.DictReader(f)}
    bad = [r for r in it["recordings"] if (r["error"] or 0) >= 1]  # a wrong class counts 1
    wrong = "; ".join(f"{r['beta']:g}: {r['beta_estimate']:.1f} {r['class']} "
                      f"({Path(r['recording']).stem.split('_')[0]}, "
                      f"{gaps.get(r['recording'], '?')} mm)" for r in bad)  # fmt: skip
    m = it["metrics"]
    phases = ", ".join(f"{k} {v:.0f}" for k, v in it.get("cpu_seconds", {}).items())
    return (f"| {law} | {it['world']} ({it['world_reason']}) | {it['n_trajectories']} "
            f"| {m['accuracy']:.3f} | {m['beta_mape']:.3f} | {wrong or '-'} "
            f"| {phases} |")  # fmt: skip


def rig_row(law: str, folder: Path, family: str, n: int | None, details: list[str]) -> str:
    """One law: write the campaign, diagnose it, loop on it where a law is proposed (its
    last iteration's line appended to ``details``)."""
    import json

    from independent_rig import write_campaign

    camp = write_campaign(folder / law, rig_runs(law))
    only = [a for c in RIG_CANDIDATES for a in ("--only", c)]
    d_json = folder / f"{law}-diagnose.json"
    load0 = os.getloadavg()[0]
    wall, cpu = _cli(["diagnose", str(camp), *only, "--no-inclination", "--json", str(d_json)])
    d = json.loads(d_json.read_text())
    ll = d.get("learned_law") or {}
    after = ll.get("discrepancy_after") if ll.get("proposed") else None
    of_base = 1 - after / d["baseline_discrepancy"] if after is not None else None
    cells = [law, d["verdict"], f"{d['baseline_discrepancy']:.3g}",
             ", ".join(d.get("missing_effects") or []) or "-",
             (ll.get("law") or {}).get("equation", "-") if ll.get("proposed") else "none",
             f"{ll['removed_fraction']:.0%} / {of_base:.0%}" if after is not None else "-",
             f"{wall:.0f} / {cpu:.0f}"]  # fmt: skip
    if ll.get("proposed"):
        l_json = folder / f"{law}-loop.json"
        state = str(folder / f"{law}-loop")
        size = ["--n-trajectories", str(n)] if n else []
        wall, cpu = _cli(["loop", str(camp), "--state", state, "--diagnosis", str(d_json),
                          "--family", family, "--iterations", "1", *size,
                          "--tracking-uri", f"sqlite:///{folder.resolve()}/mlflow.db",
                          "--json", str(l_json)])  # fmt: skip
        its = json.loads(l_json.read_text())["iterations"]
        details.append(iteration_detail(law, its[-1], Path(camp)))
        m0, m1 = its[0]["metrics"], its[-1]["metrics"]
        cells += [f"{m0['accuracy']:.3f} → {m1['accuracy']:.3f}",
                  f"{m0['beta_mape']:.3f} → {m1['beta_mape']:.3f}",
                  f"{m0['discrepancy']:.3g} → {m1['discrepancy']:.3g}",
                  f"{wall:.0f} / {cpu:.0f}"]  # fmt: skip
    else:
        cells += ["-"] * 4
    cells.append(f"{load0:.1f} → {os.getloadavg()[0]:.1f}")
    return "| " + " | ".join(cells) + " |"


def rig_table(laws: list[str], folder: Path | None, family: str, n: int | None) -> None:
    """Part 4's table, one row per law, then each loop's last iteration (module notes)."""
    print(f"| rig law | verdict | baseline | library selects | learned law | removed (of the "
          f"selection's / of the baseline) | diagnose wall / CPU s | {family} accuracy | "
          f"β MAPE | discrepancy | loop wall / CPU s | load |")  # fmt: skip
    print("|---" * 12 + "|")
    details: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        for law in laws:
            print(rig_row(law, Path(folder or tmp), family, n, details), flush=True)
    print("\n| rig law | world (why) | trajectories | accuracy | β MAPE | misses (β: read, "
          "class; point, gap) | CPU s by phase |\n|---|---|---|---|---|---|---|")  # fmt: skip
    print("\n".join(details))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trajectories", type=int, default=48)
    ap.add_argument("--loop", type=int, default=0, help="one GBM loop iteration, N trajectories")
    ap.add_argument("--seeds", default="", help="dataset seeds of part 3, e.g. 0,1,7")
    ap.add_argument("--seed-trajectories", type=int, default=400)
    ap.add_argument("--edge-share", type=float, default=0.5)
    ap.add_argument("--shared", default="", help="part 1b: POINTS,TRAJECTORIES[,WARM]")
    ap.add_argument(
        "--solvers",
        default="",
        help="part 1c: POINTS,TRAJECTORIES;JSON;JSON..., "
        'e.g. \'6,24;{"substeps": 8};{"substeps": 4, "warm_start": 0.1}\'',
    )
    ap.add_argument("--zero-chain", default="", help="part 1d: POINTS,TRAJECTORIES")
    ap.add_argument("--rig", default="", help=f"part 4: laws among {', '.join(RIG_LAWS)}")
    ap.add_argument("--rig-dir", type=Path, default=None, help="where the campaigns go (kept)")
    ap.add_argument("--rig-family", default="gbm")
    ap.add_argument("--rig-trajectories", type=int, default=None,
                    help="part 4: --n-trajectories (default the loop's); 4b: 400")  # fmt: skip
    ap.add_argument(
        "--rig-iteration",
        type=Path,
        default=None,
        help="part 4c: a loop state folder of the two-stage campaign",
    )
    ap.add_argument("--rig-diagnosis", type=Path, default=None, help="part 4c: diagnose --json")
    ap.add_argument("--rig-repeats", type=int, default=1, help="part 4c: runs")
    ap.add_argument(
        "--rig-campaign",
        type=Path,
        default=None,
        help="part 4c: the campaign (default --rig-dir's two_stage)",
    )
    ap.add_argument(
        "--rig-sizes", default="default", help="part 4c: dataset sizes, e.g. default,1600"
    )
    ap.add_argument(
        "--rig-dataset-seeds",
        default="",
        help="part 4c: dataset seeds, e.g. 0,1 (default the state's)",
    )
    ap.add_argument("--rig-seeds", default="", help="part 4b: dataset seeds, e.g. 0,1")
    ap.add_argument("--rig-shares", default="0.0,0.5", help="part 4b: near-edge shares")
    ap.add_argument("--rig-per-shard", action="store_true", help="part 4b: no shared batches")
    ap.add_argument("--rig-eval-ratio", action="store_true",
                    help="part 4b: each model evaluated again by the old and this code's "
                    "estimate, side by side")  # fmt: skip
    ap.add_argument("--rig-families", default="gbm", help="part 4b: families, e.g. gbm,cnn")
    ap.add_argument("--rig-weights", default="none", help="part 4b: per-point rules, e.g. "
                    "none,small_gaps")  # fmt: skip
    ap.add_argument("--rig-hold", default="none", help="part 4b: orbit holds, e.g. none,orbit")
    ap.add_argument("--rig-jitter", default="", help="part 4b: the rows' jitters, e.g. "
                    "0.05,0.02 (default the loop's)")  # fmt: skip
    ap.add_argument("--rig-law", default="", help="part 4b: the law's centre KNEE,RATIO "
                    "(default the discovery's 0.249,2.436)")  # fmt: skip
    ap.add_argument("--rig-orbits", default="", help="part 4d: campaign rows, e.g. 3,6")
    args = ap.parse_args()
    if args.rig_orbits:
        if args.rig_dir is None:
            ap.error("--rig-orbits needs --rig-dir (its two_stage)")
        print("| row (recording) | gap mm | recording's orbit | windows | training windows' "
              "orbits | by β band | impacts per forcing period, median |")  # fmt: skip
        print("|---" * 7 + "|")
        seeds = [int(s) for s in (args.rig_seeds or "0").split(",")]
        for seed in seeds:
            rig_orbits([int(r) for r in args.rig_orbits.split(",")], seed,
                       args.rig_trajectories or 400, args.rig_dir)  # fmt: skip
        return
    if args.rig_iteration:
        if args.rig_diagnosis is None or (args.rig_dir is None and args.rig_campaign is None):
            ap.error("--rig-iteration needs --rig-diagnosis and --rig-campaign or --rig-dir")
        sizes = tuple(None if x == "default" else int(x) for x in args.rig_sizes.split(","))
        seeds = (
            tuple(int(x) for x in args.rig_dataset_seeds.split(","))
            if args.rig_dataset_seeds
            else (None,)
        )
        rig_iteration(args.rig_iteration, args.rig_diagnosis,
                      args.rig_campaign or args.rig_dir / "two_stage", args.rig_repeats,
                      sizes, seeds)  # fmt: skip
        return
    if args.rig_seeds:
        centre = tuple(float(x) for x in args.rig_law.split(",")) if args.rig_law else None
        rig_seeds(args.rig_dir or Path(tempfile.mkdtemp()),
                  [int(s) for s in args.rig_seeds.split(",")],
                  [float(s) for s in args.rig_shares.split(",")],
                  not args.rig_per_shard, args.rig_trajectories or 400,
                  tuple(args.rig_families.split(",")),
                  tuple(args.rig_weights.split(",")),
                  tuple(args.rig_hold.split(",")),
                  centre,
                  tuple(float(x) for x in args.rig_jitter.split(",")) if args.rig_jitter
                  else (None,), args.rig_eval_ratio)  # fmt: skip
        return
    if args.rig:
        rig_table(args.rig.split(","), args.rig_dir, args.rig_family, args.rig_trajectories)
        return
    if args.shared:
        print(
            "| what | one batch per point | shared batches | speed-up | draws | RMS difference "
            "/ noise std: median / 90 % / max, windows above | impact counts equal | load |"
        )
        print("|---" * 8 + "|")
        k, n, *w = args.shared.split(",")
        shared_batches_ratio(int(k), int(n), float(w[0]) if w else 0.0, args.rig_dir)
        return
    if args.zero_chain:
        print("| what | samples on zeros | draws CPU s, chain on zeros | without it | the chain "
              "on zeros | load |")  # fmt: skip
        print("|---" * 6 + "|")
        k, n = args.zero_chain.split(",")
        zero_chain(int(k), int(n), args.rig_dir)
        return
    if args.solvers:
        import json

        head, *solvers = args.solvers.split(";")
        k, n = head.split(",")
        print("| solver | CPU s | speed-up | RMS difference / noise std: median / 90 % / max "
              "| windows above the noise | impact counts equal | load |")  # fmt: skip
        print("|---|---|---|---|---|---|---|")
        solver_ratio(int(k), int(n), [json.loads(x) for x in solvers])
        return
    if args.seeds:
        seeds = [int(s) for s in args.seeds.split(",")]
        seed_spread(seeds, args.seed_trajectories, args.edge_share)
        return
    print("| what | old path s | new path s | speed-up | max difference / peak | load |")
    print("|---|---|---|---|---|---|")
    campaign_ratio()
    if args.trajectories:
        dataset_ratio(args.trajectories)
    if args.loop:
        print("\n| iteration | trajectories | discrepancy | accuracy | seconds | load |")
        print("|---|---|---|---|---|---|")
        loop_iteration(args.loop)


if __name__ == "__main__":
    main()

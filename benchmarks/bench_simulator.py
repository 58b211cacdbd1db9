"""Benchmark the closed-form Simulator against scipy's event-located ``solve_ivp``.

Both produce the same samples in this one process: the same random parameter
sets (default domain: beta 5-100, gap 0-3, a 0.2-2, w 0.8-1.2, xi 0.01-0.05,
fs / f_n = 100), the same initial conditions, the same transient
(:meth:`Simulator.transient_time`, settle tolerance 1e-3, i.e. up to ~110
natural periods) and the same sample times.

* ``Simulator`` (the compiled closed-form engine) runs the whole batch at once,
  on one numba thread (the headline: per core, like the reference) and on all
  of numba's threads (``NUMBA_NUM_THREADS``, default: the cores);
* the reference, ``tests/reference_solve_ivp.py``'s ``reference_trajectory``
  (DOP853, rtol 1e-10, atol 1e-12, terminal events, dense output, scalar
  right-hand sides with ``math.sin``: an efficient scipy user's code), runs a
  handful of them, one after the other (it manages ~10,000 samples/s).

On the reference trajectories the samples of both are compared (max |accel
difference| / peak |accel|). ``solve_ivp`` detects events only at its step
ends, so it can step over a shallow contact; where the difference exceeds 1e-6
the reference is rerun, untimed, with ``max_step=0.05`` to tell whose error it is.

Timings are wall-clock; the simulator's are the best of ``--repeat`` runs after an
untimed one (the batch's ~1 GB of output is then memory the process has touched
before, as in dataset generation, which simulates shard after shard), the
reference's one run. Process CPU time is printed too, a check where other jobs
share the cores, with the load average before and after. The headline is the single-thread ratio:
``speedup_1_thread: X``, simulator samples/s on one thread over reference
samples/s (wall-clock), target >= 1000; the all-threads ratio is printed beside it.

Run: ``OMP_NUM_THREADS=1 python benchmarks/bench_simulator.py [--quick]``
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import time
from pathlib import Path

import numpy as np

from stiffnet.simulator import compiled
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from reference_solve_ivp import reference_trajectory  # noqa: E402  (a test oracle)

DOMAIN = {  # the default sampling domain of the parameter sets
    "beta": (5.0, 100.0),
    "gap": (0.0, 3.0),
    "amplitude": (0.2, 2.0),
    "omega": (0.8, 1.2),
    "damping": (0.01, 0.05),
}
MAX_ELEMENTS = 4e7  # B * N: each output array is B x N float64 (320 MB at the limit)
RECHECK_MAX_STEP = 0.05


def draw(n: int, rng: np.random.Generator) -> tuple[OscillatorBatch, np.ndarray, np.ndarray]:
    """``n`` parameter sets uniform over DOMAIN and initial states as the Simulator draws them."""
    batch = OscillatorBatch(**{k: rng.uniform(lo, hi, n) for k, (lo, hi) in DOMAIN.items()})
    x0 = rng.uniform(-1, 1, n) * batch.amplitude
    v0 = rng.uniform(-1, 1, n) * batch.amplitude * batch.omega
    return batch, x0, v0


def warm_up(sim: Simulator) -> float:
    """Compile numba's kernels outside the timing; returns the seconds it took."""
    t = time.perf_counter()
    sim.simulate(OscillatorBatch.single(20.0, 1.0, 1.0, 1.0, 0.05), 50.0, 10, rng=0)
    return time.perf_counter() - t


def timed(sim: Simulator, batch, fs_ratio, n, x0, v0) -> tuple[float, float]:
    t, c = time.perf_counter(), time.process_time()
    sim.simulate(batch, fs_ratio, n, x0=x0, v0=v0)
    return time.perf_counter() - t, time.process_time() - c


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small batch, under a minute")
    ap.add_argument("--batch", type=int, help="parameter sets for the simulator (16384)")
    ap.add_argument("--samples", type=int, help="samples per trajectory (2000)")
    ap.add_argument("--reference", type=int, help="trajectories for solve_ivp (16)")
    ap.add_argument("--fs-ratio", type=float, default=100.0, help="fs / f_n (100)")
    ap.add_argument("--ref-max-step", type=float, default=np.inf,
                    help="max_step of the timed reference (default: none, as scipy's)")  # fmt: skip
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeat", type=int, default=2, help="timed runs per variant, best kept (2)")
    ap.add_argument("--profile", action="store_true", help="cProfile the simulator run")
    args = ap.parse_args()
    b = args.batch or (2048 if args.quick else 16384)
    n = args.samples or (1000 if args.quick else 2000)
    k = min(args.reference or (4 if args.quick else 16), b)
    if b * n > MAX_ELEMENTS:
        ap.error(f"--batch x --samples = {b * n:.2g} > {MAX_ELEMENTS:.0e}: too much memory")

    batch, x0, v0 = draw(b, np.random.default_rng(args.seed))
    sim = Simulator()  # default transient, closed-form engine (no effects)
    h = 2 * np.pi / args.fs_ratio
    print(f"domain: {DOMAIN}, fs/f_n {args.fs_ratio:g}")
    print(f"transient: {sim.transient_time(batch).min():.0f}-{sim.transient_time(batch).max():.0f}"
          f" model time units; samples: {n} x h={h:.4f}")  # fmt: skip

    load_before = os.getloadavg()
    compile_s = warm_up(sim)
    threads = compiled.threads()
    profiler = cProfile.Profile() if args.profile else None
    with compiled.limited_threads(1):  # the headline: one core, as solve_ivp uses
        if profiler:
            profiler.enable()
        res = sim.simulate(batch, args.fs_ratio, n, x0=x0, v0=v0)  # untimed: samples, memory
        if profiler:
            profiler.disable()
        one = [timed(sim, batch, args.fs_ratio, n, x0, v0) for _ in range(args.repeat)]
    every = [timed(sim, batch, args.fs_ratio, n, x0, v0) for _ in range(args.repeat)]
    (t_one, c_one), (t_all, c_all) = min(one), min(every)

    model = sim.linear_model(batch, res.effect_params)
    t_ref, c_ref, errors, rechecked = 0.0, 0.0, [], {}
    for i in range(k):
        t_samples = res.t0[i] + np.arange(n) * h
        t_start, c_start = time.perf_counter(), time.process_time()
        ref = reference_trajectory(model, i, x0[i], v0[i], t_samples, max_step=args.ref_max_step)
        t_ref += time.perf_counter() - t_start
        c_ref += time.process_time() - c_start
        peak = np.abs(ref["accel"]).max()
        errors.append(np.abs(ref["accel"] - res.clean_accel[i]).max() / peak)
        if errors[-1] > 1e-6:  # untimed: is the reference the one that is off?
            fine = reference_trajectory(model, i, x0[i], v0[i], t_samples,
                                        max_step=RECHECK_MAX_STEP)  # fmt: skip
            rechecked[i] = np.abs(fine["accel"] - res.clean_accel[i]).max() / peak

    rate_ref = k * n / t_ref
    rows = [("Simulator (compiled, 1 thread)", b, b * n, t_one, c_one, float("nan"))]
    rows.append((f"Simulator (compiled, {threads} threads)", b, b * n, t_all, c_all, float("nan")))
    rows.append(("solve_ivp DOP853 + events", k, k * n, t_ref, c_ref, max(errors)))
    # cpu s: process time, a check on wall-clock seconds on a shared machine
    print(f"\n{'engine':<33}{'traj':>7}{'samples':>12}{'seconds':>10}{'cpu s':>9}"
          f"{'samples/s':>12}{'vs solve_ivp':>14}{'max rel err':>13}")  # fmt: skip
    for name, traj, samples, sec, cpu, err in rows:
        err_text = "-" if np.isnan(err) else f"{err:.1e}"
        ratio = samples / sec / rate_ref
        print(f"{name:<33}{traj:>7}{samples:>12}{sec:>10.2f}{cpu:>9.2f}{samples / sec:>12.4g}"
              f"{ratio:>13.0f}x{err_text:>13}")  # fmt: skip
    print(f"\nimpacts per trajectory (simulator batch): {res.impacts.sum(axis=1).mean():.1f}; "
          f"trajectories that impact: {np.mean(res.impacts.sum(axis=1) > 0):.0%}")  # fmt: skip
    print("accel error / peak on the reference trajectories: "
          + ", ".join(f"{e:.1e}" for e in errors))  # fmt: skip
    for i, err in rechecked.items():
        print(f"  trajectory {i}: {errors[i]:.1e} against the timed reference, {err:.1e} "
              f"against solve_ivp with max_step={RECHECK_MAX_STEP} (it stepped over a contact)"
              if err <= 1e-6 else
              f"  trajectory {i}: {errors[i]:.1e}, still {err:.1e} with max_step="
              f"{RECHECK_MAX_STEP}")  # fmt: skip
    if profiler:
        print()
        pstats.Stats(profiler).sort_stats("tottime").print_stats(15)
    print(f"numba compile (first call, cached afterwards): {compile_s:.1f} s, not timed above")
    load_after = os.getloadavg()
    print(
        f"load average (1/5/15 min) before: {'/'.join(f'{x:.2f}' for x in load_before)}, "
        f"after: {'/'.join(f'{x:.2f}' for x in load_after)} on {os.cpu_count()} cores"
    )
    print(f"speedup in cpu time, 1 thread: {(b * n / c_one) / (k * n / c_ref):.0f}")
    print(f"speedup_{threads}_threads: {(b * n / t_all) / rate_ref:.0f}")
    print(f"speedup_1_thread: {(b * n / t_one) / rate_ref:.0f}")


if __name__ == "__main__":
    main()

"""Benchmark the numerical engine: trajectories per CPU second, per numerical effect, with
its compiled RK4 step and right-hand side (:mod:`stiffnet.simulator.rk4_kernel`) and
without (numpy's path, ``numerical.COMPILED_STEP = False``), in one process, alternated.

The batch is the one the diagnosis's numerical-engine fits simulate in spirit: ``--rows``
forced rows driven into contact (beta 10-60, gap 0.2-0.8, w 0.8-1.6, xi 0.02), each
``--transient`` then ``--samples`` steps of a fortieth of its forcing period, 3 RK4
substeps a step; every row has many located events (contacts; slip reversals and
sticking with dry friction; the restraint's ringing). The learned contact law runs as
the measurement loop draws it: two-stage (the rig's discovered knee and ratio, in model
units a knee of 0.05), Hunt-Crossley (the rig's alpha 0.356) and with a face of its own
(mass 0.3, stiffness 40), with a face that is each row's own (``SCALED_FACE``, the one
``diagnose`` chose on the material-beam campaign), and as a power law with a preload
(exponent 1.3, compressed 0.04 before touch at ``d_r`` 0.4: compiled to round-off only,
numpy's SIMD ``pow`` not being libm's, so its ``bitwise`` column reads False; the impacting
rows amplify that round-off as they would any: numpy's path alone with each beta one unit
in the last place higher moves the acceleration by up to 2e-2 of its range, the kernel's
power law by 3.5e-3, the same impacts). Each variant runs ``--repeats`` times,
alternated, after one untimed run (numba's compilation, or its cache's load); the figure
is the best CPU time (``time.process_time``) and trajectories per CPU second. The outputs
of the two variants are compared (max abs difference over the range of each output, and
whether they are equal bit for bit). The load average is printed before and after.

Run: ``OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_numerical_engine.py``
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator import numerical
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.numerical import simulate_numerical

SUBSTEPS = 3
STEPS_PER_PERIOD = 40
KEYS = ("x", "v", "accel", "contact_force", "impacts")
#: The face that is each recording's own which ``diagnose`` chose on the material-beam
#: campaign (m5): support 1.266 beta, mass 0.0655 (beta / 23)^-0.729.
SCALED_FACE = {"face_mass": 0.0655, "face_stiffness_ratio": 1.266, "face_mass_exponent": -0.729,
               "face_reference_beta": 23.0, "face_damping": 0.05}  # fmt: skip


def _batch(rows: int, seed: int) -> OscillatorBatch:
    rng = np.random.default_rng(seed)
    return OscillatorBatch(
        rng.uniform(10, 60, rows), rng.uniform(0.2, 0.8, rows), np.full(rows, 1.0),
        rng.uniform(0.8, 1.6, rows), np.full(rows, 0.02),
    )  # fmt: skip


def _run(batch, effect, params, compiled: bool, transient: int, samples: int):
    numerical.COMPILED_STEP = compiled
    h = 2 * np.pi / batch.omega / STEPS_PER_PERIOD
    t = time.process_time()
    out = simulate_numerical(batch, [effect], [params], 0.0, 0.0, h, transient, h, samples,
                             SUBSTEPS)  # fmt: skip
    return time.process_time() - t, out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=24)
    ap.add_argument("--transient", type=int, default=400)
    ap.add_argument("--samples", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default="", help="effects whose name holds one of these words")
    args = ap.parse_args()
    print(f"load before: {os.getloadavg()[0]:.2f}")
    batch = _batch(args.rows, args.seed)
    print("| effect | numpy: CPU s (traj./CPU s) | compiled: CPU s (traj./CPU s) | ratio | "
          "max diff / range | bitwise |\n|---|---|---|---|---|---|")  # fmt: skip
    effects = {
        "hertz_contact": HertzContact(),
        "dry_friction": DryFriction(coefficient=0.18),
        "restraint_mass": RestraintMass(),
        "learned two-stage": LearnedContact(knee=0.05, knee_ratio=2.436),
        "learned Hunt-Crossley": LearnedContact(hunt_crossley=0.356),
        "learned face": LearnedContact(face_mass=0.3, face_stiffness=40.0, face_damping=0.05),
        "learned scaled face": LearnedContact(**SCALED_FACE),
        # the fourth check's rig: a power law 1.3 set 0.04 mm into its stop (d_r 0.4 mm)
        "learned power law": LearnedContact(exponent=1.3, reference_penetration=0.4, preload=0.04),
    }
    for name, effect in effects.items():
        if args.only and not any(w in name for w in args.only.split(",")):
            continue
        p = effect.batch_params(args.rows, None)
        best = {False: np.inf, True: np.inf}
        outs = {}
        for compiled in (False, True):  # untimed: compilation or the cache's load
            _run(batch, effect, p, compiled, args.transient, args.samples)
        for _ in range(args.repeats):
            for compiled in (False, True):
                cpu, outs[compiled] = _run(batch, effect, p, compiled, args.transient,
                                           args.samples)  # fmt: skip
                best[compiled] = min(best[compiled], cpu)
        diff, same = 0.0, True
        for key in KEYS:
            a = getattr(outs[True], key).astype(float)
            b = getattr(outs[False], key).astype(float)
            diff = max(diff, float(np.max(np.abs(a - b))) / max(float(np.ptp(b)), 1.0))
            same &= bool(np.array_equal(a, b))
        rate = {k: args.rows / v for k, v in best.items()}
        ratio = best[False] / best[True]
        print(f"| {name} | {best[False]:.3f} ({rate[False]:.1f}) | {best[True]:.3f} "
              f"({rate[True]:.1f}) | x{ratio:.2f} | {diff:.1e} | {same} |")  # fmt: skip
    numerical.COMPILED_STEP = True
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()

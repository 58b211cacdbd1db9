"""Why a loop model misreads a campaign's recording: three probes at its operating point.

* ``profile``: the recording's discrepancy (:mod:`stiffnet.measurement.discrepancy`, the
  statistics ``diagnose`` compares) against the learned law simulated at its manifest point
  with other betas, per simulation seed (initial state). A minimum at the truth, well above
  the recording's noise floor elsewhere, says the physics tells those betas apart there; a
  profile that never reaches the floor and moves with the seed says it does not (a
  wandering orbit). ``*`` marks a simulation on another orbit than the measurement.
* ``reads``: what a model reads on stiffnet's own simulation of the row (the learned law,
  white noise of ``--noise`` times the base acceleration, as the independent rig's) at those
  betas, beside its read of the recording: a model that misreads its own training world at
  the point is short of data or of information there, not misled by the rig.
* ``--estimate``: every recording's beta by simulation: its discrepancy against the learned
  law at its manifest point over a log grid of betas (all rows and betas in one batch), the
  least refined by a parabola in log beta; the class it gives and the least discrepancy
  against the recording's noise floor (far above it: the law at that point cannot reproduce
  the recording at any beta, an alarm).
* ``penetration``: the independent rig (``tests/independent_rig.py``, its two-stage law)
  at the row's point, noiseless: the deepest penetration against the knee, and the impact
  spike over the base acceleration (the level the models' standardised windows drop).

    OMP_NUM_THREADS=1 PYTHONPATH=.:tests python benchmarks/probe_rig_points.py CAMPAIGN \\
        --diagnosis d.json --recordings p2_1 --betas 35,41,50,57,64,70 \\
        [--seeds 0,1] [--model iter-001/model/gbm.onnx] [--penetration]
    ... benchmarks/probe_rig_points.py CAMPAIGN --diagnosis d.json --estimate [--seeds 0,1]

The learned law is ``--knee``/``--ratio`` (the rig campaign's discovered ``0.249``/``2.436``);
the rig's true law for ``--penetration`` is ``--rig-knee``/``--rig-ratio`` (0.25 mm, 2.5).
Prints Markdown-ready lines with CPU seconds and the load.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from stiffnet.campaign import load_campaign  # noqa: E402
from stiffnet.campaign.simulate import CampaignSolverSettings, simulate_rows  # noqa: E402
from stiffnet.effects.learned_contact import LearnedContact  # noqa: E402
from stiffnet.measurement.compare import _simulated_statistics  # noqa: E402
from stiffnet.measurement.discrepancy import (  # noqa: E402
    normalised_differences,
    recording_discrepancy,
)
from stiffnet.measurement.nuisance import resolve_rows  # noqa: E402
from stiffnet.measurement.orbits import orbit_name  # noqa: E402
from stiffnet.measurement.target import measured_statistics  # noqa: E402


def beta_profile(meas, row, length: int, law, betas: list[float], seed: int) -> str:
    """``beta:discrepancy`` of the recording against the law at each beta (``*``: another
    orbit than the measured one)."""
    alt = [row.model_copy(update={"beta": b}) for b in betas]
    sims = simulate_rows(alt, law, [length] * len(alt), seed, CampaignSolverSettings())
    out = []
    for b, a in zip(betas, sims, strict=True):
        s = _simulated_statistics(alt[0], a)
        d = recording_discrepancy(normalised_differences(meas, s)) if s else float("nan")
        out.append(f"{b:g}:{d:.2f}" + ("" if orbit_name(s) == orbit_name(meas) else "*"))
    return "  ".join(out)


def model_reads(pred, row, length: int, law, betas: list[float], seed: int, noise_g: float,
                fn_hz: float) -> str:  # fmt: skip
    """``beta->read class`` of the model on the law's simulation of ``row`` at each beta."""
    alt = [row.model_copy(update={"beta": b}) for b in betas]
    sims = simulate_rows(alt, law, [length] * len(alt), seed, CampaignSolverSettings())
    rng = np.random.default_rng([seed, 1])
    out = []
    for b, a in zip(betas, sims, strict=True):
        p = pred.predict(a + rng.normal(0.0, noise_g, a.shape), row.fs_hz,
                         natural_frequency_hz=fn_hz)  # fmt: skip
        out.append(f"{b:g}->{p['beta']:.1f} {p['class']}")
    return "  ".join(out)


def rig_penetration(m: dict, betas: list[float], knee_mm: float, ratio: float) -> list[str]:
    """The independent rig at the manifest row ``m``'s point, noiseless: per beta, the
    impact spike over the base acceleration and the deepest penetration (the two-stage law
    inverted at the spike, where the contact force dominates the acceleration)."""
    import independent_rig as ir

    out = []
    for beta in betas:
        run = ir.RigRun("probe", beta, float(m["natural_frequency_hz"]),
                        float(m["forcing_frequency_hz"]), float(m["base_acceleration_g"]),
                        float(m["gap_mm"]), float(m["damping_ratio"]), float(m["fs_hz"]), 3.0,
                        contact="two_stage", knee_mm=knee_mm, stage_ratio=ratio,
                        noise=0.0)  # fmt: skip
        _, a = ir.simulate(run)
        k, force, knee = beta * run.omega_n**2, -a.min(), knee_mm * 1e-3
        depth = force / k if force <= k * knee else knee + (force - k * knee) / (ratio * k)
        out.append(f"{beta:g}: spike {force / run.base_acceleration_ms2:.1f}x the base, "
                   f"penetration {depth * 1e3:.3f} mm")  # fmt: skip
    return out


def beta_by_simulation(camp, meas, rows, lengths, law, seed: int, floors: dict,
                       grid: np.ndarray) -> None:  # fmt: skip
    """``--estimate``: each recording's beta at the least discrepancy over ``grid`` (see the
    module notes), its class against the manifest's, and the accuracy and MAPE."""
    from stiffnet.measurement.metrics import true_class

    alt = [r.model_copy(update={"beta": float(b)}) for r in rows for b in grid]
    n = len(grid)
    sims = simulate_rows(alt, law, [lengths[i] for i in range(len(rows)) for _ in grid], seed,
                         CampaignSolverSettings())  # fmt: skip
    right, ape = [], []
    for i, r in enumerate(rows):
        d = np.full(n, np.inf)
        for j in range(n):
            s = _simulated_statistics(alt[i * n + j], sims[i * n + j])
            if s is not None:
                d[j] = recording_discrepancy(normalised_differences(meas[i], s))
        k, lb = int(np.argmin(d)), np.log(grid)
        est = float(grid[k])
        if 0 < k < n - 1 and np.all(np.isfinite(d[k - 1 : k + 2])):
            y0, y1, y2 = d[k - 1 : k + 2]
            if y0 - 2 * y1 + y2 > 0:  # the parabola's vertex, within the bracket
                est = float(np.exp(lb[k] + 0.5 * (lb[1] - lb[0]) * (y0 - y2) / (y0 - 2 * y1 + y2)))
        ok = true_class(est, True) == true_class(r.beta, True)
        right.append(ok)
        ape.append(abs(est / r.beta - 1))
        print(f"  {r.recording}: beta {r.beta:g}, by simulation {est:.1f} "
              f"{true_class(est, True)}{'' if ok else ' (wrong)'}, least discrepancy "
              f"{d[k]:.2f}, floor {floors[r.recording]:.2f}")  # fmt: skip
    print(f"seed {seed}: accuracy {np.mean(right):.3f}, beta MAPE {np.mean(ape):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("campaign", type=Path)
    ap.add_argument("--diagnosis", type=Path, required=True, help="diagnose --json (floors)")
    ap.add_argument("--recordings", default="", help="parts of the names, e.g. p2_1,p1_0")
    ap.add_argument("--betas", default="", help="e.g. 35,41,50,57,64,70")
    ap.add_argument("--estimate", action="store_true", help="every recording's beta by "
                    "simulation over --grid")  # fmt: skip
    ap.add_argument("--grid", default="6,95,21", help="LOW,HIGH,N: log-spaced betas")
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--knee", type=float, default=0.249)
    ap.add_argument("--ratio", type=float, default=2.436)
    ap.add_argument("--model", default="", help="an ONNX model: its reads of the simulation")
    ap.add_argument("--noise", type=float, default=0.02, help="of the base acceleration")
    ap.add_argument("--penetration", action="store_true")
    ap.add_argument("--rig-knee", type=float, default=0.25)
    ap.add_argument("--rig-ratio", type=float, default=2.5)
    args = ap.parse_args()
    c0 = time.process_time()
    camp = load_campaign(args.campaign)
    d = json.loads(args.diagnosis.read_text())
    floors = dict(zip(d["recordings"], d["noise_floor_per_recording"], strict=True))
    with open(camp.folder / "manifest.csv", newline="") as f:
        manifest = {m["recording"]: m for m in csv.DictReader(f)}
    betas = [float(b) for b in args.betas.split(",") if b]
    seeds = [int(s) for s in args.seeds.split(",")]
    law = [LearnedContact(knee=args.knee, knee_ratio=args.ratio, reference_penetration=0.54)]
    rows, _ = resolve_rows(camp)
    meas, lengths, samples = measured_statistics(camp, rows)
    if args.estimate:
        lo, hi, n = args.grid.split(",")
        grid = np.exp(np.linspace(np.log(float(lo)), np.log(float(hi)), int(n)))
        for seed in seeds:
            beta_by_simulation(camp, meas, rows, lengths, law, seed, floors, grid)
    pred = None
    if args.model:
        from serving.predictor import Predictor

        pred = Predictor.load(args.model)
    for i, row in enumerate(rows):
        if not args.recordings or not any(w in row.recording for w in args.recordings.split(",")):
            continue
        m = manifest[row.recording]
        fn = float(m["natural_frequency_hz"])
        print(f"\n{row.recording}: beta {row.beta:g}, gap {m['gap_mm']} mm, noise floor "
              f"{floors[row.recording]:.3f}, measured orbit: {orbit_name(meas[i])}")  # fmt: skip
        for seed in seeds:
            profile = beta_profile(meas[i], row, lengths[i], law, betas, seed)
            print(f"  profile, seed {seed}: {profile}")
        if pred is not None:
            r = pred.predict(samples[i], row.fs_hz, natural_frequency_hz=fn)
            print(f"  model on the recording: {r['beta']:.1f} {r['class']}")
            noise_g = args.noise * float(m["base_acceleration_g"])
            for seed in seeds:
                reads = model_reads(pred, row, lengths[i], law, betas, seed, noise_g, fn)
                print(f"  model on the law's simulation, seed {seed}: {reads}")
        if args.penetration:
            for line in rig_penetration(m, betas, args.rig_knee, args.rig_ratio):
                print(f"  rig {line}")
    print(f"\nCPU {time.process_time() - c0:.0f} s, load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()

"""Benchmark the numerical engine on oversampled records: every sample integrated (before)
against the logger's substeps plus RK4's dense output (now, ``SolverSettings.oversampled``).

The campaign simulations run an analog sensor chain (``sensor_dynamics``) at 8x the
logger's rate (:data:`stiffnet.campaign.simulate.ANALOG_OVERSAMPLING`). Before, the engine
took one RK4 substep per oversampled sample; now it takes the substeps a record at the
logger's rate gets (2 per sample in the fitting loop) and fills the rest. Both ways run here
through ``simulate_rows``' own mapping (rows of ``examples/hidden_effect_manifest.csv``, the
fitting loop's numerical settings, 6 s recordings cut to 16 periods, a 1 Hz high-pass:
1.5 s lead-in), alternated ``--repeats`` times, for each numerical-engine effect with the
sensor chain. The table gives the CPU seconds of one simulation (median), their ratio, and
how far the new signals are from the old ones (largest difference over the row's RMS;
the white noise, 0.02 of the forcing, is about 0.01 of the RMS), with the load average.

Run (from the repository root)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_dense_output.py [--repeats 2]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from stiffnet.campaign import simulate as cs
from stiffnet.campaign.manifest import read_manifest
from stiffnet.effects.registry import effect_class

ROOT = Path(__file__).resolve().parents[1]
SENSOR = {"resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 0.0, "highpass_hz": 1.0}


def simulate(rows, effects, dense: bool) -> tuple[list[np.ndarray], float]:
    """``simulate_rows`` as now (``dense``) or as before (one substep per oversampled
    sample: ``substeps`` divided by the oversampling, no dense output)."""
    settings = cs.FIT_SETTINGS_NUMERICAL
    original = cs.Simulator
    if not dense:
        k = cs.ANALOG_OVERSAMPLING

        def before(effs, s):
            s = s.model_copy(update={"oversampled": 1, "substeps": max(1, -(-s.substeps // k))})
            return original(effs, s)

        cs.Simulator = before
    try:
        lengths = [int(r.fs_hz * 6) for r in rows]
        t = time.process_time()
        out = cs.simulate_rows(rows, effects, lengths, settings=settings)
        return out, time.process_time() - t
    finally:
        cs.Simulator = original


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=2, help="alternated runs of each way")
    args = ap.parse_args()
    rows = read_manifest(ROOT / "examples" / "hidden_effect_manifest.csv")
    sensor = effect_class("sensor_dynamics")(**SENSOR)
    print(f"load average {os.getloadavg()[0]:.2f} at the start; {len(rows)} rows")
    print("| effects | before CPU s | now CPU s | before / now | max diff / RMS |")
    print("|---|---|---|---|---|")
    for name in ("hertz_contact", "dry_friction", "restraint_mass"):
        effects = [effect_class(name)(), sensor]
        times: dict[bool, list[float]] = {False: [], True: []}
        sims = {}
        for _ in range(args.repeats):
            for dense in (False, True):
                sims[dense], t = simulate(rows, effects, dense)
                times[dense].append(t)
        old, new = float(np.median(times[False])), float(np.median(times[True]))
        diff = max(
            float(np.max(np.abs(a - b)) / np.sqrt(np.mean(b**2)))
            for a, b in zip(sims[True], sims[False], strict=True)
        )
        print(f"| {name} + sensor_dynamics | {old:.2f} | {new:.2f} | {old / new:.2f} | "
              f"{diff:.2g} |")  # fmt: skip
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()

"""Benchmark ``diagnose`` on a 24-recording campaign with the whole library and joint refits.

The campaign: the 8 rows of ``examples/hidden_effect_manifest.csv`` three times
(``a/``, ``b/``, ``c/``: forcing frequency ratio shifted by -2 %, 0, +2 %), 4 s each,
with two hidden effects at once (contact damping 0.25 and an accelerometer
resonance at 237 Hz). ``diagnose`` runs on it with every shipped effect (the three
numerical-engine ones included) and the default budgets, under cProfile, and the
table splits the wall time by what it was spent on: simulation
(``simulate_rows``), statistics (``signal_statistics``) and the rest (search,
significance, nuisances). The diagnosis itself is checked (both effects found).

Target (issue 13): <= 2 minutes wall on 2 cores. ``--workers 2`` runs each step's
fits on a 2-process LocalCluster (the profile then covers only this process).

Run (from the repository root, so this checkout's package is imported)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py \
        [--workers 2] [--fast-only] [--no-inclination]
"""

from __future__ import annotations

import argparse
import cProfile
import csv
import os
import pstats
import tempfile
import time
from pathlib import Path

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.measurement.diagnose import diagnose_campaign

ROOT = Path(__file__).resolve().parents[1]
HIDDEN = [
    "contact_damping:damping_ratio=0.25",
    "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0",
]
FAST = ["contact_damping", "forcing_harmonics", "gap_drift", "sensor_dynamics",
        "colored_noise", "adc"]  # fmt: skip


def campaign(tmp: Path) -> Path:
    with open(ROOT / "examples" / "hidden_effect_manifest.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    manifest = tmp / "manifest24.csv"
    with open(manifest, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for prefix, shift in (("a", 0.98), ("b", 1.0), ("c", 1.02)):
            for r in rows:
                ratio = f"{float(r['frequency_ratio']) * shift:.4f}"
                name = f"{prefix}/{Path(r['recording']).name}"
                w.writerow({**r, "recording": name, "frequency_ratio": ratio})
    return simulate_campaign(manifest, tmp / "campaign24", HIDDEN, seed=0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--fast-only", action="store_true", help="closed-form effects only")
    ap.add_argument("--no-inclination", action="store_true", help="leave out the geometric "
                    "method's inclination statistics (as the tests do)")  # fmt: skip
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        camp = load_campaign(campaign(Path(d)))
        t_sim = time.perf_counter() - t
        prof = cProfile.Profile()
        t = time.perf_counter()
        prof.enable()
        res = diagnose_campaign(
            camp, effects=FAST if args.fast_only else None, workers=args.workers,
            inclination=not args.no_inclination,
            progress=lambda done, total: print(f"  fits {done}/{total}", flush=True),
        )  # fmt: skip
        prof.disable()
        wall = time.perf_counter() - t
    st = pstats.Stats(prof)
    cum = {k[2]: v[3] for k, v in st.stats.items()}  # function name -> cumulative s
    sim, stats_ = cum.get("simulate_rows", 0.0), cum.get("signal_statistics", 0.0)
    print(f"\nload average {os.getloadavg()[0]:.2f}; campaign simulated in {t_sim:.1f} s")
    print("| stage | seconds | share |\n|---|---|---|")
    rest = wall - sim - stats_
    stages = [("simulation", sim), ("statistics", stats_), ("search, tests, nuisances", rest)]
    for name, v in [*stages, ("total (wall)", wall)]:
        print(f"| {name} | {v:.1f} | {v / wall:.0%} |")
    print(f"\nselected {res['missing_effects']} {res['fitted_params']}")
    print(f"verdict {res['verdict']}, residual {res['residual_discrepancy']:.3g}, "
          f"noise floor {res['noise_floor']:.3g}; target <= 120 s: "
          f"{'met' if wall <= 120 else 'NOT met'} ({wall:.0f} s)")  # fmt: skip


if __name__ == "__main__":
    main()

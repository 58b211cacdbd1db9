"""The restoring-force beta of a learned two-stage law's campaign, read four ways.

For every recording of a campaign folder (``manifest.csv`` with ``beta``): the library's
law (the cross-check without a learned law), the shipped two-stage reading (ratio held at
the card's range, knee free: ``restoring_force_estimate(stage_ratio=...)``), and two
alternatives fitted on the same map: ratio and knee both free, and the knee held at the
card's value in model units (possible only where the record's gain is known: a campaign
in g with a model length of 1 mm, :func:`stiffnet.campaign.sensor_gain`). Prints a table
(beta error per recording, MAPE, interval coverage of the shipped reading) and the CPU
seconds of the shipped reading.

Run (the independent rig's two-stage campaign, ratio 2.5 knee 0.25 mm; a card's range)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_staged_law.py CAMPAIGN \\
        --ratio 2.31,2.56 --knee 0.249
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np
from scipy import optimize

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from stiffnet.campaign import sensor_gain  # noqa: E402
from stiffnet.restoring_force import restoring_force_estimate  # noqa: E402
from stiffnet.restoring_force.estimate import CHAIN_FIT_WHEN_NEEDED, impact_regions  # noqa: E402
from stiffnet.restoring_force.staged_law import KNEE_STARTS, staged_force  # noqa: E402


def alternative_fit(force, disp, vel, law, ratio: float | None, knee: float | None) -> float:
    """The first-stage slope ``K`` with the ratio free (`ratio` None) or the knee held."""
    inside = (disp - law.onset)[disp > law.onset]
    best = None
    for q in KNEE_STARTS:
        k0 = [np.log(law.stiffness), law.onset, law.damping]
        free_knee = [] if knee is not None else [np.log(np.quantile(inside, q))]
        free_ratio = [] if ratio is not None else [np.log(2.0)]
        theta0 = np.array(k0 + free_knee + free_ratio)

        def residual(t, fk=bool(free_knee), fr=bool(free_ratio)):
            dk = np.exp(t[3]) if fk else knee
            r = np.exp(t[-1]) if fr else ratio
            return staged_force(disp, vel, np.exp(t[0]), t[1], t[2], dk, r) - force

        lo = [-np.inf, -np.inf, 0.0] + [-np.inf] * len(free_knee) + [np.log(0.2)] * len(free_ratio)
        hi = [np.inf] * (3 + len(free_knee)) + [np.log(20.0)] * len(free_ratio)
        res = optimize.least_squares(residual, np.clip(theta0, lo, hi), bounds=(lo, hi),
                                     x_scale="jac", max_nfev=200)  # fmt: skip
        if best is None or res.cost < best.cost:
            best = res
    return float(np.exp(best.x[0]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", type=Path)
    ap.add_argument("--ratio", required=True, help="the card's knee_ratio range, LOW,HIGH")
    ap.add_argument("--knee", type=float, required=True, help="the card's knee (model units)")
    args = ap.parse_args()
    lo_r, hi_r = (float(v) for v in args.ratio.split(","))
    mid = float(np.sqrt(lo_r * hi_r))
    rows = list(csv.DictReader(open(args.campaign / "manifest.csv")))
    errors: dict[str, list[float]] = {k: [] for k in ("library", "shipped", "free", "card knee")}
    covered, cpu = 0, 0.0
    print(
        "| recording | beta | library | ratio held, knee free (shipped) | interval | both free "
        "| knee at the card's |"
    )
    print("|---|---|---|---|---|---|---|")
    for row in rows:
        accel = np.loadtxt(args.campaign / row["recording"], delimiter=",", skiprows=1)[:, 1]
        fs, fn, beta = float(row["fs_hz"]), float(row["natural_frequency_hz"]), float(row["beta"])
        kw = dict(natural_frequency_hz=fn, max_periods=24.0,
                  chain_fit_below_r2=CHAIN_FIT_WHEN_NEEDED)  # fmt: skip
        lib = restoring_force_estimate(accel, fs, **kw)
        t0 = time.process_time()
        shipped = restoring_force_estimate(accel, fs, stage_ratio=(lo_r, hi_r), **kw)
        cpu += time.process_time() - t0
        k, law = lib.free_stiffness, lib.law
        f = lib.force
        sigma = 1.4826 * float(np.median(np.abs(f - np.median(f))))
        near = impact_regions(f > 5.0 * sigma, 3)[0] > 0
        state = (f[near], lib.displacement[near], lib.velocity[near], law)
        knee_map = args.knee * sensor_gain(fn) / k  # x_map = x G / k
        readings = {
            "library": lib.beta,
            "shipped": shipped.beta,
            "free": alternative_fit(*state, None, None) / k,
            "card knee": alternative_fit(*state, mid, knee_map) / k,
        }
        for key, value in readings.items():
            errors[key].append(abs(value / beta - 1))
        lo, hi = shipped.beta_interval
        covered += lo <= beta <= hi
        cells = [f"{readings[x]:.1f} ({100 * (readings[x] / beta - 1):+.0f} %)" for x in readings]
        print(
            f"| {row['recording']} | {beta:g} | {cells[0]} | {cells[1]} | [{lo:.1f}, {hi:.1f}]"
            f"{' no knee' if shipped.beyond_knee_interval else ''} | {cells[2]} | {cells[3]} |"
        )
    print()
    print("MAPE: " + ", ".join(f"{k} {np.mean(v):.3f}" for k, v in errors.items()))
    print(f"shipped interval coverage {covered}/{len(rows)}; shipped reading {cpu:.1f} s CPU")


if __name__ == "__main__":
    main()

"""Reproduce the paper's numerical results (sections 4, 5.2.1, 5.2.2) with stiffnet.geometry.

The paper's parameter set (a = 1.9, w = 1.05, xi = 0.02, e = 2.8, f_n = 9.48 Hz)
at 100 samples per natural period, 6000 samples (63 forcing periods) per
record, on the period-1 branch (one impact per forcing period, Fig. 9), and
from beta = 35 on also on the coexisting attractor with two impacts every three
periods (reached from rest). Prints, as Markdown tables:

* Table 1 side by side with ours (polynomial fit) and the gradient approach;
* all sixteen betas (the paper says seventeen, lists sixteen), both branches;
* the noise study (0, 2, 4, 9 % of the forcing amplitude) on Table 1's betas;
* the embedding delay (AMI, both rules) and dimension (FNN, Cao) without and
  with impacts, and the Kaplan-Glass determinism factor;

and draws the Fig. 11 analogue (per-orbit inclinations before vs after impact,
coloured by beta) to ``docs/figures/inclination_vs_beta.png``.

Run: ``OMP_NUM_THREADS=1 python benchmarks/reproduce_paper.py`` (about 30 s).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from stiffnet.geometry import geometric_estimate
from stiffnet.geometry.paper import (
    PAPER_BETAS,
    PAPER_FS_RATIO,
    TABLE1,
    period1_state,
    simulate_paper,
)
from stiffnet.nlts import (
    cao_curves,
    cao_dimension,
    false_nearest_neighbours,
    fnn_dimension,
    kaplan_glass,
    mutual_information,
    savgol_smooth,
)
from stiffnet.nlts.delay import first_minimum, first_prominent_minimum
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
from stiffnet.simulator.simulator import Simulator

FS_HZ = PAPER_FS_RATIO * PAPER_NATURAL_FREQUENCY_HZ
ROOT = Path(__file__).resolve().parents[1]


def analyse(accel: np.ndarray) -> list:
    return [geometric_estimate(a, FS_HZ) for a in accel]


def impacts_per_period(res, i: int) -> float:
    """Impacts per forcing period in record i (contact onsets)."""
    c = res.contact_force[i] > 0
    onsets = np.count_nonzero(c[1:] & ~c[:-1])
    periods = c.size / (PAPER_FS_RATIO / 1.05)
    return onsets / periods


def table1(period1: list) -> None:
    print("\n## Table 1: inclinations before / after impact (degrees)\n")
    print("| beta | paper (polynomial) | ours, polynomial fit | ours, gradient (eqs 9-10) |")
    print("|---:|---:|---:|---:|")
    for b, (pb, pa) in TABLE1.items():
        r = period1[PAPER_BETAS.index(b)]
        print(
            f"| {b:g} | {pb:.1f} / {pa:.1f} | {r.polynomial_before_deg:.1f} / "
            f"{r.polynomial_after_deg:.2f} | {r.gradient_before_deg:.1f} / "
            f"{r.gradient_after_deg:.2f} |"
        )


def all_betas(period1: list, other: list, res_other) -> None:
    print("\n## All sixteen betas (noise-free)\n")
    print(
        "| beta | polynomial before / after | gradient before / after | beta est. | class "
        "| coexisting attractor: impacts/period, polynomial before / after, "
        "before by position (flight in periods: angle), beta est., class |"
    )
    print("|---:|---:|---:|---:|---|---|")
    for i, b in enumerate(PAPER_BETAS):
        r, o = period1[i], other[i]
        ipp = impacts_per_period(res_other, i)
        alt = "same orbit"
        if abs(ipp - 1.0) > 0.05:
            pos = "; ".join(
                f"{p['flight_periods']:.2f}: {p['before_deg']:.1f}" for p in o.positions()
            )
            alt = (
                f"{ipp:.2f}, {o.polynomial_before_deg:.1f} / {o.polynomial_after_deg:.2f}, "
                f"{pos}, {o.geometric_beta:.0f}, {o.geometric_class}"
            )
        print(
            f"| {b:g} | {r.polynomial_before_deg:.1f} / {r.polynomial_after_deg:.2f} | "
            f"{r.gradient_before_deg:.1f} / {r.gradient_after_deg:.2f} | "
            f"{r.geometric_beta:.0f} | {r.geometric_class} | {alt} |"
        )
    for m in ("polynomial", "gradient"):
        b = [getattr(r, f"{m}_before_deg") for r in period1]
        a = [getattr(r, f"{m}_after_deg") for r in period1]
        print(
            f"\nSpearman rho with beta ({m}): before {spearmanr(PAPER_BETAS, b)[0]:.3f}, "
            f"after {spearmanr(PAPER_BETAS, a)[0]:.3f}"
        )


def noise_study(seeds: int) -> dict:
    betas = sorted(TABLE1)
    print("\n## Noise (Table 1's betas; mean over seeds, +- per-orbit std of the first seed)\n")
    print(
        "| noise | beta | polynomial before / after | gradient before / after | beta est. | class |"
    )
    print("|---:|---:|---:|---:|---:|---|")
    out = {}
    for noise in (0.0, 0.02, 0.04, 0.09):
        runs = [analyse(simulate_paper(betas, noise=noise, rng=s).accel) for s in range(seeds)]
        out[noise] = runs
        for j, b in enumerate(betas):
            rs = [run[j] for run in runs]

            def mean(attr: str, rs=rs) -> float:
                return float(np.mean([getattr(r, attr) for r in rs]))

            r0 = rs[0]
            print(
                f"| {100 * noise:g} % | {b} | {mean('polynomial_before_deg'):.1f} "
                f"+- {np.std(r0.orbit_before_deg):.1f} / {mean('polynomial_after_deg'):.2f} "
                f"+- {np.std(r0.orbit_after_deg):.2f} | {mean('gradient_before_deg'):.1f} / "
                f"{mean('gradient_after_deg'):.2f} | {mean('geometric_beta'):.0f} | "
                f"{'/'.join(sorted({r.geometric_class for r in rs}))} |"
            )
        ordered = [
            all(np.all(np.diff([getattr(r, f"{m}_{w}_deg") for r in run]) > 0) for run in runs)
            for m in ("polynomial", "gradient")
            for w in ("before", "after")
        ]
        print(
            f"| {100 * noise:g} % | | order 12<26<31<47 kept in all seeds: polynomial "
            f"{ordered[0]}/{ordered[1]}, gradient {ordered[2]}/{ordered[3]} | | | |"
        )
    return out


def embedding_study() -> None:
    print("\n## Embedding parameters, determinism\n")
    betas = np.array([12.0, 47.0, 26.0])
    gaps = np.array([2.8, 2.8, 30.0])
    names = ["impacts, beta 12", "impacts, beta 47", "no impact (gap 30)"]
    x0, v0 = period1_state()
    batch = OscillatorBatch(betas, gaps, 1.9, 1.05, 0.02)
    sim = Simulator()
    print(
        "| record | AMI first min (16 bins) | AMI prominent min | FNN m (2 %) at 0.5 % noise "
        "| Cao m, noise-free | Cao m, 0.5 % noise |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    clean = sim.simulate(batch, PAPER_FS_RATIO, 6000, rng=0, x0=np.full(3, x0), v0=np.full(3, v0))
    noisy = sim.simulate(
        batch, PAPER_FS_RATIO, 6000, noise=0.005, rng=0, x0=np.full(3, x0), v0=np.full(3, v0)
    )
    for i, name in enumerate(names):
        s = savgol_smooth(clean.accel[i], 9)
        sn = savgol_smooth(noisy.accel[i], 9)
        ami = mutual_information(s, 60)
        fnn = fnn_dimension(false_nearest_neighbours(sn, 17, 6), 0.02)
        cao0 = cao_dimension(cao_curves(s, 17, 6)[0])
        cao1 = cao_dimension(cao_curves(sn, 17, 6)[0])
        print(
            f"| {name} | {first_minimum(ami)} | {first_prominent_minimum(ami)} | {fnn} | "
            f"{cao0} | {cao1} |"
        )
    # AMI delay over all betas (the paper: "around 17")
    res = simulate_paper(PAPER_BETAS, n_samples=6000)
    taus = [first_prominent_minimum(mutual_information(savgol_smooth(a, 9), 60)) for a in res.accel]
    print(f"\nAMI first prominent minimum over the 16 betas: {taus} (median {np.median(taus):g})")
    print("\nKaplan-Glass determinism factor (m = 4, tau = 17, 12000 samples; 8 boxes, and")
    print("the range over 6, 8, 10, 12 boxes):\n")
    print("| noise | beta 12 | beta 26 | beta 47 |")
    print("|---:|---|---|---|")
    for noise in (0.0, 0.02, 0.05):
        r = simulate_paper([12.0, 26.0, 47.0], n_samples=12000, noise=noise)
        cells = []
        for a in r.accel:
            s = savgol_smooth(a, 9)
            f = [kaplan_glass(s, dim=4, tau=17, n_boxes=nb)[1] for nb in (6, 8, 10, 12)]
            cells.append(f"{f[1]:.2f} ({min(f):.2f}-{max(f):.2f})")
        print(f"| {100 * noise:g} % | " + " | ".join(cells) + " |")


def figure(accel: np.ndarray, period1: list, noise_runs: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    grad = [geometric_estimate(a, FS_HZ, method="gradient", calibration=None) for a in accel]
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.4), constrained_layout=True)
    norm = LogNorm(5, 100)
    cmap = plt.get_cmap("viridis")
    ax = axes[0]
    for r, b in zip(grad, PAPER_BETAS, strict=True):
        ax.scatter(r.orbit_before_deg, r.orbit_after_deg, s=5, color=cmap(norm(b)), alpha=0.6)
    means = [(r.inclination_before_deg, r.inclination_after_deg) for r in grad]
    ax.plot(*zip(*means, strict=True), "k-", lw=0.8, label="mean per beta (trend)")
    ax.set(
        xlabel="inclination before impact (deg)",
        ylabel="inclination after impact (deg)",
        title="Fig. 11 analogue: gradient approach, per orbit",
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, label="beta (colour)")
    ax = axes[1]
    for m, mk in (("polynomial", "o"), ("gradient", "s")):
        b = [getattr(r, f"{m}_before_deg") for r in period1]
        a = [getattr(r, f"{m}_after_deg") for r in period1]
        ax.plot(b, a, "-", color="0.7", lw=0.6, zorder=0)
        ax.scatter(b, a, c=PAPER_BETAS, cmap=cmap, norm=norm, marker=mk, s=28, label=f"ours, {m}")
    pb, pa = zip(*TABLE1.values(), strict=True)
    ax.scatter(pb, pa, marker="x", color="r", s=40, label="paper, Table 1")
    for bb, (x, y) in TABLE1.items():
        ax.annotate(
            f"{bb}", (x, y), fontsize=7, color="r", xytext=(3, -9), textcoords="offset points"
        )
    ax.set(xlabel="inclination before impact (deg)", title="means per beta; paper's Table 1")
    ax.legend(loc="lower right", fontsize=8)
    ax = axes[2]
    markers = {0.0: "o", 0.04: "s", 0.09: "^"}
    for noise, mk in markers.items():
        for r, bb in zip(noise_runs[noise][0], sorted(TABLE1), strict=True):
            ax.errorbar(
                np.mean(r.orbit_before_deg),
                np.mean(r.orbit_after_deg),
                xerr=np.std(r.orbit_before_deg),
                yerr=np.std(r.orbit_after_deg),
                fmt=mk,
                color=cmap(norm(bb)),
                ms=6,
                capsize=2,
                lw=0.8,
            )
        ax.plot([], [], mk, color="0.3", label=f"{100 * noise:g} % noise")
    for bb in sorted(TABLE1):
        ax.plot([], [], "-", color=cmap(norm(bb)), lw=3, label=f"beta {bb}")
    ax.set(
        xlabel="inclination before impact (deg)",
        title="Fig. 12 analogue: noise (polynomial, orbit mean +- std)",
    )
    ax.legend(loc="lower right", fontsize=7, ncol=2)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    print(f"\nfigure: {path} ({path.stat().st_size / 1024:.0f} KB)")


def main() -> None:
    ap = argparse.ArgumentParser(description="Reproduce the paper's numerical results.")
    ap.add_argument("--seeds", type=int, default=3, help="noise realisations per level")
    ap.add_argument("--figure", type=Path, default=ROOT / "docs/figures/inclination_vs_beta.png")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res_p1 = simulate_paper(PAPER_BETAS)
    period1 = analyse(res_p1.accel)
    # From rest: from beta = 35 on, some records settle on the other attractor.
    res_rest = simulate_paper(PAPER_BETAS, branch="rest")
    other = analyse(res_rest.accel)
    table1(period1)
    all_betas(period1, other, res_rest)
    runs = noise_study(args.seeds)
    embedding_study()
    figure(res_p1.accel, period1, runs, args.figure)
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()

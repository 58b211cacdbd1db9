"""How the embedding-delay rules depend on the AMI histogram's bin count.

Prints, for bin counts 8..64, the delay chosen by the plain first AMI minimum
and by the robust rule (first prominent minimum of the smoothed curve) on
Lorenz x, noisy Lorenz, a noisy sine and simulated impact records (the paper's
parameters), next to the bin-free period rule used by the geometric method
(0.18 of the dominant period). See docs/nlts.md for the reading.

    OMP_NUM_THREADS=1 python benchmarks/ami_bin_stability.py        # ~20 s
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from stiffnet.geometry.estimate import DELAY_FRACTION, dominant_period
from stiffnet.nlts import first_minimum, first_prominent_minimum, mutual_information
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from _lorenz import lorenz_x  # noqa: E402

BINS = (8, 12, 16, 24, 32, 48, 64)
MAX_LAG = 150


def signals(n: int = 20000) -> list[tuple[str, np.ndarray]]:
    rng = np.random.default_rng(0)
    lz = lorenz_x(n)
    t = np.arange(n)
    out = [
        ("Lorenz x (dt 0.01)", lz),
        ("Lorenz x + 25 % noise", lz + 0.25 * lz.std() * rng.standard_normal(n)),
        (
            "sine, period 200, 20 % noise",
            np.sin(2 * np.pi * t / 200) + 0.2 * rng.standard_normal(n),
        ),
    ]
    for beta, noise in ((12.0, 0.05), (47.0, 0.0), (47.0, 0.05), (47.0, 0.09), (80.0, 0.02)):
        batch = OscillatorBatch.single(beta, 2.8, 1.9, 1.05, 0.02)
        sim = Simulator(settle_tolerance=0.01).simulate(batch, 100.0, n, noise=noise, rng=2)
        out.append((f"impact beta={beta:.0f}, noise {noise:.0%}", sim.accel[0]))
    return out


def main() -> int:
    print(f"delay [samples] by bin count {list(BINS)}; impact records: 100 samples per natural")
    print("period (95 per forcing period)")
    print(f"{'signal':<32}{'plain first minimum':<34}{'first prominent minimum':<34}period rule")
    for name, x in signals():
        plain, robust = [], []
        for bins in BINS:
            ami = mutual_information(x, MAX_LAG, bins)
            plain.append(first_minimum(ami))
            robust.append(first_prominent_minimum(ami))
        # the period rule is for forced, periodic records; Lorenz has no dominant period
        period = (
            "-" if name.startswith("Lorenz") else max(1, round(DELAY_FRACTION * dominant_period(x)))
        )
        spread = f"(range {min(robust)}-{max(robust)})"
        print(f"{name:<32}{' '.join(f'{v:3d}' for v in plain):<34}"
              f"{' '.join(f'{v:3d}' for v in robust):<34}{period:>3}  {spread}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

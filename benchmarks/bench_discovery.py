"""Speed and accuracy of the contact-law discovery on 24 recordings (target: <= 10 s).

The example manifest's eight operating points at three forcing ratios (x0.98, x1,
x1.02), 24 forcing periods each after the transient, simulated in one batch per law
(the numerical engine) with 3 % white noise; each law is a user effect of
``tests/unknown_contact_laws.py`` (or the library's linear / Kelvin-Voigt contact).
Timed: the restoring-force maps of the 24 recordings (the baseline, what
``diagnose``'s evidence already runs) and the discovery on their samples (forward
path with held-out impacts and the 30-replicate bootstrap). Prints a Markdown
table with the machine's load.

    OMP_NUM_THREADS=1 PYTHONPATH=.:tests python benchmarks/bench_discovery.py
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import unknown_contact_laws as laws  # noqa: E402

from stiffnet.discovery import discover_contact_law  # noqa: E402
from stiffnet.discovery.samples import record_contact_samples  # noqa: E402
from stiffnet.effects.contact_damping import ContactDamping  # noqa: E402
from stiffnet.simulator.batch import OscillatorBatch  # noqa: E402
from stiffnet.simulator.simulator import Simulator  # noqa: E402

#: beta, forcing ratio, amplitude, gap, samples per natural period (the example manifest).
ROWS = [(8, 1.05, 1.9, 2.8, 105), (14, 1.0, 1.2, 1.2, 105), (22, 1.1, 1.9, 2.0, 132),
        (30, 0.98, 1.5, 1.6, 132), (45, 1.08, 1.7, 2.4, 158), (65, 1.02, 1.3, 0.9, 158),
        (80, 1.05, 1.9, 2.8, 211), (95, 1.0, 1.2, 1.2, 211)]  # fmt: skip
LAWS = {
    "linear": [],
    "kelvin_voigt 0.2": [ContactDamping(damping_ratio=0.2)],
    "two_stage 0.2 / 3": [laws.TwoStageContact(knee=0.2, ratio=3.0)],
    "power 2.0": [laws.PowerLawContact(exponent=2.0)],
    "hunt_crossley 0.3": [laws.HuntCrossleyContact(c=0.3)],
    "sprung face 0.3 / 12": [laws.SprungFaceContact(m_f=0.3, f_face=12.0, eta=0.2)],
}
TRUTH = {"linear": (), "kelvin_voigt 0.2": ("damping",), "two_stage 0.2 / 3": ("hinge",),
         "power 2.0": ("power",), "hunt_crossley 0.3": ("hunt_crossley",),
         "sprung face 0.3 / 12": ("face",)}  # fmt: skip


def recordings(effects, noise: float, periods: float, seed: int):
    """24 records (8 points x 3 forcing ratios) in model units, and their betas."""
    rows = [(b, w * f, a, e, fs) for f in (0.98, 1.0, 1.02) for b, w, a, e, fs in ROWS]
    beta, w, a, e, fsr = (np.array(c, float) for c in zip(*rows, strict=True))
    batch = OscillatorBatch(beta=beta, gap=e, amplitude=a, omega=w,
                            damping=np.full(beta.size, 0.02))  # fmt: skip
    n = int(periods * fsr.max() / w.min())
    res = Simulator(effects).simulate(batch, fsr, n, noise=noise, rng=seed)
    return [
        (res.accel[i, : int(periods * fsr[i] / w[i])], fsr[i], w[i]) for i in range(beta.size)
    ], beta


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--periods", type=float, default=26.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--law", action="append", choices=list(LAWS), help="only these laws")
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()}")
    print("| law | terms found (truth) | explained (library) | maps s | discovery s | total s "
          "| discovery / maps | beta MAPE |")  # fmt: skip
    print("|---|---|---|---:|---:|---:|---:|---:|")
    for name, effects in LAWS.items():
        if args.law and name not in args.law:
            continue
        recs, beta = recordings(effects, args.noise, args.periods, args.seed)
        fn = 9.48
        t0 = time.perf_counter()
        samples = []
        for i, (acc, fsr, w) in enumerate(recs):
            s, _ = record_contact_samples(acc, fsr * fn, fn, w * fn, 1.0, str(i))
            if s is not None:
                samples.append((i, s))
        t1, c1 = time.perf_counter(), time.process_time()
        law = discover_contact_law([s for _, s in samples], seed=args.seed)
        t2, cpu = time.perf_counter(), time.process_time() - c1
        truth = beta[[i for i, _ in samples]]
        mape = float(np.mean(np.abs(np.array(law.betas) / truth - 1)))
        print(f"| {name} | {', '.join(law.terms) or '-'} ({', '.join(TRUTH[name]) or '-'}) | "
              f"{law.explained_fraction:.3f} ({law.library_explained_fraction:.3f}) | "
              f"{t1 - t0:.2f} | {t2 - t1:.2f} (CPU {cpu:.2f}) | {t2 - t0:.2f} | "
              f"{(t2 - t1) / (t1 - t0):.1f} | {mape:.3f} |")  # fmt: skip
        if "face" in law.terms:
            p = law.params
            print(f"|  | mu {p['face_mass']:.3g}, kappa {p['face_stiffness']:.4g}, zeta "
                  f"{p['face_damping']:.3g} (truth 0.3, 43.2, 0.1) | | | | | | |")  # fmt: skip
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()

"""Speed and accuracy of the contact-law discovery on 24 recordings (target: <= 10 s).

Stiffnet's simulator: the example manifest's eight operating points at three forcing
ratios (x0.98, x1, x1.02), 24 forcing periods each after the transient, simulated in
one batch per law (the numerical engine) with 3 % white noise; each law is a user
effect of ``tests/unknown_contact_laws.py`` (or the library's linear / Kelvin-Voigt
contact). The independent rig (cases "rig ..."): the 24-recording campaigns of
``benchmarks/bench_loop_iteration.py --rig`` (``tests/independent_rig.py``, solve_ivp in
SI units, CSV in g, 3 s at 2 % noise; two-stage knee 0.25 mm ratio 2.5, Hunt-Crossley
lambda 6 s/m), written once to ``--rig-dir`` and read back as ``diagnose`` reads them.

Timed apart, wall and CPU seconds: the restoring-force maps of the 24 recordings
(:func:`stiffnet.discovery.campaign_contact_samples`: what the discovery reads) and
the discovery on their samples (forward path with held-out impacts and the
30-replicate bootstrap). ``--compare`` also times the maps with every recording's own
sensor chain fitted (the path before the campaign's chain decision,
:func:`stiffnet.discovery.samples.campaign_readings`) and counts the recordings whose
samples differ (with the law they give where any do). Prints a Markdown table with the
machine's load per row (measured before -> after: docs/measurement_loop.md, "What the
discovery costs on 24 recordings").

    OMP_NUM_THREADS=1 PYTHONPATH=.:tests python benchmarks/bench_discovery.py \
        [--law linear ...] [--rig-dir /tmp/rig] [--compare]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import unknown_contact_laws as laws  # noqa: E402

from stiffnet.discovery import campaign_contact_samples, discover_contact_law  # noqa: E402
from stiffnet.discovery.samples import (  # noqa: E402
    CHAIN_RECORDINGS,
    campaign_readings,
    record_contact_samples,
)
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


#: The independent rig's 24-recording campaigns (``bench_loop_iteration.py --rig``'s laws).
RIG = {"rig two_stage 0.25 / 2.5": "two_stage", "rig hunt_crossley 6": "hunt_crossley"}
RIG_TRUTH = {"two_stage": ("hinge",), "hunt_crossley": ("hunt_crossley",)}


def rig_campaign(law: str, folder: Path):
    """The rig's campaign of ``bench_loop_iteration.rig_runs`` (written once, then reused)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench_loop_iteration import rig_runs
    from independent_rig import write_campaign

    from stiffnet.campaign import load_campaign

    if not (folder / law / "manifest.csv").exists():
        write_campaign(folder / law, rig_runs(law))
    return load_campaign(folder / law)


def sim_maps(recs: list, beta: np.ndarray, chain_recordings) -> tuple[list, np.ndarray]:
    """The simulator's records (:func:`recordings`) through the restoring-force maps: samples
    and true betas."""
    fn = 9.48

    def read(i: int, fit_chain: bool):
        acc, fsr, w = recs[i]
        return record_contact_samples(acc, fsr * fn, fn, w * fn, 1.0, str(i), fit_chain=fit_chain)

    got = campaign_readings(read, len(recs), chain_recordings)
    kept = [i for i in range(len(recs)) if not isinstance(got[i], Exception) and got[i][0]]
    return [got[i][0] for i in kept], beta[kept]


def rig_maps(campaign, chain_recordings) -> tuple[list, np.ndarray]:
    """The rig campaign's recordings through the restoring-force maps, as ``diagnose`` reads
    them: samples and true betas."""
    samples, _ = campaign_contact_samples(campaign, campaign.rows,
                                          chain_recordings=chain_recordings)  # fmt: skip
    given = {r.recording: r.beta for r in campaign.rows}
    return samples, np.array([given[s.recording] for s in samples], float)


def clocks() -> tuple[float, float]:
    return time.perf_counter(), time.process_time()


def same_samples(a: list, b: list) -> int:
    """Recordings whose samples differ between two readings of a campaign (by name)."""
    fields = ("displacement", "velocity", "force", "impact")
    old = {s.recording: s for s in b}
    diff = {s.recording for s in a} ^ set(old)
    for s in a:
        o = old.get(s.recording)
        if o is not None and not (
            all(np.array_equal(getattr(s, f), getattr(o, f)) for f in fields)
            and (s.onset, s.beta) == (o.onset, o.beta)
        ):
            diff.add(s.recording)
    return len(diff)


def row(name: str, truth: tuple, maps, seed: int, compare: bool) -> None:
    """Time the maps (``maps(chain_recordings)`` returns samples and betas) and the
    discovery; one row. ``compare``: the maps with every recording's own chain fit too (the
    path before the campaign's chain decision), timed, and the recordings that differ."""
    load0 = os.getloadavg()[0]
    t0, c0 = clocks()
    samples, truth_beta = maps(CHAIN_RECORDINGS)
    t1, c1 = clocks()
    law = discover_contact_law(samples, seed=seed)
    t2, c2 = clocks()
    mape = float(np.mean(np.abs(np.array(law.betas) / truth_beta - 1)))
    print(f"| {name} | {len(samples)} | {', '.join(law.terms) or '-'} "
          f"({', '.join(truth) or '-'}) | "
          f"{law.explained_fraction:.3f} ({law.library_explained_fraction:.3f}) | "
          f"{c1 - c0:.2f} / {t1 - t0:.2f} | {c2 - c1:.2f} / {t2 - t1:.2f} | "
          f"{c2 - c0:.2f} / {t2 - t0:.2f} | {mape:.3f} | {_coefs(law)} | "
          f"{load0:.1f} → {os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip
    if compare:
        t3, c3 = clocks()
        every, _ = maps(None)
        t4, c4 = clocks()
        n_diff = same_samples(samples, every)
        words = f"{n_diff} of {len(every)} recordings' samples differ"
        if n_diff:
            old = discover_contact_law(every, seed=seed)
            words += f"; law with them: {', '.join(old.terms) or '-'}, {_coefs(old)}"
        print(f"|  | every recording's chain fitted: maps CPU {c4 - c3:.2f} / wall {t4 - t3:.2f} "
              f"s; {words} | | | | | | | | {os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


def _coefs(law) -> str:
    p = law.params
    if "face" in law.terms:
        return (f"mu {p['face_mass']:.3g}, kappa {p['face_stiffness']:.4g}, zeta "
                f"{p['face_damping']:.3g} (truth 0.3, 43.2, 0.1)")  # fmt: skip
    words = {"hinge": f"knee {p['knee']:.3g}, ratio {p['knee_ratio']:.3g}",
             "power": f"exponent {p['exponent']:.3g}",
             "hunt_crossley": f"alpha {p['hunt_crossley']:.3g}",
             "damping": f"zeta {p['damping_ratio']:.3g}"}  # fmt: skip
    return "; ".join(words[t] for t in law.terms if t in words) or "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", type=float, default=0.03)
    ap.add_argument("--periods", type=float, default=26.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--law", action="append", choices=[*LAWS, *RIG], help="only these cases")
    ap.add_argument("--rig-dir", type=Path, default=None,
                    help="where the rig's campaigns are written (kept and reused)")  # fmt: skip
    ap.add_argument(
        "--compare",
        action="store_true",
        help="also every recording's own chain fitted (the earlier path), timed",
    )
    args = ap.parse_args()
    print(f"load average at start: {os.getloadavg()}")
    print(
        "| case | recordings | terms found (truth) | explained (library) | maps CPU / wall s "
        "| discovery CPU / wall s | total CPU / wall s | beta MAPE | coefficients | load |"
    )
    print("|---|---:|---|---|---:|---:|---:|---:|---|---|")
    for name, effects in LAWS.items():
        if not args.law or name in args.law:
            recs, beta = recordings(effects, args.noise, args.periods, args.seed)
            maps = lambda c, r=recs, b=beta: sim_maps(r, b, c)  # noqa: E731
            row(name, TRUTH[name], maps, args.seed, args.compare)
    with tempfile.TemporaryDirectory() as tmp:
        for name, law in RIG.items():
            if args.law and name not in args.law:
                continue
            camp = rig_campaign(law, Path(args.rig_dir or tmp))
            row(name, RIG_TRUTH[law], lambda c, k=camp: rig_maps(k, c), args.seed, args.compare)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()

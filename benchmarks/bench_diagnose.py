"""Benchmark ``diagnose`` on a 24-recording campaign with the whole library and joint refits.

The campaign: the 8 rows of ``examples/hidden_effect_manifest.csv`` three times
(``a/``, ``b/``, ``c/``: forcing frequency ratio shifted by -2 %, 0, +2 %), 6 s each
(``--duration``),
with two hidden effects at once (contact damping 0.25 and an accelerometer
resonance at 237 Hz). ``diagnose`` runs on it with every shipped effect (the three
numerical-engine ones included) and the default budgets, and the table splits
the wall time of this process by what it was spent on: the restoring-force evidence
(contact laws and the shared sensor chain, ``restoring_force_evidence``), simulation
(``simulate_rows``; the numerical engine's share, ``simulate_numerical``, on its own
line), statistics (``signal_statistics`` / ``batch_signal_statistics``)
and the rest (search, significance, nuisances, waiting for the workers), timed by
wrappers (cProfile's own overhead on the numerical engine's Python loop would
quadruple its share; ``--profile-out`` still writes a cProfile file), with the
CPU time (this process and its worker processes) and the load average (the
machine may be shared). The diagnosis itself is checked (both effects found).

Baseline in the same run: one objective evaluation (the 24 rows simulated once,
their statistics and discrepancies) the way every evaluation ran before
(statistics record by record, inclinations included) against the search's
evaluation now (rows batched per sampling rate, inclinations left out; the best
point of each fit is scored with them).

``--baseline DIR`` runs the same diagnosis on the same campaign with the code of another
checkout (e.g. ``git archive`` of the commit before) in a fresh process after this one,
and prints the wall-time ratio: a before/after measured in the same run.

Target: 24 recordings x 6 s in <= 60 s wall on a quiet 2-core machine: ``--workers 2``
(the default) runs each step's fits on one 2-process LocalCluster for the whole diagnosis (the split
then covers only this process: the joint refits, nuisances and verdict);
``--workers 0`` runs everything in-process.

Run (from the repository root, so this checkout's package is imported)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py \
        [--workers N] [--fast-only] [--no-inclination] [--duration S] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import cProfile
import csv
import os
import pstats
import resource
import tempfile
import time
from pathlib import Path

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.campaign.simulate import FIT_SETTINGS, natural_frequency, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.diagnose import diagnose_campaign
from stiffnet.measurement.discrepancy import normalised_differences, recording_discrepancy
from stiffnet.measurement.nuisance import resolve_rows
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import CampaignTarget, measured_statistics

ROOT = Path(__file__).resolve().parents[1]
HIDDEN = [
    "contact_damping:damping_ratio=0.25",
    "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0",
]
FAST = ["contact_damping", "forcing_harmonics", "gap_drift", "sensor_dynamics",
        "colored_noise", "adc"]  # fmt: skip


def campaign(tmp: Path, duration_s: float = 6.0, n_rows: int = 24) -> Path:
    """The campaign (see the module notes); ``n_rows`` < 24: that many of its rows, evenly
    spread over the three shifts and eight operating points."""
    with open(ROOT / "examples" / "hidden_effect_manifest.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    out = []
    for prefix, shift in (("a", 0.98), ("b", 1.0), ("c", 1.02)):
        for r in rows:
            ratio = f"{float(r['frequency_ratio']) * shift:.4f}"
            name = f"{prefix}/{Path(r['recording']).name}"
            out.append({**r, "recording": name, "frequency_ratio": ratio,
                        "duration_s": f"{duration_s:g}"})  # fmt: skip
    keep = sorted({round(i * (len(out) - 1) / max(n_rows - 1, 1)) for i in range(n_rows)})
    manifest = tmp / "manifest24.csv"
    with open(manifest, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(out[i] for i in keep)
    return simulate_campaign(manifest, tmp / "campaign24", HIDDEN, seed=0)


def timed() -> dict[str, float]:
    """Wrap the simulation and statistics entry points of the modules diagnose calls with
    timers (this process only); returns the seconds spent in each, filled as it runs:
    ``numerical`` (the numerical engine) is part of ``simulation``, ``evidence`` (the
    restoring-force contact laws and the shared sensor chain) a stage of its own."""
    from stiffnet.measurement import diagnose, noise_floor, target
    from stiffnet.simulator import simulator

    spent = {"simulation": 0.0, "statistics": 0.0, "numerical": 0.0, "evidence": 0.0}

    def wrap(module, name: str, stage: str) -> None:
        fn = getattr(module, name)

        def timed_fn(*a, **k):
            t = time.perf_counter()
            try:
                return fn(*a, **k)
            finally:
                spent[stage] += time.perf_counter() - t

        setattr(module, name, timed_fn)

    wrap(target, "simulate_rows", "simulation")
    wrap(simulator, "simulate_numerical", "numerical")
    # by the function itself: the quoted name is an earlier result key the naming test bans
    wrap(diagnose, diagnose.restoring_force_evidence.__name__, "evidence")
    for module, name in ((target, "batch_signal_statistics"), (target, "signal_statistics"),
                         (noise_floor, "signal_statistics")):  # fmt: skip
        wrap(module, name, "statistics")
    return spent


def cpu_seconds() -> float:
    """User + system CPU time of this process and its waited-for children (the workers)."""
    own, kids = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def evaluation_ratio(camp, repeats: int = 5) -> tuple[float, float]:
    """Seconds of one objective evaluation before (record by record, inclinations in every
    evaluation) and now (the search's: batched, inclinations left out)."""
    rows, _ = resolve_rows(camp)
    measured, lengths, _ = measured_statistics(camp, rows, True)
    target = CampaignTarget(rows, measured, lengths, [], inclination=True)
    model = [effect_class("contact_damping")(damping_ratio=0.2)]

    def before() -> None:
        sims = simulate_rows(rows, model, lengths, target.seed, FIT_SETTINGS)
        for m, a, r in zip(measured, sims, rows, strict=True):
            s = signal_statistics(a, r.fs_hz, natural_frequency(r), r.frequency_ratio, True)
            recording_discrepancy(normalised_differences(m, s))

    def now() -> None:
        target.known.clear()  # a real evaluation each time, not the target's kept result
        target.per_recording(model, FIT_SETTINGS, inclination=False)

    out = []
    for fn in (before, now):
        fn()  # warm (imports, numba, filter designs)
        t = time.perf_counter()
        for _ in range(repeats):
            fn()
        out.append((time.perf_counter() - t) / repeats)
    return out[0], out[1]


BASELINE = """
import json, resource, sys, time
from stiffnet.campaign import load_campaign
from stiffnet.measurement.diagnose import diagnose_campaign
def cpu():
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
a = json.loads(sys.argv[1])
camp = load_campaign(a["campaign"])
t, c = time.perf_counter(), cpu()
res = diagnose_campaign(camp, effects=a["effects"],
                        workers=a["workers"], inclination=a["inclination"])
print(json.dumps({"wall": time.perf_counter() - t, "cpu": cpu() - c,
                  "selected": res["missing_effects"], "params": res["fitted_params"],
                  "verdict": res["verdict"], "residual": res["residual_discrepancy"]}))
"""


def baseline_run(code: str, folder: Path, args: argparse.Namespace) -> dict:
    """The same diagnosis with another checkout's code (``code``: its root), in a fresh
    process on the same campaign folder: the before of a before/after in one run."""
    import json
    import subprocess
    import sys

    spec = {"campaign": str(folder), "effects": FAST if args.fast_only else None,
            "workers": args.workers or None, "inclination": not args.no_inclination}  # fmt: skip
    env = {**os.environ, "PYTHONPATH": str(Path(code).resolve())}
    out = subprocess.run([sys.executable, "-c", BASELINE, json.dumps(spec)], env=env,
                         capture_output=True, text=True, check=True, cwd=code)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2, help="LocalCluster processes (0: none)")
    ap.add_argument("--fast-only", action="store_true", help="closed-form effects only")
    ap.add_argument("--no-inclination", action="store_true", help="leave out the geometric "
                    "method's inclination statistics (as the tests do)")  # fmt: skip
    ap.add_argument("--profile-out", help="also write the cProfile statistics to this file")
    ap.add_argument("--duration", type=float, default=6.0, help="seconds per recording (6)")
    ap.add_argument("--rows", type=int, default=24, help="recordings (24; fewer: spread over "
                    "the campaign's)")  # fmt: skip
    ap.add_argument("--baseline", help="root of another checkout (the code before): the same "
                    "diagnosis run with it after this one, on the same campaign")  # fmt: skip
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        folder = campaign(Path(d), args.duration, args.rows)
        camp = load_campaign(folder)
        t_sim = time.perf_counter() - t
        t_before, t_now = evaluation_ratio(camp)
        load0 = os.getloadavg()[0]
        prof = cProfile.Profile() if args.profile_out else None
        spent = timed()
        cpu0 = cpu_seconds()
        t = time.perf_counter()
        if prof is not None:
            prof.enable()
        res = diagnose_campaign(
            camp, effects=FAST if args.fast_only else None, workers=args.workers or None,
            inclination=not args.no_inclination,
            progress=lambda done, total: print(f"  fits {done}/{total}", flush=True),
        )  # fmt: skip
        if prof is not None:
            prof.disable()
            pstats.Stats(prof).dump_stats(args.profile_out)
        wall = time.perf_counter() - t
        cpu = cpu_seconds() - cpu0
        load1 = os.getloadavg()[0]
        base = baseline_run(args.baseline, folder, args) if args.baseline else None
        load2 = os.getloadavg()[0]
    sim, stats_, evid = spent["simulation"], spent["statistics"], spent["evidence"]
    where = "this process" if args.workers else "in-process, everything"
    print(f"\nload average {load0:.2f} at the start, {load1:.2f} at the end; "
          f"campaign simulated in {t_sim:.1f} s; workers: {args.workers or 'none'}")  # fmt: skip
    print(f"one objective evaluation ({args.rows} rows): before {t_before:.3f} s, "
          f"now {t_now:.3f} s (x{t_before / t_now:.1f})")  # fmt: skip
    print(f"| stage ({where}) | seconds | share of wall |\n|---|---|---|")
    rest = wall - sim - stats_ - evid
    stages = [
        ("restoring-force evidence (contact laws, shared sensor chain)", evid),
        ("simulation", sim),
        ("of which the numerical engine", spent["numerical"]),
        ("statistics", stats_),
        ("search, tests, nuisances", rest),
    ]
    for name, v in [*stages, ("total (wall)", wall)]:
        print(f"| {name} | {v:.1f} | {v / wall:.0%} |")
    print(f"| CPU time (this process + workers) | {cpu:.1f} | {cpu / wall:.0%} |")
    print(f"\nselected {res['missing_effects']} {res['fitted_params']}")
    print(f"verdict {res['verdict']}, residual {res['residual_discrepancy']:.3g}, "
          f"noise floor {res['noise_floor']:.3g}; target <= 60 s (quiet machine): "
          f"{'met' if wall <= 60 else 'NOT met'} ({wall:.0f} s)")  # fmt: skip
    if base is not None:
        print(f"\nbaseline ({args.baseline}), same campaign, run after this one (load "
              f"{load1:.2f} -> {load2:.2f}): {base['wall']:.1f} s wall, selected "
              f"{base['selected']} {base['params']}, verdict {base['verdict']}, residual "
              f"{base['residual']:.3g}")  # fmt: skip
        print(
            f"| code | wall s | CPU s |\n|---|---|---|\n"
            f"| before | {base['wall']:.1f} | {base['cpu']:.1f} |\n"
            f"| now | {wall:.1f} | {cpu:.1f} |\n"
            f"| ratio before / now | {base['wall'] / wall:.2f} | {base['cpu'] / cpu:.2f} |"
        )


if __name__ == "__main__":
    main()

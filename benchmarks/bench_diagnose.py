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
machine may be shared). The diagnosis itself is checked (both effects found). A second
table splits this process's numerical-engine CPU by stage (the single fits, each selection
step, outside the fits), the numerical-engine candidate whose design it simulated, and what:
the design's screen or its kept point on every recording (``--workers 0`` sees every fit).

Baseline in the same run: one objective evaluation (the 24 rows simulated once,
their statistics and discrepancies) the way every evaluation ran before
(statistics record by record, inclinations included) against the search's
evaluation now (rows batched per sampling rate, inclinations left out; the best
point of each fit is scored with them).

``--statistics``: the statistics alone, per record, instead of a diagnosis: CPU
milliseconds per record of ``batch_signal_statistics`` on one evaluation's simulated rows
(the campaign's rows with contact damping 0.2), inclinations left out and included, and of
the geometric estimate they come from (``geometric_estimate`` in three dimensions, no
calibration), each the best of ``--rounds`` rounds in a fresh process; with ``--baseline
DIR`` the same with DIR's code, the two alternating (before, now, before, now, ...), and the
largest difference of their statistics (the answers must not change).

``--baseline DIR`` runs the same diagnosis on the same campaign with the code of another
checkout (e.g. ``git archive`` of the commit before) in a fresh process after this one,
and prints the wall-time ratio: a before/after measured in the same run.

Target: 24 recordings x 6 s in <= 60 s wall on a quiet 2-core machine: ``--workers 2``
(the default) runs each step's fits on one 2-process LocalCluster for the whole diagnosis (the split
then covers only this process: the joint refits, nuisances and verdict);
``--workers 0`` runs everything in-process. ``--timeline``: each stage's wall time, this
process's and the workers' CPU and the cores' idle seconds (:mod:`stage_timeline`): where the
workers wait for this process and where it waits for them.

``--rig NAME[,NAME]``: held-out campaigns of the independent rig instead
(``tests/independent_rig.py``, solve_ivp in SI units; nothing of stiffnet wrote them): the 24
recordings of ``bench_loop_iteration.rig_runs`` (the eight operating points of
``tests/test_independent_rig.POINTS``, three betas each), ``--duration`` seconds at
``--rig-fs`` Hz, hiding what :data:`RIG` names: ``ideal`` (nothing: the control),
``damped_sensor`` (contact damping 0.25 and a mounted resonance at 237 Hz, 25 f_n),
``harmonics`` (shaker harmonics at random levels and phases, :data:`HARMONICS`),
``hunt_crossley`` (a law the library lacks). Each is diagnosed in-process with the rig
candidates of ``bench_loop_iteration`` (``RIG_CANDIDATES``), inclinations left out, once per
value of ``--subset`` (``diagnose.SUBSET_SEARCH`` set for that run: 8 is the default
search on 8 recordings, 24 searches all of them); the table gives the verdict, the effects
named with their values against the truth, the residual, the explained fraction, wall and
CPU seconds and the load. ``--polish N`` sets ``diagnose.POLISH_EVALUATIONS`` for every run
(here and with ``--rig``).

``--campaign DIR``: an existing campaign folder instead (e.g. the independent rig's 8-recording
material beam, whose diagnosis ends on the face decided by simulation), diagnosed with the
effects ``--only`` names (repeatable; default every shipped effect) on ``--workers`` (``0``:
in-process), each code in a fresh process: this checkout, and with ``--baseline DIR`` the
other checkout's, alternately for ``--rounds`` rounds (before first); the table gives each
run's CPU seconds (the process and its children), wall seconds, the load, the verdict, the
learned law's proposal (the share of the base model's excess it explains, its discrepancy, its
face's values) and the seconds of the face by simulation, then the CPU ratio of the best runs
(the answers must not change: the verdict, the selected effects and their fitted values, the
learned law's proposal and face). ``--dump DIR`` also writes each run's whole result
(``DIR/<code>_<round>.json``) to compare beyond them. ``--phases``: also a table of each
run's CPU seconds per phase (:data:`PHASES`: the restoring-force evidence, the library's fits,
the discovery, the face by simulation and its parts), timed by wrappers in the run's process
(``--workers 0`` to see them all), and a second table of what they spend it on: the
restoring-force readings by caller (the evidence, the discovery's maps) and kind (a chain
fitted, read through a data sheet or shared chain, read as recorded), and the simulations
(``simulate_rows``: calls and rows) by the innermost phase that asked for them.

Every code compared is first run once on two rows untimed (:func:`warm_kernels`): numba
compiles the engines' kernels into a checkout's cache on its first run, and a copy of the
commit before (or a new worktree) would otherwise count that compilation as its diagnosis.

Run (from the repository root, so this checkout's package is imported)::

    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py \
        [--workers N] [--fast-only] [--no-inclination] [--duration S] [--baseline DIR]
    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py --workers 0 \
        --rig ideal,damped_sensor,harmonics --subset 8,24 [--rig-dir /tmp/rig]
    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py --statistics \
        [--baseline DIR] [--rounds 3]
    OMP_NUM_THREADS=1 PYTHONPATH=. python benchmarks/bench_diagnose.py --campaign DIR \
        --only contact_damping --only gap_drift --no-inclination [--baseline DIR] [--rounds 1]
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import csv
import json
import math
import os
import pstats
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.campaign.manifest import MANIFEST_NAME
from stiffnet.campaign.simulate import FIT_SETTINGS, natural_frequency, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.diagnose import diagnose_campaign
from stiffnet.measurement.discrepancy import normalised_differences, recording_discrepancy
from stiffnet.measurement.evidence import restoring_force_evidence
from stiffnet.measurement.loop import cpu_seconds
from stiffnet.measurement.nuisance import resolve_rows
from stiffnet.measurement.statistics import signal_statistics
from stiffnet.measurement.target import DEFAULT_SEED, CampaignTarget, measured_statistics

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stage_timeline import StageTimeline, label_stages  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
HIDDEN = [
    "contact_damping:damping_ratio=0.25",
    "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0",
]
FAST = ["contact_damping", "forcing_harmonics", "gap_drift", "sensor_dynamics",
        "colored_noise", "adc"]  # fmt: skip


def _harmonics(seed: int = 7) -> dict[str, float]:
    """Shaker harmonics drawn at random as tests/test_harmonic_phases_campaign.py draws them:
    levels 0.15-0.3 and 0.06-0.15 of the forcing, phases anywhere."""
    rng = np.random.default_rng(seed)
    second, third = rng.uniform(0.15, 0.3), rng.uniform(0.06, 0.15)
    phases = rng.uniform(-math.pi, math.pi, 2)
    return {"second": float(second), "phase_second": float(phases[0]), "third": float(third),
            "phase_third": float(phases[1])}  # fmt: skip


HARMONICS = _harmonics()
#: ``--rig`` campaigns: (``bench_loop_iteration.RIG_LAWS`` law, the rig's extra settings).
RIG = {
    "ideal": ("ideal", {}),
    "damped_sensor": ("ideal", {"contact": "kelvin_voigt", "contact_zeta": 0.25,
                                "sensor": {"resonance_hz": 237.0, "resonance_damping": 0.03}}),
    "harmonics": ("ideal", {"harmonics": ((2, HARMONICS["second"], HARMONICS["phase_second"]),
                                          (3, HARMONICS["third"], HARMONICS["phase_third"]))}),
    "hunt_crossley": ("hunt_crossley", {}),
}  # fmt: skip
#: What each campaign hides, in the library's parameters (the hunt_crossley law has none).
RIG_TRUTH = {
    "ideal": {},
    "damped_sensor": {"contact_damping": {"damping_ratio": 0.25},
                      "sensor_dynamics": {"resonance_hz": 237.0, "resonance_damping": 0.03}},
    "harmonics": {"forcing_harmonics": HARMONICS},
    "hunt_crossley": {},
}  # fmt: skip


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


def numerical_by_stage() -> dict[str, float]:
    """Wrap the numerical engine, the selection's fits and a numerical-engine design's scoring
    with CPU timers (this process only: ``--workers 0`` sees every fit); returns the engine's
    CPU seconds by the diagnosis' stage (single fits, each step; outside them: joint refits,
    nuisances, verdict), the effect whose design it was, and what it simulated: ``screen``
    (the design's points and "effect off" on the screen's subset) or ``kept point`` (the
    point kept, on every recording); filled as it runs."""
    from stiffnet.measurement import diagnose, fitting
    from stiffnet.measurement.target import CampaignTarget
    from stiffnet.simulator import simulator

    spent: dict[str, float] = {}
    stage, effect, what = ["outside the fits"], ["-"], ["-"]

    def labelled(owner, name: str, stack: list[str], label) -> None:
        fn = getattr(owner, name)

        def inner(*a, **k):
            stack.append(label(*a, **k))
            try:
                return fn(*a, **k)
            finally:
                stack.pop()

        setattr(owner, name, inner)

    engine = simulator.simulate_numerical

    def timed_engine(*a, **k):
        t = time.process_time()
        try:
            return engine(*a, **k)
        finally:
            key = f"{stage[-1]}: {effect[-1]}, {what[-1]}"
            spent[key] = spent.get(key, 0.0) + time.process_time() - t

    simulator.simulate_numerical = timed_engine
    labelled(diagnose._Run, "fits", stage, lambda run, *a, **k: run.stage.split(",")[0])
    labelled(fitting, "_fit_design", effect, lambda target, name, *a, **k: name)
    labelled(CampaignTarget, "per_recording_points", what, lambda *a, **k: "screen")

    # "effect off" scored like the design (not oversampled) is part of the screen
    def scoring(*a, **k) -> str:
        if effect[-1] == "-":
            return "-"
        return "screen" if k.get("oversample") is False else "kept point"

    labelled(CampaignTarget, "per_recording", what, scoring)
    return spent


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


def rig_campaign(name: str, folder: Path, duration_s: float, fs_hz: float) -> Path:
    """The ``--rig`` campaign ``name`` (:data:`RIG`) written under ``folder`` by the
    independent rig, or read back when already there (``--rig-dir``)."""
    sys.path[:0] = [str(ROOT / "benchmarks"), str(ROOT / "tests")]
    from bench_loop_iteration import rig_runs
    from independent_rig import write_campaign

    out = folder / f"{name}_{duration_s:g}s_{fs_hz:g}hz"
    if not (out / "manifest.csv").exists():
        law, extra = RIG[name]
        runs = [replace(r, duration_s=duration_s, fs_hz=fs_hz, **extra) for r in rig_runs(law)]
        write_campaign(out, runs)
    return out


def _named(res: dict, truth: dict[str, dict[str, float]]) -> str:
    """The selected effects with their fitted values against the truth (relative error;
    phases in radians off)."""
    cells = []
    for eff, params in res["fitted_params"].items():
        vals = []
        for k, v in params.items():
            t = truth.get(eff, {}).get(k)
            if t is None:
                continue
            off = (f"{math.remainder(v - t, 2 * math.pi):+.2f} rad" if k.startswith("phase")
                   else f"{v / t - 1:+.0%}")  # fmt: skip
            vals.append(f"{k} {v:.4g} ({off})")
        cells.append(f"{eff}: {', '.join(vals) or 'no truth'}")
    return "; ".join(cells) or "-"


def _plain(o: object) -> object:
    """numpy values (and anything else) as JSON can write them."""
    return o.tolist() if hasattr(o, "tolist") else str(o)


def rig_table(args: argparse.Namespace) -> None:
    """``--rig``: each campaign diagnosed once per ``--subset`` value, in this process, one
    after the other (see the module notes)."""
    from bench_loop_iteration import RIG_CANDIDATES

    from stiffnet.measurement import diagnose

    subsets = [int(k) for k in args.subset.split(",")]
    print(
        "| campaign | search subset | verdict | effects named (fitted vs truth) | residual "
        "mean / median | worst recording | explained | polish before -> after | wall s | CPU s | "
        "load |"
    )
    print("|---" * 11 + "|", flush=True)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.rig.split(","):
            folder = rig_campaign(name, Path(args.rig_dir or tmp), args.duration, args.rig_fs)
            for k in subsets:
                diagnose.SUBSET_SEARCH = k
                load0, cpu0, t = os.getloadavg()[0], cpu_seconds(), time.perf_counter()
                res = diagnose_campaign(load_campaign(folder), effects=RIG_CANDIDATES,
                                        inclination=False)  # fmt: skip
                wall, cpu = time.perf_counter() - t, cpu_seconds() - cpu0
                if args.rig_dir:  # the whole result beside the campaign, to read afterwards
                    out = folder.with_name(f"{folder.name}_subset{k}_polish{args.polish}.json")
                    out.write_text(json.dumps(res, default=_plain))
                pol = res.get("polish") or {}
                polish = (f"{pol['before']:.4g} -> {pol['after']:.4g} ({pol['cpu_seconds']:.1f}"
                          f" s CPU)" if pol else "-")  # fmt: skip
                rs = res["residual_summary"]
                worst = max(res["per_recording"], key=lambda r: r["residual"])
                print(f"| {name} | {k} | {res['verdict']} | {_named(res, RIG_TRUTH[name])} | "
                      f"{res['residual_discrepancy']:.4g} / {rs['median']:.4g} | "
                      f"{worst['recording']} {worst['residual']:.3g} | "
                      f"{res['explained_fraction']:.0%} | {polish} | {wall:.0f} | {cpu:.0f} | "
                      f"{load0:.1f} -> {os.getloadavg()[0]:.1f} |", flush=True)  # fmt: skip


#: What both scripts run before the diagnosis: the CPU clock and the campaign.
SCRIPT_HEAD = """
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
"""


BASELINE = (
    SCRIPT_HEAD
    + """
res = diagnose_campaign(camp, effects=a["effects"],
                        workers=a["workers"], inclination=a["inclination"])
print(json.dumps({"wall": time.perf_counter() - t, "cpu": cpu() - c,
                  "selected": res["missing_effects"], "params": res["fitted_params"],
                  "verdict": res["verdict"], "residual": res["residual_discrepancy"]}))
"""
)


#: ``--phases``: the diagnosis' phases timed in CPU seconds of this process (label: module,
#: function), each counted where it is not nested in itself; the face by simulation's parts
#: are within its own line.
PHASES = {
    "restoring-force evidence": (
        "stiffnet.measurement.diagnose",
        restoring_force_evidence.__name__,
    ),
    "library fits alone": ("stiffnet.measurement.diagnose", "_fit_alone"),
    "selection steps": ("stiffnet.measurement.diagnose", "_step"),
    "discovery's maps": ("stiffnet.measurement.learned_law", "campaign_contact_samples"),
    "  through the shared chain": ("stiffnet.discovery.samples", "shared_chain_readings"),
    "law discovered": ("stiffnet.measurement.learned_law", "_discovered"),
    "face by simulation": ("stiffnet.measurement.learned_law", "face_by_simulation"),
    "  maps' face fits": ("stiffnet.measurement.face_by_simulation", "maps_face_law"),
    "  grid screens": ("stiffnet.measurement.face_by_simulation", "_screen_batch"),
    "  grid points alone": ("stiffnet.measurement.face_by_simulation", "_scored_alone"),
    "  refits (sweeps)": ("stiffnet.measurement.face_by_simulation", "refine_face"),
    "law simulated (no face in question)": ("stiffnet.measurement.learned_law", "_law_scored"),
    "sensor chains fitted (evidence and maps)": ("stiffnet.restoring_force.estimate", "fit_chain"),
    "soft contacts' joint fits (evidence and maps)": (
        "stiffnet.restoring_force.estimate",
        "_soft_reading",
    ),
    "polish": ("stiffnet.measurement.diagnose", "_polish"),
}

#: A fresh process that compiles the engines' numba kernels into this checkout's cache (the
#: closed-form kernel, the numerical engine's RK4 substep and event search) on two rows of
#: the campaign, and prints its CPU seconds. numba's cache is per source file and its
#: modification time: a checkout whose kernels were never run (a new worktree, a ``git
#: archive`` of the commit before, the first run after a merge that touched the simulator)
#: compiles them in its first diagnosis: 44 s of CPU on a copy of main, 20 s the closed-form
#: kernel's, 23 s the numerical engine's (load 10-12), which belong to no diagnosis after it.
WARM = (
    SCRIPT_HEAD
    + """
from stiffnet.campaign.simulate import FIT_SETTINGS, FIT_SETTINGS_NUMERICAL, simulate_rows
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.nuisance import resolve_rows
rows = resolve_rows(camp)[0][:2]
for model, settings in (([], FIT_SETTINGS),
                        ([effect_class("hertz_contact")()], FIT_SETTINGS_NUMERICAL)):
    simulate_rows(rows, model, [2000] * len(rows), 0, settings)
print(json.dumps({"wall": time.perf_counter() - t, "cpu": cpu() - c}))
"""
)


def warm_kernels(code: str, campaign: str) -> float:
    """Compile ``code``'s numba kernels into its cache before it is timed (:data:`WARM`, a
    fresh process); returns the CPU seconds that took (a few where the cache is warm)."""
    import subprocess

    env = {**os.environ, "PYTHONPATH": str(Path(code).resolve())}
    out = subprocess.run([sys.executable, "-c", WARM, json.dumps({"campaign": campaign})],
                         env=env, capture_output=True, text=True, check=True, cwd=code)  # fmt: skip
    return json.loads(out.stdout.strip().splitlines()[-1])["cpu"]


CAMPAIGN = (
    SCRIPT_HEAD
    + """
phases = {}
if a.get("phases"):
    import importlib

    def timed_phase(label, module, name):
        fn, active = getattr(module, name), []

        def run(*args, **kw):
            t0 = time.process_time()
            active.append(1)
            try:
                return fn(*args, **kw)
            finally:
                active.pop()
                if not active:
                    c, n = phases.get(label, (0.0, 0))
                    phases[label] = (c + time.process_time() - t0, n + 1)

        setattr(module, name, run)

    for label, (mod, name) in a["phases"].items():
        m = importlib.import_module(mod)
        if hasattr(m, name):
            timed_phase(label, m, name)

    # what each phase spends its seconds on: the restoring-force readings (by caller and
    # kind) and the simulations (calls, rows), each counted where it is called
    opened, work = [], {}

    def count(key, t0, n=1):
        c, k, r = work.get(key, (0.0, 0, 0))
        work[key] = (c + time.process_time() - t0, k + 1, r + n)

    def read_counted(caller, fn):
        def run(accel, fs_hz, **kw):
            kind = ("through a sheet" if kw.get("sensor") is not None else "as recorded"
                    if kw.get("chain_fit_below_r2", np.inf) == -np.inf else "chain fitted")
            t0 = time.process_time()
            try:
                return fn(accel, fs_hz, **kw)
            finally:
                count(f"readings: {caller}, {kind}", t0)
        return run

    def simulated(fn):
        def run(rows, *args, **kw):
            t0 = time.process_time()
            try:
                return fn(rows, *args, **kw)
            finally:
                count(f"simulations: {opened[-1] if opened else 'outside the phases'}", t0,
                      len(rows))
        return run

    def opening(label, module, name):
        fn = getattr(module, name)

        def run(*args, **kw):
            opened.append(label.strip())
            try:
                return fn(*args, **kw)
            finally:
                opened.pop()

        setattr(module, name, run)

    import numpy as np
    import stiffnet.discovery.samples as samples_mod
    import stiffnet.measurement.evidence as evidence_mod
    import stiffnet.measurement.target as target_mod

    for caller, m in (("evidence", evidence_mod), ("discovery", samples_mod)):
        m.restoring_force_estimate = read_counted(caller, m.restoring_force_estimate)
    target_mod.simulate_rows = simulated(target_mod.simulate_rows)
    for label, (mod, name) in a["phases"].items():
        m = importlib.import_module(mod)
        if hasattr(m, name) and not label.startswith("  "):
            opening(label, m, name)
res = diagnose_campaign(camp, effects=a["effects"], workers=a["workers"],
                        inclination=a["inclination"])
ll = res.get("learned_law") or {}
face = ll.get("face_by_simulation") or {}
params = (ll.get("effect") or {}).get("params") or {}
print(json.dumps({"wall": time.perf_counter() - t, "cpu": cpu() - c,
                  "verdict": res["verdict"], "selected": res["missing_effects"],
                  "residual": res["residual_discrepancy"], "proposed": ll.get("proposed"),
                  "explained": ll.get("explained_fraction"), "after": ll.get("discrepancy_after"),
                  "face": {k: v for k, v in params.items() if k.startswith("face_")},
                  "term": face.get("term"), "face_seconds": face.get("seconds"),
                  "phases": phases, "work": work if a.get("phases") else {},
                  "params": res["fitted_params"]}))
if a.get("dump"):  # the whole result, to compare answers afterwards
    with open(a["dump"], "w") as fh:
        json.dump(res, fh, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
"""
)


def campaign_runs(args: argparse.Namespace) -> None:
    """``--campaign``: the folder diagnosed by this checkout and ``--baseline`` in fresh
    processes, alternately (see the module notes)."""
    import subprocess

    spec = {"campaign": str(Path(args.campaign).resolve()), "effects": args.only,
            "inclination": not args.no_inclination, "workers": args.workers or None,
            "phases": PHASES if args.phases else None, "dump": None}  # fmt: skip
    codes = ({"before": args.baseline} if args.baseline else {}) | {"now": str(ROOT)}
    if args.dump:
        Path(args.dump).mkdir(parents=True, exist_ok=True)
    for name, code in codes.items():  # a cold kernel cache is no part of a diagnosis
        warm = warm_kernels(code, spec["campaign"])
        print(f"{name}: kernels compiled or loaded in {warm:.1f} s CPU before the timed runs",
              flush=True)  # fmt: skip
    runs: list[tuple[str, dict]] = []
    print("| code | round | CPU s | wall s | load | verdict | learned law: explained, "
          "discrepancy | face | face by simulation, s |\n|---|---|---|---|---|---|---|---|---|",
          flush=True)  # fmt: skip
    best: dict[str, dict] = {}
    for k in range(args.rounds):
        for name, code in codes.items():
            env = {**os.environ, "PYTHONPATH": str(Path(code).resolve())}
            load0 = os.getloadavg()[0]
            if args.dump:
                spec["dump"] = str(Path(args.dump) / f"{name}_{k + 1}.json")
            out = subprocess.run([sys.executable, "-c", CAMPAIGN, json.dumps(spec)], env=env,
                                 capture_output=True, text=True, check=True, cwd=code)  # fmt: skip
            r = json.loads(out.stdout.strip().splitlines()[-1])
            runs.append((f"{name} {k + 1}", r))
            if name not in best or r["cpu"] < best[name]["cpu"]:
                best[name] = r
            face = ", ".join(f"{f.removeprefix('face_')} {v:.4g}" for f, v in r["face"].items()
                             if v)  # fmt: skip
            said = (f"{r['explained']:.1%}, {r['after']:.4g}" if r["proposed"] else
                    "not proposed")  # fmt: skip
            print(f"| {name} | {k + 1} | {r['cpu']:.1f} | {r['wall']:.1f} | {load0:.1f} -> "
                  f"{os.getloadavg()[0]:.1f} | {r['verdict']} | {said} | {face or '-'} | "
                  f"{r['face_seconds'] or '-'} |", flush=True)  # fmt: skip
    if args.phases:
        _phase_table(runs)
    if "before" in best:
        b, n = best["before"], best["now"]
        same = all(b[k] == n[k] for k in ("verdict", "selected", "params", "proposed",
                                          "explained", "after", "face"))  # fmt: skip
        print(
            f"\nCPU before / now (the best of each): {b['cpu']:.1f} / {n['cpu']:.1f} = "
            f"x{b['cpu'] / n['cpu']:.2f}; the same verdict, law and face to the bit: {same}"
        )


def _phase_table(runs: list[tuple[str, dict]]) -> None:
    """``--phases``: each run's CPU seconds per phase (:data:`PHASES`; calls in brackets)."""
    print("\n| phase | " + " | ".join(name for name, _ in runs) + " |\n|---|"
          + "---|" * len(runs))  # fmt: skip
    for label in PHASES:
        cells = [r["phases"].get(label) for _, r in runs]
        print(f"| {label} | " + " | ".join("-" if c is None else f"{c[0]:.1f} ({c[1]})"
                                           for c in cells) + " |")  # fmt: skip
    print("| the whole run | " + " | ".join(f"{r['cpu']:.1f}" for _, r in runs) + " |")
    keys = sorted({k for _, r in runs for k in r.get("work", {})})
    if keys:  # CPU s (calls; rows simulated)
        print(
            "\n| readings and simulations: CPU s (calls; rows) | "
            + " | ".join(name for name, _ in runs)
            + " |\n|---|"
            + "---|" * len(runs)
        )
        for key in keys:
            cells = [r.get("work", {}).get(key) for _, r in runs]
            print(f"| {key} | " + " | ".join(
                "-" if c is None else f"{c[0]:.1f} ({c[1]}" + ("" if key.startswith("readings")
                                                             else f"; {c[2]}") + ")"
                for c in cells) + " |")  # fmt: skip


STATISTICS = """
import json, pickle, sys, time
import numpy as np
from stiffnet.geometry.estimate import geometric_estimate
from stiffnet.measurement.statistics import batch_signal_statistics
records, fs, fn, ratio = pickle.load(open(sys.argv[1], "rb"))
repeats = int(sys.argv[2])

def cpu_ms(fn):
    fn()  # warm: imports, filter designs, kept operators
    t = time.process_time()
    for _ in range(repeats):
        fn()
    return (time.process_time() - t) / repeats / len(records) * 1e3

def geometry():
    for a, f in zip(records, fs):
        try:
            geometric_estimate((a - a.mean()) / a.std(), f, dimension=3, calibration=None)
        except Exception:
            pass

out = {
    "without": cpu_ms(lambda: batch_signal_statistics(records, fs, fn, ratio, inclination=False)),
    "with": cpu_ms(lambda: batch_signal_statistics(records, fs, fn, ratio, inclination=True)),
    "geometry": cpu_ms(geometry),
}
stats = batch_signal_statistics(records, fs, fn, ratio, inclination=True)
out["values"] = [None if s is None else [np.nan if v is None else v for v in s.scalars().values()]
                 + list(s.log_psd) + list(s.waveform) for s in stats]
print(json.dumps(out))
"""


def statistics_table(args: argparse.Namespace) -> None:
    """``--statistics``: CPU per record of the statistics of one evaluation's simulated rows,
    this checkout against ``--baseline`` alternately (see the module notes)."""
    import pickle
    import subprocess

    with tempfile.TemporaryDirectory() as d:
        camp = load_campaign(campaign(Path(d), args.duration, args.rows))
        rows, _ = resolve_rows(camp)
        _, lengths, _ = measured_statistics(camp, rows, False)
        model = [effect_class("contact_damping")(damping_ratio=0.2)]
        sims = simulate_rows(rows, model, lengths, DEFAULT_SEED, FIT_SETTINGS)
        blob = Path(d) / "records.pkl"
        blob.write_bytes(pickle.dumps((sims, [r.fs_hz for r in rows],
                                       [natural_frequency(r) for r in rows],
                                       [r.frequency_ratio for r in rows])))  # fmt: skip
        codes = {"now": str(ROOT)} | ({"before": args.baseline} if args.baseline else {})
        best: dict[str, dict] = {}
        load0 = os.getloadavg()[0]
        for _ in range(args.rounds):
            for name, code in sorted(codes.items()):  # "before" first
                env = {**os.environ, "PYTHONPATH": str(Path(code).resolve())}
                cmd = [sys.executable, "-c", STATISTICS, str(blob), "5"]
                out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True,
                                     cwd=code)  # fmt: skip
                res = json.loads(out.stdout.strip().splitlines()[-1])
                keep = best.setdefault(name, res)
                for k in ("without", "with", "geometry"):
                    keep[k] = min(keep[k], res[k])
        load1 = os.getloadavg()[0]
    print(f"{len(sims)} records, {args.duration:g} s each; best of {args.rounds} rounds of 5 "
          f"batches, CPU; load {load0:.2f} -> {load1:.2f}")  # fmt: skip
    print(
        "| code | statistics, inclinations left out, ms/record | with inclinations | "
        "inclinations' share (with - without) | geometric estimate alone |\n|---|---|---|---|---|"
    )
    for name in sorted(best):
        b = best[name]
        print(f"| {name} | {b['without']:.2f} | {b['with']:.2f} | {b['with'] - b['without']:.2f} "
              f"| {b['geometry']:.2f} |")  # fmt: skip
    if "before" in best:
        pairs = list(zip(best["before"]["values"], best["now"]["values"], strict=True))
        alike = [(a is None) == (b is None) and (a is None or len(a) == len(b)) for a, b in pairs]
        diffs = [
            np.nanmax(np.abs(np.subtract(a, b, dtype=float)))
            for (a, b), ok in zip(pairs, alike, strict=True)
            if ok and a is not None
        ]
        same = sum(alike)
        print(f"statistics before vs now: {same}/{len(sims)} records alike in shape, largest "
              f"difference of any value {max(diffs, default=0.0):.2e}")  # fmt: skip


def baseline_run(code: str, folder: Path, args: argparse.Namespace) -> dict:
    """The same diagnosis with another checkout's code (``code``: its root), in a fresh
    process on the same campaign folder: the before of a before/after in one run."""
    import subprocess
    import sys

    spec = {"campaign": str(folder), "effects": FAST if args.fast_only else None,
            "workers": args.workers or None, "inclination": not args.no_inclination}  # fmt: skip
    warm_kernels(code, str(folder))  # its first-run compile is no part of the diagnosis
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
    ap.add_argument("--rig", default="", help=f"independent-rig campaigns among {', '.join(RIG)}")
    ap.add_argument("--rig-dir", help="where the rig's campaigns are written (kept, reused)")
    ap.add_argument("--rig-fs", type=float, default=2000.0, help="the rig's sampling rate, Hz")
    ap.add_argument("--subset", default="8", help="--rig: diagnose.SUBSET_SEARCH per run, e.g. "
                    "8,24 (24: the search on every recording)")  # fmt: skip
    ap.add_argument("--timeline", action="store_true", help="also print each stage's wall "
                    "time, this process's and the workers' CPU (stage_timeline.py)")  # fmt: skip
    ap.add_argument("--statistics", action="store_true", help="the statistics per record "
                    "(--baseline: before and now alternately), no diagnosis")  # fmt: skip
    ap.add_argument("--rounds", type=int, default=3, help="--statistics, --campaign: rounds "
                    "per code (3)")  # fmt: skip
    ap.add_argument("--campaign", help="an existing campaign folder to diagnose (with "
                    "--baseline: before and now alternately)")  # fmt: skip
    ap.add_argument("--phases", action="store_true", help="--campaign: also each run's CPU "
                    "seconds per phase of the diagnosis (in-process: --workers 0)")  # fmt: skip
    ap.add_argument("--dump", help="--campaign: write each run's whole result to this folder "
                    "(<code>_<round>.json), to compare the answers")  # fmt: skip
    ap.add_argument("--only", action="append", help="--campaign: a candidate effect "
                    "(repeatable; default: every shipped effect)")  # fmt: skip
    ap.add_argument(
        "--polish",
        type=int,
        default=None,
        help="diagnose.POLISH_EVALUATIONS for every run (0: no polish)",
    )
    args = ap.parse_args()
    unknown = [n for n in args.rig.split(",") if n and n not in RIG]
    if unknown:
        ap.error(f"--rig: unknown campaign {unknown[0]!r}; choose among {', '.join(RIG)}")
    if args.workers and (args.polish is not None or args.rig):
        ap.error("--rig and --polish set module constants: run them in-process (--workers 0)")
    if args.polish is not None:
        from stiffnet.measurement import diagnose

        diagnose.POLISH_EVALUATIONS = args.polish
    if args.rig:
        rig_table(args)
        return
    if args.statistics:
        statistics_table(args)
        return
    if args.campaign:
        if not (Path(args.campaign) / MANIFEST_NAME).is_file():
            ap.error(f"--campaign: no manifest.csv in {args.campaign}")
        campaign_runs(args)
        return
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        folder = campaign(Path(d), args.duration, args.rows)
        camp = load_campaign(folder)
        t_sim = time.perf_counter() - t
        t_before, t_now = evaluation_ratio(camp)
        warm_kernels(str(ROOT), str(folder))
        load0 = os.getloadavg()[0]
        prof = cProfile.Profile() if args.profile_out else None
        timeline = StageTimeline() if args.timeline else None
        if timeline is not None:
            label_stages(timeline)
        spent = timed()
        by_stage = numerical_by_stage()
        cpu0 = cpu_seconds()
        t = time.perf_counter()
        if prof is not None:
            prof.enable()
        with timeline or contextlib.nullcontext():
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
    if by_stage:
        print("\n| the numerical engine in this process (stage: design, what) | CPU s |\n|---|---|")
        for k, v in sorted(by_stage.items(), key=lambda kv: -kv[1]):
            print(f"| {k} | {v:.1f} |")
    print(f"\nselected {res['missing_effects']} {res['fitted_params']}")
    if res.get("polish"):
        p = res["polish"]
        print(f"polish: residual {p['before']:.4g} -> {p['after']:.4g}, {p['evaluations']} "
              f"evaluations, {p['cpu_seconds']:.1f} s CPU")  # fmt: skip
    print(f"verdict {res['verdict']}, residual {res['residual_discrepancy']:.3g}, "
          f"noise floor {res['noise_floor']:.3g}; target <= 60 s (quiet machine): "
          f"{'met' if wall <= 60 else 'NOT met'} ({wall:.0f} s)")  # fmt: skip
    if timeline is not None:
        print(f"\n{timeline.table()}")
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

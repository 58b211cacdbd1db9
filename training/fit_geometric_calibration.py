"""Fit the geometric calibration (inclinations -> beta, class) on simulated windows.

Simulates two families of trajectories, cuts them into windows of
``window_periods`` natural periods (the dataset's 16 by default), runs
:func:`stiffnet.geometry.geometric_estimate` without a calibration on every
window, fits :func:`stiffnet.geometry.fit_calibration` on the windows of the
training trajectories and reports the accuracy on held-out trajectories by
noise level and family. Writes ``models/geometric_calibration.json``.

Families:

* ``paper``: the paper's parameter set (a = 1.9, w = 1.05, xi = 0.02,
  e = 2.8), beta log-uniform in 5-100, random initial states (so both
  attractors that coexist from beta = 35 on appear), fs_ratio log-uniform in
  50-500.
* ``domain``: every parameter drawn over the default simulation domain
  (``configs/sim/ideal.yaml``: beta 5-100 log-uniform, gap 0-3, a 0.2-2,
  w 0.8-1.2, xi 0.01-0.05, fs_ratio 50-500 log-uniform).

Noise: each trajectory gets one of ``noise_levels`` (fractions of ``a w^2``,
the paper's 0, <5 % and 9 %).

Orbits: the "before" inclination reads the orbit as well as beta
(:mod:`stiffnet.geometry.orbit`), so besides the main map, fitted on every
window and used for the period-1 orbit (impact pattern (1, 1)), the windows of
all other orbits (several impacts per period, one every few periods, no
repeating pattern) fit the calibration's ``period_n`` map
(``period_n_degree``); ``single`` writes the main map alone (the format
before the split). The held-out errors are reported by orbit too.

Library use (the settings of :class:`CalibrationRun` are the shipped file's):
``OMP_NUM_THREADS=1 python -c "from training.fit_geometric_calibration import *;
fit_geometric_calibration()"`` (about 3-4 minutes on 2 cores;
``fit_geometric_calibration(CalibrationRun().quick(), out="/tmp/cal.json")`` for a
smoke run).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.errors import StiffnetError
from stiffnet.geometry import (
    DEFAULT_CALIBRATION_PATH,
    beta_class,
    fit_calibration,
    geometric_estimate,
    save_calibration,
)
from stiffnet.geometry.calibration import NO_CONTACT, GeometricCalibration, beta_errors
from stiffnet.geometry.estimate import DELAY_FRACTION, SMOOTHING_FRACTION
from stiffnet.geometry.orbit import is_period1
from stiffnet.geometry.paper import PAPER_PARAMS
from stiffnet.geometry.tangent import TANGENT_LAG_FRACTION
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
from stiffnet.simulator.simulator import Simulator

DOMAIN = {
    "beta": (5.0, 100.0),
    "gap": (0.0, 3.0),
    "amplitude": (0.2, 2.0),
    "omega": (0.8, 1.2),
    "damping": (0.01, 0.05),
    "fs_ratio": (50.0, 500.0),
}
FEATURES = (
    "gradient_before_deg",
    "gradient_after_deg",
    "polynomial_before_deg",
    "polynomial_after_deg",
)


def draw_parameters(family: str, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Parameters of `n` trajectories of a family (beta and fs_ratio log-uniform)."""

    def logu(lo: float, hi: float) -> np.ndarray:
        return np.exp(rng.uniform(np.log(lo), np.log(hi), n))

    p = {"beta": logu(*DOMAIN["beta"]), "fs_ratio": logu(*DOMAIN["fs_ratio"])}
    if family == "paper":
        p.update({k: np.full(n, v) for k, v in PAPER_PARAMS.items()})
    elif family == "domain":
        for k in ("gap", "amplitude", "omega", "damping"):
            p[k] = rng.uniform(*DOMAIN[k], n)
    else:
        raise ValueError(family)
    return p


def _simulate_chunk(args: tuple) -> list[dict]:
    """Simulate one chunk of trajectories and analyse its windows (runs in a worker)."""
    params, noise, n_windows, window_periods, seed = args
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    batch = OscillatorBatch(
        params["beta"], params["gap"], params["amplitude"], params["omega"], params["damping"]
    )
    fs = params["fs_ratio"]
    win_len = np.round(window_periods * fs).astype(int)
    res = Simulator().simulate(batch, fs, int(win_len.max()) * n_windows, noise=noise, rng=seed)
    rows = []
    for i in range(len(batch)):
        for w in range(n_windows):
            sl = slice(w * win_len[i], (w + 1) * win_len[i])
            row = {k: float(v[i]) for k, v in params.items()}
            row.update(noise=float(noise[i]), window=w, trajectory=int(params["id"][i]))
            row["contact_fraction"] = float(np.mean(res.contact_force[i, sl] > 0))
            fs_hz = fs[i] * PAPER_NATURAL_FREQUENCY_HZ
            try:
                est = geometric_estimate(res.accel[i, sl], fs_hz, calibration=None)
            except StiffnetError as exc:
                row.update(contact_detected=False, error=str(exc))
                rows.append(row)
                continue
            row.update(contact_detected=est.contact_detected, n_orbits=est.n_orbits)
            row["impact_pattern"] = list(est.impact_pattern) if est.impact_pattern else None
            for f in FEATURES:
                row[f] = float(getattr(est, f))
            rows.append(row)
    return rows


def simulate_windows(
    family: str,
    n_traj: int,
    noise_levels: list[float],
    n_windows: int,
    window_periods: float,
    seed: int,
    workers: int,
    chunk: int = 64,
) -> list[dict]:
    """Simulate and analyse `n_traj` trajectories of a family; one dict per window."""
    rng = np.random.default_rng(seed)
    p = draw_parameters(family, n_traj, rng)
    p["id"] = np.arange(n_traj) + (0 if family == "paper" else 1_000_000)
    noise = rng.choice(np.asarray(noise_levels, float), n_traj)
    # Chunks of similar fs_ratio: a batch simulates max(fs_ratio) x window samples.
    order = np.argsort(p["fs_ratio"])
    jobs = []
    for k, lo in enumerate(range(0, n_traj, chunk)):
        idx = order[lo : lo + chunk]
        sub = {key: val[idx] for key, val in p.items()}
        jobs.append((sub, noise[idx], n_windows, window_periods, seed * 1000 + k))
    rows: list[dict] = []
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            for r in pool.map(_simulate_chunk, jobs):
                rows.extend(r)
    else:
        for job in jobs:
            rows.extend(_simulate_chunk(job))
    for r in rows:
        r["family"] = family
    return rows


def _orbit(r: dict) -> str:
    return "period1" if is_period1(r.get("impact_pattern")) else "period_n"


def _predicted_beta(cal: GeometricCalibration, r: dict) -> float:
    """Beta of a window with contact, by the map for its orbit."""
    m = cal.method
    return float(
        cal.for_orbit(r.get("impact_pattern")).predict_beta(
            r[f"{m}_before_deg"], r[f"{m}_after_deg"]
        )[0]
    )


def _predicted_class(cal: GeometricCalibration, r: dict) -> str:
    if not r["contact_detected"]:
        return NO_CONTACT
    return str(beta_class(_predicted_beta(cal, r), cal.classes))


def _true_class(cal: GeometricCalibration, r: dict) -> str:
    return NO_CONTACT if r["contact_fraction"] == 0 else str(beta_class(r["beta"], cal.classes))


def heldout_errors(cal: GeometricCalibration, rows: list[dict], key: str) -> dict[str, dict]:
    """Held-out accuracy grouped by `key` (a window field, "family/noise" or "orbit").

    ``class_accuracy_all`` scores every window, the true class of a window
    without contact being ``no_contact``; the beta errors (``mape_beta`` ...)
    use the windows that have contact and in which the method found it.
    """

    def group(r: dict) -> str:
        if key == "family/noise":
            return f"{r['family']}/{r['noise']:g}"
        if key == "orbit":
            return _orbit(r)
        v = r[key]
        return f"{v:g}" if isinstance(v, float) else str(v)

    out: dict[str, dict] = {}
    for g in [*sorted({group(r) for r in rows}), "all"]:
        sel = [r for r in rows if g == "all" or group(r) == g]
        contact = [r for r in sel if r["contact_fraction"] > 0]
        found = [r for r in contact if r["contact_detected"]]
        err: dict = {}
        if found:
            err = beta_errors(
                np.array([_predicted_beta(cal, r) for r in found]),
                np.array([r["beta"] for r in found]),
                cal.classes,
            )
        hits = [_true_class(cal, r) == _predicted_class(cal, r) for r in sel]
        out[g] = {
            "windows": len(sel),
            "with_contact": len(contact),
            "contact_found": len(found),
            "false_contact": sum(r["contact_fraction"] == 0 and r["contact_detected"] for r in sel),
            "class_accuracy_all": float(np.mean(hits)),
            **{k: v for k, v in err.items() if k not in ("n", "n_missing")},
        }
    return out


@dataclass(frozen=True)
class CalibrationRun:
    """What :func:`fit_geometric_calibration` simulates and fits (the shipped file's defaults)."""

    n_paper: int = 600  # trajectories of the paper's parameter set
    n_domain: int = 1200  # trajectories over the default domain
    windows: int = 2  # consecutive windows per trajectory
    window_periods: float = float(WINDOW_PERIODS)
    noise_levels: tuple[float, ...] = (0.0, 0.02, 0.05, 0.09)
    holdout: float = 0.3  # fraction of held-out trajectories
    degree: int = 3  # polynomial degree in the two angles (main map)
    method: str = "polynomial"  # or "gradient"
    period_n_degree: int = 2  # degree of the map for the other orbits
    single: bool = False  # one map for every orbit
    seed: int = 0
    workers: int = min(2, os.cpu_count() or 1)

    def quick(self) -> CalibrationRun:
        """A small smoke run of the same settings."""
        return replace(self, n_paper=24, n_domain=48)


def simulate_rows(run: CalibrationRun, cache: Path | None = None) -> list[dict]:
    """Every analysed window of both families (read from / written to `cache` if given)."""
    if cache is not None and cache.exists():
        return json.loads(cache.read_text())
    rows = []
    for k, (family, n) in enumerate((("paper", run.n_paper), ("domain", run.n_domain))):
        rows += simulate_windows(family, n, list(run.noise_levels), run.windows,
                                 run.window_periods, run.seed + k, run.workers)  # fmt: skip
    if cache is not None:
        cache.write_text(json.dumps(rows))
    return rows


def split_heldout(rows: list[dict], run: CalibrationRun) -> tuple[list[dict], list[dict]]:
    """Training and held-out windows, split by trajectory (a trajectory never straddles it)."""
    ids = np.unique([r["trajectory"] for r in rows])
    perm = np.random.default_rng(run.seed + 7).permutation(ids)
    held = set(perm[: int(run.holdout * ids.size)].tolist())
    return ([r for r in rows if r["trajectory"] not in held],
            [r for r in rows if r["trajectory"] in held])  # fmt: skip


def provenance(run: CalibrationRun) -> tuple[dict, str]:
    """The calibration's ``simulation`` record and its ``validity`` statement."""
    simulation = {
        "families": {
            "paper": {
                **PAPER_PARAMS,
                "beta": [5, 100],
                "beta_sampling": "log_uniform",
                "initial_state": "random",
            },  # fmt: skip
            "domain": {k: list(v) for k, v in DOMAIN.items()},
        },
        "fs_ratio_sampling": "log_uniform",
        "trajectories": {"paper": run.n_paper, "domain": run.n_domain},
        "windows_per_trajectory": run.windows,
        "window_natural_periods": run.window_periods,
        "noise_levels": list(run.noise_levels),
        "natural_frequency_hz": PAPER_NATURAL_FREQUENCY_HZ,
        "seed": run.seed,
        "heldout_fraction": run.holdout,
        "processing": {
            "delay": f"{DELAY_FRACTION} x dominant period",
            "smoothing": f"Savitzky-Golay order 2, window {SMOOTHING_FRACTION} x period",
            "tangent_lag": f"{TANGENT_LAG_FRACTION} x period",
            "inclination_method": run.method,
            "orbits": "one map" if run.single else "main map (all windows) for period-1; period_n",
        },
    }
    validity = (
        "Windows of >= 16 natural periods with contact, simulated by the base impact "
        "oscillator (no extra effects) over beta 5-100, gap 0-3, a 0.2-2, w 0.8-1.2, "
        "xi 0.01-0.05, fs/f_n 50-500, white noise 0-9 % of a w^2. Most accurate on the "
        "paper's parameter set (see residuals.heldout_by_family); off the paper's set the "
        "inclinations also depend on gap, amplitude and frequency, which the two angles "
        "cannot separate from beta. Period-1 windows (one impact per forcing period) use "
        "the main map (fitted on all windows); windows on any other orbit the period_n map."
    )
    return simulation, validity


def fit_maps(fit_rows: list[dict], run: CalibrationRun) -> GeometricCalibration:
    """The main map on every window with contact, and (unless ``single``) the period-n map."""
    simulation, validity = provenance(run)
    m = run.method

    def fit(sel: list[dict], degree: int) -> GeometricCalibration:
        return fit_calibration(
            np.array([r[f"{m}_before_deg"] for r in sel]),
            np.array([r[f"{m}_after_deg"] for r in sel]),
            np.array([r["beta"] for r in sel]),
            degree=degree, method=m, simulation=simulation, validity=validity,
        )  # fmt: skip

    # The main map sees every window: fitted on period-1 windows alone it read
    # realistic records (damped contact, sensor chains) worse (docs/crosscheck.md).
    cal = fit(fit_rows, run.degree)
    if run.single:
        return cal
    other = fit([r for r in fit_rows if _orbit(r) == "period_n"], run.period_n_degree)
    other = GeometricCalibration(**{**other.__dict__, "simulation": {"orbits": "all but period-1"}})
    return GeometricCalibration(**{**cal.__dict__, "period_n": other})


#: The held-out groupings of the calibration's residuals.
HELDOUT_KEYS = {"heldout_by_noise": "noise", "heldout_by_family": "family",
                "heldout_by_family_noise": "family/noise", "heldout_by_orbit": "orbit"}  # fmt: skip


def fit_geometric_calibration(
    run: CalibrationRun = CalibrationRun(),
    out: str | Path = DEFAULT_CALIBRATION_PATH,
    cache: Path | None = None,
    say: Callable[[str], None] = print,
) -> GeometricCalibration:
    """Simulate, fit, score on held-out trajectories and write the calibration to `out`."""
    t0 = time.perf_counter()
    rows = simulate_rows(run, cache)
    t_sim = time.perf_counter() - t0
    train, test = split_heldout(rows, run)
    fit_rows = [r for r in train if r["contact_detected"] and r["contact_fraction"] > 0]
    cal = fit_maps(fit_rows, run)
    residuals = {
        **cal.residuals,
        **({"train_period_n": cal.period_n.residuals["train"]} if cal.period_n else {}),
        **{key: heldout_errors(cal, test, by) for key, by in HELDOUT_KEYS.items()},
        "train_windows": len(train),
        "heldout_windows": len(test),
    }
    cal = GeometricCalibration(**{**cal.__dict__, "residuals": residuals})
    save_calibration(cal, out)
    n1 = sum(_orbit(r) == "period1" for r in fit_rows)
    say(f"windows: {len(rows)} ({len(train)} train, {len(test)} held out); "
        f"simulation + analysis {t_sim:.0f} s")  # fmt: skip
    maps = f"degree={run.degree}" + ("" if run.single else f", period-n {run.period_n_degree}")
    say(f"fit on {len(fit_rows)} windows with contact ({n1} period-1), method={run.method}, {maps}")
    for line in report_lines(cal):
        say(line)
    say(f"wrote {out}")
    return cal


def report_lines(cal: GeometricCalibration) -> list[str]:
    """The calibration's training residuals and held-out errors, one line per group."""
    lines = ["train: " + json.dumps(cal.residuals["train"])]
    for key in HELDOUT_KEYS:
        lines.append(key)
        for g, e in cal.residuals[key].items():
            lines.append(
                f"  {g:>12}: class acc {e['class_accuracy_all']:.2f} (all windows), "
                f"beta MAPE {e.get('mape_beta', float('nan')):.0f} %, "
                f"median APE {e.get('median_ape_beta', float('nan')):.0f} %, "
                f"contact found {e['contact_found']}/{e['with_contact']}, "
                f"false contact {e['false_contact']}/{e['windows'] - e['with_contact']}"
            )
    return lines

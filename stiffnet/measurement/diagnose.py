"""Which physical effect is missing: fit every effect to a campaign and rank them.

For each candidate effect (the library's, :func:`stiffnet.effects.registry.available_effects`,
and user effects ``module:Class``), its free parameters are fitted, **shared
across recordings**, with the manifest's nominal parameters fixed, to minimise
the simulator-measurement discrepancy (:mod:`stiffnet.measurement.discrepancy`)
of the campaign simulated with the current model plus that effect.

Objective. The mean of ``log(1 + D_r)`` over the best-matched 75 % of the
recordings: the log and the trimming keep a recording whose simulation jumps
to another attractor (multistable orbits are common in impact oscillators)
from steering the fit. The simulations use common
random numbers (:mod:`stiffnet.measurement.simulate`), so the objective is a
deterministic function of the parameters.

Search (documented evaluation budget). Parameters are mapped to the unit cube
(log scale where :class:`FitParam` says so). A coarse grid (9 points for one
parameter, 3 per axis for two or more, at most 27; the sensor's resonance gets
9 log-spaced frequencies, plus data-driven starting points at the measured
post-impact ringing frequency, :data:`SEEDERS`, because its basin is a few
per cent wide) is followed by a bounded Brent search between the best grid
point's neighbours (one parameter) or a bounded Nelder-Mead from it
(several), until ``budget`` evaluations in all (default
:data:`DEFAULT_BUDGET` = 24, raised to the grid plus 8 for one parameter or
plus 4 for several). Effects that need the numerical engine (Hertz contact,
friction, a restraint's mass) cost about 2-5 s per evaluation on 16-period
records and get :data:`DEFAULT_BUDGET_NUMERICAL` = 6: grid points spread
evenly over the grid (no refinement). One evaluation of a closed-form effect on 8 recordings costs
about 0.1 s; a whole-library diagnosis of the 8-recording example campaign
takes about a minute on one core.

Fit spaces (:data:`FIT_SPACES`). A shipped effect is fitted on the parameters
that make it what it is, within (sub-ranges of) its declared ranges; the
others are fixed where they leave the effect's core alone (e.g. the sensor's
anti-alias low-pass is off and its high-pass stays at the default 1 Hz while
its resonance is fitted). A user effect is fitted on
all its parameters within their declared ranges (log scale when the range is
positive and spans more than two decades).

Ranking. ``discrepancy_reduction = D_base - D_effect`` (campaign
discrepancies at the fit's settings). Effects are ranked by a BIC-like score
``N ln(D_effect / D_base) + k ln N``, ``N`` = recordings x statistic
components, ``k`` = fitted parameters: a parameter must buy about a 5 %
reduction to pay for itself.

Significance (all must hold): the relative reduction is at least
:data:`MIN_RELATIVE_REDUCTION` (25 %); at least 75 % of the recordings are
better; a one-sided sign test over recordings gives p <= 0.1; in 95 % of
1000 bootstrap resamples of the recordings the mean reduction is positive;
without the recording it helps most, the relative reduction is still at least
half the threshold (not one outlier); and the BIC score is negative. Then a
forward selection (:func:`forward_selection`) walks down the ranking and keeps
a significant effect only if it passes the same test on top of the ones
already kept, so an effect that merely imitates a better one is not flagged.
The ``missing_effect`` is the best-ranked significant effect (``missing_effects``
lists all kept), or null when none is: the base model explains the data.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import optimize, stats

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.effects.base import Effect
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.errors import SignalError, StiffnetError
from stiffnet.measurement.discrepancy import (
    COMPONENTS,
    campaign_discrepancy,
    normalised_differences,
    recording_discrepancy,
)
from stiffnet.measurement.simulate import (
    DEFAULT_SEED,
    FIT_SETTINGS,
    FIT_SETTINGS_NUMERICAL,
    SolverSettings,
    natural_frequency,
    simulate_rows,
)
from stiffnet.measurement.statistics import SignalStatistics, signal_statistics
from stiffnet.progress import task as progress_task

DEFAULT_BUDGET = 24
DEFAULT_BUDGET_NUMERICAL = 6
MIN_RELATIVE_REDUCTION = 0.25
MIN_IMPROVED_FRACTION = 0.75
SIGN_TEST_P = 0.1
BOOTSTRAP_LEVEL = 0.95
N_BOOTSTRAP = 1000


@dataclass(frozen=True)
class FitParam:
    """One fitted parameter: its search interval and scale."""

    name: str
    low: float
    high: float
    log: bool = False
    points: int | None = None  # coarse-grid points on this axis (default 9 alone, else 3)

    def unit(self, v: float) -> float:
        """Inverse of :meth:`value`: the unit-cube coordinate of a parameter value."""
        if self.log:
            u = (math.log(v) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        else:
            u = (v - self.low) / (self.high - self.low) if self.high > self.low else 0.0
        return float(np.clip(u, 0.0, 1.0))

    def value(self, u: float) -> float:
        u = float(np.clip(u, 0.0, 1.0))
        if self.log:
            v = math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        else:
            v = self.low + u * (self.high - self.low)
        return float(min(max(v, self.low), self.high))  # rounding must not leave the range


@dataclass(frozen=True)
class FitSpace:
    """Fixed and fitted parameters of an effect."""

    fixed: dict[str, float]
    free: tuple[FitParam, ...]


#: Fit spaces of the shipped effects (see the module notes). Sensor and ADC limits that
#: depend on the sampling rate are set from the campaign by :func:`fit_space`.
FIT_SPACES: dict[str, FitSpace] = {
    "contact_damping": FitSpace({}, (FitParam("damping_ratio", 0.0, 0.6),)),
    "hertz_contact": FitSpace({}, (FitParam("reference_penetration", 0.01, 10.0, log=True),)),
    "restraint_mass": FitSpace(
        {"damping_ratio": 0.05},
        (
            FitParam("mass_ratio", 0.1, 3.0, log=True),
            FitParam("stiffness_ratio", 1.0, 100.0, log=True),
        ),
    ),
    "forcing_harmonics": FitSpace(
        {"phase_second": 0.0, "phase_third": 0.0},
        (FitParam("second", 0.0, 0.5), FitParam("third", 0.0, 0.5)),
    ),
    "gap_drift": FitSpace(
        {"phase": 0.0},
        (FitParam("amplitude", 0.0, 1.0), FitParam("period", 10.0, 1000.0, log=True)),
    ),
    "dry_friction": FitSpace(
        {"static_ratio": 1.2}, (FitParam("coefficient", 0.001, 1.0, log=True),)
    ),
    "sensor_dynamics": FitSpace(
        {"highpass_hz": 1.0, "lowpass_hz": 0.0, "lowpass_order": 2.0},
        (
            FitParam("resonance_hz", 50.0, 1000.0, log=True),
            FitParam("resonance_damping", 0.01, 0.3, log=True, points=2),
        ),
    ),
    "colored_noise": FitSpace(
        {"pink_exponent": 1.0, "narrowband_hz": 50.0, "narrowband_width_hz": 1.0},
        (FitParam("pink_level", 0.0, 0.3), FitParam("narrowband_level", 0.0, 0.3)),
    ),
    "adc": FitSpace(
        {}, (FitParam("bits", 4.0, 16.0), FitParam("full_scale", 1.0, 1000.0, log=True))
    ),
}


def fit_space(name: str, rows: Sequence[ManifestRow]) -> FitSpace:
    """The fit space of an effect for a campaign (user effects: every declared parameter)."""
    cls = effect_class(name)
    space = FIT_SPACES.get(cls.name) if name in CANONICAL else None
    if space is not None:
        if cls.name == "sensor_dynamics":  # a resonance above 0.45 fs is skipped by the effect
            top = 0.45 * min(r.fs_hz for r in rows)
            free = (
                FitParam("resonance_hz", 50.0, max(60.0, top), log=True, points=9),
                space.free[1],
            )
            space = FitSpace(space.fixed, free)
        return space
    free = []
    for row in cls.parameter_table():
        lo, hi = row["range"]
        if lo is None or hi is None or not hi > lo:
            continue
        free.append(FitParam(row["name"], float(lo), float(hi), log=lo > 0 and hi / lo > 100))
    return FitSpace({}, tuple(free))


def sensor_seeds(target: CampaignTarget, space: FitSpace) -> list[dict[str, float]]:
    """Starting points for the sensor's resonance: the measured post-impact ringing frequency.

    The resonance's basin is a few per cent wide (the ringing is a few samples
    per cycle), so a log grid alone misses it; the median ringing frequency of
    the recordings that ring (ringing statistic above 0.2 decades) lands in it.
    """
    f = [
        m.ringing_frequency * m.natural_frequency_hz
        for m in target.measured
        if np.isfinite(m.ringing) and m.ringing > 0.2 and np.isfinite(m.ringing_frequency)
    ]
    if not f:
        return []
    free = {fp.name: fp for fp in space.free}
    res, damp = free["resonance_hz"], free["resonance_damping"]
    centre = float(np.median(f))
    out = []
    for scale in (0.98, 1.0, 1.02):
        hz = float(np.clip(centre * scale, res.low, res.high))
        for zeta in (0.01, 0.03, 0.1):
            out.append(
                {"resonance_hz": hz, "resonance_damping": float(np.clip(zeta, damp.low, damp.high))}
            )
    return out


#: Data-driven starting points of the fit, by effect (added to the coarse grid).
SEEDERS: dict[str, Callable[[CampaignTarget, FitSpace], list[dict[str, float]]]] = {
    "sensor_dynamics": sensor_seeds,
}


def needs_numerical(name: str) -> bool:
    """True when the effect switches the simulator to the numerical engine."""
    cls = effect_class(name)
    return cls.kind == "dynamics" and not cls().closed_form


# ------------------------------------------------------------------------- the target


@dataclass
class CampaignTarget:
    """What the fits compare against: rows, measured statistics, lengths, the base effects.

    Picklable, so a fit can run on a Dask worker.
    """

    rows: list[ManifestRow]
    measured: list[SignalStatistics]
    lengths: list[int]
    base_effects: list[Effect] = field(default_factory=list)
    seed: int = DEFAULT_SEED
    inclination: bool = True

    def simulated_statistics(
        self, effects: Sequence[Effect], settings: SolverSettings
    ) -> list[SignalStatistics | None]:
        """Statistics of the campaign simulated with ``effects`` (one batch)."""
        sims = simulate_rows(self.rows, effects, self.lengths, self.seed, settings)
        out: list[SignalStatistics | None] = []
        for row, a in zip(self.rows, sims, strict=True):
            try:
                out.append(
                    signal_statistics(
                        a,
                        row.fs_hz,
                        natural_frequency(row),
                        row.frequency_ratio,
                        inclination=self.inclination,
                    )
                )
            except SignalError:
                out.append(None)
        return out

    def per_recording(self, effects: Sequence[Effect], settings: SolverSettings) -> np.ndarray:
        """Per-recording discrepancies of the campaign simulated with ``effects``.

        A recording whose simulation cannot be analysed scores a large constant (100).
        """
        sims = self.simulated_statistics(effects, settings)
        out = np.full(len(self.rows), 100.0)
        for i, (m, s) in enumerate(zip(self.measured, sims, strict=True)):
            if s is not None:
                d = recording_discrepancy(normalised_differences(m, s))
                out[i] = d if np.isfinite(d) else 100.0
        return out


def measured_statistics(
    campaign: Campaign, inclination: bool = True
) -> tuple[list[SignalStatistics], list[int]]:
    """Statistics and lengths of every recording of a campaign."""
    stats_, lengths = [], []
    for row, rec in campaign.recordings():
        try:
            stats_.append(
                signal_statistics(
                    rec.accel,
                    rec.fs_hz,
                    natural_frequency(row),
                    row.frequency_ratio,
                    inclination=inclination,
                )
            )
        except SignalError as exc:
            raise StiffnetError(f"{row.recording}: {exc}") from None
        lengths.append(len(rec.accel))
    return stats_, lengths


#: Fraction of the recordings (the best-matched ones) the objective averages over.
OBJECTIVE_KEEP = 0.75


def objective_value(per_recording: np.ndarray) -> float:
    """The fit's objective: the mean of ``log(1 + D_r)`` over the best 75 % of recordings.

    Impact oscillators are often multistable: a recording whose simulation
    jumps to another orbit when a parameter moves by a per cent makes the
    objective jagged. The log compresses such outliers and the trimming drops
    them (the significance test still sees every recording).
    """
    v = np.sort(np.log1p(np.asarray(per_recording, dtype=np.float64)))
    return float(np.mean(v[: max(1, int(math.ceil(OBJECTIVE_KEEP * v.size)))]))


# ---------------------------------------------------------------------------- fitting


def settings_for(name: str | None) -> SolverSettings:
    return FIT_SETTINGS_NUMERICAL if name is not None and needs_numerical(name) else FIT_SETTINGS


def coarse_grid(free: Sequence[FitParam]) -> np.ndarray:
    """Grid in the unit cube: ``points`` per axis (9 for a single parameter, else 3); axes
    beyond the third stay at the middle."""
    k = len(free)
    axes = [np.linspace(0.0, 1.0, fp.points or (9 if k == 1 else 3)) for fp in free[:3]]
    mesh = np.meshgrid(*axes, indexing="ij")
    pts = np.column_stack([m.ravel() for m in mesh])
    if k > 3:
        pts = np.column_stack([pts, np.full((pts.shape[0], k - 3), 0.5)])
    return pts


def fit_effect(
    target: CampaignTarget,
    name: str,
    budget: int | None = None,
    on_evaluation: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Fit one effect's parameters to the campaign (see the module notes).

    ``on_evaluation(done, budget)`` is called after each objective evaluation.

    Returns
    -------
    dict
        ``effect``, ``params`` (fitted and fixed), ``fitted`` (names),
        ``per_recording`` and ``baseline_per_recording`` (discrepancies at the
        fit's settings), ``evaluations``, ``seconds``, ``engine``.
    """
    t0 = time.perf_counter()
    space = fit_space(name, target.rows)
    cls = effect_class(name)
    numerical = needs_numerical(name)
    settings = settings_for(name)
    if budget is None:
        budget = DEFAULT_BUDGET_NUMERICAL if numerical else DEFAULT_BUDGET
    base = [e for e in target.base_effects if e.name != cls.name]
    baseline = target.per_recording(base, settings)
    grid = coarse_grid(space.free) if space.free else np.empty((1, 0))
    seeder = SEEDERS.get(cls.name) if name in CANONICAL else None
    seeds = seeder(target, space) if seeder is not None else []
    if seeds:
        grid = np.vstack(
            [np.array([[fp.unit(p[fp.name]) for fp in space.free] for p in seeds]), grid]
        )
    if not numerical:  # the grid, then at least a few refinement steps
        budget = max(budget, len(grid) + (8 if len(space.free) == 1 else 4))

    cache: dict[tuple[float, ...], np.ndarray] = {}

    def params_of(u: np.ndarray) -> dict[str, float]:
        p = dict(space.fixed)
        p.update({fp.name: fp.value(x) for fp, x in zip(space.free, u, strict=True)})
        return p

    def evaluate(u: np.ndarray) -> float:
        key = tuple(np.round(np.clip(u, 0, 1), 6))
        if key not in cache:
            if len(cache) >= budget:
                return float("inf")
            effect = cls(**params_of(np.array(key)))
            cache[key] = target.per_recording([*base, effect], settings)
            if on_evaluation:
                on_evaluation(len(cache), budget)
        return objective_value(cache[key])

    k = len(space.free)
    if k == 0:
        best_u = np.empty(0)
        evaluate(best_u)
    else:
        if len(grid) > budget:  # a small budget spreads its points over the whole grid
            grid = grid[
                np.unique(np.round(np.linspace(0, len(grid) - 1, max(1, budget)))).astype(int)
            ]
        values = [evaluate(u) for u in grid]
        best_u = grid[int(np.argmin(values))]
        if len(cache) < budget and k == 1:  # bounded Brent between the grid neighbours
            h = 1.0 / (len(grid) - 1)
            lo, hi = max(0.0, best_u[0] - h), min(1.0, best_u[0] + h)
            optimize.minimize_scalar(
                lambda x: evaluate(np.array([x])),
                bounds=(lo, hi),
                method="bounded",
                options={"maxiter": budget - len(cache), "xatol": 1e-3},
            )
        elif len(cache) < budget:
            step = 0.5 / 3
            simplex = np.vstack(
                [best_u]
                + [
                    np.clip(best_u + step * np.eye(k)[j] * (1 if best_u[j] < 0.5 else -1), 0, 1)
                    for j in range(k)
                ]
            )
            optimize.minimize(
                evaluate,
                best_u,
                method="Nelder-Mead",
                bounds=[(0.0, 1.0)] * k,
                options={
                    "initial_simplex": simplex,
                    "maxfev": budget - len(cache),
                    "xatol": 1e-3,
                    "fatol": 1e-4,
                },
            )
        best_key = min(cache, key=lambda key: objective_value(cache[key]))
        best_u = np.array(best_key)
    per = cache[tuple(np.round(np.clip(best_u, 0, 1), 6))]
    return {
        "effect": name,
        "params": params_of(best_u),
        "fitted": [fp.name for fp in space.free],
        "per_recording": per.tolist(),
        "baseline_per_recording": baseline.tolist(),
        "evaluations": len(cache),
        "seconds": round(time.perf_counter() - t0, 3),
        "engine": "numerical" if numerical else "closed_form",
    }


def _fit_task(item: tuple[CampaignTarget, str, int | None]) -> dict[str, Any]:
    target, name, budget = item
    with progress_task(f"fitting {name}", budget) as bar:  # silent on Dask workers
        return fit_effect(target, name, budget, lambda done, total: bar.update(done, total))


# ------------------------------------------------------------------------ significance


def sign_test_p(deltas: np.ndarray) -> float:
    """One-sided sign test: P(at least this many improvements | no effect), ties dropped."""
    d = deltas[np.abs(deltas) > 1e-12]
    if d.size == 0:
        return 1.0
    return float(stats.binomtest(int(np.sum(d > 0)), d.size, 0.5, alternative="greater").pvalue)


def bootstrap_positive_fraction(deltas: np.ndarray, n: int = N_BOOTSTRAP, seed: int = 0) -> float:
    """Fraction of bootstrap resamples of the recordings with a positive mean reduction."""
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, deltas.size, size=(n, deltas.size))
    return float(np.mean(deltas[idx].mean(axis=1) > 0))


def significance(baseline: np.ndarray, fitted: np.ndarray, k: int) -> dict[str, Any]:
    """The consistency evidence of one effect's fit (see the module notes)."""
    deltas = baseline - fitted
    d_base, d_fit = campaign_discrepancy(baseline), campaign_discrepancy(fitted)
    relative = (d_base - d_fit) / d_base if d_base > 0 else 0.0
    top = int(np.argmax(deltas))
    keep = np.arange(deltas.size) != top
    if keep.any() and campaign_discrepancy(baseline[keep]) > 0:
        loo = (campaign_discrepancy(baseline[keep]) - campaign_discrepancy(fitted[keep])) / (
            campaign_discrepancy(baseline[keep])
        )
    else:
        loo = 0.0
    n_obs = deltas.size * len(COMPONENTS)
    bic = n_obs * math.log(max(d_fit, 1e-12) / max(d_base, 1e-12)) + k * math.log(n_obs)
    out = {
        "relative_reduction": float(relative),
        "improved_fraction": float(np.mean(deltas > 0)),
        "sign_test_p": sign_test_p(deltas),
        "bootstrap_positive": bootstrap_positive_fraction(deltas),
        "leave_one_out_relative_reduction": float(loo),
        "bic_delta": float(bic),
    }
    out["significant"] = bool(
        relative >= MIN_RELATIVE_REDUCTION
        and out["improved_fraction"] >= MIN_IMPROVED_FRACTION
        and out["sign_test_p"] <= SIGN_TEST_P
        and out["bootstrap_positive"] >= BOOTSTRAP_LEVEL
        and loo >= 0.5 * MIN_RELATIVE_REDUCTION
        and bic < 0
    )
    return out


# ---------------------------------------------------------------------------- diagnose


def forward_selection(target: CampaignTarget, ranking: list[dict[str, Any]]) -> list[str]:
    """Keep a significant effect only if it still helps on top of the better-ranked ones.

    Effects are fitted one at a time against the base model, so a second effect
    can look significant merely by imitating part of the first (forcing
    harmonics reshape the orbit a little like contact damping does). Walking
    down the ranking, each significant effect is added, with its fitted
    parameters, to those already selected and must pass :func:`significance`
    against them (one evaluation each, no refit); otherwise it is marked
    ``significant: false`` with ``redundant_with``. Updates ``ranking`` in place.

    Returns
    -------
    list of str
        The selected effects, best first (empty: nothing is missing).
    """
    selected: list[dict[str, Any]] = []
    current: np.ndarray | None = None
    for r in ranking:
        if not r["significant"]:
            continue
        if not selected:
            selected.append(r)
            current = np.asarray(r["per_recording"])
            continue
        names = [s["effect"] for s in selected] + [r["effect"]]
        settings = (
            FIT_SETTINGS_NUMERICAL if any(needs_numerical(n) for n in names) else FIT_SETTINGS
        )
        effects = [effect_class(s["effect"])(**s["params"]) for s in selected]
        base = target.base_effects
        if settings is not FIT_SETTINGS:  # both sides at the same settings
            current = target.per_recording([*base, *effects], settings)
        trial = target.per_recording(
            [*base, *effects, effect_class(r["effect"])(**r["params"])], settings
        )
        sig = significance(current, trial, len(r["fitted"]))
        r["given_selected_relative_reduction"] = sig["relative_reduction"]
        if sig["significant"]:
            selected.append(r)
            current = trial
        else:
            r["significant"] = False
            r["redundant_with"] = [s["effect"] for s in selected]
    return [s["effect"] for s in selected]


def candidate_effects(
    base_effects: Sequence[Effect], extra: Sequence[str] = (), only: Sequence[str] | None = None
) -> list[str]:
    """Effects to try: the library (or ``only``) plus user effects, minus those in the model."""
    names = list(only) if only is not None else list(CANONICAL)
    names += [e for e in extra if e not in names]
    present = {e.name for e in base_effects}
    for n in names:
        effect_class(n)  # one-line error for an unknown name
    return [n for n in names if effect_class(n).name not in present]


def diagnose_campaign(
    campaign: Campaign,
    base_effects: Sequence[Effect] = (),
    effects: Sequence[str] | None = None,
    user_effects: Sequence[str] = (),
    budget: int | None = None,
    budget_numerical: int | None = None,
    seed: int = DEFAULT_SEED,
    inclination: bool = True,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, Any]:
    """Fit and rank every candidate effect on a campaign.

    Parameters
    ----------
    campaign : Campaign
        A campaign whose manifest gives the simulation columns for every row.
    base_effects : sequence of Effect
        The current simulator config's effects (kept in every simulation).
    effects : sequence of str, optional
        Candidate effect names (default: every shipped effect).
    user_effects : sequence of str
        Extra ``module:Class`` effects.
    budget, budget_numerical : int, optional
        Objective evaluations per effect (closed form / numerical engine).
    seed : int
        Common-random-number seed.
    inclination : bool
        Include the inclination statistics (the geometric method) in the discrepancy.
    scheduler, workers
        Where the per-effect fits run (:func:`stiffnet.distributed.map_tasks`).
    progress : callable, optional
        ``progress(done, total)`` after each fit (in-process runs).

    Returns
    -------
    dict
        ``baseline_discrepancy``, ``ranking`` (each ``effect``,
        ``discrepancy_reduction``, ``params``, ``significant`` and the evidence),
        ``missing_effect`` (name or None), ``baseline_per_recording``,
        ``recordings``, ``settings``, ``seconds``.
    """
    from stiffnet.distributed import map_tasks
    from stiffnet.distributed.cluster import check_target
    from stiffnet.inputs import bounded_count

    bounded_count(budget, "--budget", 1, 100_000)  # checked before any simulation
    bounded_count(budget_numerical, "--budget-numerical", 1, 100_000)
    check_target(scheduler, workers)
    t0 = time.perf_counter()
    measured, lengths = measured_statistics(campaign, inclination)
    target = CampaignTarget(
        list(campaign.rows), measured, lengths, list(base_effects), seed, inclination
    )
    names = candidate_effects(base_effects, user_effects, effects)
    items = []
    for n in names:
        b = budget_numerical if needs_numerical(n) else budget
        items.append((target, n, b))
    with progress_task("effects fitted", len(items)) as bar:

        def report(done: int, total: int) -> None:
            bar.update(done, total, note=names[done - 1] if 0 < done <= len(names) else None)
            if progress:
                progress(done, total)

        fits = map_tasks(
            _fit_task, items, scheduler=scheduler, workers=workers, progress=report, names=names
        )
    baseline = target.per_recording(list(base_effects), FIT_SETTINGS)
    ranking = []
    for fit in fits:
        base_r = np.array(fit["baseline_per_recording"])
        per = np.array(fit["per_recording"])
        sig = significance(base_r, per, len(fit["fitted"]))
        ranking.append(
            {
                "effect": fit["effect"],
                "discrepancy_reduction": campaign_discrepancy(base_r) - campaign_discrepancy(per),
                "params": fit["params"],
                "fitted": fit["fitted"],
                "significant": sig.pop("significant"),
                "discrepancy": campaign_discrepancy(per),
                "baseline_discrepancy": campaign_discrepancy(base_r),
                **sig,
                "per_recording": fit["per_recording"],
                "evaluations": fit["evaluations"],
                "seconds": fit["seconds"],
                "engine": fit["engine"],
            }
        )
    ranking.sort(key=lambda r: (r["bic_delta"], -r["discrepancy_reduction"]))
    selected = forward_selection(target, ranking)
    missing = selected[0] if selected else None
    return {
        "baseline_discrepancy": campaign_discrepancy(baseline),
        "baseline_per_recording": baseline.tolist(),
        "recordings": [r.recording for r in campaign.rows],
        "base_effects": [e.name for e in base_effects],
        "ranking": ranking,
        "missing_effect": missing,
        "missing_effects": selected,
        "settings": {
            "seed": seed,
            "budget": budget or DEFAULT_BUDGET,
            "budget_numerical": budget_numerical or DEFAULT_BUDGET_NUMERICAL,
            "periods": FIT_SETTINGS.periods,
            "periods_numerical": FIT_SETTINGS_NUMERICAL.periods,
            "inclination": inclination,
            "objective": "mean log(1 + D_r) over the best 75 % of recordings",
            "rank_score": "N ln(D_effect / D_base) + k ln N",
        },
        "seconds": round(time.perf_counter() - t0, 3),
    }


__all__ = [
    "FIT_SPACES",
    "CampaignTarget",
    "FitParam",
    "FitSpace",
    "candidate_effects",
    "diagnose_campaign",
    "fit_effect",
    "fit_space",
    "measured_statistics",
    "significance",
]

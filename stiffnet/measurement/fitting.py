"""Fitting effects to a campaign: one effect on top of a model, or several jointly.

Objective. The campaign discrepancy itself (:func:`campaign_discrepancy`, the
mean over recordings of the mean squared normalised differences, i.e. a
chi-square with fixed tolerances). The simulations use common random numbers
(:mod:`stiffnet.campaign.simulate`), so it is a deterministic function of
the parameters. The model without the effect ("effect off") is always one of
the candidates: a fit can end at "no improvement" (reduction 0), never below it.
The search leaves out the two inclination statistics when the target has them
(the geometric method costs twice all the other statistics together, and what
moves them, the shape of the contact and of free flight, moves the waveform,
spike and harmonic statistics as well); the best point is then scored with
every statistic, and that number, compared with "effect off" scored the same
way, is the one reported and tested.

Search, in the unit cube of the effect's fit space
(:attr:`stiffnet.effects.base.Effect.fit_space`, declared by each effect):

* :func:`fit_effect` (one effect, others held): an initial design (9 points for
  one coordinate, a 3 x 3 grid for two, 32 Sobol points plus the centre for
  more), the effect's data-driven seeds (:meth:`~stiffnet.effects.base.Effect.fit_seeds`,
  e.g. the sensor resonance at the measured ringing frequency), a **global
  stage** over the parameters the effect declares multimodal
  (:attr:`~stiffnet.effects.fit_space.FitSpace.multimodal`: each phase swept over
  8 angles at 3 amplitudes, each frequency over 9 points, block after block, two
  rounds; :func:`global_stage`; an effect whose multimodal parameters are read off the
  measurement in closed form declares ``global_seeds``: its seeds and the centre are the
  whole design, e.g. the harmonics read off the free flights,
  :mod:`stiffnet.measurement.forcing_lines`), then a bounded
  Brent search between the best design point's neighbours (one coordinate) or a
  bounded Nelder-Mead from it, within ``budget`` evaluations. A diagnosis searches on
  :data:`SUBSET_SEARCH` recordings spread over the campaign's operating points
  (:func:`spread_subset`) and scores the best point on all of them.
  Numerical-engine effects (seconds per simulated batch, whatever its number of
  rows: the integrator's cost is per time step) get only a design spread over the
  budget, simulated as one batch holding :data:`SUBSET_NUMERICAL` recordings
  (spread over the campaign) once per point
  (:meth:`~stiffnet.measurement.target.CampaignTarget.per_recording_points`; an analog
  sensor in the model filters at the logger's rate there, a screen at a quarter of the
  integration steps, and runs in for ln 20 of the chain's slowest time constant instead of
  the standard 1.5 s, :func:`screen_settings`); the best point is then scored alone on every
  recording, oversampled, with the standard lead-in.
* :func:`fit_joint` (every effect of a model at once): Nelder-Mead from the
  current values over all their coordinates, so an effect fitted first cannot
  keep a share of the discrepancy that belongs to one found later. In a diagnosis's
  selection steps it searches on the same :data:`SUBSET_SEARCH` recordings as the fits
  and scores its best point on all of them (the serial part of a diagnosis: a third of
  the simulations on a 24-recording campaign); the final polish searches on all.

Points that do not depend on each other (an initial design, a global-stage block's grid, a
Nelder-Mead's first simplex, the starts profiled at a reading) are evaluated as one batch
(:meth:`_Evaluator.prefetch`, :mod:`~stiffnet.measurement.evaluation_pool`): on the
workers when the diagnosis runs this search in its own process, with the same numbers.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import optimize
from scipy.stats import qmc

from stiffnet.campaign.simulate import CampaignSolverSettings as SolverSettings
from stiffnet.campaign.simulate import oversampling
from stiffnet.effects.base import Effect
from stiffnet.effects.fit_space import FitSpace, global_blocks
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.discrepancy import campaign_discrepancy
from stiffnet.measurement.evaluation_pool import per_recording_many
from stiffnet.measurement.nuisance import N_STARTS
from stiffnet.measurement.target import CampaignTarget, needs_numerical
from stiffnet.simulator.motion_cache import reuse_motion

#: Evaluations of a one-effect fit (closed form) after its initial design.
REFINE_EVALUATIONS = {1: 8, 2: 12}
REFINE_EVALUATIONS_MANY = 24
#: Evaluations of a numerical-engine effect's fit (design only).
DEFAULT_BUDGET_NUMERICAL = 6
#: A numerical-engine effect's design is simulated on at most this many recordings (evenly
#: spread over the campaign; the engine's cost grows with the batch's rows, though far
#: slower than with the number of batches), then its best point is scored on all of them.
SUBSET_NUMERICAL = 8
#: The transient of a numerical-engine effect's design when its best point is scored again
#: anyway (:func:`_fit_design`): free oscillations settled to this fraction instead of the
#: fits' 1e-3 (24 natural periods instead of 55 at a damping ratio of 0.02; the transient
#: was 63 % of the engine's time). "Effect off" is screened with the same transient, and the
#: point kept is scored with the full one, the number reported and tested.
SCREEN_SETTLE_TOLERANCE = 0.05
#: A screen's warm start (:attr:`~stiffnet.simulator.settings.SolverSettings.warm_start`):
#: the closed form settles the transient onto the linear orbit and the numerical engine
#: integrates only the stretch that lets an orbit difference of this fraction decay to
#: the screen's tolerance. The point kept is scored with a cold start.
SCREEN_WARM_START = 0.1
#: A diagnosis searches a closed-form effect on at most this many recordings spread over the
#: campaign's operating points (:func:`spread_subset`) and scores the point found on all of
#: them, with every statistic: the fit's shared parameters are set by every operating point
#: at least once, and what is reported and tested is the whole campaign's discrepancy (a
#: campaign of 24 recordings is three shifts of 8 operating points: the search costs a third).
SUBSET_SEARCH = 8
#: Evaluations of a joint refit per fitted coordinate (closed form; numerical engine).
JOINT_PER_COORDINATE = 8
JOINT_PER_COORDINATE_NUMERICAL = 2
#: Nelder-Mead's first step in the unit cube for a joint refit (a local search).
JOINT_STEP = 0.08
#: Rounds of the global stage over an effect's multimodal parameters, and the local
#: search's first step after it (the grid already holds the basin).
GLOBAL_ROUNDS = 2
LOCAL_STEP = 0.08
#: Nelder-Mead's first step when the best start is a seed read off the measurement (an
#: identified sensor chain, the ringing frequency): within about 10 % of the answer, a
#: basin a first step of 1/6 of the unit cube oversteps (a chain seeded 10 % off ended at
#: its seed; 0.03 and 0.04 reached it, 0.05 and 0.08 did not).
SEED_STEP = 0.03


def objective_value(per_recording: np.ndarray, weights: Sequence[float] | None = None) -> float:
    """The fit's objective: the campaign discrepancy (mean over recordings, weighted by the
    target's weights: a non-repeatable recording weighs less)."""
    return campaign_discrepancy(per_recording, weights)


def effect_space(
    name: str,
    rows: Sequence[Any],
    observed: dict[str, float] | None = None,
    at: dict[str, float] | None = None,
) -> FitSpace:
    """The effect's fit space for a campaign (its lowest sampling rate bounds a resonance);
    for a refit from values ``at``, the effect's space around them, every value it does not
    fit held (:meth:`~stiffnet.effects.base.Effect.fit_space_at`); ``observed``: what the
    measurement shows, e.g. an identified sensor stage to search."""
    fs = min(r.fs_hz for r in rows)
    cls = effect_class(name)
    space = cls.campaign_fit_space(fs) if at is None else cls.fit_space_at(at, fs)
    return space if observed is None else cls.observed_fit_space(space, observed)


def off_params(name: str, space: FitSpace) -> list[dict[str, float]] | None:
    """ "Effect off" as a full parameter set (None for an effect without ``neutral``): the
    neutral values, the fixed ones, and the declared defaults of every other fitted
    parameter (a harmonic's phase at zero amplitude), so a rejected fit still names a value
    for each parameter it fits."""
    cls = effect_class(name)
    if cls.neutral is None:
        return None
    defaults = cls().params.model_dump()
    out = {k: defaults[k] for k in space.fitted if isinstance(defaults.get(k), int | float)}
    return [{**out, **space.fixed, **cls.neutral}]


def initial_design(space: FitSpace) -> np.ndarray:
    """Design points in the unit cube (see the module notes)."""
    k = len(space.free)
    if k == 0:
        return np.empty((1, 0))
    if k == 1:
        return np.linspace(0.0, 1.0, 9)[:, None]
    if k == 2:
        g = np.linspace(0.0, 1.0, 3)
        return np.array([[a, b] for a in g for b in g])
    pts = qmc.Sobol(d=k, scramble=True, seed=0).random(32)
    return np.vstack([np.full(k, 0.5), pts])


@dataclass
class _Evaluator:
    """Cached per-recording discrepancies of a model with some effects fixed, one set free."""

    target: CampaignTarget
    fixed: list[Effect]
    names: list[str]
    spaces: list[FitSpace]
    settings: SolverSettings
    budget: int

    #: The whole campaign when the search runs on a subset of it (:data:`SUBSET_SEARCH`): the
    #: best point is scored there.
    whole: CampaignTarget | None = None

    def __post_init__(self) -> None:
        self.cache: dict[tuple[float, ...], np.ndarray] = {}
        self.sizes = [len(s.free) for s in self.spaces]
        self.scored = 0  # evaluations with every statistic (the search's leave inclinations out)
        self.full: dict[tuple[float, ...], np.ndarray] = {}  # known values with every statistic

    def split(self, u: np.ndarray) -> list[dict[str, float]]:
        out, i = [], 0
        for space, k in zip(self.spaces, self.sizes, strict=True):
            out.append(space.params(np.asarray(u[i : i + k])))
            i += k
        return out

    def key(self, u: np.ndarray) -> tuple[float, ...]:
        return tuple(np.round(np.clip(np.asarray(u, float), 0.0, 1.0), 6))

    def per(self, u: np.ndarray) -> np.ndarray | None:
        key = self.key(u)
        if key not in self.cache:
            if len(self.cache) >= self.budget:
                return None
            effects = self._effects(np.array(key))
            self.cache[key] = self.target.per_recording(
                [*self.target.base_effects, *self.fixed, *effects],
                self.settings,
                inclination=False,
            )
        return self.cache[key]

    def prefetch(self, points: Sequence[np.ndarray]) -> None:
        """Evaluate the points not yet cached at once (:func:`per_recording_many`: spread over
        the workers inside an evaluation pool), as many as the budget leaves, in order: the
        cache then holds exactly what calling the evaluator on them one by one would."""
        new: dict[tuple[float, ...], None] = {}
        for u in points:
            key = self.key(u)
            if key not in self.cache and len(self.cache) + len(new) < self.budget:
                new.setdefault(key, None)
        if not new:
            return
        models = [
            [*self.target.base_effects, *self.fixed, *self._effects(np.array(key))] for key in new
        ]
        pers = per_recording_many(
            self.target, [(m, self.settings, {"inclination": False}) for m in models]
        )
        self.cache.update(zip(new, pers, strict=True))

    def _effects(self, u: np.ndarray) -> list[Effect]:
        return [effect_class(n)(**p) for n, p in zip(self.names, self.split(u), strict=True)]

    def __call__(self, u: np.ndarray) -> float:
        per = self.per(u)
        return float("inf") if per is None else objective_value(per, self.target.weights)

    def best(self) -> tuple[np.ndarray, np.ndarray]:
        """The best point searched and its per-recording discrepancies with every statistic
        (scored again when the search left the inclinations out)."""
        key = min(self.cache, key=lambda k: objective_value(self.cache[k], self.target.weights))
        whole = self.target if self.whole is None else self.whole
        if whole is self.target and not whole.inclination:
            return np.array(key), self.cache[key]
        if key in self.full:
            return np.array(key), self.full[key]
        effects = [
            effect_class(n)(**p) for n, p in zip(self.names, self.split(np.array(key)), strict=True)
        ]
        self.scored += 1
        return np.array(key), whole.per_recording(
            [*whole.base_effects, *self.fixed, *effects], self.settings
        )


def _result(
    ev: _Evaluator, off: np.ndarray, t0: float, off_values: list[dict[str, float]] | None = None
) -> dict[str, Any]:
    """The best point, or the starting model ("off") when nothing beats it."""
    u, per = ev.best()
    w = (ev.target if ev.whole is None else ev.whole).weights
    improves = objective_value(per, w) < objective_value(off, w)
    params = ev.split(u)
    if not improves:
        per = off
        params = off_values if off_values is not None else params
    return {
        "effects": list(ev.names),
        "params": params,
        "fitted": [s.fitted for s in ev.spaces],
        "per_recording": per,
        "improves": bool(improves),
        "evaluations": len(ev.cache) + ev.scored,
        "seconds": round(time.perf_counter() - t0, 3),
    }


def fit_effect(
    target: CampaignTarget,
    name: str,
    fixed: Sequence[Effect] = (),
    settings: SolverSettings | None = None,
    budget: int | None = None,
    off: np.ndarray | None = None,
    seeds: Sequence[dict[str, float]] = (),
    subset: int | None = None,
) -> dict[str, Any]:
    """Fit one effect's parameters, shared by all recordings, on top of ``fixed`` effects.

    Parameters
    ----------
    target : CampaignTarget
    name : str
        Canonical name or ``module:Class``.
    fixed : sequence of Effect
        Effects already in the model (held at their values; ``target.base_effects`` too).
    settings : SolverSettings, optional
        Default: by the engine the model needs.
    budget : int, optional
        Objective evaluations (default: design + :data:`REFINE_EVALUATIONS`, or
        :data:`DEFAULT_BUDGET_NUMERICAL` for a numerical-engine effect).
    off : numpy.ndarray, optional
        Per-recording discrepancies of the model without the effect, if known.
    seeds : sequence of dict
        Extra starting points (effect parameters), e.g. the current values in a joint refit.
    subset : int, optional
        A closed-form effect is searched on at most this many recordings
        (:func:`spread_subset`, e.g. :data:`SUBSET_SEARCH`), its best point scored on all;
        None: searched on all (a numerical-engine effect's design has its own subset).

    Returns
    -------
    dict
        ``effect``, ``params`` (fitted and fixed), ``fitted``, ``per_recording``,
        ``off_per_recording``, ``improves``, ``evaluations``, ``seconds``, ``engine``.
    """
    # a measurement effect's evaluations share one motion (only its chain moves)
    with reuse_motion():
        return _fit_effect(target, name, fixed, settings, budget, off, seeds, subset)


def _fit_effect(
    target: CampaignTarget,
    name: str,
    fixed: Sequence[Effect],
    settings: SolverSettings | None,
    budget: int | None,
    off: np.ndarray | None,
    seeds: Sequence[dict[str, float]],
    subset: int | None = None,
) -> dict[str, Any]:
    from stiffnet.measurement.target import settings_for

    t0 = time.perf_counter()
    fixed = list(fixed)
    space, design, read, blocks, budget = _plan(target, name, seeds, budget)
    numerical = needs_numerical(name)
    if settings is None:
        settings = settings_for([name, *(e.name for e in fixed if e.kind == "dynamics")])
    if off is None:
        off = target.per_recording([*target.base_effects, *fixed], settings)
    seeded = bool(space.global_seeds and read)
    k = len(space.free)
    if numerical:
        return _fit_design(target, name, fixed, space, design, settings, off, t0)
    if seeded:  # the orbit moves with the effect: starts profiled at it
        model = [*target.base_effects, *fixed, effect_class(name)(**read[0])]
        target = starts_at(target, model, settings)
    idx = spread_subset(target.rows, subset or len(target.rows))
    if idx.size < len(target.rows):  # searched on a subset, the best point scored on all
        ev = _Evaluator(target.subset(idx), fixed, [name], [space], settings, budget, target)
    else:
        ev = _Evaluator(target, fixed, [name], [space], settings, budget)
    ev.prefetch(design)
    values = [ev(u) for u in design]
    best = design[int(np.argmin(values))]
    step = 0.5 / 3
    if blocks:  # the global stage: grids over the multimodal parameters, then a local search
        best, step = global_stage(ev, blocks, best), LOCAL_STEP
    # a seed read off the measurement that beats the design and the grids: the answer's basin
    if any(np.allclose(best, space.unit(s)) for s in read):
        step = min(step, SEED_STEP)
    if len(ev.cache) < budget and k == 1:  # bounded Brent between the design neighbours
        h = 1.0 / (len(design) - 1) if len(design) > 1 else 0.5
        optimize.minimize_scalar(
            lambda x: ev(np.array([x])),
            bounds=(max(0.0, best[0] - h), min(1.0, best[0] + h)),
            method="bounded",
            options={"maxiter": budget - len(ev.cache), "xatol": 1e-3},
        )
    elif len(ev.cache) < budget and k > 1:
        _nelder_mead(ev, best, step, budget - len(ev.cache))
    res = _result(ev, off, t0, off_params(name, space))
    profiled = N_STARTS if seeded else 0  # the starts profiled at the reading
    return {
        "effect": name,
        "params": res["params"][0],
        "fitted": res["fitted"][0],
        "per_recording": res["per_recording"].tolist(),
        "off_per_recording": off.tolist(),
        "improves": res["improves"],
        "evaluations": res["evaluations"] + profiled,
        "seconds": res["seconds"],
        "engine": "numerical" if numerical else "closed_form",
    }


def _plan(
    target: CampaignTarget, name: str, seeds: Sequence[dict[str, float]], budget: int | None
) -> tuple[FitSpace, np.ndarray, list[dict[str, float]], list, int]:
    """What a fit of ``name`` will search (:func:`fit_effect`): its space, its design (the
    given seeds and those read off the measurement first), the seeds read, the global stage's
    blocks and the evaluation budget."""
    observed = target.observed()
    space = effect_space(name, target.rows, observed, dict(seeds[0]) if seeds else None)
    numerical = needs_numerical(name)
    design = initial_design(space)
    n_seeds = len(seeds)
    read = effect_class(name).fit_seeds(observed, space)
    seeds = [*seeds, *read]
    # seeds read off the measurement that stand for the global stage replace the design
    # (but the centre): the basin is known, a design would only find orbit jumps elsewhere
    if space.global_seeds and read:
        design = design[:1]
    if seeds:
        design = np.vstack([np.array([space.unit(s) for s in seeds]), design])
    k = len(space.free)
    blocks = [] if numerical else global_blocks(space)
    if budget is None:
        refine = REFINE_EVALUATIONS.get(k, REFINE_EVALUATIONS_MANY)
        sweeps = GLOBAL_ROUNDS * sum(len(grid) for _, grid in blocks)
        budget = DEFAULT_BUDGET_NUMERICAL if numerical else len(design) + sweeps + refine
    if len(design) > budget:  # a small budget keeps the given seeds, spreads the rest
        keep = np.unique(
            np.r_[
                np.arange(min(n_seeds, budget)),
                np.round(np.linspace(0, len(design) - 1, budget - min(n_seeds, budget))),
            ]
        )
        design = design[keep.astype(int)[:budget]]
    return space, design, read, blocks, budget


def planned_evaluations(target: CampaignTarget, name: str, budget: int | None = None) -> int:
    """The evaluation budget a fit of ``name`` on ``target`` starts with (:func:`fit_effect`
    with no seeds given): a closed-form fit's design, global stage and refinement."""
    return _plan(target, name, (), budget)[4]


def spread_subset(rows: Sequence[Any], k: int) -> np.ndarray:
    """Indices of at most ``k`` recordings spread over the campaign's operating points: the
    rows ordered by β, gap over amplitude, forcing frequency ratio and sampling rate, then
    ``k`` evenly spaced in that order (sorted). A campaign that repeats its operating points
    (shifted forcing, another day) keeps one recording of each where ``k`` allows; with more
    operating points than ``k``, the subset spans their range."""
    n = len(rows)
    if k >= n:
        return np.arange(n)

    def order_key(i: int) -> tuple[float, ...]:
        r = rows[i]
        ratio = r.gap / r.amplitude if r.gap is not None and r.amplitude else 0.0
        return (r.beta or 0.0, ratio, r.frequency_ratio or 0.0, r.fs_hz, i)

    order = sorted(range(n), key=order_key)
    picks = np.unique(np.round(np.linspace(0, n - 1, max(k, 1))).astype(int))
    return np.sort(np.array([order[j] for j in picks], dtype=int))


def starts_at(
    target: CampaignTarget, model: Sequence[Effect], settings: SolverSettings
) -> CampaignTarget:
    """The target with each recording's initial state profiled for ``model``: of the
    :data:`~stiffnet.measurement.nuisance.N_STARTS` starts, the one whose simulation matches
    the recording best (the target's own start where it ties).

    The starts are profiled for the model without the effect; an effect that moves the
    orbit (a harmonic's phase) can send a recording from its start to another orbit than
    the measured one at the truth (measured: 4.3 against 0.04-0.5 without the harmonics),
    so a fit whose global stage reads the effect off the measurement profiles them again
    there, once."""
    n = len(target.rows)
    held = list(target.starts) if target.starts is not None else [0] * n
    pers = np.vstack(
        per_recording_many(
            target,
            [(model, settings, {"starts": [k] * n, "inclination": False}) for k in range(N_STARTS)],
        )
    )
    cols = np.arange(n)
    best = np.argmin(pers, axis=0)
    starts = np.where(pers[best, cols] < pers[held, cols], best, held)
    return replace(target, starts=[int(k) for k in starts])


def global_stage(
    ev: _Evaluator, blocks: Sequence[tuple[list[int], np.ndarray]], start: np.ndarray
) -> np.ndarray:
    """Sweep each multimodal block's grid with the other coordinates held at the best point
    so far, block after block, for :data:`GLOBAL_ROUNDS` rounds (blocks interact: a
    harmonic's best phase depends on the other's); returns the best point found."""
    u = np.asarray(start, float).copy()
    for _ in range(GLOBAL_ROUNDS):
        before = u.copy()
        for idx, grid in blocks:
            pts = np.repeat(u[None, :], len(grid), axis=0)
            pts[:, idx] = grid
            ev.prefetch(pts)
            values = [ev(p) for p in pts]
            j = int(np.argmin(values))
            if values[j] < ev(u):
                u = pts[j]
        if np.array_equal(u, before):
            break
    return u


def _fit_design(
    target: CampaignTarget,
    name: str,
    fixed: list[Effect],
    space: FitSpace,
    design: np.ndarray,
    settings: SolverSettings,
    off: np.ndarray,
    t0: float,
) -> dict[str, Any]:
    """A numerical-engine effect's fit: its design simulated as one batch on a subset of the
    recordings (:meth:`CampaignTarget.per_recording_points`), the best point scored alone on
    all of them when it beats "effect off" on the subset."""
    cls = effect_class(name)
    model = [*target.base_effects, *fixed]
    points = [space.params(u) for u in design]
    n = len(target.rows)
    idx = np.unique(np.round(np.linspace(0, n - 1, min(n, SUBSET_NUMERICAL))).astype(int))
    searched = target if idx.size == n else target.subset(idx)
    # the design scores what a full evaluation would (its first point is then the answer)
    same = idx.size == n and not target.inclination and oversampling(model) == 1
    # else it screens: an analog sensor in the model filters at the logger's rate there
    # (the numerical engine's cost is per step: 8x oversampled, 4x the steps) and the
    # transient is shorter (SCREEN_SETTLE_TOLERANCE); the best point is then scored in full
    design_settings = settings if same else screen_settings(settings, True)
    pers = searched.per_recording_points(
        model, name, points, design_settings, inclination=False, oversample=False
    )
    values = [objective_value(p, searched.weights) for p in pers]
    j = int(np.argmin(values))
    # "effect off" on the same recordings, scored like the design: when no point beats it
    # there, the effect is off (the best point would need a full evaluation to say so)
    off_searched = (
        off
        if same
        else searched.per_recording(model, design_settings, inclination=False, oversample=False)
    )
    if values[j] >= objective_value(off_searched, searched.weights):
        per, rescored = off, False
    else:
        rescored = not (j == 0 and same)
        # the first point of the batch drew the standard noise; the others did not
        per = target.per_recording([*model, cls(**points[j])], settings) if rescored else pers[0]
    improves = bool(objective_value(per, target.weights) < objective_value(off, target.weights))
    params = points[j]
    if not improves:
        per = off
        params = (off_params(name, space) or [params])[0]
    return {
        "effect": name,
        "params": params,
        "fitted": space.fitted,
        "per_recording": per.tolist(),
        "off_per_recording": off.tolist(),
        "improves": improves,
        "evaluations": len(points) + (not same) + rescored,
        "seconds": round(time.perf_counter() - t0, 3),
        "engine": "numerical",
        "searched_on": [target.rows[i].recording for i in idx],
    }


def screen_settings(settings: SolverSettings, short_lead_in: bool = False) -> SolverSettings:
    """The settings of a numerical-engine design that is only a screen (see
    :data:`SCREEN_SETTLE_TOLERANCE`): the same, with a transient no longer than that rule's,
    begun warm (:data:`SCREEN_WARM_START`); with ``short_lead_in`` (an effect's design,
    :func:`_fit_design`), an analog chain's lead-in run in to the same tolerance
    (``lead_in_tolerance``, :func:`~stiffnet.campaign.simulate.screen_lead_in_seconds`: 0.48 s
    for a 1-Hz high-pass instead of the standard 1.5 s, a third of the RK4 steps of a screen
    whose model holds the sensor)."""
    tol = max(settings.settle_tolerance, SCREEN_SETTLE_TOLERANCE)
    warm = max(settings.warm_start, SCREEN_WARM_START)
    update: dict[str, float] = {"settle_tolerance": tol, "warm_start": warm}
    if short_lead_in and "lead_in_tolerance" in type(settings).model_fields:
        update["lead_in_tolerance"] = max(settings.lead_in_tolerance or 0.0, tol)
    return settings.model_copy(update=update)


def _nelder_mead(ev: _Evaluator, start: np.ndarray, step: float, maxfev: int) -> None:
    k = start.size
    simplex = np.vstack(
        [start]
        + [
            np.clip(start + step * np.eye(k)[j] * (1 if start[j] < 0.5 else -1), 0, 1)
            for j in range(k)
        ]
    )
    ev.prefetch(simplex)  # the first simplex's points do not depend on each other
    optimize.minimize(
        ev,
        start,
        method="Nelder-Mead",
        bounds=[(0.0, 1.0)] * k,
        options={"initial_simplex": simplex, "maxfev": maxfev, "xatol": 1e-3, "fatol": 1e-4},
    )


def fit_joint(
    target: CampaignTarget,
    names: Sequence[str],
    params: Sequence[dict[str, float]],
    settings: SolverSettings,
    budget: int | None = None,
    start: np.ndarray | None = None,
    rounds: int = 2,
    subset: int | None = None,
) -> dict[str, Any]:
    """Refit every effect of a model jointly, from ``params`` (a local Nelder-Mead).

    ``start`` is the per-recording discrepancy at ``params`` if known;
    ``rounds`` of block coordinate descent come first (0 for a polish only), each effect's
    refit searched on ``subset`` recordings (:func:`fit_effect`), then the Nelder-Mead on the
    same subset (:func:`spread_subset`; None: on every recording, as the polish), its best
    point scored on every recording. The result never ends worse than the start.

    Returns
    -------
    dict
        ``effects``, ``params`` (one dict per effect), ``fitted``, ``per_recording``,
        ``improves`` (over the start), ``evaluations``, ``seconds``.
    """
    t0 = time.perf_counter()
    names = list(names)
    observed = target.observed()
    spaces = [
        effect_space(n, target.rows, observed, dict(p)) for n, p in zip(names, params, strict=True)
    ]
    k = sum(len(s.free) for s in spaces)
    params = [{**s.fixed, **p} for s, p in zip(spaces, params, strict=True)]
    numerical = any(needs_numerical(n) for n in names)
    if start is None:
        start = target.per_recording([*target.base_effects, *_effects(names, params)], settings)
    start = np.asarray(start, float)
    given, evaluations = [dict(p) for p in params], 0
    # block coordinate descent: each effect refitted from its own design with the others
    # held, so one effect cannot keep a share that belongs to another (a local search alone
    # stays in the valley where the first effect was fitted)
    for _ in range(0 if numerical else rounds):
        round_start = objective_value(start, target.weights)
        for i, n in enumerate(names):
            others = _effects(names[:i] + names[i + 1 :], params[:i] + params[i + 1 :])
            fit = fit_effect(target, n, others, settings, seeds=[params[i]], subset=subset)
            evaluations += fit["evaluations"]
            w = target.weights
            if objective_value(np.asarray(fit["per_recording"]), w) < objective_value(start, w):
                params[i], start = dict(fit["params"]), np.asarray(fit["per_recording"], float)
        if (
            objective_value(start, target.weights) >= round_start
        ):  # a round that moved nothing ends the descent
            break
    if budget is None:
        per = JOINT_PER_COORDINATE_NUMERICAL if numerical else JOINT_PER_COORDINATE
        budget = max(1, per * k) + 1
    # the Nelder-Mead searches on the subset too, its best point scored on every recording
    idx = spread_subset(target.rows, subset or len(target.rows))
    if idx.size < len(target.rows):
        ev = _Evaluator(target.subset(idx), [], names, spaces, settings, budget, target)
    else:
        ev = _Evaluator(target, [], names, spaces, settings, budget)
    u0 = np.concatenate([s.unit(p) for s, p in zip(spaces, params, strict=True)])
    ev.full[ev.key(u0)] = start
    if not target.inclination and ev.whole is None:  # the search's values are the full ones
        ev.cache[ev.key(u0)] = start
    ev.per(u0)
    if k and len(ev.cache) < budget:
        _nelder_mead(ev, u0, JOINT_STEP, budget - len(ev.cache))
    res = _result(ev, start, t0, [dict(p) for p in params])
    if not res["improves"]:  # keep the values exactly (not their unit-cube image)
        res["params"] = [dict(p) for p in params]
    res["improves"] = bool(res["improves"] or params != given)
    res["evaluations"] += evaluations
    return res


def _effects(names: Sequence[str], params: Sequence[dict[str, float]]) -> list[Effect]:
    return [effect_class(n)(**p) for n, p in zip(names, params, strict=True)]

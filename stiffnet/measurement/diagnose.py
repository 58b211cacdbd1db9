"""Which physical effects are missing: forward selection with joint refits, and a verdict.

The orchestration of the diagnosis; the parts live in their own modules:
what is compared (:mod:`~stiffnet.measurement.target`), how an effect is
fitted (:mod:`~stiffnet.measurement.fitting`, each effect's own fit space),
the nuisance parameters (:mod:`~stiffnet.measurement.nuisance`), whether an
improvement is real (:mod:`~stiffnet.measurement.significance`) and the
campaign's noise floor and verdict (:mod:`~stiffnet.measurement.noise_floor`).

1. **Nuisances.** The manifest's rows are resolved (physical units, forcing
   frequency from the spectrum, β from the model's estimate when missing) and
   the uncertain ones profiled against the base model within their
   tolerances.
2. **Single fits.** Every candidate effect (the library and user
   ``module:Class`` effects) is fitted alone on top of the base model
   (parallel tasks, :func:`stiffnet.distributed.map_tasks`, the longest first) and tested
   against it; with workers, those whose fit reads nothing of the restoring-force evidence
   (:func:`reads_evidence`) start while it is read.
3. **Forward selection with joint refits.** At each step every remaining
   candidate that showed something alone (:data:`SCREEN_EXCESS`, or is
   closed-form) is fitted on top of the selected effects, the closed-form ones first (with
   their joint refits): the numerical-engine ones (most of a diagnosis' CPU) only when the
   effect accepted among them leaves the model above the recordings' floors, or none is
   accepted (at the floors nothing is left for them to explain); the best by the
   BIC-like score is then refitted **jointly with all selected effects** and
   kept if the joint model passes every significance test against the
   previous one. The nuisances are profiled again after each accepted step (where they
   moved, the selected effects are refitted locally, :data:`ACCEPT_ROUNDS`).
   Selection stops when no candidate passes. The first step has one more candidate: the
   effects the restoring-force evidence identifies together (:func:`evidence_group`, the
   shared sensor chain with the contact law it supports), fitted jointly from its values;
   neither of a damped contact and a mounted chain passes alone when both are there.
   Closed-form fits and the joint refits search
   on :data:`~stiffnet.measurement.fitting.SUBSET_SEARCH` recordings spread over the
   operating points and are scored and tested on all of them; the selected effects then get
   a joint Nelder-Mead on every recording (:data:`POLISH_EVALUATIONS`), which takes back what
   the searches on a subset left of the whole campaign's optimum.
4. **Verdict.** The final model's ``residual_discrepancy`` against the
   campaign's noise floor: ``nothing_missing`` (the base model is at the
   floor), ``explained`` or ``partially_explained`` with
   ``explained_fraction`` and where the rest lives.

Every rejected candidate carries ``reasons``: the tests it failed, in words.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.campaign.loaded import LoadedCampaign, memo
from stiffnet.campaign.simulate import DEFAULT_SEED, FIT_SETTINGS, FIT_SETTINGS_NUMERICAL
from stiffnet.effects.base import Effect
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.measurement.discrepancy import campaign_discrepancy, where_sums
from stiffnet.measurement.evaluation_pool import evaluation_pool
from stiffnet.measurement.evidence import restoring_force_evidence
from stiffnet.measurement.fitting import (
    DEFAULT_BUDGET_NUMERICAL,
    SUBSET_SEARCH,
    effect_space,
    fit_effect,
    fit_joint,
    planned_evaluations,
)
from stiffnet.measurement.forcing_lines import campaign_forcing_lines
from stiffnet.measurement.learned_law import learned_law_proposal
from stiffnet.measurement.noise_floor import (
    AT_FLOOR_FACTOR,
    Floors,
    noise_floor,
    recording_floors,
    verdict,
)
from stiffnet.measurement.nuisance import profile_nuisances, resolve_rows
from stiffnet.measurement.orbits import orbit_name, orbit_pattern
from stiffnet.measurement.significance import significance
from stiffnet.measurement.target import (
    CampaignTarget,
    measured_statistics,
    needs_numerical,
    rows_key,
    settings_for,
)
from stiffnet.progress import task as progress_task

#: A candidate is refitted on top of selected effects when alone it removed at least this
#: fraction of the excess discrepancy (closed-form candidates always are: they are cheap).
SCREEN_EXCESS = 0.05
#: How the reasons of a numerical-engine candidate left unfitted in a step begin.
NOT_FITTED = "not fitted on top of"
#: Candidates given a joint refit per selection step (best conditional scores first).
JOINT_TRIES = 2
#: Rounds of block coordinate descent (:func:`~stiffnet.measurement.fitting.fit_joint`) in the
#: refit of the selected effects after the nuisances moved: 0, a local refit only (each
#: effect's design search costs as much as the step that ran it just before).
ACCEPT_ROUNDS = 0
#: Evaluations of the final polish: the selected effects' joint Nelder-Mead on every
#: recording, from where the selection left them, before the verdict (0: none). The
#: searches ran on :data:`~stiffnet.measurement.fitting.SUBSET_SEARCH` recordings and end a
#: little off the whole campaign's optimum (bench_diagnose's 24 x 6 s campaign: residual
#: 0.0748 -> 0.0650 for 1.6 s of CPU in 210). Closed-form models only: a numerical-engine
#: model's evaluation costs seconds.
POLISH_EVALUATIONS = 40
#: At most this many effects are selected.
MAX_EFFECTS = 4
#: Dask priority of the single fits submitted before the restoring-force evidence is read
#: (:meth:`_Run.submit_early`): below the evidence's tasks (0), so a worker takes one only
#: where the evidence leaves it idle (its three chain fits on two workers, the reads' tail).
EARLY_PRIORITY = -1
#: Effects never searched blind from their class defaults: a learned law is proposed by the
#: contact-law discovery with its own terms (``learned_law``).
PROPOSED_ONLY = ("learned_contact",)


def candidate_effects(
    base_effects: Sequence[Effect], extra: Sequence[str] = (), only: Sequence[str] | None = None
) -> list[str]:
    """Effects to try: the library (or ``only``) plus user effects, minus those in the model."""
    names = list(only) if only is not None else [n for n in CANONICAL if n not in PROPOSED_ONLY]
    names += [e for e in extra if e not in names]
    present = {e.name for e in base_effects}
    for n in names:
        effect_class(n)  # one-line error for an unknown name
    return [n for n in names if effect_class(n).name not in present]


def reads_evidence(name: str) -> bool:
    """Whether an effect's fit starts from what the measurement shows
    (:meth:`CampaignTarget.observed`, which holds the restoring-force evidence's shared sensor
    chain): its class overrides :meth:`Effect.fit_seeds` or :meth:`Effect.observed_fit_space`.
    The others' single fits need nothing of the evidence and may run while it is read."""
    cls = effect_class(name)
    return any(
        getattr(cls, hook).__func__ is not getattr(Effect, hook).__func__
        for hook in ("fit_seeds", "observed_fit_space")
    )


def _fit_task(item: tuple[CampaignTarget, str, list[Effect], int | None]) -> dict[str, Any]:
    target, name, fixed, budget = item
    return fit_effect(target, name, fixed, budget=budget, subset=SUBSET_SEARCH)


def _effects(names: Sequence[str], params: Sequence[dict[str, float]]) -> list[Effect]:
    return [effect_class(n)(**p) for n, p in zip(names, params, strict=True)]


#: Steps of the diagnosis before the fits: recordings and statistics, noise floor, nuisances.
SETUP_STEPS = 3


def planned_steps(n_candidates: int) -> list[int]:
    """The diagnosis' plan, known before any work: the cumulative step count at the end of
    the setup, of the single fits and of each possible selection step (its conditional
    fits, :data:`JOINT_TRIES` joint refits and a profile of the nuisances; the first, the
    evidence's group instead of conditional fits), then the verdict. An upper bound: a
    selection that stops early skips to the verdict."""
    ends = [SETUP_STEPS, SETUP_STEPS + n_candidates]
    for k in range(min(MAX_EFFECTS, n_candidates)):
        ends.append(ends[-1] + (n_candidates - k if k else 1) + JOINT_TRIES + 1)
    return [*ends, ends[-1] + 1]


class _Progress:
    """The diagnosis' progress against its plan (:func:`planned_steps`): ``progress(done,
    total)`` and a :func:`stiffnet.progress.task` line whose note names the stage and the
    effect being fitted (bars with an ETA when a command installs a display)."""

    def __init__(self, fn: Callable[[int, int], None] | None, line: Any, plan: list[int]) -> None:
        self.fn, self.line, self.plan = fn, line, plan
        self.done, self.total = 0, plan[-1]

    def to(self, done: int, note: str | None = None) -> None:
        """Steps done so far (never backwards, never past the plan)."""
        self.done = min(self.total, max(self.done, int(done)))
        if self.fn is not None:
            self.fn(self.done, self.total)
        if self.line is not None:
            self.line.update(self.done, self.total, note=note)

    def step(self, note: str | None = None) -> None:
        self.to(self.done + 1, note)

    def end_of(self, stage: int, note: str | None = None) -> None:
        """Skip to the planned end of ``stage`` (0: setup, 1: single fits, 2 + k: step k)."""
        self.to(self.plan[min(stage, len(self.plan) - 1)], note)


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
    model_path: str | None = None,
) -> dict[str, Any]:
    """Find the effects the model lacks on a campaign (see the module notes).

    Parameters
    ----------
    campaign : Campaign
        Only ``recording, fs_hz`` are required in its manifest; missing or
        uncertain parameters are estimated (:mod:`stiffnet.measurement.nuisance`).
    base_effects : sequence of Effect
        The current simulator config's effects (kept in every simulation).
    effects : sequence of str, optional
        Candidate effect names (default: every shipped effect).
    user_effects : sequence of str
        Extra ``module:Class`` effects.
    budget, budget_numerical : int, optional
        Objective evaluations of a single fit (closed form / numerical engine).
    seed : int
        Common-random-number seed.
    inclination : bool
        Include the inclination statistics (the geometric method) in the discrepancy.
    scheduler, workers
        Where the fits of one step run (:func:`stiffnet.distributed.map_tasks`).
    progress : callable, optional
        ``progress(done, total)`` after each step of the plan (:func:`planned_steps`: the
        total is known from the start).
    model_path : str, optional
        ONNX model whose β estimate starts the fit of recordings without β.

    Returns
    -------
    dict
        ``baseline_discrepancy``, ``noise_floor``, ``ranking`` (each ``effect``,
        ``selected``, ``significant``, ``params``, ``discrepancy_reduction``, the
        evidence and ``reasons``), ``missing_effects`` (selected, in order),
        ``missing_effect`` (the first or None), ``selection`` (the steps),
        ``residual_discrepancy``, ``explained_fraction``, ``verdict``,
        ``unexplained_where``, ``summary``, ``nuisances`` (per recording, profiled with the
        selected effects, named in its ``profiled_with``), ``nuisances_effect_free`` (profiled
        with no effect: the baseline's), ``settings``, ``seconds``.
    """
    from stiffnet.distributed.cluster import check_target
    from stiffnet.inputs import bounded_count

    bounded_count(budget, "--budget", 1, 100_000)  # checked before any simulation
    bounded_count(budget_numerical, "--budget-numerical", 1, 100_000)
    check_target(scheduler, workers)
    from stiffnet.distributed.cluster import dask_client

    t0 = time.perf_counter()
    campaign = LoadedCampaign.of(campaign)  # each recording read once
    # one cluster for the whole diagnosis (a LocalCluster starts in seconds; steps are many)
    plan = planned_steps(len(candidate_effects(base_effects, user_effects, effects)))
    with (
        progress_task("diagnosis", plan[-1]) as line,
        dask_client(scheduler, workers) as client,
    ):
        bar = _Progress(progress, line, plan)
        bar.to(0, "reading the recordings")
        options = {"budget": budget, "budget_numerical": budget_numerical, "seed": seed,
                   "inclination": inclination, "model_path": model_path}  # fmt: skip
        candidates = candidate_effects(base_effects, user_effects, effects)
        # this process's searches spread their independent evaluations over the workers
        with evaluation_pool(client):
            return _diagnose(campaign, base_effects, candidates, options, client, bar, t0)


@dataclass
class _Run:
    """What the parts of one diagnosis share: the target, the floors, where fits run."""

    campaign: Campaign
    base_effects: list[Effect]
    #: The rows as resolved (the target's move with the nuisances).
    rows: list[ManifestRow]
    target: CampaignTarget
    names: list[str]
    nuisance_info: dict[str, Any]
    floor_info: dict[str, Any]
    floors: dict[Any, Floors]
    budget: int | None
    budget_numerical: int | None
    client: Any
    bar: _Progress
    stage: str = "single fits"
    #: The restoring-force evidence (contact law and shared sensor chain per recording).
    evidence: dict[str, Any] | None = None
    #: Single fits submitted before the evidence (:meth:`submit_early`): names, tasks.
    early: tuple[list[str], Any] | None = None

    def _items(
        self, cands: list[str], fixed: list[Effect], target: CampaignTarget | None = None
    ) -> tuple[list[str], list[tuple]]:
        """The fit tasks of ``cands`` on top of ``fixed``, the longest first so parallel
        workers finish together: the numerical-engine fits, then the closed-form ones by
        their evaluation budget (:func:`planned_evaluations`), the largest first."""
        budget = {True: self.budget_numerical, False: self.budget}
        target = self.target if target is None else target

        def longest_first(n: str) -> tuple[bool, int]:
            numerical = needs_numerical(n)
            return not numerical, -planned_evaluations(target, n, budget[numerical])

        order = sorted(cands, key=longest_first)
        return order, [(target, n, fixed, budget[needs_numerical(n)]) for n in order]

    def _score_off(self, cands: list[str], fixed: list[Effect]) -> None:
        """Score "effect off", every fit's reference, here once per settings: it travels with
        the target (CampaignTarget.known) instead of being simulated again by every task."""
        dynamics = [e.name for e in fixed if e.kind == "dynamics"]
        for settings in {settings_for([n, *dynamics]) for n in cands}:
            self.target.per_recording([*self.target.base_effects, *fixed], settings)

    def submit_early(self, cands: list[str]) -> None:
        """With workers, submit the single fits of the candidates whose fit reads nothing of
        the restoring-force evidence (:func:`reads_evidence`) before it is read, below its
        priority (:data:`EARLY_PRIORITY`): they fill the cores the evidence leaves idle, and
        :meth:`fits` collects them. Each task gets the target as it is now (its memo
        copied), which is what it would get after the evidence: nothing they read moves."""
        from stiffnet.distributed.tasks import submit_tasks
        from stiffnet.simulator.compiled import limited_threads

        early = [n for n in cands if not reads_evidence(n)]
        if self.client is None or not early:
            return
        self._score_off(cands, [])
        snapshot = replace(self.target)  # the evidence then sets the target's sensor chain
        snapshot.known = dict(self.target.known)
        order, items = self._items(early, [], snapshot)
        self.early = (order, submit_tasks(
            _fit_task, items, client=self.client, names=order, thread_limit=limited_threads,
            priority=EARLY_PRIORITY,
        ))  # fmt: skip

    def fits(self, cands: list[str], fixed: list[Effect]) -> list[dict[str, Any]]:
        """Fit each candidate on top of ``fixed`` (parallel tasks), in the order given; the
        single fits submitted early (:meth:`submit_early`) are collected here."""
        from stiffnet.distributed.tasks import run_tasks
        from stiffnet.simulator.compiled import limited_threads

        early_order, early = ([], None) if fixed or self.early is None else self.early
        self.early = None
        order, items = self._items([n for n in cands if n not in early_order], fixed)
        self._score_off(order, fixed)
        start = self.bar.done
        everything = [*order, *early_order]

        def show(done: int, _total: int) -> None:
            nxt = f": fitting {everything[done]}" if done < len(everything) else ""
            self.bar.to(start + done, f"{self.stage}{nxt}")

        show(0, len(everything))
        report = run_tasks(
            _fit_task, items, client=self.client, names=order, progress=show,
            thread_limit=limited_threads,
        )  # fmt: skip
        report.raise_failures()
        by_name = dict(zip(order, report.results, strict=True))
        if early is not None:
            late = early.collect(lambda done, total: show(len(order) + done, total))
            late.raise_failures()
            by_name.update(zip(early_order, late.results, strict=True))
        return [by_name[n] for n in cands]

    def judge(self, fit: dict[str, Any], before: np.ndarray, kept: list[str]) -> dict[str, Any]:
        """The ranking entry of a fit tested against the model it was fitted on top of."""
        sig = significance(
            before,
            np.array(fit["per_recording"]),
            len(fit["fitted"]),
            self.floors[settings_for([*kept, fit["effect"]])],
            self.names,
        )
        return _entry(fit, sig)

    def current(
        self, current: dict[Any, np.ndarray], kept: list[str], params: list[dict[str, float]],
        new: str,
    ) -> np.ndarray:  # fmt: skip
        return _current(self.target, current, kept, params, new)


def _diagnose(
    campaign: Campaign,
    base_effects: Sequence[Effect],
    candidates: list[str],
    options: dict[str, Any],
    client: Any,
    bar: _Progress,
    t0: float,
) -> dict[str, Any]:
    """The body of :func:`diagnose_campaign` (``client``: Dask client or None, in-process;
    ``options``: ``budget``, ``budget_numerical``, ``seed``, ``inclination``, ``model_path``)."""
    run, nuisances, baseline = _prepare(
        campaign, list(base_effects), options, client, bar, candidates
    )
    # the baseline's nuisances (no effect) stay in the result beside the final model's
    effect_free = {**nuisances, "profiled_with": []}
    entries, searched = _fit_alone(run, candidates, baseline)
    bar.end_of(1, "selection")
    kept, kept_params, steps, nuisances = _select(run, searched, entries, baseline, nuisances)
    kept_params, polish = _polish(run, kept, kept_params, entries)
    res = _conclude(run, kept, kept_params, entries, steps, baseline, nuisances, options, t0)
    res["polish"] = polish
    res["nuisances"] = {**nuisances, "profiled_with": list(kept)}
    res["nuisances_effect_free"] = effect_free
    return res


def _prepare(
    campaign: Campaign,
    base_effects: list[Effect],
    options: dict[str, Any],
    client: Any,
    bar: _Progress,
    candidates: Sequence[str] = (),
) -> tuple[_Run, dict[str, Any], np.ndarray]:
    """Rows and nuisances resolved, measured statistics, the recordings' floors, the
    nuisances profiled against the base model and its per-recording discrepancies.

    With workers the restoring-force evidence is read on them while this process profiles
    the nuisances, and the single fits of the ``candidates`` that need nothing of it are
    submitted before it ends (:meth:`_Run.submit_early`): the three chain fits on two
    workers and the reads' tail leave a core idle, which those fits fill."""
    inclination = options["inclination"]
    rows, nuisance_info = resolve_rows(campaign, options["model_path"])
    measured, lengths, signals = measured_statistics(campaign, rows, inclination)
    target = CampaignTarget(rows, measured, lengths, base_effects, options["seed"], inclination)
    bar.step("noise floor (split halves)")
    floor_info = memo(
        campaign, ("noise_floor", inclination, rows_key(rows)),
        lambda: noise_floor(signals, rows, FIT_SETTINGS.periods, inclination),
    )  # fmt: skip
    floors: dict[Any, Floors] = {
        FIT_SETTINGS: floor_info["floors"],
        FIT_SETTINGS_NUMERICAL: recording_floors(
            floor_info, signals, rows, FIT_SETTINGS_NUMERICAL.periods
        ),
    }
    # a non-repeatable recording (halves far apart) weighs less in every fit's objective
    target.weights = floors[FIT_SETTINGS].weights().tolist()

    # the contact law read off each force-displacement map (evidence without simulation);
    # its shared sensor chain is where sensor_dynamics' fit starts
    def read_evidence() -> dict[str, Any]:
        return memo(
            campaign, ("restoring_force", rows_key(rows)),
            lambda: restoring_force_evidence(campaign, rows, client),
        )  # fmt: skip

    with ThreadPoolExecutor(max_workers=1) as beside:
        reading = beside.submit(read_evidence) if client is not None else None
        evidence = read_evidence() if reading is None else None
        bar.step("nuisances and initial states")
        nuisances = profile_nuisances(target, [], FIT_SETTINGS, nuisance_info)
        baseline = target.per_recording(base_effects, FIT_SETTINGS)
        run = _Run(
            campaign, base_effects, rows, target, [r.recording for r in rows], nuisance_info,
            floor_info, floors, options["budget"], options["budget_numerical"], client, bar,
        )  # fmt: skip
        if reading is not None and not floors[FIT_SETTINGS].at_floor(baseline):
            run.submit_early(list(candidates))
        evidence = _await_evidence(reading) if reading is not None else evidence
    run.evidence = evidence
    target.sensor = evidence.get("sensor")
    # seeds forcing_harmonics' fit (read through the chain the evidence identified: a
    # mount's ringing after each impact reads as forcing lines otherwise)
    target.forcing = campaign_forcing_lines(signals, rows, target.sensor)
    return run, nuisances, baseline


def _await_evidence(reading: Any) -> dict[str, Any]:
    """The evidence read beside the nuisances (a future of this process's thread)."""
    return reading.result()


def _fit_alone(
    run: _Run, candidates: list[str], baseline: np.ndarray
) -> tuple[dict[str, dict[str, Any]], list[str]]:
    """Step 0: every candidate alone against the base model. Returns the ranking entries and
    the candidates the selection searches (none when the base model is at the floor)."""
    entries: dict[str, dict[str, Any]] = {}
    if run.floors[FIT_SETTINGS].at_floor(baseline):
        # nothing to explain, so no effect could pass the tests: no fits (a clean campaign
        # is diagnosed in seconds), every candidate says why
        for n in candidates:
            entries[n] = _unfitted(n, baseline, run.floors[FIT_SETTINGS])
        return entries, []
    for fit in run.fits(candidates, []):
        entries[fit["effect"]] = run.judge(fit, np.array(fit["off_per_recording"]), [])
    return entries, list(candidates)


def _select(
    run: _Run,
    candidates: list[str],
    entries: dict[str, dict[str, Any]],
    baseline: np.ndarray,
    nuisances: dict[str, Any],
) -> tuple[list[str], list[dict[str, float]], list[dict[str, Any]], dict[str, Any]]:
    """Forward selection with joint refits (see the module notes): the selected effects,
    their joint values, the steps tried and the nuisances as last profiled."""
    kept: list[str] = []
    kept_params: list[dict[str, float]] = []
    current = {FIT_SETTINGS: baseline}
    steps: list[dict[str, Any]] = []
    while len(kept) < MAX_EFFECTS:
        remaining = [n for n in candidates if n not in kept]
        if not remaining:
            break
        cur_settings, cur_per = next(iter(current.items()))
        if kept and run.floors[cur_settings].at_floor(cur_per):
            for n in remaining:  # the model is at the noise floor: nothing left to explain
                unfitted = [r for r in entries[n]["reasons"] if r.startswith(NOT_FITTED)]
                entries[n]["reasons"] = [
                    f"nothing left to explain: {', '.join(kept)} bring the model to the "
                    "campaign's noise floor",
                    *unfitted,
                ]
            break
        accepted = _step(run, remaining, kept, kept_params, current, entries, steps)
        if not kept:
            grouped = _evidence_step(run, remaining, entries, current, steps)
            if grouped is not None and (
                accepted is None or grouped[5]["bic_delta"] < accepted[5]["bic_delta"]
            ):
                accepted = grouped
        if accepted is None:
            break
        kept_params, current, nuisances = _accept(run, accepted, kept, entries)
    return kept, kept_params, steps, nuisances


def _step(
    run: _Run,
    remaining: list[str],
    kept: list[str],
    kept_params: list[dict[str, float]],
    current: dict[Any, np.ndarray],
    entries: dict[str, dict[str, Any]],
    steps: list[dict[str, Any]],
) -> tuple | None:
    """One selection step: the remaining candidates fitted on top of the selected effects
    and the best refitted jointly (:func:`_joint_step`; returns what it returns).

    After the first step the closed-form candidates go first, alone: when the effect their
    joint refit accepts brings the model to the recordings' floors, the numerical-engine
    candidates (most of a diagnosis' CPU) are not fitted, for nothing is left for them to
    explain, and say so in their ``reasons``. Otherwise they are fitted too and the step is
    the one over every candidate (the closed-form joint refits already run are reused)."""
    deferred = [n for n in remaining if kept and needs_numerical(n)]
    conditional = _conditional_fits(run, [n for n in remaining if n not in deferred], kept,
                                     kept_params, current, entries)  # fmt: skip
    numerical = [n for n in deferred if entries[n]["excess_reduction"] >= SCREEN_EXCESS]
    if not numerical:
        return _joint_step(run, conditional, kept, kept_params, current, entries, steps)
    tried: dict[str, dict[str, Any]] = {}
    said = {n: (list(e["reasons"]), e.get("redundant_with")) for n, e in entries.items()}
    trial: list[dict[str, Any]] = []
    accepted = _joint_step(run, conditional, kept, kept_params, current, entries, trial, tried)
    if accepted is not None and run.floors[accepted[4]].at_floor(np.asarray(accepted[3])):
        steps.extend(trial)
        for n in numerical:
            entries[n]["reasons"] = [
                f"{NOT_FITTED} {', '.join(kept)}: {accepted[0]} (closed form) brings the "
                "model to the recordings' own noise floors, so nothing is left for a "
                "numerical-engine candidate to explain"
            ]
        return accepted
    for n, (reasons, redundant) in said.items():  # the trial's words were not its last
        entries[n]["reasons"] = reasons
        if redundant is None:
            entries[n].pop("redundant_with", None)
        else:
            entries[n]["redundant_with"] = redundant
    conditional |= _conditional_fits(run, numerical, kept, kept_params, current, entries)
    conditional = {n: conditional[n] for n in remaining if n in conditional}
    return _joint_step(run, conditional, kept, kept_params, current, entries, steps, tried)


def _conditional_fits(
    run: _Run,
    cands: list[str],
    kept: list[str],
    kept_params: list[dict[str, float]],
    current: dict[Any, np.ndarray],
    entries: dict[str, dict[str, Any]],
) -> dict[str, dict[str, Any]]:
    """Each candidate fitted on top of the selected effects (alone: the single fits); a
    numerical-engine one only when alone it removed :data:`SCREEN_EXCESS`."""
    if not kept:
        return {n: entries[n] for n in cands}
    cands = [
        n
        for n in cands
        if not needs_numerical(n) or entries[n]["excess_reduction"] >= SCREEN_EXCESS
    ]
    run.stage = f"step {len(kept) + 1}, on top of {', '.join(kept)}"
    conditional = {}
    for fit in run.fits(cands, _effects(kept, kept_params)) if cands else []:
        before = run.current(current, kept, kept_params, fit["effect"])
        conditional[fit["effect"]] = run.judge(fit, before, kept)
    return conditional


def _joint_step(
    run: _Run,
    conditional: dict[str, dict[str, Any]],
    kept: list[str],
    kept_params: list[dict[str, float]],
    current: dict[Any, np.ndarray],
    entries: dict[str, dict[str, Any]],
    steps: list[dict[str, Any]],
    tried: dict[str, dict[str, Any]] | None = None,
) -> tuple | None:
    """The best conditional candidates (at most :data:`JOINT_TRIES`) refitted jointly with
    the selected effects; the first whose joint model passes every test is accepted
    (returned with its values, discrepancies, settings and tests), else None. ``tried``:
    the joint refits of this step already run, by candidate (read and filled)."""
    order = sorted(conditional, key=lambda n: conditional[n]["bic_delta"])
    tries = [n for n in order if conditional[n]["improves"]][:JOINT_TRIES]
    for n in tries:
        run.bar.step(f"step {len(kept) + 1}: joint refit of {', '.join([*kept, n])}")
        c = conditional[n]
        names_new = [*kept, n]
        settings = settings_for(names_new)
        before = run.current(current, kept, kept_params, n)
        joint = (tried or {}).get(n) or fit_joint(
            run.target,
            names_new,
            [*kept_params, c["params"]],
            settings,
            start=np.array(c["per_recording"]),
            rounds=2 if kept else 0,  # alone, it was just fitted from its own design
            subset=SUBSET_SEARCH,
        )
        if tried is not None:
            tried[n] = joint
        after, params_new = joint["per_recording"], joint["params"]
        sig = significance(before, after, len(c["fitted"]), run.floors[settings], run.names)
        prefix = f"on top of {', '.join(kept)} (joint refit): " if kept else ""
        record = {
            "step": len(kept),
            "effect": n,
            "params": params_new,
            "discrepancy_before": campaign_discrepancy(before),
            "discrepancy_after": campaign_discrepancy(after),
            **{k: sig[k] for k in ("excess_reduction", "bootstrap_positive", "bic_delta")},
            "significant": sig["significant"],
            "reasons": [prefix + r for r in sig["reasons"]],
        }
        steps.append(record)
        if sig["significant"]:
            return n, params_new, before, after, settings, sig
        if kept:  # its last word: rejected on top of the selected effects
            entries[n]["reasons"] = record["reasons"]
            entries[n]["redundant_with"] = list(kept)
    for n in entries:  # not tried jointly: say why
        if kept and n in conditional and n not in tries and conditional[n]["reasons"]:
            entries[n]["reasons"] = [
                f"on top of {', '.join(kept)}: {r}" for r in conditional[n]["reasons"]
            ]
    return None


def evidence_group(evidence: dict[str, Any] | None, candidates: Sequence[str]) -> list[str]:
    """The effects the restoring-force evidence identifies together: ``sensor_dynamics`` when
    it identified the campaign's shared sensor chain (a resonance or a low-pass), with the
    contact effects its maps support (``supports``, read through that chain); empty unless
    the chain and one contact effect are both among the ``candidates``.

    The chain and the contact law act on one thing, the impact's pulse: a mounted resonance
    rings as hard as the spike that excites it, so with the contact left elastic the chain
    makes the model far worse, and with the chain left out a damped contact explains little;
    neither passes alone and a forward selection never reaches the pair."""
    sensor = (evidence or {}).get("sensor") or {}
    if "sensor_dynamics" not in candidates or not any(
        sensor.get(k) for k in ("resonance_hz", "lowpass_hz")
    ):
        return []
    contact = [n for n in (evidence or {}).get("supports") or [] if n in candidates]
    return ["sensor_dynamics", *contact] if contact else []


def _group_start(run: _Run, group: list[str], entries: dict[str, Any]) -> list[dict[str, float]]:
    """Each member's start: the values the evidence reads for it (``supported_values``,
    :func:`~stiffnet.measurement.evidence.contact_evidence`), else its first seed from the
    measurement (the identified chain), else its single fit's values."""
    observed = run.target.observed()
    read = (run.evidence or {}).get("supported_values") or {}
    starts = []
    for n in group:
        space = effect_space(n, run.rows, observed)
        seeds = effect_class(n).fit_seeds(observed, space)
        start = dict(seeds[0]) if seeds else dict(entries[n]["params"])
        for key, value in read.get(n, {}).items():
            if value is not None and np.isfinite(value) and key in space.names:
                fp = next(f for f in space.free if f.name == key)
                start[key] = float(np.clip(value, fp.low, fp.high))
        starts.append(start)
    return starts


def _evidence_step(
    run: _Run,
    remaining: list[str],
    entries: dict[str, dict[str, Any]],
    current: dict[Any, np.ndarray],
    steps: list[dict[str, Any]],
) -> tuple | None:
    """The first step's other candidate: the group the evidence identifies together
    (:func:`evidence_group`) fitted jointly from the evidence's values (a joint refit on the
    subset, :func:`~stiffnet.measurement.fitting.fit_joint`) and tested against the base
    model with all its parameters, then each member against the group without it (the group
    is kept only when every member pays for itself). Returns what :func:`_joint_step`
    returns, or None."""
    group = evidence_group(run.evidence, remaining)
    if not group:
        return None
    run.bar.step(f"step 1: the evidence's {', '.join(group)} jointly")
    settings = settings_for(group)
    base = run.target.base_effects
    if settings not in current:
        current[settings] = run.target.per_recording(base, settings)
    before = current[settings]
    # each member refitted from its own design with the others held, then the Nelder-Mead:
    # from the evidence's values alone the local search stops short (a damped contact 0.25
    # behind a 237 Hz mount: 16.1 -> 0.62, where the refits reach the floor)
    joint = fit_joint(run.target, group, _group_start(run, group, entries), settings,
                      rounds=2, subset=SUBSET_SEARCH)  # fmt: skip
    after, params = np.asarray(joint["per_recording"]), joint["params"]
    floors = run.floors[settings]
    sig = significance(before, after, sum(map(len, joint["fitted"])), floors, run.names)
    reasons = [f"jointly with the evidence's {', '.join(group)}: {r}" for r in sig["reasons"]]
    for i, n in enumerate(group):  # each member against the group without it
        others = [m for m in range(len(group)) if m != i]
        without = run.target.per_recording(
            [*base, *_effects([group[m] for m in others], [params[m] for m in others])],
            settings,
        )
        sig_n = significance(without, after, len(joint["fitted"][i]), floors, run.names)
        reasons += [f"{n} on top of the rest of the evidence's group: {r}"
                    for r in sig_n["reasons"]]  # fmt: skip
    steps.append({
        "step": 0,
        "effect": "+".join(group),
        "effects": group,
        "proposed_by": "restoring-force evidence",
        "params": params,
        "discrepancy_before": campaign_discrepancy(before),
        "discrepancy_after": campaign_discrepancy(after),
        **{k: sig[k] for k in ("excess_reduction", "bootstrap_positive", "bic_delta")},
        "significant": not reasons,
        "reasons": reasons,
    })  # fmt: skip
    return None if reasons else (group, params, before, after, settings, sig)


def _accept(
    run: _Run, accepted: tuple, kept: list[str], entries: dict[str, dict[str, Any]]
) -> tuple[list[dict[str, float]], dict[Any, np.ndarray], dict[str, Any]]:
    """Select the accepted effect (``kept`` grows), profile the nuisances again and, when
    they moved, refit the selected effects on them. Returns the selected effects' values,
    the model's per-recording discrepancies (by settings) and the nuisances."""
    selected, params_new, before, after, settings, sig = accepted
    # one effect from a forward step, or the evidence's group (:func:`_evidence_step`)
    names = [selected] if isinstance(selected, str) else list(selected)
    step = len(kept)
    kept.extend(names)
    kept_params = [dict(p) for p in params_new]
    for i, n in enumerate(names):  # a group shares its step's numbers
        entries[n].update(
            selected=True,
            significant=True,
            reasons=[],
            selected_at_step=step,
            params=kept_params[step + i],
            discrepancy_reduction=campaign_discrepancy(before) - campaign_discrepancy(after),
            relative_reduction=sig["relative_reduction"],
            excess_reduction=sig["excess_reduction"],
            bootstrap_positive=sig["bootstrap_positive"],
            bic_delta=sig["bic_delta"],
        )
        if len(names) > 1:
            entries[n]["selected_with"] = [m for m in names if m != n]
    for name_k, p in zip(kept, kept_params, strict=True):  # joint values of the earlier ones
        entries[name_k]["params"] = p
    run.bar.end_of(1 + len(kept), f"step {len(kept)}: nuisances and initial states again")
    target = run.target
    before_profile = (list(target.rows), list(target.starts or []))
    nuisances = profile_nuisances(target, _effects(kept, kept_params), settings, run.nuisance_info)
    if (list(target.rows), list(target.starts or [])) != before_profile:
        # the nuisances moved (another orbit, another gap): refit the effects on them, locally
        # (ACCEPT_ROUNDS: a Nelder-Mead over all their coordinates from where the step that
        # selected them left them, after searching each from its own design)
        joint = fit_joint(
            target, kept, kept_params, settings, rounds=ACCEPT_ROUNDS, subset=SUBSET_SEARCH
        )
        kept_params = [dict(p) for p in joint["params"]]
        for name_k, p in zip(kept, kept_params, strict=True):
            entries[name_k]["params"] = p
    model = [*target.base_effects, *_effects(kept, kept_params)]
    return kept_params, {settings: target.per_recording(model, settings)}, nuisances


def _polish(
    run: _Run, kept: list[str], kept_params: list[dict[str, float]], entries: dict[str, Any]
) -> tuple[list[dict[str, float]], dict[str, Any] | None]:
    """The selected effects refitted jointly on every recording (a Nelder-Mead of
    :data:`POLISH_EVALUATIONS` evaluations, never worse than its start in the fits'
    objective, weighted by the floors). Returns their values and what the polish did (the
    campaign discrepancy before and after, evaluations, seconds and CPU seconds of this
    process), or None when there is nothing to polish or the model needs the numerical
    engine."""
    if not kept or POLISH_EVALUATIONS <= 0 or any(needs_numerical(n) for n in kept):
        return kept_params, None
    t, cpu = time.perf_counter(), time.process_time()
    settings = settings_for(kept)
    start = run.target.per_recording([*run.target.base_effects, *_effects(kept, kept_params)],
                                     settings)  # fmt: skip
    joint = fit_joint(run.target, kept, kept_params, settings, budget=POLISH_EVALUATIONS,
                      start=start, rounds=0)  # fmt: skip
    kept_params = [dict(p) for p in joint["params"]]
    for name_k, p in zip(kept, kept_params, strict=True):
        entries[name_k]["params"] = p
    return kept_params, {
        "before": campaign_discrepancy(start),
        "after": campaign_discrepancy(joint["per_recording"]),
        "evaluations": joint["evaluations"],
        "seconds": round(time.perf_counter() - t, 3),
        "cpu_seconds": round(time.process_time() - cpu, 3),
    }


def _conclude(
    run: _Run,
    kept: list[str],
    kept_params: list[dict[str, float]],
    entries: dict[str, dict[str, Any]],
    steps: list[dict[str, Any]],
    baseline: np.ndarray,
    nuisances: dict[str, Any],
    options: dict[str, Any],
    t0: float,
) -> dict[str, Any]:
    """The final model against every recording, the verdict, the learned-law proposal and
    the result (see :func:`diagnose_campaign`)."""
    bar, target, campaign, names = run.bar, run.target, run.campaign, run.names
    base_effects = run.base_effects
    bar.to(bar.total - 1, "the final model against every recording")
    settings = settings_for(kept)
    final_effects = [*base_effects, *_effects(kept, kept_params)]
    base_at = baseline if settings is FIT_SETTINGS else target.per_recording(base_effects, settings)
    final_stats = target.simulated_statistics(final_effects, settings)
    residual = target.discrepancies_of(final_stats)
    residual_where = [
        None if s is None else where_sums(m, s)
        for m, s in zip(target.measured, final_stats, strict=True)
    ]
    v = verdict(base_at, residual, run.floors[settings], kept, residual_where)
    bar.to(bar.total, "done")
    recordings = recording_verdicts(
        names, base_at, residual, run.floors[settings], target.measured, final_stats,
        nuisances.get("orbits"),
    )  # fmt: skip
    v["summary"] += (
        _above_note(recordings) + _orbit_warning(recordings) + _non_repeatable_note(recordings)
    )
    # the library lacks the physics: learn the contact law from the maps and score it
    learned = learned_law_proposal(
        campaign, run.rows, target, v, final_effects, residual,
        run.floors[FIT_SETTINGS_NUMERICAL], options["seed"],
    )  # fmt: skip
    ranking = _ranking(kept, entries)
    return {
        "baseline_discrepancy": campaign_discrepancy(baseline),
        "baseline_per_recording": baseline.tolist(),
        "noise_floor": run.floor_info["floor"],
        "noise_floor_per_recording": run.floor_info["per_recording"],
        "recordings": names,
        "base_effects": [e.name for e in base_effects],
        "ranking": ranking,
        "missing_effect": kept[0] if kept else None,
        "missing_effects": list(kept),
        "fitted_params": dict(zip(kept, kept_params, strict=True)),
        "selection": steps,
        "residual_per_recording": residual.tolist(),
        "per_recording": recordings,
        **v,
        "restoring_force": run.evidence,
        "learned_law": learned,
        "nuisances": nuisances,
        "settings": _settings_record(options),
        "seconds": round(time.perf_counter() - t0, 3),
    }


def _ranking(kept: list[str], entries: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """The selected effects in order, then the others by score; only selected ones are
    significant."""
    for n in kept:
        entries[n]["selected"] = True
    ranking = [entries[n] for n in kept] + sorted(
        (e for n, e in entries.items() if n not in kept),
        key=lambda e: (e["bic_delta"], -e["discrepancy_reduction"]),
    )
    for e in ranking:
        if not e.get("selected"):
            e["significant"] = False  # the only significant effects are the selected ones
    return ranking


def _settings_record(options: dict[str, Any]) -> dict[str, Any]:
    return {
        "seed": options["seed"],
        "budget": options["budget"],
        "budget_numerical": options["budget_numerical"] or DEFAULT_BUDGET_NUMERICAL,
        "periods": FIT_SETTINGS.periods,
        "periods_numerical": FIT_SETTINGS_NUMERICAL.periods,
        "inclination": options["inclination"],
        "objective": "campaign discrepancy (mean over recordings); effect off included",
        "rank_score": "N ln(D_effect / D_before) + k ln N",
    }


def recording_verdicts(
    names: Sequence[str],
    baseline: np.ndarray,
    residual: np.ndarray,
    floors: Floors,
    measured: Sequence[Any],
    simulated: Sequence[Any],
    orbits: Sequence[dict[str, Any]] | None,
) -> list[dict[str, Any]]:
    """Each recording judged against its own floor, with its orbit and the simulation's.

    Returns
    -------
    list of dict
        Per recording: ``recording``, ``floor``, ``baseline``, ``residual``, ``ratio``
        (residual over its floor), ``above_floor``, ``non_repeatable``, ``weight``,
        ``measured_orbit``, ``simulated_orbit``, ``orbit_matched`` (None when the measured
        orbit does not repeat), ``distinct_orbits`` and ``starts_on_measured_orbit`` (the
        starts profiled), ``note`` (words for the table).
    """
    ratios, eff = floors.ratios(residual), floors.effective()
    non_rep, weights = floors.non_repeatable(), floors.weights()
    out = []
    for i, name in enumerate(names):
        sim_orbit = orbit_name(simulated[i])
        want = orbit_pattern(measured[i])
        matched = None if want is None else orbit_pattern(simulated[i]) == want
        o = (orbits or [{}] * len(names))[i]
        notes = []
        if non_rep[i]:
            notes.append(
                "non-repeatable: its halves differ by "
                f"{floors.per_recording[i] / max(floors.median, 1e-300):.0f}x the campaign's "
                "median floor (wandering or chaotic orbit, long transient, near grazing)"
            )
        if matched is False:
            hits = o.get("starts_on_measured_orbit")
            notes.append(
                "simulated on another orbit than measured"
                + (" (no start reached the measured one)" if hits == 0 else "")
            )
        out.append(
            {
                "recording": name,
                "floor": float(eff[i]),
                "baseline": float(baseline[i]),
                "residual": float(residual[i]),
                "ratio": float(ratios[i]),
                "above_floor": bool(ratios[i] > AT_FLOOR_FACTOR),
                "non_repeatable": bool(non_rep[i]),
                "weight": float(weights[i]),
                "measured_orbit": orbit_name(measured[i]),
                "simulated_orbit": sim_orbit,
                "orbit_matched": matched,
                "distinct_orbits": o.get("distinct_orbits"),
                "starts_on_measured_orbit": o.get("starts_on_measured_orbit"),
                "note": "; ".join(notes),
            }
        )
    return out


def _above_note(recordings: Sequence[dict[str, Any]]) -> str:
    """Which repeatable recordings stay above their floors (whatever the verdict)."""
    above = [r for r in recordings if r["above_floor"] and not r["non_repeatable"]]
    if not above:
        return ""
    worst = sorted(above, key=lambda r: -r["ratio"])[:5]
    return (
        f". Above {AT_FLOOR_FACTOR:g}x their own floor: "
        + ", ".join(f"{r['recording']} ({r['ratio']:.1f}x)" for r in worst)
        + (" and others" if len(above) > 5 else "")
    )


def _orbit_warning(recordings: Sequence[dict[str, Any]]) -> str:
    """A sentence when no start reached a recording's measured orbit."""
    lost = [r["recording"] for r in recordings if r["starts_on_measured_orbit"] == 0]
    if not lost:
        return ""
    return (
        f". No start reached the measured orbit of {', '.join(lost[:5])}"
        + (" and others" if len(lost) > 5 else "")
        + ": more starts, or continuation from the measured state, are needed before "
        "concluding anything about physics there"
    )


def _non_repeatable_note(recordings: Sequence[dict[str, Any]]) -> str:
    n = sum(r["non_repeatable"] for r in recordings)
    if not n:
        return ""
    return (
        f". {n} of {len(recordings)} recordings are non-repeatable (their halves disagree "
        "more than the model does: wandering or chaotic orbits); they weigh less"
    )


def _unfitted(name: str, baseline: np.ndarray, floors: Floors) -> dict[str, Any]:
    """The ranking entry of a candidate not fitted because the base model is at the floor."""
    d = campaign_discrepancy(baseline)
    judged = floors.judge(baseline)
    return {
        "effect": name,
        "selected": False,
        "significant": False,
        "reasons": [
            f"nothing to explain: the base model is at the recordings' own noise floors "
            f"({judged['n_above']} of {judged['n']} above {AT_FLOOR_FACTOR:g}x theirs), so it "
            "was not fitted"
        ],
        "params": {},
        "fitted": [],
        "discrepancy_reduction": 0.0,
        "discrepancy": d,
        "baseline_discrepancy": d,
        "relative_reduction": 0.0,
        "excess_reduction": 0.0,
        "bic_delta": 0.0,
        "improves": False,
        "evaluations": 0,
        "seconds": 0.0,
        "engine": "numerical" if needs_numerical(name) else "closed_form",
    }


def _entry(fit: dict[str, Any], sig: dict[str, Any]) -> dict[str, Any]:
    before = np.array(fit["off_per_recording"])
    after = np.array(fit["per_recording"])
    return {
        "effect": fit["effect"],
        "selected": False,
        "significant": sig["significant"],
        "reasons": list(sig["reasons"]),
        "params": fit["params"],
        "fitted": fit["fitted"],
        "discrepancy_reduction": campaign_discrepancy(before) - campaign_discrepancy(after),
        "discrepancy": campaign_discrepancy(after),
        "baseline_discrepancy": campaign_discrepancy(before),
        **{k: v for k, v in sig.items() if k not in ("significant", "reasons")},
        "improves": fit["improves"],
        "per_recording": fit["per_recording"],
        "evaluations": fit["evaluations"],
        "seconds": fit["seconds"],
        "engine": fit["engine"],
    }


def _current(
    target: CampaignTarget,
    current: dict[Any, np.ndarray],
    kept: list[str],
    params: list[dict[str, float]],
    new: str,
) -> np.ndarray:
    """Per-recording discrepancies of the selected model at the settings ``new`` needs."""
    settings = settings_for([*kept, new])
    if settings not in current:
        current[settings] = target.per_recording(
            [*target.base_effects, *_effects(kept, params)], settings
        )
    return current[settings]


__all__ = ["candidate_effects", "diagnose_campaign", "evidence_group", "recording_verdicts"]

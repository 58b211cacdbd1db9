"""``diagnose`` proposes the contact law the library lacks, learned from the recordings.

When the library's effects leave a campaign ``partially_explained``
(:func:`should_propose`), :func:`propose_learned_law`
runs the contact-law discovery (:mod:`stiffnet.discovery`) on the campaign's
force-displacement maps and, when the law has terms outside the library, adds it
as a candidate: the ``learned_contact`` effect at the discovered values replaces
the library's contact effects (``contact_damping``, ``hertz_contact``: the law
holds its own dissipation), on top of the other selected effects or of none
(they may have stood in for the law), whichever fits better, and the campaign
is simulated with it; a preload the maps cannot resolve is then swept by simulation
(:mod:`.preload_by_simulation`). Reported: the law (equation, words, coefficients
with intervals, the term path), the discrepancy before and after over the
recordings the verdict counts (:func:`counted_recordings`) and over all, the share of
it removed, whether the rest is at the noise floor, and the force-penetration
map (data, library law, learned law) as compact data for the figure
(:func:`learned_law_figure`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.discovery import campaign_contact_samples, discover_contact_law
from stiffnet.discovery.face_candidate import face_in_question, series_betas
from stiffnet.discovery.samples import ContactSamples
from stiffnet.effects.base import Effect
from stiffnet.effects.learned_contact import LearnedContact, learned_contact_force
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.errors import StiffnetError
from stiffnet.measurement.discrepancy import campaign_discrepancy
from stiffnet.measurement.evaluation_pool import per_recording_many
from stiffnet.measurement.face_by_simulation import face_by_simulation, face_unknowns, refine_face
from stiffnet.measurement.fitting import fit_effect, objective_value
from stiffnet.measurement.noise_floor import Floors
from stiffnet.measurement.nuisance import N_STARTS
from stiffnet.measurement.preload_by_simulation import preload_applies, preload_by_simulation
from stiffnet.measurement.significance import significance
from stiffnet.measurement.target import FIT_SETTINGS_NUMERICAL
from stiffnet.restoring_force.chain import shared_chain_sheet

#: Residual groups where a contact law shows.
CONTACT_GROUPS = ("contact", "free_flight")
#: Effects the learned law replaces (it holds its own elastic law and dissipation).
REPLACED = ("contact_damping", "hertz_contact", "learned_contact")
#: Recordings (low, middle and high beta) and points per recording kept for the map figure.
MAP_RECORDINGS = 3
MAP_POINTS = 300
#: A chain start's low-pass corner standing for none (``sensor_dynamics``' largest corner:
#: above 0.45 fs the stage is skipped, and a searched corner is clipped to its top).
NO_LOWPASS_HZ = 1.0e5
#: The restraint's two accounts, as a refusal names them.
FACE_WORDS = {"face": "the rig's shared face", "face_scaled": "a face that scales with beta"}


def should_propose(verdict_info: dict[str, Any]) -> tuple[bool, str]:
    """Rule: the discovery runs on every partially explained campaign.

    Where the residual statistics lie is reported, not required: once the library's
    effects have stood in for a contact law (a damping at an implausible value, harmonics
    mimicking the spikes' shape), what is left may sit in the sensor band although the
    cause is the contact (an independent Hunt-Crossley rig: 45 % in contact and free
    flight). The discovery reads the contact itself and proposes only terms that pass its
    held-out test, so running it costs seconds and decides nothing by itself.
    """
    if verdict_info.get("verdict") != "partially_explained":
        return False, f"the verdict is {verdict_info.get('verdict')}: no law to learn"
    where = verdict_info.get("unexplained_where") or {}
    share = sum(float(where.get(g, 0.0)) for g in CONTACT_GROUPS)
    return True, f"{share:.0%} of what is left lies in the contact and the free flight"


def learned_law_proposal(
    campaign: Any,
    rows: Sequence[Any],
    target: Any,
    verdict_info: dict[str, Any],
    effects: Sequence[Effect],
    residual: np.ndarray,
    floor: Floors,
    seed: int = 0,
) -> dict[str, Any]:
    """diagnose's ``learned_law`` entry: :func:`propose_learned_law` where
    :func:`should_propose` says so, else why not (``ran`` False)."""
    run, why = should_propose(verdict_info)
    if not run:
        return {"ran": False, "proposed": False, "summary": why}
    out = propose_learned_law(campaign, rows, target, effects, residual, floor, seed)
    return {"ran": True, "why": why, **out}


def propose_learned_law(
    campaign: Any,
    rows: Sequence[Any],
    target: Any,
    effects: Sequence[Effect],
    residual: np.ndarray,
    floor: Floors,
    seed: int = 0,
) -> dict[str, Any]:
    """Discover the campaign's contact law and score the model with it (see the module notes).

    Parameters
    ----------
    campaign, rows
        The campaign and its resolved rows (diagnose's).
    target : CampaignTarget
        Diagnose's target (rows, measured statistics, nuisances).
    effects : sequence of Effect
        The diagnosed model (base effects and the selected ones).
    residual : numpy.ndarray
        Its per-recording discrepancy at diagnose's settings.
    floor : Floors
        The recordings' own noise floors at the numerical engine's settings: the rest is
        at the floor when no more recordings sit above theirs than chance allows.
    seed : int
        Seed of the discovery's folds and bootstrap.

    Returns
    -------
    dict
        ``proposed`` (bool), ``summary`` (one line), and when the discovery ran:
        ``law`` (:meth:`DiscoveredLaw.to_dict`), ``effect`` (name and params),
        ``replaces``, ``discrepancy_before``/``_after`` (the mean over the ``counted``
        recordings, :func:`counted_recordings`) and per recording (all),
        ``removed_fraction``, ``explained_fraction`` and ``removed_excess_fraction`` (see
        :func:`excess_shares`; the counted recordings), ``all_recordings``
        (:func:`law_change`), ``at_floor``, ``noise_floor``, ``map``, ``skipped``.
    """
    notes: list[str] = []  # the recordings' unit where it is not g
    lowpass: dict[str, Any] = {}  # a low-pass the maps were read through (profiled by the law)
    samples, skipped = campaign_contact_samples(campaign, rows, notes=notes, lowpass=lowpass)
    law = _discovered(samples, seed)
    if isinstance(law, str):
        return {"proposed": False, "summary": law, "skipped": skipped, "notes": notes}
    # a power law's beta is a secant at d_r: referred to the manifest's where it gives beta
    given = {g.recording: g.beta for g in campaign.rows}
    law = law.referred_to([given.get(name) for name in law.recordings])
    out: dict[str, Any] = {"law": law.to_dict(), "skipped": skipped, "notes": notes,
                           "map": law_map(samples, law)}  # fmt: skip
    if lowpass:
        out["maps_lowpass"] = lowpass
    if not law.new and not face_in_question(law):
        out.update(proposed=False, summary=(
            f"the learned contact law has nothing the library lacks ({law.words})"))  # fmt: skip
        return out
    settings = FIT_SETTINGS_NUMERICAL
    before = residual if _numerical(effects) else target.per_recording(list(effects), settings)
    # the law in place of the library's contact effects, or of every selected effect (they
    # may have stood in for it): the better of the two
    base = {id(e) for e in target.base_effects}
    models = [[e for e in effects if e.name not in REPLACED],
              [e for e in effects if id(e) in base and e.name not in REPLACED]]  # fmt: skip
    models = [with_maps_lowpass(m, lowpass) for m in models]
    rows_law = law_rows(campaign, target.rows, law)
    if not law.new:  # the maps saw a restraint with dynamics and could not decide its face
        face = face_by_simulation(samples, law, target, rows_law, models, before, floor, settings)
        out.update(_face_entries(face, law, samples, rows_law))
        if not face["significant"]:
            return out
        law, params, after = face["law"], face["params"], np.asarray(face["per_recording"])
        kept, refit = models[face["model"]], face["refit"]
    else:
        after, kept, params, refit, target = _law_scored(target, rows_law, models, law, settings)
        model = kept
        chain = chain_refit_with_law(target, rows_law, kept, params, after, settings, floor)
        if chain is not None:
            out["chain_refit"] = {k: v for k, v in chain.items() if k != "model"}
            if chain["improves"]:
                model, after = chain["model"], np.asarray(chain["per_recording"], float)
        if preload_applies(params):  # a preload the maps cannot resolve, by simulation
            pre = preload_by_simulation(target, rows_law, model, params, after, floor, settings)
            out["preload_by_simulation"] = {k: v for k, v in pre.items() if k != "params"}
            if pre["significant"]:
                law, params = law.with_preload(pre["preload"]), pre["params"]
                after = np.asarray(pre["per_recording"], float)
                out.update(law=law.to_dict(), map=law_map(samples, law))
    before, after = np.asarray(before, dtype=float), np.asarray(after, dtype=float)
    counted = np.flatnonzero(counted_recordings(floor))
    d0, d1 = campaign_discrepancy(before[counted]), campaign_discrepancy(after[counted])
    removed = float((d0 - d1) / d0) if d0 > 0 else 0.0
    rest = floor.at_floor(after)
    base_model = list(target.base_effects)
    same = len(base_model) == len(effects) and all(
        a is b for a, b in zip(base_model, effects, strict=True)
    )
    baseline = before if same else np.asarray(target.per_recording(base_model, settings))
    shares = excess_shares(floor.subset(counted), baseline[counted], before[counted],
                           after[counted])  # fmt: skip
    out.update(
        proposed=bool(d1 < d0),
        counted=len(counted),
        all_recordings=law_change(floor, rows, before, after),
        effect={"name": LearnedContact.name, "params": params},
        refit=refit,
        replaces=[e.name for e in effects if all(e is not k for k in kept)],
        discrepancy_before=d0,
        discrepancy_after=d1,
        before_per_recording=np.asarray(before).tolist(),
        after_per_recording=np.asarray(after).tolist(),
        removed_fraction=removed,
        **shares,
        at_floor=rest,
        noise_floor=floor.median,
    )
    out["summary"] = _proposal_summary(law, out, floor.median)
    return out


def counted_recordings(floor: Floors) -> np.ndarray:
    """The recordings the law's comparison counts: the repeatable ones, as the verdict's floor
    test counts them (:meth:`Floors.judge`; every recording where none is repeatable).

    A non-repeatable recording (its halves differ by more than
    :data:`~stiffnet.measurement.noise_floor.NON_REPEATABLE_FACTOR` times the campaign's
    median floor: a wandering orbit, near-grazing impacts) is as sensitive to the law as to
    its own noise: behind a 250 Hz low-pass, a power law learned with its exponent read high
    (1.71 for 1.6) took 23 of 24 recordings down, the 22 repeatable ones from 5.65 to 1.42,
    and one near-grazing recording (beta 83 at a 0.5 mm gap) from 21.9 to 179, which alone
    raised the campaign's mean from 6.15 to 8.77.
    """
    keep = ~floor.non_repeatable()
    return keep if keep.any() else np.ones_like(keep)


def law_change(
    floor: Floors, rows: Sequence[Any], before: np.ndarray, after: np.ndarray
) -> dict[str, Any]:
    """The law's change over every recording, the non-repeatable ones included: the mean
    before and after, on how many recordings it is lower, and the recordings it raises most
    (up to three, with whether they are counted)."""
    counted = counted_recordings(floor)
    up = [i for i in np.argsort(before - after) if after[i] > before[i]][:3]
    return {
        "discrepancy_before": campaign_discrepancy(before),
        "discrepancy_after": campaign_discrepancy(after),
        "n": len(before),
        "lower_on": int(np.sum(after < before)),
        "raised": [
            {
                "recording": rows[i].recording,
                "before": float(before[i]),
                "after": float(after[i]),
                "counted": bool(counted[i]),
            }
            for i in up
        ],  # fmt: skip
    }


def _discovered(samples: Sequence[ContactSamples], seed: int) -> Any:
    """The campaign's discovered law, or the one-line reason none was learned."""
    try:
        return discover_contact_law(samples, seed=seed)
    except StiffnetError as exc:
        return f"no contact law learned: {exc}"
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        # a fit that breaks numerically is a missing proposal, never a failed diagnosis
        return f"no contact law learned: the fit failed numerically ({type(exc).__name__})"


def _proposal_summary(law: Any, out: dict[str, Any], floor_median: float) -> str:
    """The proposal in one line: the law, the discrepancy before and after, what is left."""
    floor_words = (
        "at the noise floor"
        if out["at_floor"]
        else f"above the recordings' noise floors (median {floor_median:.3g})"
    )
    d0, d1 = out["discrepancy_before"], out["discrepancy_after"]
    whole = out["all_recordings"]
    which = (
        "" if out["counted"] == whole["n"] else f" of the {out['counted']} repeatable recordings"
    )
    summary = (
        f"learned contact law: {law.equation}; {law.words}. With it the discrepancy{which} goes "
        f"from {d0:.3g} to {d1:.3g} ({out['removed_fraction']:.0%} removed; it explains "
        f"{out['explained_fraction']:.0%} of the base model's excess over the recordings' "
        f"floors), the rest {floor_words}"
    )
    if which:  # the non-repeatable ones are reported, as the verdict reports them
        raised = "; ".join(
            f"{r['recording']} {r['before']:.3g} to {r['after']:.3g}"
            + ("" if r["counted"] else " (non-repeatable)")
            for r in whole["raised"]
        )
        summary += (
            f". Over all {whole['n']} the mean goes from {whole['discrepancy_before']:.3g} to "
            f"{whole['discrepancy_after']:.3g}, lower on {whole['lower_on']}"
            + (f"; raised: {raised}" if raised else "")
        )
    chain = out.get("chain_refit") or {}
    if chain.get("improves"):  # the selection's chain was fitted with the library's contact
        c = chain["params"]
        how = (
            "fitted with the law from the restoring-force evidence's (none was selected)"
            if chain.get("source") == "evidence"
            else "refitted with the law"
        )
        summary += (
            f". The sensor chain {how}: resonance {c['resonance_hz']:.4g} Hz "
            f"(damping {c['resonance_damping']:.2g}), low-pass {c['lowpass_hz']:.4g} Hz, "
            f"high-pass {c['highpass_hz']:.3g} Hz"
        )
    pre = out.get("preload_by_simulation") or {}
    if pre.get("significant"):  # the maps do not resolve a preload; the orbits do
        summary += (
            f". The preload ({pre['preload']:.3g} model lengths) was found by simulating the "
            "campaign: the maps do not resolve it"
        )
    if out.get("unknowns"):  # a face the maps refused, kept by the simulation
        summary += (
            ". The face was decided by simulating the campaign (the maps' held-out test refused "
            f"it); not known: {'; '.join(out['unknowns'])}"
        )
    return summary


def _face_entries(
    face: dict[str, Any], law: Any, samples: Sequence[ContactSamples], rows: Sequence[Any]
) -> dict[str, Any]:
    """The proposal's entries from a face decided by simulation: refused (``proposed`` False
    and why), or the face law with its map, series betas and what it leaves unknown."""
    out: dict[str, Any] = {"face_by_simulation": {k: v for k, v in face.items() if k != "law"}}
    if not face["significant"]:
        why = "; ".join(
            f"{FACE_WORDS[f['term']]}: {'; '.join(f['significance']['reasons'])}"
            for f in (face.get("refused_first"), face)
            if f is not None
        )
        out.update(proposed=False, summary=(
            f"the learned contact law has nothing the library lacks ({law.words}); a face "
            f"simulated on the campaign was refused ({why})"))  # fmt: skip
        return out
    chosen, params = face["law"], face["params"]
    out.update(law=chosen.to_dict(), map=law_map(samples, chosen),
               unknowns=face_unknowns(chosen, rows, params),
               series_betas=series_betas(chosen.betas, params))  # fmt: skip
    return out


def _law_scored(
    target: Any, rows_law: Sequence[Any], models: list[list[Effect]], law: Any, settings: Any
) -> tuple[np.ndarray, list[Effect], dict[str, float], dict[str, Any] | None, Any]:
    """The discovered law simulated on each model, each recording from the start that suits
    it (:func:`starts_for_law`; the better model by the fits' objective kept, as
    :func:`refine_face` judges: a non-repeatable recording weighed down) and, with a face,
    refitted by simulation: per-recording discrepancy, model, params, refit, and the target
    with the kept model's starts (what the law's later fits start from)."""
    learned = LearnedContact(**law.effect_params)
    trials = [starts_for_law(target, rows_law, [*m, learned], settings) for m in models]
    best = int(np.argmin([objective_value(t[1], target.weights) for t in trials]))
    (starts, after), kept = trials[best], models[best]
    target = replace(target, starts=starts)
    refit, params = None, law.effect_params
    if float(params.get("face_mass", 0.0)) > 0:
        refit = refine_face(target, rows_law, kept, params, after, settings)
        if refit["improves"]:
            params, after = refit["params"], np.asarray(refit["per_recording"])
    return after, kept, params, refit, target


def starts_for_law(
    target: Any, rows_law: Sequence[Any], model: Sequence[Effect], settings: Any
) -> tuple[list[int], np.ndarray]:
    """Each recording's initial state profiled for ``model`` (of the
    :data:`~stiffnet.measurement.nuisance.N_STARTS` starts, the one whose simulation matches
    the recording best; the target's own where it ties) and the per-recording discrepancy
    there.

    The target's starts were profiled for the library's model, and a law that changes the
    impacts moves the orbits: behind a 250 Hz low-pass, a power law (the rig's own, through
    the rig's own chain) scored 3.82 at them against the linear law's 5.02, and 1.72 with
    each recording's start profiled for it (one recording 43.5 -> 5.1); the linear law had
    its starts profiled for it.
    """
    n = len(rows_law)
    held = np.asarray(target.starts if target.starts is not None else [0] * n, dtype=int)
    calls = [(list(model), settings, {"rows": list(rows_law), "starts": [k] * n})
             for k in range(N_STARTS)]  # fmt: skip
    pers = np.vstack(per_recording_many(target, calls))
    cols = np.arange(n)
    best = np.argmin(pers, axis=0)
    starts = np.where(pers[best, cols] < pers[held, cols], best, held)
    return [int(k) for k in starts], pers[starts, cols]


def with_maps_lowpass(model: Sequence[Effect], lowpass: dict[str, Any]) -> list[Effect]:
    """``model`` with the low-pass the maps were read through (:func:`~stiffnet.discovery.
    lowpass_profile.profiled_lowpass`) as its ``sensor_dynamics``, where it has none (a
    selected chain was fitted by simulation and stays; its refit with the law follows).

    The maps' low-pass is the sensor's, read with the law the campaign is scored with; a
    model without it compares unfiltered spikes with filtered ones (behind a 250 Hz
    low-pass the rig's own power law removed 34 % of the discrepancy without its chain, 66 %
    with it)."""
    if not lowpass or any(e.name == SensorDynamics.name for e in model):
        return list(model)
    return [*model, maps_chain(lowpass)]


def maps_chain(lowpass: dict[str, Any]) -> SensorDynamics:
    """The ``sensor_dynamics`` effect of a low-pass the maps were read through: that corner
    and order, no high-pass, and no resonance (at the parameter's top, far above any band a
    rig's recording passes: a stage at or above 0.45 fs is skipped)."""
    top = float(SensorDynamics.Params.model_fields["resonance_hz"].json_schema_extra["le"])
    return SensorDynamics(
        resonance_hz=top, highpass_hz=0.0,
        lowpass_hz=float(lowpass["lowpass_hz"]), lowpass_order=float(lowpass["lowpass_order"]),
    )  # fmt: skip


def chain_refit_with_law(
    target: Any,
    rows_law: Sequence[Any],
    model: Sequence[Effect],
    params: dict[str, float],
    at_law: np.ndarray,
    settings: Any,
    floor: Floors | None = None,
) -> dict[str, Any] | None:
    """The selected sensor chain refitted with the learned law in place of the library's
    contact; where none was selected, a chain fitted with the law from the restoring-force
    evidence's (:func:`evidence_chain_starts`); None where the model has no
    ``sensor_dynamics`` and the evidence no resonance.

    The chain was fitted by simulation with the library's linear contact, and a contact that
    stiffens shapes each spike as a chain would: on the held-out two-stage campaign behind a
    240 Hz mount the selection read 180.8 Hz (damping 0.065) with a 248 Hz first-order
    low-pass and a 0.67 Hz high-pass, and the learned hinge through it removed 47 % of the
    discrepancy, through the rig's own mount 99 % (the rig's law through the fitted chain 47 %:
    the chain was the whole remainder). The refit starts from the selected chain (the same
    fit diagnose's selection runs, :func:`~stiffnet.measurement.fitting.fit_effect`, the
    law's motion shared by every evaluation) and is kept where it lowers the fits' objective.

    Where the selection kept no chain, the law is scored without one, and a restraint's face
    or nothing at all stands for the mount's ringing the records carry. The chain the
    restoring-force evidence identified is the start then (and its variants without its
    low-pass or high-pass: the evidence's chain fit reads a contact the library lacks as a
    low-pass, and such a pair is refuted as a whole), and the chain is kept as a diagnosed
    effect is, where it passes :func:`~stiffnet.measurement.significance.significance`
    against the law alone (``floor``; without one, where it lowers the objective).

    Returns
    -------
    dict or None
        ``improves``, ``params`` (the chain's), ``before`` and ``after`` (its parameters and the
        objective), ``per_recording``, ``model`` (the model with the refitted chain),
        ``fitted``, ``evaluations``, ``seconds``, ``source`` (``"selection"`` or
        ``"evidence"``) and, from the evidence, ``significance``.
    """
    chain = [e for e in model if e.name == SensorDynamics.name]
    starts = [chain[0].params.model_dump()] if chain else evidence_chain_starts(target.sensor)
    if not starts:
        return None
    others = [e for e in model if e.name != SensorDynamics.name]
    learned = LearnedContact(**params)
    tgt = replace(target, rows=list(rows_law), base_effects=[])
    start = starts[0]
    fit = fit_effect(tgt, SensorDynamics.name, [*others, learned], settings, seeds=starts)
    per = np.asarray(fit["per_recording"], float)
    o0, o1 = objective_value(np.asarray(at_law, float), target.weights), objective_value(
        per, target.weights)  # fmt: skip
    refitted = SensorDynamics(**fit["params"])
    improves, extra = bool(o1 < o0), {"source": "selection"}
    if not chain:  # a new effect: it must pay for its parameters, as a diagnosed one does
        extra = {"source": "evidence"}
        if floor is not None:
            names = [r.recording for r in rows_law]
            sig = significance(np.asarray(at_law, float), per, len(fit["fitted"]), floor, names)
            extra["significance"] = {k: sig[k] for k in ("excess_reduction", "bic_delta",
                                                         "reasons")}  # fmt: skip
            improves = improves and bool(sig["significant"])
    return {
        **extra,
        "improves": improves,
        "params": {k: float(v) for k, v in fit["params"].items()},
        "fitted": list(fit["fitted"]),
        "before": {"params": {k: float(v) for k, v in start.items()}, "objective": o0},
        "after": {"objective": o1},
        "per_recording": per.tolist(),
        "model": [*others, refitted],
        "evaluations": fit["evaluations"],
        "seconds": fit["seconds"],
    }


def evidence_chain_starts(sensor: dict[str, Any] | None) -> list[dict[str, float]]:
    """The starts of a chain fitted with the learned law where the selection kept none: the
    restoring-force evidence's shared chain (:func:`~stiffnet.restoring_force.chain.shared_chain`,
    refuted or not: a refuted chain still seeds ``sensor_dynamics``) as a data sheet, then
    without its low-pass, without its high-pass, and without both; none without a resonance
    (a low-pass alone is what a stiffening or dissipative contact reads as).

    Behind a 260 Hz mount, a Hunt-Crossley contact's three chain fits shared the mount's
    259 Hz with a 46 Hz low-pass the rig lacks: the pair was refuted as a whole, the
    resonance is the mount's.
    """
    sheet = shared_chain_sheet(sensor)
    if sheet is None or not sheet["resonance_hz"]:
        return []
    # no low-pass: the corner at the top of its search (a stage at 0.45 fs or above is
    # skipped), for a corner of 0 would be read as the bottom of a searched corner
    off = NO_LOWPASS_HZ
    variants = [sheet, {**sheet, "lowpass_hz": off}, {**sheet, "highpass_hz": 0.0},
                {**sheet, "lowpass_hz": off, "highpass_hz": 0.0}]  # fmt: skip
    out: list[dict[str, float]] = []
    for v in variants:
        v = {**v, "lowpass_order": float(v["lowpass_order"] or 2.0)}
        v["lowpass_hz"] = v["lowpass_hz"] or off
        if v not in out:
            out.append(v)
    return out


def excess_shares(
    floor: Floors, baseline: np.ndarray, before: np.ndarray, after: np.ndarray
) -> dict[str, float]:
    """The law's shares of the discrepancy as the verdict counts it: the weighted excess of
    each recording over its own floor (:meth:`Floors.excess`).

    A campaign's mean discrepancy is led by a few recordings: non-repeatable ones (their
    halves differ more than any model does) and ones whose orbit no start reached. On the
    independent rig's two-stage campaign (24 recordings, docs/measurement_loop.md) the law
    put 19 recordings within twice their floors while the mean fell by only 69 %: four
    recordings (two non-repeatable, two on an orbit no start reached) held most of the rest.

    Returns
    -------
    dict
        ``explained_fraction``: of the base model's excess (the verdict's
        ``explained_fraction``, for the law); ``removed_excess_fraction``: of the excess
        the library's selection left.
    """

    def share(ref: np.ndarray) -> float:
        e_ref, e_after = floor.excess(np.asarray(ref, float)), floor.excess(np.asarray(after))
        return float(np.clip(1.0 - e_after / e_ref, 0.0, 1.0)) if e_ref > 0 else 0.0

    return {"explained_fraction": share(baseline), "removed_excess_fraction": share(before)}


def law_rows(campaign: Any, rows: Sequence[Any], law: Any) -> list[Any]:
    """The rows to simulate the law on: a recording without a manifest beta takes the law's
    (the β diagnose profiled there belongs to the library's linear law, another quantity
    for a nonlinear one: docs/crosscheck.md, "Beta for a nonlinear contact law")."""
    betas = dict(zip(law.recordings, law.betas, strict=True))
    out = []
    for given, row in zip(campaign.rows, rows, strict=True):
        b = betas.get(row.recording)
        out.append(row.model_copy(update={"beta": b}) if given.beta is None and b else row)
    return out


def _numerical(effects: Sequence[Effect]) -> bool:
    return any(e.kind == "dynamics" and not e.closed_form for e in effects)


def law_map(samples: Sequence[ContactSamples], law: Any) -> list[dict[str, Any]]:
    """Force against penetration of a few recordings: data, library law and learned law."""
    order = np.argsort(law.betas)
    picks = sorted(
        {int(order[k]) for k in np.linspace(0, len(order) - 1, MAP_RECORDINGS).round().astype(int)}
    )
    out = []
    for r in picks:
        s = samples[r]
        step = max(1, s.force.size // MAP_POINTS)
        x, v, f = s.displacement[::step], s.velocity[::step], s.force[::step]
        delta = x - law.onsets[r]
        learned = learned_contact_force(delta, v, law.betas[r], law.params)
        library = (
            learned_contact_force(
                x - law.library_onsets[r], v, law.library_betas[r], law.library_params
            )
            if law.library_params
            else np.zeros_like(f)
        )
        out.append({
            "recording": s.recording, "beta": float(law.betas[r]),
            "penetration": np.round(delta, 5).tolist(), "force": np.round(f, 4).tolist(),
            "learned": np.round(learned, 4).tolist(), "library": np.round(library, 4).tolist(),
        })  # fmt: skip
    return out


def learned_law_figure(proposal: dict[str, Any], path: str | Path) -> Path:
    """The force-penetration map of :func:`law_map`: measured samples, library law, learned law."""
    from stiffnet.inputs import mpl_text
    from stiffnet.measurement.plots import _plt, _save

    plt = _plt()
    maps = proposal.get("map") or []
    fig, axes = plt.subplots(1, max(1, len(maps)), figsize=(4 * max(1, len(maps)), 3.4))
    axes = np.atleast_1d(axes)
    for ax, m in zip(axes, maps, strict=False):
        d = np.asarray(m["penetration"])
        i = np.argsort(d)
        ax.plot(d, m["force"], ".", ms=2.5, color="0.4", label="measured (restoring force)")
        ax.plot(d[i], np.asarray(m["library"])[i], "x", ms=3, color="tab:blue",
                label="library's best law")  # fmt: skip
        ax.plot(d[i], np.asarray(m["learned"])[i], "o", ms=2, mfc="none", color="tab:red",
                label="learned law")  # fmt: skip
        ax.set_title(f"{mpl_text(m['recording'])} (law's beta {m['beta']:.3g})", fontsize=8)
        ax.set_xlabel("penetration delta [model length]")
        ax.set_ylabel("contact force [model units]")
        ax.axvline(0, color="k", lw=0.5)
    axes[0].legend(fontsize=7)
    law = proposal.get("law") or {}
    fig.suptitle(law.get("equation", ""), fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def learned_law_html(proposal: dict[str, Any] | None, png: Path) -> list[str]:
    """The report's section on the learned law (nothing when the discovery did not run)."""
    import html

    from stiffnet.measurement.report import _img

    if not proposal or not proposal.get("ran"):
        return []
    parts = ["<h3>Learned contact law</h3>", f"<p>{html.escape(proposal['summary'])}.</p>"]
    law = proposal.get("law")
    if law:
        path = " &rarr; ".join(
            f"{html.escape(s['term'])} ({'in' if s['entered'] else 'out'}, explains "
            f"{s['explained_fraction']:.1%})"
            for s in law["path"]
        )
        parts.append(f"<p>Term path: {path}.</p>")
        recs = ", ".join(str(m.get("recording")) for m in proposal.get("map") or [])
        alt = (f"Contact force against penetration for {recs or 'no recording'}: the measured "
               f"restoring force (grey dots), the library's best law (blue crosses) and the "
               f"learned law {law.get('equation', '')} (red circles).")  # fmt: skip
        parts.append(_img(learned_law_figure(proposal, png), alt))
    return parts


def with_learned_law(added: list[dict[str, Any]], diagnosis: dict[str, Any] | None) -> list[dict]:
    """The loop's effects to add, with the diagnosis's learned law where it proposed one.

    The law enters like any diagnosed effect (its discovered values, the non-neutral ones
    fitted, so the loop's prior is centred on them) and replaces the library's contact
    effects (it holds its own dissipation; two elastic laws cannot run together).
    """
    learned = (diagnosis or {}).get("learned_law") or {}
    if not learned.get("proposed"):
        return added
    params = {k: float(v) for k, v in learned["effect"]["params"].items()}
    fitted = [k for k, v in params.items()
              if k in LearnedContact.neutral and v != LearnedContact.neutral[k]] + [
              k for k in ("knee",) if "hinge" in learned["law"]["terms"]]  # fmt: skip
    fitted += ["face_stiffness"] if "face" in learned["law"]["terms"] else []
    face = bool({"face", "face_scaled"} & set(learned["law"]["terms"]))
    fitted += ["face2_stiffness"] if "face2" in learned["law"]["terms"] else []
    # a law with its own face replaces a library restraint with a mass (two faces would add)
    gone = {*REPLACED, *learned.get("replaces", []), *(["restraint_mass"] if face else [])}
    keep = [with_refitted_chain(a, learned) for a in added if a["name"] not in gone]
    keep += evidence_chain_entry(keep, learned)
    lowpass = learned.get("maps_lowpass")
    if lowpass and all(a["name"] != SensorDynamics.name for a in keep):
        # the law was read and scored through the sensor's low-pass: the loop's world has it,
        # as the proposal's chain refit left it where that lowered the fits' objective
        chain = maps_chain(lowpass).params.model_dump()
        refit = learned.get("chain_refit") or {}
        origin = "the low-pass the maps were read through"
        if refit.get("improves"):
            chain = {**chain, **{k: float(v) for k, v in refit["params"].items()}}
            origin += ", refitted with the learned law"
        keep.append({"name": SensorDynamics.name, "params": chain, "fitted": sorted(
            {"lowpass_hz", *(refit["params"] if refit.get("improves") else [])}),
            "source": "diagnosis", "origin": origin, "maps_lowpass": dict(lowpass)})  # fmt: skip
    return [*keep, {"name": LearnedContact.name, "params": params, "fitted": fitted,
                    "source": "diagnosis", "origin": "contact-law discovery",
                    "replaces": sorted(gone)}]  # fmt: skip


def with_refitted_chain(entry: dict[str, Any], learned: dict[str, Any]) -> dict[str, Any]:
    """A diagnosed sensor chain's loop entry centred on the chain refitted with the learned
    law in place (:func:`chain_refit_with_law`), where that refit lowered the fits'
    objective: the selection's own values were read through the library's contact, which
    the law replaces in the loop's world. The selection's values stay as
    ``linear_contact_fit``."""
    refit = learned.get("chain_refit") or {}
    if entry["name"] != SensorDynamics.name or not refit.get("improves"):
        return entry
    params = {**entry["params"], **{k: float(v) for k, v in refit["params"].items()}}
    return {**entry, "params": params, "linear_contact_fit": entry["params"],
            "origin": "refitted with the learned law"}  # fmt: skip


def evidence_chain_entry(
    added: list[dict[str, Any]], learned: dict[str, Any]
) -> list[dict[str, Any]]:
    """The loop's entry of a chain the proposal fitted with the learned law from the
    restoring-force evidence's where the selection kept none (:func:`chain_refit_with_law`,
    ``source`` ``"evidence"``, kept by its test): one entry, or none."""
    refit = learned.get("chain_refit") or {}
    if (refit.get("source") != "evidence" or not refit.get("improves")
            or any(a["name"] == SensorDynamics.name for a in added)):  # fmt: skip
        return []
    params = {k: float(v) for k, v in refit["params"].items()}
    fitted = list(refit.get("fitted") or params)
    return [{"name": SensorDynamics.name, "params": params, "fitted": fitted,
             "source": "diagnosis", "origin": "fitted with the learned law from the "
             "restoring-force evidence's chain"}]  # fmt: skip


def replaced_by(added: list[dict[str, Any]]) -> set[str]:
    """Effects of earlier iterations that the added ones replace (a learned law: the
    library's contact effects)."""
    return {n for a in added if a["name"] == LearnedContact.name for n in a.get("replaces", [])}

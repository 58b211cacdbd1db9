"""A face the maps cannot decide on, decided by simulating the campaign with it.

Where the discovery sees a restraint with dynamics but refuses its face
(:func:`stiffnet.discovery.face_candidate.face_in_question`: at the rig's rates a
tip's second mode aliases into the measured force the face is driven by), the
face becomes a candidate like any diagnosed effect: ``learned_contact`` with the
face, started from the maps' own face fit and from a coarse grid of faces
(:func:`~stiffnet.discovery.face_candidate.face_grid`), all simulated as one
batch on the campaign as a screen (:func:`~stiffnet.measurement.fitting.screen_settings`:
a numerical-engine design's shorter transient begun warm; on the beam campaign it picked
the same grid point as the full transient); the best point is scored again alone in full,
refitted by the
face's sweep (:func:`refine_face`, which also refits a face the discovery kept), and kept
only where it passes the tests every diagnosed effect must
(:func:`~stiffnet.measurement.significance.significance`: it lowers the
discrepancy beyond the recordings' noise floors, for most recordings, and pays
for its parameters). The betas are then read on the maps behind the chosen face
(:func:`~stiffnet.discovery.face_candidate.betas_behind_face`).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from stiffnet.campaign.simulate import natural_frequency
from stiffnet.discovery.face_candidate import (
    betas_behind_face,
    face_grid,
    maps_face_law,
    series_betas,
)
from stiffnet.discovery.law import DiscoveredLaw
from stiffnet.discovery.samples import ContactSamples
from stiffnet.effects.base import Effect
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.measurement.discrepancy import campaign_discrepancy
from stiffnet.measurement.fitting import screen_settings
from stiffnet.measurement.noise_floor import Floors
from stiffnet.measurement.significance import significance

#: Parameters a one-mode face adds (mass, stiffness, damping).
FACE_PARAMETERS = 3
#: The face's parameters: the report gives them, and the refit (:func:`refine_face`) sweeps
#: them one after the other, each across its box (:meth:`LearnedContact.fit_space_at`) on a
#: grid of this many points simulated as one batch with the best point so far (the objective
#: is rough: the face's ringing locks the impacts onto one orbit or another, so a local step
#: misses what a sweep finds).
FACE_KEYS = ("face_mass", "face_stiffness", "face_damping")
FACE_REFIT_GRID = 7


def face_by_simulation(
    samples: Sequence[ContactSamples],
    law: DiscoveredLaw,
    target: Any,
    rows: Sequence[Any],
    models: Sequence[Sequence[Effect]],
    before: np.ndarray,
    floor: Floors,
    settings: Any,
) -> dict[str, Any]:
    """Decide by simulation whether the campaign's restraint has a face (module notes).

    Parameters
    ----------
    samples : sequence of ContactSamples
        The campaign's restoring-force maps (the discovery's).
    law : DiscoveredLaw
        The discovery's law (nothing new, its face refused on the maps).
    target : CampaignTarget
        diagnose's target; ``rows``: its rows with the law's betas where the manifest has none.
    models : sequence of sequences of Effect
        The models the face may join (the diagnosed selection without the library's contact
        effects, and the base model alone: the selection may have stood in for the face).
    before : numpy.ndarray
        Per-recording discrepancy of the diagnosed model (what the face must lower).
    floor : Floors
        The recordings' own floors at ``settings``.
    settings : SolverSettings
        The numerical engine's settings.

    Returns
    -------
    dict
        ``significant`` (bool), ``law`` (the face law with the betas behind the chosen face,
        or None), ``params``, ``model`` (index into ``models``), ``per_recording``,
        ``significance``, ``maps_face``, ``grid_best``, ``refit``, ``seconds``.
    """
    t0 = time.perf_counter()
    maps = maps_face_law(samples, law.path)
    start = maps.effect_params
    points = [start, *({**start, **g} for g in face_grid(law.betas))]
    tgt = replace(target, rows=list(rows))
    # every point on every model as one batch each, a screen: the batch draws other noise per
    # point and runs the numerical-engine design's shorter transient begun warm, so the best
    # is scored again alone, in full (the noise and transient of per_recording)
    scored = []
    for i, m in enumerate(models):
        if any(_same(m, o) for o in models[:i]):
            continue  # the same model twice (the selection held only contact effects)
        pers = tgt.per_recording_points(list(m), LearnedContact.name, points,
                                        screen_settings(settings), inclination=False,
                                        oversample=False)  # fmt: skip
        scored += [(campaign_discrepancy(p), i, j) for j, p in enumerate(pers)]
    _, mi, pj = min(scored)
    model, point = list(models[mi]), points[pj]
    alone = tgt.per_recording([*model, LearnedContact(**point)], settings)
    refit = refine_face(tgt, rows, model, point, alone, settings)
    params = refit["params"] if refit["improves"] else point
    after = np.asarray(refit["per_recording"] if refit["improves"] else alone, float)
    names = [r.recording for r in rows]
    sig = significance(before, after, FACE_PARAMETERS, floor, names)
    chosen = {k: float(params[k]) for k in FACE_KEYS}
    face_law = betas_behind_face(samples, maps, chosen) if sig["significant"] else None
    return {
        "significant": bool(sig["significant"]),
        "law": face_law,
        "params": params,
        "model": mi,
        "per_recording": after.tolist(),
        "discrepancy": campaign_discrepancy(after),
        "significance": {k: sig[k] for k in ("excess_reduction", "bic_delta", "reasons")},
        "maps_face": {k: float(start[k]) for k in FACE_KEYS}
        | {"explained_fraction": maps.explained_fraction},
        "grid_best": {k: float(point[k]) for k in FACE_KEYS},
        "grid_discrepancies": [float(d) for d, i, _ in scored if i == mi],
        "refit": {
            k: refit[k]
            for k in ("improves", "discrepancy_discovered", "discrepancy_refit", "seconds")
        },  # fmt: skip
        "seconds": round(time.perf_counter() - t0, 2),
    }


def _same(a: Sequence[Effect], b: Sequence[Effect]) -> bool:
    return len(a) == len(b) and all(x is y for x, y in zip(a, b, strict=True))


def face_unknowns(law: DiscoveredLaw, rows: Sequence[Any], params: dict[str, float]) -> list[str]:
    """What a face chosen by simulation leaves unknown, in words (the proposal says so)."""
    w = float(np.sqrt(params["face_stiffness"] / params["face_mass"]))
    nyq = min(0.5 * r.fs_hz / natural_frequency(r) for r in rows)  # in natural frequencies
    series = series_betas(law.betas, params)
    return [
        "the face was chosen by simulating the campaign, not by the maps' held-out test "
        "(it failed there): its values carry no bootstrap interval, only the refit's box "
        "(mass and stiffness within a factor 1.5)",
        f"modes of the restraint above {nyq:.3g} natural frequencies (the slowest recording's "
        "Nyquist frequency) alias into the measured force and are not identified: the face "
        f"is one mode at {w:.3g} natural frequencies standing for all of them",
        "beta behind the face is the contact's own stiffness and moves with the face's "
        "support stiffness; the contact in series with the support, "
        f"1 / (1/beta + 1/kappa) = {min(series):.3g}-{max(series):.3g}, is what a static "
        "test measures and is the better-determined of the two",
    ]


def refine_face(
    target: Any,
    rows: Sequence[Any],
    model: Sequence[Effect],
    params: dict[str, float],
    at_discovered: np.ndarray,
    settings: Any,
) -> dict[str, Any]:
    """The law refitted by simulation around its discovered values, the rest of the model held.

    The discovery reads the face's mode through the measured force (its damping weakly); the
    campaign's statistics see the face ringing between impacts too. The refit searches
    ``learned_contact``'s space around the law (:meth:`LearnedContact.fit_space_at`: the face
    within a factor 1.5, its damping 2.25): each of the face's parameters swept across its
    box on a grid simulated as one batch (:data:`FACE_REFIT_GRID`), the best point so far
    among its points, a point taken only where, scored again alone, it lowers the
    discrepancy.

    Returns
    -------
    dict
        ``params`` (the law's, all of them), ``fitted``, ``per_recording``, ``improves`` (over
        the discovered values), ``discrepancy_discovered``, ``discrepancy_refit``, ``seconds``.
    """
    from stiffnet.measurement.fitting import fit_effect

    tgt = replace(target, rows=list(rows), base_effects=list(model))
    best, per = dict(params), np.asarray(at_discovered, float)
    fitted: list[str] = []
    t0 = time.perf_counter()
    space = LearnedContact.fit_space_at(params, min(r.fs_hz for r in rows))
    box = {fp.name: fp for fp in space.free}
    for key in FACE_KEYS:  # a sweep of each across its box, the others at the best so far
        grid = [{**best, key: box[key].value(u)} for u in np.linspace(0, 1, FACE_REFIT_GRID)]
        fit = fit_effect(tgt, LearnedContact.name, [], settings, budget=1 + len(grid),
                         off=per, seeds=[best, *grid])  # fmt: skip
        fitted = list(fit["fitted"])
        if fit["improves"]:
            best, per = {**best, **fit["params"]}, np.asarray(fit["per_recording"], float)
    d0, d1 = campaign_discrepancy(at_discovered), campaign_discrepancy(per)
    return {
        "params": best,
        "fitted": fitted,
        "per_recording": per.tolist(),
        "improves": bool(d1 < d0),
        "discrepancy_discovered": d0,
        "discrepancy_refit": d1,
        "seconds": round(time.perf_counter() - t0, 2),
    }

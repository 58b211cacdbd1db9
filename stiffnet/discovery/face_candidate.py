r"""A face the maps cannot decide on: its candidates, for the simulation to decide.

On a beam's tip the restoring-force maps see a restraint with dynamics (the linear
spring explains under :data:`FACE_QUESTION_FIT` of the force) and a face that
explains more of it, yet the face fails the held-out test: at the rig's 1-2 kHz the
tip's second mode rings above the Nyquist frequency and aliases into the measured
force that drives the face's recoil, so the held-out impacts of the median recording
are fitted worse (independent rig, cantilever of mass 0.4 ringing at 10 natural
frequencies: linear 71 %, face 78 %, held-out gain -35 %). The maps cannot decide;
the campaign's statistics, simulated with the face as ``learned_contact`` states, can
(:mod:`stiffnet.measurement.face_by_simulation`). This module gives the candidates:
the maps' own face fit (:func:`maps_face_law`), a coarse grid of faces around the
contact's frequencies (:func:`face_grid`), and, once a face is chosen, the betas the
maps read behind it (:func:`betas_behind_face`).

Which beta: behind a face, the law's beta is the contact's own stiffness; what a
static test (or the linear spring on the maps) measures is that contact in series
with the face's support, ``1 / (1/beta + sum_i 1/kappa_i)`` (:func:`series_betas`).
On a tip much softer than the contact the series value is set by the support and
carries little of the contact's beta; both are reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from stiffnet.discovery.face import face_starts
from stiffnet.discovery.face_scaled import scaled_face_starts
from stiffnet.discovery.law import DiscoveredLaw
from stiffnet.discovery.samples import ContactSamples
from stiffnet.discovery.select import (
    FACE_SCREEN_NFEV,
    law_from_fit,
    library_fit,
    reference_penetration,
)
from stiffnet.discovery.terms import FACE_MODES, explained_fraction, fit_law, stack

#: The face's masses (over the mass m) of the coarse grid.
GRID_MASSES = (0.05, 0.15, 0.45)
#: The face's frequencies of the grid, as multiples of the fastest contact frequency
#: ``sqrt(1 + beta)`` the maps read: a soft support reads the contact low (in series), so
#: the face rings several times above it (3.7 on the cantilever above).
GRID_FREQUENCIES = (1.5, 3.0, 6.0)
#: The grid's damping ratio (a beam's modes ring lightly; the refit sweeps it).
GRID_DAMPING = 0.05
#: A scaled face's grid (:func:`scaled_face_grid`): its support over beta (a contact 10, 3
#: and 1.5 times stiffer than the support in front of it) and its mass at the reference beta.
SCALED_GRID_RATIOS = (1.1, 1.33, 1.67)
SCALED_GRID_MASSES = (0.05, 0.15, 0.45)
#: The two accounts of a restraint the maps could not decide on, in the order the simulation
#: tries them: the rig's shared ``face`` (three parameters), then the ``face_scaled`` that is
#: each recording's own (four), the second only where the simulation refuses the first,
#: whichever the path refused. Where the restraint's modes alias into the measured force the
#: maps' ranking of the two is not the campaign's: on a beam's tip shared by every recording
#: the path refused the scaled face, the better fit on the maps, and the shared face
#: simulated removes most of the excess; so the simpler account goes first.
FACE_ACCOUNTS = ("face", "face_scaled")
#: Below this explained fraction a law with nothing new leaves room for a restraint with
#: dynamics (:func:`face_in_question`). A light stiff tip reads almost as a softer linear
#: spring on the maps (the contact in series with its support), yet what it leaves is the
#: face's: on the independent rig's tip of 0.3 m at 15 natural frequencies behind a 2 Hz
#: high-pass the linear spring explained 90.1 % (a face 90.7 %), just above the law's
#: :data:`~.law.POOR_FIT`, and nothing was simulated. Laws of contacts the library or the
#: path describes explain 98.5-99.9 % on the held-out rig campaigns (Hunt-Crossley, two
#: stages and a power law behind mounts and low-passes), well above it.
FACE_QUESTION_FIT = 0.95


def face_in_question(law: DiscoveredLaw) -> bool:
    """Rule: the maps cannot decide on a face when the law has nothing new, explains less
    than :data:`FACE_QUESTION_FIT` of the force, and the path's refused step is a face (one
    mode, or two) that explains more of the force than the law kept.

    The refusal is the held-out test's; the explained share says a restraint with dynamics
    may be there. Where the two disagree the simulation decides, as for any diagnosed effect.
    """
    if law.new or not law.explained_fraction < FACE_QUESTION_FIT or not law.path:
        return False
    last = law.path[-1]
    return bool(
        last["term"] in ("face", "face2", "face_scaled")
        and not last["entered"]
        and last["explained_fraction"] > law.explained_fraction
    )


def maps_face_law(
    samples: Sequence[ContactSamples], path: list[dict[str, Any]], term: str = "face"
) -> DiscoveredLaw:
    """The one-mode face (``term``: ``face``, or ``face_scaled``) fitted on the maps from every
    start of the discovery's screen, as a law (no bootstrap: its intervals are the
    simulation's to give), whatever the held-out test said (``path``: the discovery's, kept
    for the report)."""
    data = stack(samples)
    dr = reference_penetration(data)
    lin = fit_law(data, frozenset(), dr)
    per = lin.theta[: 2 * lin.n_rec]
    terms = frozenset({term})
    starts = face_starts(lin.betas) if term == "face" else scaled_face_starts(lin.betas)
    short = [fit_law(data, terms, dr, s, per, max_nfev=FACE_SCREEN_NFEV) for s in starts]
    best = min(short, key=lambda f: f.sse)
    fit = fit_law(data, terms, dr, best.shared, best.theta[: 2 * best.n_rec])
    return law_from_fit(data, fit, path, library_fit(data, dr))


def face_grid(betas: Sequence[float]) -> list[dict[str, float]]:
    """The coarse grid of one-mode faces (:data:`GRID_MASSES` x :data:`GRID_FREQUENCIES` times
    the fastest contact frequency of ``betas``, the maps' linear betas), as
    ``learned_contact`` face parameters."""
    w_top = float(np.sqrt(1.0 + np.max(betas)))
    return [
        {"face_mass": m, "face_stiffness": float(f"{m * (f * w_top) ** 2:.4g}"),
         "face_damping": GRID_DAMPING}
        for m in GRID_MASSES for f in GRID_FREQUENCIES
    ]  # fmt: skip


def scaled_face_grid(maps: DiscoveredLaw) -> list[dict[str, float]]:
    """The coarse grid of scaled faces (:data:`SCALED_GRID_RATIOS` x :data:`SCALED_GRID_MASSES`)
    at the maps' own mass exponent, reference beta and the grid's damping, as
    ``learned_contact`` parameters."""
    p = maps.params
    return [
        {"face_mass": m, "face_stiffness_ratio": r, "face_damping": GRID_DAMPING,
         "face_mass_exponent": float(f"{p['face_mass_exponent']:.3g}"),
         "face_reference_beta": p["face_reference_beta"]}
        for m in SCALED_GRID_MASSES for r in SCALED_GRID_RATIOS
    ]  # fmt: skip


def betas_behind_face(
    samples: Sequence[ContactSamples], law: DiscoveredLaw, face: dict[str, float]
) -> DiscoveredLaw:
    """``law`` with the face's parameters set to ``face`` and each recording's beta and onset
    refitted on the maps behind that face (the face held: its recoil under the measured
    force taken off the penetration, the linear spring fitted on what is left). A scaled
    face depends on each recording's beta: its law keeps the maps' betas (the restraint's
    static stiffness, read with the maps' own scaled face)."""
    if float(face.get("face_stiffness_ratio", 0.0)) > 0:
        return replace(law, params={**law.params, **face})
    data = stack(samples)
    params = {**law.params, **face}
    modes = [m for m in FACE_MODES if float(params.get(f"{m}_mass", 0.0)) > 0]
    x, v = data.behind_face(data.x, data.v, params, modes)
    behind = replace(data, x=x, v=v, parent=None)
    dr = float(params["reference_penetration"])
    fit = fit_law(behind, frozenset(), dr)
    return replace(
        law,
        params=params,
        betas=tuple(float(b) for b in fit.betas),
        onsets=tuple(float(e) for e in fit.onsets),
        beta_intervals=tuple([None] * len(fit.betas)),
        explained_fraction=explained_fraction(behind, fit),
    )


def series_betas(betas: Sequence[float], params: dict[str, float]) -> list[float]:
    """The contact in series with the face's support(s): ``1 / (1/beta + sum 1/kappa_i)``; a
    scaled face's betas are that already (its definition of beta)."""
    if float(params.get("face_stiffness_ratio", 0.0)) > 0:
        return [float(b) for b in betas]
    comp = 1.0 / float(params["face_stiffness"]) if float(params.get("face_mass", 0)) > 0 else 0.0
    if float(params.get("face2_mass", 0.0)) > 0:
        comp += 1.0 / float(params["face2_stiffness"])
    return [float(1.0 / (1.0 / b + comp)) for b in betas]

r"""A face the maps cannot decide on: its candidates, for the simulation to decide.

On a beam's tip the restoring-force maps see a restraint with dynamics (the linear
spring explains well under :data:`~.law.POOR_FIT` of the force) and a face that
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


def face_in_question(law: DiscoveredLaw) -> bool:
    """Rule: the maps cannot decide on a face when the law has nothing new, leaves more than
    ``1 - POOR_FIT`` of the force unexplained, and the path's refused step is a face (one
    mode, or two) that explains more of the force than the law kept.

    The refusal is the held-out test's; the explained share says a restraint with dynamics
    is there. Where the two disagree the simulation decides, as for any diagnosed effect.
    """
    if law.new or not law.poorly_explained or not law.path:
        return False
    last = law.path[-1]
    return bool(
        last["term"] in ("face", "face2")
        and not last["entered"]
        and last["explained_fraction"] > law.explained_fraction
    )


def maps_face_law(samples: Sequence[ContactSamples], path: list[dict[str, Any]]) -> DiscoveredLaw:
    """The one-mode face fitted on the maps from every start of the discovery's screen, as a
    law (no bootstrap: its intervals are the simulation's to give), whatever the held-out
    test said (``path``: the discovery's, kept for the report)."""
    data = stack(samples)
    dr = reference_penetration(data)
    lin = fit_law(data, frozenset(), dr)
    per = lin.theta[: 2 * lin.n_rec]
    terms = frozenset({"face"})
    short = [fit_law(data, terms, dr, s, per, max_nfev=FACE_SCREEN_NFEV)
             for s in face_starts(lin.betas)]  # fmt: skip
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


def betas_behind_face(
    samples: Sequence[ContactSamples], law: DiscoveredLaw, face: dict[str, float]
) -> DiscoveredLaw:
    """``law`` with the face's parameters set to ``face`` and each recording's beta and onset
    refitted on the maps behind that face (the face held: its recoil under the measured
    force taken off the penetration, the linear spring fitted on what is left)."""
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
    """The contact in series with the face's support(s): ``1 / (1/beta + sum 1/kappa_i)``."""
    comp = 1.0 / float(params["face_stiffness"]) if float(params.get("face_mass", 0)) > 0 else 0.0
    if float(params.get("face2_mass", 0.0)) > 0:
        comp += 1.0 / float(params["face2_stiffness"])
    return [float(1.0 / (1.0 / b + comp)) for b in betas]

r"""The ``face_scaled`` term: a restraint face whose stiffness and mass are each recording's.

The ``face`` term's restraint is the rig's, shared by the campaign (a stop at a beam's
tip, the rock's contact in front of it). On the paper's own rig the beam **is** the
material: beta is set by the beam's length, and every recording has its own beam, struck
through a local contact stiffer than it. Its face then scales with beta: a cantilever's
static tip stiffness is ``3 EI / L^3`` and its mass ``rho A L``, so at a fixed section the
modal mass goes as ``beta^(-1/3)``. The term writes it as the physics is built, per
recording ``r`` with its beta ``beta_r``::

    kappa_r = r beta_r                        the face's support (the beam's first mode)
    mu_r    = mu (beta_r / beta_ref)^q        its modal mass
    F_c     = c beta_r (x - e_r - y)          the contact in front of it, c = r / (r - 1)

with ``r``, ``mu``, ``q`` and the damping ratio ``zeta`` shared, and ``beta_ref`` fixed (the
campaign's median beta, rounded, as ``d_r``). **Beta** is the restraint's static stiffness
at the contact, the contact in series with the support: ``1 / (c beta) + 1 / (r beta) =
1 / beta``, so the linear spring on the maps, this law and a dataset generated with it
(``learned_contact``'s ``face_stiffness_ratio``) read the same quantity; for a beam struck
through a contact much stiffer than it (``r`` near 1) it is the beam's static tip stiffness.

The exponent ``q`` is fitted (:data:`SCALED_PARAMS`: from -1 to 1; -1/3 for a beam whose
length sets beta, 0 for a face whose mass does not change, 1/3 for one whose thickness
does). Each recording's recoil is the ``face`` term's filter (:func:`.face.face_response`)
at its own mass and support, all recordings filtered at once.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from stiffnet.discovery.face import FACE_PARAMS
from stiffnet.effects.learned_contact import scaled_face

if TYPE_CHECKING:
    from stiffnet.discovery.terms import Data

#: Shared parameters of the term: name, lower and upper bound, starting value. The ratio's
#: lower bound keeps the contact's own stiffness ``beta r / (r - 1)`` finite (101 beta).
#: The mass and damping are the ``face`` term's own entries (one name, one range and start).
SCALED_PARAMS = (
    FACE_PARAMS[0],
    ("face_stiffness_ratio", 1.01, 50.0, 1.2),
    FACE_PARAMS[2],
    ("face_mass_exponent", -1.0, 1.0, 0.0),
)
#: Support stiffnesses tried as starts, over beta: a contact 10, 3 and 1 times the support.
RATIO_STARTS = (1.1, 1.33, 2.0)
#: Face frequencies tried as starts with each ratio, as multiples of the median recording's
#: contact frequency ``sqrt(1 + beta)`` (a soft support rings above it: ``face``'s starts).
FREQUENCY_STARTS = (1.5, 4.0)


def reference_beta(betas: np.ndarray) -> float:
    """``beta_ref``: the campaign's median beta, to two significant digits."""
    med = float(np.median(betas)) if np.size(betas) else 30.0
    return float(f"{med:.2g}") if med > 0 else 30.0


def scaled_params(shared: dict[str, float], beta_ref: float) -> dict[str, float]:
    """The ``learned_contact`` parameters :func:`~stiffnet.effects.learned_contact.scaled_face`
    reads, from the term's shared values (the maps fit each recording's beta, the law's own:
    its scale over the rows' is 1)."""
    return {
        "face_mass": float(shared["face_mass"]),
        "face_stiffness_ratio": float(shared["face_stiffness_ratio"]),
        "face_mass_exponent": float(shared["face_mass_exponent"]),
        "face_reference_beta": float(beta_ref),
        "face_beta_scale": 1.0,
    }


def scaled_face_recoil(
    data: Data, betas: np.ndarray, shared: dict[str, float], beta_ref: float
) -> tuple[np.ndarray, np.ndarray]:
    """The recoil and its rate on every sample, (N,) each: each recording's face (its support
    ``r beta_r``, mass ``mu (beta_r / beta_ref)^q``) driven by its measured force.

    Parameters
    ----------
    data : Data
        The samples (:func:`~.terms.stack`); a subset of held-out impacts filters its parent's.
    betas : numpy.ndarray
        Each recording's beta (R,), the restraint's static stiffness at the contact.
    shared : dict
        The term's shared parameters (:data:`SCALED_PARAMS`).
    beta_ref : float
        The beta at which the face's mass is ``face_mass``.
    """
    p = {**scaled_params(shared, beta_ref), "face_stiffness": 1.0}  # an absolute face's: unused
    _, kappa, mass = scaled_face(np.asarray(betas, float), p)
    # every recording's face in one filter (a loop over recordings, one filter each, was
    # three fifths of the discovery's time on a 23-recording campaign), its recoils kept
    return data.face_recoil(mass, kappa, float(shared["face_damping"]))


def scaled_face_starts(betas: np.ndarray) -> list[dict[str, float]]:
    """Starting faces: supports :data:`RATIO_STARTS` times beta, ringing at
    :data:`FREQUENCY_STARTS` times the median recording's contact frequency."""
    beta = float(np.median(betas))
    out = []
    for r in RATIO_STARTS:
        for fw in FREQUENCY_STARTS:
            out.append({"face_stiffness_ratio": r,
                        "face_mass": r * beta / (fw * fw * (1.0 + beta))})  # fmt: skip
    return out

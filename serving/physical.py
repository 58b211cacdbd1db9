"""The restoring-force cross-check of the predictor (numpy/scipy only).

One call of :func:`stiffnet.restoring_force.restoring_force_estimate` on at most
:data:`PHYSICAL_PERIODS` forcing periods from the middle of the recording (the
cost stays bounded on long recordings), turned into the JSON fields of
:class:`serving.schemas.PhysicalCheck`. A recording the method cannot read
(no contact, no forcing line, a meaningless fit) gives ``class`` null or
``no_contact`` and the reason, never an error: the cross-check must not stop a
prediction. ``dissipation_gain`` / ``dissipation_share`` say whether the contact's
dissipation grows with penetration (:mod:`stiffnet.uncertainty.unseen_law`). The sensor
chain's high-pass corner and mount resonance are fitted from the recording itself
(``highpass_hz``, ``resonance_hz``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.errors import StiffnetError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.uncertainty.unseen_law import penetration_dissipation

#: Forcing periods the cross-check analyses (24: ~1.5 windows; bounds its cost to ~15 ms).
PHYSICAL_PERIODS = 24.0


def physical_check(accel: Any, fs_hz: float, natural_frequency_hz: float) -> dict[str, Any]:
    """Restoring-force beta, class and interval of one recording, or the reason there is none."""
    try:
        r = restoring_force_estimate(
            accel, fs_hz, natural_frequency_hz=natural_frequency_hz, max_periods=PHYSICAL_PERIODS
        )
    except StiffnetError as exc:
        return {"class": None, "beta": None, "beta_interval": None, "reason": str(exc)}
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        # a fit that breaks numerically (non-finite Jacobian, singular system) is a
        # refusal of the cross-check, never a failure of the prediction
        reason = f"the restoring-force fit failed numerically ({type(exc).__name__})"
        return {"class": None, "beta": None, "beta_interval": None, "reason": reason}
    d = r.to_dict()
    hc = None
    if r.ok and r.law is not None:  # the map's own test for a Hunt-Crossley-like dissipation
        law = r.law
        hc = penetration_dissipation(r.displacement, r.velocity, r.force, law.onset,
                                     law.exponent, law.reference_penetration)  # fmt: skip
    return {
        "class": d["physical_class"],
        "beta": d["beta"],
        "beta_interval": d["beta_interval"],
        "beta_interval_coverage": d["coverage"] if r.ok else None,
        "contact_damping_ratio": d["contact_damping_ratio"],
        "exponent": d["exponent"],
        "n_impacts": d["n_impacts"],
        "contact_r2": d["contact_r2"],
        "highpass_hz": d["highpass_hz"],
        "resonance_hz": d["resonance_hz"],
        "dissipation_gain": None if hc is None else hc[0],
        "dissipation_share": None if hc is None else hc[1],
        "reason": d["reason"],
    }

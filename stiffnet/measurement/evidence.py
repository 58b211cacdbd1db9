"""Data-driven evidence beside diagnose's simulation fits: the restoring-force map's contact law.

The restoring-force estimate (:mod:`stiffnet.restoring_force`) fits each
recording's contact law directly on its force-displacement map, with no
simulation: the **loop area** of the map is the contact's dissipation (its
damping ratio ``zeta_c``; a restitution ``e = exp(-pi zeta_c / sqrt(1 - zeta_c**2))``)
and its **curvature** is stiffening (the exponent ``p``: 1 linear, 1.5 Hertz).
Summarised over a campaign, they say which contact effects the data themselves
show, independently of the simulation fits that ``diagnose`` ranks
(``contact_damping``, ``hertz_contact``). One estimate per recording: a few
seconds each where the sensor chain is fitted, so they run as parallel tasks on
diagnose's workers (:func:`stiffnet.distributed.tasks.run_tasks`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.errors import StiffnetError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.chain import shared_chain

#: Forcing periods read per recording (the predictor's cross-check reads as many).
PERIODS = 24.0
#: A median contact damping ratio above this is dissipation worth naming (restitution < 0.86).
DISSIPATION_ZETA = 0.05
#: A median exponent above this is stiffening worth naming (Hertz is 1.5).
STIFFENING_EXPONENT = 1.15
#: Evidence needs the contact law of at least this many recordings.
MIN_ANSWERED = 2


def restitution(zeta: float) -> float:
    """Restitution coefficient of a linear Kelvin-Voigt contact of damping ratio ``zeta`` (< 1)."""
    return float(np.exp(-np.pi * zeta / np.sqrt(1.0 - zeta**2))) if zeta < 1 else 0.0


def contact_law_per_recording(
    campaign: Campaign, rows: list[ManifestRow], client: Any = None
) -> list[dict[str, Any]]:
    """The restoring-force contact law of each recording (or why there is none).

    ``rows`` are diagnose's resolved rows (natural frequency and forcing ratio
    filled in where the manifest had none). ``client``: a Dask client whose workers
    read the recordings in parallel (in-process without one); the results do not
    depend on where they ran.
    """
    from stiffnet.distributed.tasks import run_tasks

    items = [(campaign.recording(i), row) for i, row in enumerate(rows)]
    report = run_tasks(_contact_law_task, items, client=client, names=[r.recording for r in rows])
    report.raise_failures()
    return report.results


def _contact_law_task(item: tuple[Any, ManifestRow]) -> dict[str, Any]:
    """One recording's restoring-force estimate as evidence (a picklable task)."""
    rec, row = item
    fn = row.natural_frequency_hz
    ff = fn * row.frequency_ratio if fn and row.frequency_ratio else None
    try:
        r = restoring_force_estimate(
            rec.accel, rec.fs_hz, natural_frequency_hz=fn, forcing_frequency_hz=ff,
            max_periods=PERIODS, sensor=row.sensor_sheet(),
        )  # fmt: skip
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return {"recording": row.recording, "ok": False, "reason": str(exc)}
    return {
        "recording": row.recording, "ok": r.ok, "beta": r.beta,
        "contact_damping_ratio": r.contact_damping_ratio, "exponent": r.exponent,
        "contact_r2": r.contact_r2 if r.ok else None, "reason": r.reason,
        "sensor": r.sensor.to_dict() if r.sensor is not None else None,
    }  # fmt: skip


def contact_evidence(per_recording: list[dict[str, Any]]) -> dict[str, Any]:
    """Rule: the campaign's median contact damping and exponent, and the effects they support.

    Returns
    -------
    dict
        ``answered`` / ``n``, ``contact_damping_ratio`` and ``exponent`` (medians
        and 10-90 % ranges over the answered recordings), ``restitution``,
        ``supports`` (effect names the map shows), ``summary`` (one line),
        ``per_recording``.
    """
    ok = [p for p in per_recording if p["ok"]]
    n = len(per_recording)
    res: dict[str, Any] = {"n": n, "answered": len(ok), "per_recording": per_recording,
                           "supports": []}  # fmt: skip
    res["sensor"] = shared_chain([p.get("sensor") for p in per_recording])  # sensor_dynamics' start
    if len(ok) < MIN_ANSWERED:
        res["summary"] = (
            f"restoring-force evidence: the contact law was read on {len(ok)} of {n} "
            "recordings, too few to say anything about the contact"
        )
        return res
    zeta = np.array([p["contact_damping_ratio"] for p in ok], dtype=float)
    expo = np.array([p["exponent"] for p in ok], dtype=float)
    z_med, p_med = float(np.median(zeta)), float(np.median(expo))
    res.update(
        contact_damping_ratio=z_med,
        contact_damping_ratio_range=[float(v) for v in np.quantile(zeta, [0.1, 0.9])],
        restitution=restitution(z_med),
        exponent=p_med,
        exponent_range=[float(v) for v in np.quantile(expo, [0.1, 0.9])],
    )
    words = []
    if z_med > DISSIPATION_ZETA:
        res["supports"].append("contact_damping")
        words.append(f"the loops dissipate (contact damping ratio {z_med:.2f}, restitution "
                     f"{restitution(z_med):.2f}): supports contact_damping")  # fmt: skip
    else:
        words.append(f"no dissipation in the contact (damping ratio {z_med:.2f})")
    if p_med > STIFFENING_EXPONENT:
        res["supports"].append("hertz_contact")
        words.append(f"the contact stiffens (exponent {p_med:.2f}): supports hertz_contact")
    else:
        words.append(f"a linear contact (exponent {p_med:.2f})")
    res["summary"] = f"restoring-force evidence on {len(ok)} of {n} recordings: " + "; ".join(words)
    return res


def restoring_force_evidence(
    campaign: Campaign, rows: list[ManifestRow], client: Any = None
) -> dict[str, Any]:
    """:func:`contact_evidence` of :func:`contact_law_per_recording` (diagnose's JSON key)."""
    return contact_evidence(contact_law_per_recording(campaign, rows, client))

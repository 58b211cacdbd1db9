"""A restraint's preload the maps cannot resolve, decided by simulating the campaign with it.

A restraint compressed by ``delta_0`` before first touch (``learned_contact``'s ``preload``)
pushes with ``beta d_r (delta_0 / d_r)**p`` the moment the mass arrives. On a
restoring-force map that step falls between two samples of an impact lasting about ten,
where a shift of the onset copies it: on the independent rig's power law (1.3) with a
0.04 mm preload behind a 300 Hz mount, the maps' own fit read the preload at -0.016 and
the power law alone explained 99.93 % of the force, yet the campaign simulated with the
rig's preload lost 48 % of its discrepancy against 34 % without (docs/measurement_loop.md).
Between impacts the preload is not small: it sets how hard and how long each impact is,
which the orbit's statistics see.

So once the discovered law has been scored, its preload is swept by simulation, the rest
of the law and of the model held (:func:`~.face_by_simulation.sweep_parameter`, the face
refit's sweep): a coarse grid from 0 to :data:`PRELOAD_REACH` of ``d_r``, then a fine one
around its best point; the preload is kept only where it passes the tests every diagnosed
effect must (:func:`~stiffnet.measurement.significance.significance`, one parameter).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from stiffnet.effects.base import Effect
from stiffnet.effects.fit_space import FitParam
from stiffnet.measurement.face_by_simulation import FACE_REFIT_GRID, sweep_parameter
from stiffnet.measurement.fitting import objective_value
from stiffnet.measurement.noise_floor import Floors
from stiffnet.measurement.significance import significance

#: The coarse sweep's reach, as a fraction of the law's reference penetration ``d_r``: a
#: restraint set 40 % of the impacts' median depth into its stop pushes at touch with
#: ``0.4**p`` of the force at that depth (the rigs' preloads: 0.1-0.17 of it).
PRELOAD_REACH = 0.4


def preload_applies(params: dict[str, float]) -> bool:
    """Rule: a preload is swept on a law without one and without a face (a face's recoil
    at touch is the face's to decide, :mod:`.face_by_simulation`)."""
    return not float(params.get("preload", 0.0)) and not float(params.get("face_mass", 0.0))


def preload_by_simulation(
    target: Any,
    rows: Sequence[Any],
    model: Sequence[Effect],
    params: dict[str, float],
    at_law: np.ndarray,
    floor: Floors,
    settings: Any,
) -> dict[str, Any]:
    """Sweep the law's preload by simulation and test it (see the module notes).

    Parameters
    ----------
    target : CampaignTarget
        diagnose's target; ``rows``: its rows as the law is simulated on them.
    model : sequence of Effect
        The effects the law is simulated with (held).
    params : dict
        The law's ``learned_contact`` parameters (without a preload).
    at_law : numpy.ndarray
        Per-recording discrepancy with the law as discovered (what the preload must lower).
    floor : Floors
        The recordings' own floors at ``settings``.
    settings : SolverSettings
        The numerical engine's settings.

    Returns
    -------
    dict
        ``significant`` (bool), ``preload`` (the swept value, model lengths), ``params``
        (the law with it), ``per_recording``, ``objective_law``, ``objective_preload``,
        ``significance`` (excess reduction, BIC change, reasons), ``seconds``.
    """
    t0 = time.perf_counter()
    tgt = replace(target, rows=list(rows), base_effects=list(model))
    reach = PRELOAD_REACH * float(params["reference_penetration"])
    start = {**params, "preload": 0.0}
    best, per, _ = sweep_parameter(tgt, settings, {"preload": FitParam("preload", 0.0, reach)},
                                   "preload", start, np.asarray(at_law, float))  # fmt: skip
    value = float(best["preload"])
    if value > 0:  # a grid step either side of the coarse best, finer
        step = reach / (FACE_REFIT_GRID - 1)
        fine = FitParam("preload", max(value - step, 0.0), value + step)
        best, per, _ = sweep_parameter(tgt, settings, {"preload": fine}, "preload", best, per)
        value = float(best["preload"])
    names = [r.recording for r in rows]
    sig = significance(np.asarray(at_law, float), per, 1, floor, names)
    return {
        "significant": bool(value > 0 and sig["significant"]),
        "preload": value,
        "params": {**params, "preload": value},
        "per_recording": np.asarray(per, float).tolist(),
        "objective_law": objective_value(np.asarray(at_law, float), tgt.weights),
        "objective_preload": objective_value(np.asarray(per, float), tgt.weights),
        "significance": {k: sig[k] for k in ("excess_reduction", "bic_delta", "reasons")},
        "seconds": round(time.perf_counter() - t0, 2),
    }

"""Nuisance parameters: what the manifest leaves out or knows only within a tolerance.

A lab knows its rig to a few per cent, a drill site hardly at all. Before and
during the diagnosis (:mod:`stiffnet.measurement.diagnose`) these are estimated
from the recordings, so a missing effect is not blamed for a wrong setting:

``frequency_ratio``
    from the recording's spectrum (:func:`forcing_frequency_ratio`: the
    strongest line below 5 f_n, zero-padded and interpolated), within the
    manifest's tolerance when it gives one, freely when it gives none;
``gap``
    only ``gap / amplitude`` matters (the model's free length scale), so the
    gap is profiled within ``gap_tol + |gap| amplitude_tol / amplitude``, one
    value per *operating point* (rows with the same nominal gap, amplitude and
    damping share it: the same physical setting); a missing gap is profiled per
    recording over ``[-0.5, 3]`` amplitudes;
``damping_ratio``
    within ``damping_ratio_tol`` per operating point (missing: 0.02 +- 0.015);
``beta``
    per recording when the manifest has none (a field campaign), from the
    learned model's estimate (:class:`serving.predictor.Predictor`; the
    geometric method's, else 30, when it has none) over a factor 2 either way,
    or within ``beta_tol``;
``start``
    the initial state (one of :data:`N_STARTS` draws per recording): impact
    oscillators are multistable and a simulation from another state can sit
    on another orbit than the recording; the orbits the starts reached are
    returned per recording (:func:`stiffnet.measurement.orbits.start_orbits`).

Profiling (:func:`profile_nuisances`): for the current effects, each nuisance
in turn is set on a grid of :data:`GRID` values across its interval for every
row at once (one simulated batch per value), each group keeps its best
(summed discrepancy), then a finer grid of three around it. It runs before the
selection and again after every accepted effect.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.campaign.loaded import memo
from stiffnet.campaign.simulate import CampaignSolverSettings, natural_frequency
from stiffnet.effects.base import Effect
from stiffnet.errors import StiffnetError
from stiffnet.measurement.evaluation_pool import per_recording_many, statistics_many
from stiffnet.measurement.orbits import start_orbits
from stiffnet.measurement.target import CampaignTarget

N_STARTS = 8
GRID = 7
DEFAULT_AMPLITUDE = 1.0
DEFAULT_DAMPING, DEFAULT_DAMPING_TOL = 0.02, 0.015
GAP_RANGE = (-0.5, 3.0)  # in amplitudes, when the manifest has no gap
BETA_FACTOR = 2.0
DEFAULT_BETA = 30.0


@dataclass
class Nuisance:
    """One profiled row attribute: per-row interval and the group each row belongs to."""

    name: str
    low: np.ndarray
    high: np.ndarray
    groups: np.ndarray
    log: bool = False

    def values(self, u: float) -> np.ndarray:
        if self.log:
            return np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low)))
        return self.low + u * (self.high - self.low)


def forcing_frequency_ratio(
    accel: np.ndarray, fs_hz: float, f_n: float, low: float = 0.2, high: float = 5.0
) -> float:
    """The forcing frequency over ``f_n`` from the spectrum: the strongest line in
    ``[low, high] f_n`` of the Hann-windowed, 16x zero-padded record, with parabolic
    interpolation of the peak (resolution well under a per cent on ten periods)."""
    y = np.asarray(accel, float) - np.mean(accel)
    n = 16 * int(2 ** np.ceil(np.log2(max(y.size, 16))))
    spec = np.abs(np.fft.rfft(y * np.hanning(y.size), n))
    f = np.fft.rfftfreq(n, 1.0 / fs_hz) / f_n
    sel = np.flatnonzero((f >= low) & (f <= high))
    if sel.size < 3:
        raise StiffnetError("record too short to estimate the forcing frequency")
    i = sel[int(np.argmax(spec[sel]))]
    if 0 < i < spec.size - 1:
        a, b, c = np.log(spec[i - 1 : i + 2] + 1e-300)
        i = i + 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else i
    return float(i * (f[1] - f[0]))


def _operating_points(rows: Sequence[ManifestRow]) -> np.ndarray:
    keys = [(r.gap, r.amplitude, r.damping_ratio, r.frequency_ratio) for r in rows]
    index: dict[Any, int] = {}
    return np.array([index.setdefault(k, len(index)) for k in keys])


def predicted(
    campaign: Campaign,
    i: int,
    row: ManifestRow,
    model_path: str | None,
    sensor: dict[str, float] | None = None,
    sensor_fitted: bool = False,
    penetration_dissipation: bool | None = None,
) -> dict[str, Any]:
    """The predictor's result for recording ``i`` (once per model for a loaded campaign;
    ``sensor``: a data sheet in place of the row's own, e.g. the campaign's pooled chain,
    then ``sensor_fitted``; ``penetration_dissipation``: the restoring-force law's
    dissipation, None the model's: :meth:`serving.predictor.Predictor.predict`'s).

    Raises what :meth:`serving.predictor.Predictor.predict` raises."""
    from serving.predictor import Predictor

    sheet = row.sensor_sheet() if sensor is None else sensor

    def run() -> dict[str, Any]:
        predictor = memo(campaign, ("predictor", model_path), lambda: Predictor.load(model_path))
        rec = campaign.recording(i)
        return predictor.predict(
            rec.accel, rec.fs_hz, natural_frequency_hz=natural_frequency(row),
            source=row.recording, sensor=sheet,
            sensor_fitted=sensor_fitted and sensor is not None,
            penetration_dissipation=penetration_dissipation,
        )  # fmt: skip

    key = ("predicted", model_path, i, natural_frequency(row))
    if sensor is not None:
        key += (tuple(sorted(sensor.items())), sensor_fitted)
    if penetration_dissipation is not None:
        key += (("penetration_dissipation", penetration_dissipation),)
    return memo(campaign, key, run)


def _beta_starts(campaign: Campaign, rows: Sequence[ManifestRow], model_path: str | None) -> list:
    """The learned model's (else the geometric method's) β per recording."""
    try:
        from serving.predictor import Predictor

        memo(campaign, ("predictor", model_path), lambda: Predictor.load(model_path))
        have_model = True
    except Exception:  # noqa: BLE001 - no model: the geometric method or a default
        have_model = False
    out = []
    for i, row in enumerate(rows):
        beta = None
        if have_model:
            try:
                res = predicted(campaign, i, row, model_path)
                beta = res.get("beta") or (res.get("geometric") or {}).get("beta")
            except Exception:  # noqa: BLE001 - a recording the predictor refuses
                beta = None
        out.append(float(beta) if beta and np.isfinite(beta) and beta > 0 else DEFAULT_BETA)
    return out


def resolve_rows(
    campaign: Campaign, model_path: str | None = None
) -> tuple[list[ManifestRow], dict[str, Any]]:
    """Complete the rows for simulation and list the nuisances to profile (see module notes;
    once per model for a :class:`~stiffnet.campaign.LoadedCampaign`).

    Returns
    -------
    rows : list of ManifestRow
        Every simulation column set (estimates where the manifest has none).
    info : dict
        ``nuisances`` (list of :class:`Nuisance`) and ``estimated`` (column -> rows).
    """
    rows, info = memo(
        campaign, ("resolve_rows", model_path), lambda: _resolve(campaign, model_path)
    )
    return [r.model_copy() for r in rows], info


def _resolve(
    campaign: Campaign, model_path: str | None
) -> tuple[list[ManifestRow], dict[str, Any]]:
    rows = [r.model_copy() for r in campaign.rows]
    estimated: dict[str, list[str]] = {}
    for i, (row, (_, rec)) in enumerate(zip(rows, campaign.recordings(), strict=True)):
        f_n = natural_frequency(row)
        w, tol = row.frequency_ratio, row.frequency_ratio_tol
        if w is None or tol:
            lo, hi = (0.2, 5.0) if w is None else (w - tol, w + tol)
            w = forcing_frequency_ratio(rec.accel, rec.fs_hz, f_n, max(lo, 0.05), hi)
            estimated.setdefault("frequency_ratio", []).append(row.recording)
        update: dict[str, Any] = {"frequency_ratio": w}
        if row.amplitude is None:
            update["amplitude"] = DEFAULT_AMPLITUDE
        if row.damping_ratio is None:
            update["damping_ratio"] = DEFAULT_DAMPING
        if row.gap is None:
            update["gap"] = 1.0 * update.get("amplitude", row.amplitude)
        rows[i] = row.model_copy(update=update)
    nuis: list[Nuisance] = []
    ops = _operating_points(campaign.rows)
    n = len(rows)
    amp = np.array([r.amplitude for r in rows])
    gap = np.array([r.gap for r in rows])
    given_gap = np.array([r.gap is not None for r in campaign.rows])
    tol = np.array([(r.gap_tol or 0.0) for r in campaign.rows]) + np.abs(gap) * np.array(
        [(r.amplitude_tol or 0.0) / r.amplitude if r.amplitude else 0.0 for r in campaign.rows]
    )
    if (~given_gap).any() or (tol > 0).any():
        lo = np.where(given_gap, gap - tol, GAP_RANGE[0] * amp)
        hi = np.where(given_gap, gap + tol, GAP_RANGE[1] * amp)
        groups = np.where(given_gap, ops, n + np.arange(n))
        nuis.append(Nuisance("gap", lo, hi, groups))
    zeta = np.array([r.damping_ratio for r in rows])
    ztol = np.array(
        [
            r.damping_ratio_tol or (DEFAULT_DAMPING_TOL if r.damping_ratio is None else 0.0)
            for r in campaign.rows
        ]
    )
    if (ztol > 0).any():
        nuis.append(Nuisance("damping_ratio", np.maximum(zeta - ztol, 1e-3), zeta + ztol, ops))
    missing_beta = np.array([r.beta is None for r in campaign.rows])
    btol = np.array([r.beta_tol or 0.0 for r in campaign.rows])
    if missing_beta.any() or (btol > 0).any():
        starts = np.array([r.beta if r.beta is not None else np.nan for r in campaign.rows])
        if missing_beta.any():
            est = np.array(_beta_starts(campaign, rows, model_path))
            starts = np.where(missing_beta, est, starts)
            estimated["beta"] = [r.recording for r, m in zip(rows, missing_beta, strict=True) if m]
        lo = np.where(missing_beta, starts / BETA_FACTOR, np.maximum(starts - btol, 1e-3))
        hi = np.where(missing_beta, starts * BETA_FACTOR, starts + btol)
        rows = [r.model_copy(update={"beta": float(b)}) for r, b in zip(rows, starts, strict=True)]
        nuis.append(Nuisance("beta", lo, hi, np.arange(n), log=True))
    return rows, {"nuisances": nuis, "estimated": estimated}


def profile_nuisances(
    target: CampaignTarget,
    effects: Sequence[Effect],
    settings: CampaignSolverSettings,
    info: dict[str, Any],
) -> dict[str, Any]:
    """Set the nuisances of ``target`` (its rows and starts) to their best values for the model
    ``target.base_effects + effects`` (see the module notes); returns them per recording."""
    model = [*target.base_effects, *effects]
    n = len(target.rows)
    # initial states: each recording keeps the start whose orbit matches it best
    stats = statistics_many(
        target,
        [(model, settings, {"starts": [k] * n, "inclination": False}) for k in range(N_STARTS)],
    )
    pers = [target.discrepancies_of(st) for st in stats]
    target.starts = [int(k) for k in np.argmin(np.vstack(pers), axis=0)]
    orbits = start_orbits(target.measured, stats)
    for nu in info.get("nuisances", []):
        grid = np.linspace(0.0, 1.0, GRID)
        best = _profile(target, model, settings, nu, grid)
        h = 1.0 / (GRID - 1)  # then a finer grid around each group's best
        fine = np.clip(best[:, None] + np.array([-h / 2, 0.0, h / 2])[None, :], 0.0, 1.0)
        best = _profile(target, model, settings, nu, fine)
        values = nu.values(best)
        target.rows = [
            r.model_copy(update={nu.name: float(v)})
            for r, v in zip(target.rows, values, strict=True)
        ]
    out: dict[str, Any] = {
        "start": list(target.starts),
        "estimated": info.get("estimated", {}),
        "orbits": orbits,
    }
    for nu in info.get("nuisances", []):
        out[nu.name] = [float(getattr(r, nu.name)) for r in target.rows]
    if "frequency_ratio" in info.get("estimated", {}):
        out["frequency_ratio"] = [float(r.frequency_ratio) for r in target.rows]
    return out


def _profile(
    target: CampaignTarget,
    model: list[Effect],
    settings: CampaignSolverSettings,
    nu: Nuisance,
    grid: np.ndarray,
) -> np.ndarray:
    """Per-row unit coordinate of the best grid value, chosen per group (summed discrepancy).

    ``grid`` is shared (1-D) or per row (``(n, G)``)."""
    n = len(target.rows)
    g = np.broadcast_to(grid if grid.ndim == 2 else grid[None, :], (n, grid.shape[-1]))
    scores = np.empty_like(g, dtype=float)
    calls = []
    for j in range(g.shape[1]):
        values = nu.values(g[:, j])
        rows = [
            r.model_copy(update={nu.name: float(v)})
            for r, v in zip(target.rows, values, strict=True)
        ]
        calls.append((model, settings, {"rows": rows, "inclination": False}))
    for j, per in enumerate(per_recording_many(target, calls)):  # independent grid values
        scores[:, j] = per
    best = np.empty(n)
    for grp in np.unique(nu.groups):
        sel = nu.groups == grp
        j = int(np.argmin(scores[sel].sum(axis=0)))
        best[sel] = g[sel, j]
    return best

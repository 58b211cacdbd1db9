"""Simulator versus measurement on a campaign: where the model fails, and by how much.

Each recording is simulated with its manifest's parameters and the current
simulator config (:mod:`stiffnet.campaign.simulate`; the config's effects
and solver settings), at the recording's own length, and compared by the
phase-independent statistics of :mod:`stiffnet.measurement.statistics`
through :mod:`stiffnet.measurement.discrepancy`. The result says where the
disagreement sits: per component (which statistic), per group (contact, free
flight, global), per beta class, per recording.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from stiffnet.campaign import Campaign
from stiffnet.campaign.simulate import (
    DEFAULT_SEED,
    CampaignSolverSettings,
    check_rows,
    natural_frequency,
    simulate_rows,
    simulate_rows_contact,
)
from stiffnet.config.sim import SimulationConfig
from stiffnet.effects.base import Effect
from stiffnet.errors import SignalError
from stiffnet.geometry.calibration import beta_class
from stiffnet.measurement.discrepancy import (
    COMPONENTS,
    GROUPS,
    campaign_discrepancy,
    group_discrepancies,
    normalised_differences,
    recording_discrepancy,
)
from stiffnet.measurement.statistics import SignalStatistics, signal_statistics


@dataclass
class Comparison:
    """Measured and simulated statistics of every recording, and the JSON-ready summary."""

    measured: list[SignalStatistics]
    simulated: list[SignalStatistics | None]
    result: dict[str, Any]
    #: Per recording, the contact facts of its simulation
    #: (:func:`stiffnet.campaign.simulate.motion_contact`), when asked for.
    contact: list[dict[str, float]] | None = None


def config_effects(cfg: SimulationConfig) -> list[Effect]:
    """The effects of a simulation config."""
    return [e.build() for e in cfg.effects]


def config_settings(cfg: SimulationConfig, periods: float | None = None) -> CampaignSolverSettings:
    """The config's solver settings, simulating ``periods`` natural periods per row."""
    return CampaignSolverSettings(**cfg.solver.solver_settings().model_dump(), periods=periods)


def beta_class_name(beta: float | None) -> str:
    return "unknown" if beta is None else str(beta_class(beta))


def compare_campaign(
    campaign: Campaign,
    effects: Sequence[Effect] = (),
    settings: CampaignSolverSettings = CampaignSolverSettings(),
    seed: int = DEFAULT_SEED,
    contact: bool = False,
) -> Comparison:
    """Compare every recording with its simulation (see the module notes).

    ``contact``: also keep the contact facts of each row's simulation (``Comparison.contact``,
    the impact regime of :func:`stiffnet.measurement.evaluate.evaluate_campaign`), from the
    same simulation: the same signals, the rows simulated once.

    Returns
    -------
    Comparison
        ``result`` holds ``discrepancy`` (campaign), ``recordings`` (each
        ``recording``, ``beta``, ``discrepancy``, ``components`` (normalised),
        ``groups``, ``worst_component``, ``measured`` / ``simulated`` scalars),
        ``by_component`` (mean squared normalised difference), ``by_group``
        (share of the squared differences), ``by_beta_class`` and ``failure``
        (one line: where it fails).
    """
    from stiffnet.measurement.nuisance import resolve_rows
    from stiffnet.measurement.target import measured_statistics

    # a manifest without the simulation columns is completed from the recordings (forcing
    # frequency from the spectrum, beta from the model's estimate, documented defaults)
    rows, _ = resolve_rows(campaign)
    check_rows(rows, str(campaign.manifest_path))
    measured, lengths, _ = measured_statistics(campaign, rows)  # shared with diagnose
    facts = None
    if contact:
        sims, facts = simulate_rows_contact(rows, effects, lengths, seed, settings)
    else:
        sims = simulate_rows(rows, effects, lengths, seed, settings)
    simulated = [_simulated_statistics(row, a) for row, a in zip(rows, sims, strict=True)]
    recs = []
    sq = {c: [] for c in COMPONENTS}
    for row, m, s in zip(rows, measured, simulated, strict=True):
        recs.append(_recording_comparison(row, m, s, sq))
    result = {
        "campaign": str(campaign.folder),
        "effects": [repr(e) for e in effects],
        "seed": seed,
        **_campaign_summary(recs, sq),
    }
    return Comparison(measured, simulated, result, facts)


def _simulated_statistics(row: Any, accel: np.ndarray) -> SignalStatistics | None:
    """The statistics of a row's simulation (None where the simulation cannot be read)."""
    try:
        return signal_statistics(accel, row.fs_hz, natural_frequency(row), row.frequency_ratio)
    except SignalError:
        return None


def _recording_comparison(
    row: Any, m: SignalStatistics, s: SignalStatistics | None, sq: dict[str, list[float]]
) -> dict[str, Any]:
    """One recording's measured-versus-simulated entry; its squared normalised
    differences are added to `sq` (per component, for the campaign's means)."""
    if s is None:
        return {
            "recording": row.recording,
            "beta": row.beta,
            "discrepancy": None,
            "error": "simulation could not be analysed",
        }
    nd = normalised_differences(m, s)
    for c, v in nd.items():
        if np.isfinite(v):
            sq[c].append(v * v)
    present = {c: v for c, v in nd.items() if np.isfinite(v)}
    return {
        "recording": row.recording,
        "beta": row.beta,
        "beta_class": beta_class_name(row.beta),
        "discrepancy": recording_discrepancy(nd),
        "components": {c: (v if np.isfinite(v) else None) for c, v in nd.items()},
        "groups": group_discrepancies(nd),
        "worst_component": max(present, key=lambda c: abs(present[c])) if present else None,
        "measured": m.scalars(),
        "simulated": s.scalars(),
        "measured_impacts": int(m.impacts.size),
        "simulated_impacts": int(s.impacts.size),
    }


def _campaign_summary(recs: list[dict[str, Any]], sq: dict[str, list[float]]) -> dict[str, Any]:
    """The campaign's discrepancy, its recordings, and where it fails most: by component,
    by group of components, by beta class, and the worst recording."""
    per = [r["discrepancy"] for r in recs if r.get("discrepancy") is not None]
    by_component = {c: (float(np.mean(v)) if v else None) for c, v in sq.items()}
    totals = {g: float(sum(r["groups"][g] for r in recs if "groups" in r)) for g in GROUPS}
    total = sum(totals.values())
    by_group = {g: (v / total if total > 0 else 0.0) for g, v in totals.items()}
    by_class: dict[str, list[float]] = {}
    for r in recs:
        if r.get("discrepancy") is not None:
            by_class.setdefault(r["beta_class"], []).append(r["discrepancy"])
    worst_comp = max(
        (c for c in by_component if by_component[c] is not None),
        key=lambda c: by_component[c],
        default=None,
    )
    worst_group = max(by_group, key=by_group.get) if total > 0 else None
    worst_class = max(by_class, key=lambda k: np.mean(by_class[k])) if by_class else None
    return {
        "discrepancy": campaign_discrepancy(per),
        "recordings": recs,
        "by_component": by_component,
        "by_group": by_group,
        "by_beta_class": {k: float(np.mean(v)) for k, v in sorted(by_class.items())},
        "failure": {
            "group": worst_group,
            "component": worst_comp,
            "beta_class": worst_class,
            "recording": max(
                (r for r in recs if r.get("discrepancy") is not None),
                key=lambda r: r["discrepancy"],
                default={},
            ).get("recording"),
        },
    }

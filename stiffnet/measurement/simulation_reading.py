"""The reading by simulation beside the learned model's, in an evaluation.

:func:`with_simulation` adds to an evaluation
(:func:`stiffnet.measurement.evaluate.evaluate_campaign`) a fourth method, ``simulation``
(each recording's beta at the least discrepancy against the current effects,
:mod:`stiffnet.measurement.simulated_beta`), and per recording:

* ``simulation_*``: its class, beta, interval, least discrepancy over the recording's floor,
  whether it reproduces the recording, and why;
* ``simulation_alarm``: the learned model's beta interval and the simulation's are
  disjoint while the simulation reproduces the recording: the physics reproduces the
  recording at betas the model rules out, so the model's answer is not to be trusted
  silently (None where either has no interval);
* ``reading_method``, ``reading_class``, ``reading_beta`` (with
  :attr:`~stiffnet.measurement.simulated_beta.SimulatedBetaConfig.reading`): what the loop
  reports for the recording: the simulation's where it reproduces the recording, the
  learned model's otherwise. The learned model's own fields are never replaced.
* ``reading_undecided``: the reading took the simulation's class, the learned model read
  another, and their beta intervals overlap: neither excludes the other's class, so the
  class is undecided between them (a manifest whose amplitude is 10 % off is absorbed by
  beta where the profile is flat and still reproduces the recording: docs/measurement_loop.md).

Metrics: ``simulation`` (accuracy, macro-F1 and beta MAPE over the recordings it read,
``interval_coverage``, ``reproduced_share``, ``alarms``, ``learned_wrong_silent`` before and
after its alarm) and ``reading`` (its accuracy and beta MAPE, how many came from the
simulation, how many are undecided, and its wrong classes with none of the learned alarm,
the simulation's alarm or ``reading_undecided`` beside them).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stiffnet.campaign import Campaign
from stiffnet.campaign.simulate import CampaignSolverSettings
from stiffnet.effects.base import Effect
from stiffnet.measurement.metrics import (
    flag_share,
    interval_coverage,
    method_metrics,
    sliced_metrics,
)
from stiffnet.measurement.simulated_beta import (
    SimulatedBetaConfig,
    beta_by_least_discrepancy,
    simulated_beta_config,
)

#: ``reading_method`` values.
SIMULATION, LEARNED = "simulation", "learned"


def with_simulation(
    evaluation: dict[str, Any],
    campaign: Campaign,
    effects: Sequence[Effect],
    config: SimulatedBetaConfig | None = None,
    settings: CampaignSolverSettings | None = None,
) -> dict[str, Any]:
    """``evaluation`` with the simulation method, its alarm and the reading (module notes);
    ``simulation`` holds its rule, settings, CPU seconds, or why it did not run."""
    cfg = config or simulated_beta_config()
    if not cfg.enabled:
        evaluation["simulation"] = {"ran": False, "why": "switched off (simulated_beta.yaml)"}
        return evaluation
    sim = beta_by_least_discrepancy(campaign, effects, cfg, settings)
    rows = evaluation["recordings"]
    for r, s in zip(rows, sim["recordings"], strict=True):
        _add_row(r, s, cfg.reading)
    read = [r for r in rows if r["simulation_class"] is not None]
    metrics = {
        **method_metrics(read, "simulation_class", "simulation_beta"),
        "read": len(read),
        "interval_coverage": interval_coverage(read, "simulation_beta_interval"),
        "reproduced_share": flag_share([r["simulation_reproduced"] for r in read]),
        "alarms": sum(bool(r["simulation_alarm"]) for r in rows),
        "alarm_rate": flag_share([r["simulation_alarm"] for r in rows]),
        **_wrong_silent(rows),
    }
    evaluation["metrics"]["simulation"] = metrics
    if cfg.reading:
        evaluation["metrics"]["reading"] = {
            **method_metrics(rows, "reading_class", "reading_beta"),
            "from_simulation": sum(r["reading_method"] == SIMULATION for r in rows),
            "undecided": sum(bool(r["reading_undecided"]) for r in rows),
            "wrong_silent": sum(
                r["true_class"] is not None
                and r["reading_class"] != r["true_class"]
                and not (r.get("ood") or r["simulation_alarm"] or r["reading_undecided"])
                for r in rows
            ),  # fmt: skip
        }
    evaluation["slices"] = sliced_metrics(rows)  # the slices gain both methods too
    evaluation["simulation"] = {
        "ran": True,
        "effects": [repr(e) for e in effects],
        **{k: sim[k] for k in ("rule", "settings", "simulated", "cpu_seconds")},
    }
    return evaluation


def _add_row(r: dict[str, Any], s: dict[str, Any], reading: bool) -> None:
    """One recording's simulation fields, alarm and (with ``reading``) reading."""
    r.update(
        {
            "simulation_class": s["class"],
            "simulation_beta": s["beta"],
            "simulation_beta_interval": s["beta_interval"],
            "simulation_floor_ratio": s["floor_ratio"],
            "simulation_reproduced": s["reproduced"],
            "simulation_reason": s["reason"],
            "simulation_alarm": disjoint_alarm(r.get("beta_interval"), s),
        }
    )
    if reading:
        use = bool(s["reproduced"]) and s["class"] is not None
        r["reading_method"] = SIMULATION if use else LEARNED
        r["reading_class"] = s["class"] if use else r.get("class")
        r["reading_beta"] = s["beta"] if use else r.get("beta_estimate")
        r["reading_undecided"] = (
            use
            and s["class"] != r.get("class")
            and overlap(r.get("beta_interval"), s["beta_interval"])
        )


def overlap(a: Sequence[float] | None, b: Sequence[float] | None) -> bool:
    """True when both intervals are given and share a point."""
    return bool(a and b and not (a[1] < b[0] or b[1] < a[0]))


def disjoint_alarm(learned: Sequence[float] | None, sim: dict[str, Any]) -> bool | None:
    """True when the simulation reproduces the recording and its beta interval and the
    learned model's are disjoint; None where either interval is missing."""
    other = sim.get("beta_interval")
    if not learned or not other or sim.get("reproduced") is None:
        return None
    return bool(sim["reproduced"] and not overlap(learned, other))


def _wrong_silent(rows: Sequence[dict[str, Any]]) -> dict[str, int]:
    """Learned answers of the wrong class with no alarm: the model's own alarm alone, then
    with the simulation's alarm beside it."""
    wrong = [r for r in rows if r["true_class"] is not None and r["class"] != r["true_class"]]
    return {
        "learned_wrong": len(wrong),
        "learned_wrong_silent": sum(not r.get("ood") for r in wrong),
        "learned_wrong_silent_with_simulation_alarm": sum(
            not r.get("ood") and not r.get("simulation_alarm") for r in wrong
        ),
    }


def summary_lines(evaluation: dict[str, Any]) -> list[str]:
    """What the terminal says of the reading by simulation (nothing where it did not run)."""
    sim = evaluation.get("simulation") or {}
    if not sim.get("ran"):
        return [f"beta by simulation: not run ({sim['why']})"] if sim.get("why") else []
    m = evaluation["metrics"]["simulation"]
    rows = evaluation["recordings"]
    lost = [r["recording"] for r in rows if r.get("simulation_reproduced") is False]
    alarms = [r["recording"] for r in rows if r.get("simulation_alarm")]
    lines = [
        f"beta by simulation ({sim['rule']}): {m['read']} of {len(rows)} recordings read, "
        f"{sum(r.get('simulation_reproduced') is True for r in rows)} reproduced"
        + (f"; not reproduced by any beta: {', '.join(lost)}" if lost else "")
        + f" ({sim['cpu_seconds']['total']:.0f} s CPU)",
        "learned interval disjoint from the simulation's where it reproduces the recording: "
        + (", ".join(alarms) if alarms else "none"),
    ]
    if "reading" in evaluation["metrics"]:
        n = evaluation["metrics"]["reading"]["from_simulation"]
        lines.append(
            f"reading: the simulation's on {n} recordings (it reproduces them), the learned "
            f"model's on {len(rows) - n} (metrics row 'reading'; 'learned' is the model alone)"
        )
        undecided = [r["recording"] for r in rows if r.get("reading_undecided")]
        lines.append(
            "reading undecided (the simulation's class, the model's another, their intervals "
            "overlap): " + (", ".join(undecided) if undecided else "none")
        )
    return lines

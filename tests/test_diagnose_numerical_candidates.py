"""When a selection step fits the numerical-engine candidates.

In a step after the first, the closed-form candidates are fitted on top of the selected
effects and refitted jointly first; the numerical-engine ones (seconds per simulated batch)
only when the effect that closed-form step accepts leaves the model above the recordings'
own floors (more than chance-many recordings above ``AT_FLOOR_FACTOR`` times their floor):
otherwise nothing is left for them to explain. Then the step runs over every candidate, as
it would have, reusing the closed-form joint refits.

The rule is checked with the fits replaced by their results (ten recordings, each floor
0.05, so "at the floor" is a discrepancy within twice that, and a model at 1.0 before);
the end-to-end case, a campaign with a damped contact and a mount resonance diagnosed with
a numerical-engine candidate beside the closed-form ones, is slow.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from campaign_helpers import short_manifest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.campaign.simulate import FIT_SETTINGS, FIT_SETTINGS_NUMERICAL
from stiffnet.measurement import diagnose
from stiffnet.measurement.noise_floor import Floors

N = 10
FLOOR = 0.05
KEPT = ["sensor_dynamics"]


class _StubRun:
    """What a selection step uses of a diagnosis, its fits replaced by given results."""

    def __init__(self, results: dict[str, dict]) -> None:
        self.results, self.fitted = results, []
        floors = Floors(np.full(N, FLOOR))
        self.floors = {FIT_SETTINGS: floors, FIT_SETTINGS_NUMERICAL: floors}
        self.stage, self.target, self.names = "", None, [f"r{i}" for i in range(N)]
        self.bar = SimpleNamespace(step=lambda note=None: None)

    def fits(self, cands: list[str], fixed: list) -> list[dict]:
        self.fitted.append(list(cands))
        return [{"effect": n} for n in cands]

    def current(self, current, kept, params, new) -> np.ndarray:
        return np.full(N, 1.0)

    def judge(self, fit: dict, before: np.ndarray, kept: list[str]) -> dict:
        return {**self.results[fit["effect"]], "effect": fit["effect"]}


def _conditional(per: float, bic: float = -50.0) -> dict:
    """A conditional fit's ranking entry: every recording at ``per`` after it."""
    return {"per_recording": [per] * N, "bic_delta": bic, "improves": True, "params": {},
            "fitted": ["x"], "reasons": ["alone: ..."]}  # fmt: skip


def _step(monkeypatch, conditional: dict[str, dict], joint: dict[str, float], excess):
    """One step on top of ``KEPT``; ``joint``: each candidate's per-recording discrepancy
    after its joint refit. Returns the run, what was accepted, the steps, the entries and
    the joint refits run (by candidate)."""
    refits: list[str] = []

    def fit_joint(target, names, params, settings, **kw):
        refits.append(names[-1])
        return {"per_recording": np.full(N, joint[names[-1]]), "params": list(params)}

    monkeypatch.setattr(diagnose, "fit_joint", fit_joint)
    run = _StubRun(conditional)
    entries = {n: {"excess_reduction": e, "reasons": [f"{n} alone"]} for n, e in excess.items()}
    steps: list[dict] = []
    accepted = diagnose._step(
        run, list(excess), KEPT, [{"resonance_hz": 237.0}], {}, entries, steps
    )
    return run, accepted, steps, entries, refits


def test_a_closed_form_step_that_reaches_the_floor_leaves_the_numerical_ones_unfitted(
    monkeypatch,
):
    # contact damping's joint refit brings every recording to 0.06 (1.2x its floor)
    run, accepted, steps, entries, refits = _step(
        monkeypatch,
        {"contact_damping": _conditional(0.3), "gap_drift": _conditional(0.9, bic=-5.0)},
        {"contact_damping": 0.06, "gap_drift": 0.9},
        {"contact_damping": 0.9, "gap_drift": 0.1, "hertz_contact": 0.4, "restraint_mass": 0.2},
    )
    assert run.fitted == [["contact_damping", "gap_drift"]]  # the closed form only
    assert accepted[0] == "contact_damping" and refits == ["contact_damping"]
    assert [s["effect"] for s in steps] == ["contact_damping"]
    for n in ("hertz_contact", "restraint_mass"):
        (reason,) = entries[n]["reasons"]
        assert reason.startswith("not fitted on top of sensor_dynamics: contact_damping")
        assert "noise floors" in reason


def test_numerical_candidates_are_fitted_where_the_closed_form_leaves_an_excess(monkeypatch):
    # contact damping's joint refit leaves 0.5 (10x the floor): Hertz contact, whose
    # conditional fit scores better, is fitted, refitted first and accepted; dry friction
    # removed under SCREEN_EXCESS alone and is never refitted (the rule before)
    run, accepted, steps, entries, refits = _step(
        monkeypatch,
        {"contact_damping": _conditional(0.5), "hertz_contact": _conditional(0.1, bic=-80.0)},
        {"contact_damping": 0.5, "hertz_contact": 0.06},
        {"contact_damping": 0.5, "hertz_contact": 0.4, "dry_friction": 0.01},
    )
    assert run.fitted == [["contact_damping"], ["hertz_contact"]]
    assert accepted[0] == "hertz_contact" and refits == ["contact_damping", "hertz_contact"]
    assert [s["effect"] for s in steps] == ["hertz_contact"]  # the trial step is not kept
    assert entries["contact_damping"]["reasons"] == ["contact_damping alone"]


def test_the_closed_form_refit_is_reused_when_the_numerical_ones_do_not_win(monkeypatch):
    # the full step tries contact damping again (best score): its joint refit is not rerun
    run, accepted, steps, _, refits = _step(
        monkeypatch,
        {"contact_damping": _conditional(0.4, bic=-90.0), "hertz_contact": _conditional(0.8)},
        {"contact_damping": 0.4, "hertz_contact": 0.8},
        {"contact_damping": 0.5, "hertz_contact": 0.4},
    )
    assert run.fitted == [["contact_damping"], ["hertz_contact"]]
    assert accepted[0] == "contact_damping" and refits == ["contact_damping"]
    assert [s["effect"] for s in steps] == ["contact_damping"]


def test_the_first_step_fits_every_candidate_at_once():
    run = _StubRun({})
    entries = {n: {"excess_reduction": 0.4, "reasons": []} for n in ("hertz_contact", "adc")}
    out = diagnose._conditional_fits(run, list(entries), [], [], {}, entries)
    assert out == entries and run.fitted == []  # the single fits are the first step's


@pytest.mark.slow  # a numerical-engine candidate's fit alone, then the selection
def test_damped_contact_and_mount_with_a_numerical_candidate(tmp_path, monkeypatch):
    """Contact damping 0.25 and a 237-Hz mount resonance hidden, Hertz contact among the
    candidates: both closed-form effects found with their values, and Hertz contact fitted
    only alone (step 1), never on top of them once they reached the floor (the evidence's
    chain and damping, selected together in the first step)."""
    hidden = ["contact_damping:damping_ratio=0.25",
              "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0"]  # fmt: skip
    camp = simulate_campaign(short_manifest(tmp_path, 8), tmp_path / "c", hidden, seed=0)
    fitted: list[tuple[str, list[str]]] = []
    task = diagnose._fit_task

    def recorded(item):
        fitted.append((item[1], [e.name for e in item[2]]))
        return task(item)

    monkeypatch.setattr(diagnose, "_fit_task", recorded)
    d = diagnose.diagnose_campaign(
        load_campaign(camp),
        effects=["contact_damping", "sensor_dynamics", "hertz_contact"],
        inclination=False,
    )
    assert set(d["missing_effects"]) == {"contact_damping", "sensor_dynamics"}
    p = d["fitted_params"]
    assert p["contact_damping"]["damping_ratio"] == pytest.approx(0.25, rel=0.1)
    assert p["sensor_dynamics"]["resonance_hz"] == pytest.approx(237, rel=0.03)
    assert d["verdict"] == "explained"
    hertz = next(r for r in d["ranking"] if r["effect"] == "hertz_contact")
    # alone it removed enough of the excess to be refitted on top of the others (0.30)...
    assert hertz["excess_reduction"] >= diagnose.SCREEN_EXCESS
    # ... but the first step left nothing to explain: it was fitted alone only
    assert [fixed for n, fixed in fitted if n == "hertz_contact"] == [[]]
    assert hertz["reasons"][0].startswith(
        "nothing left to explain: sensor_dynamics, contact_damping bring the model"
    )

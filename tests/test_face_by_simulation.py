"""The face's refit by simulation (``refine_face``) reads one objective, its sweeps' own, and
so does the choice of the model a discovered law joins (``learned_law._law_scored``).

The campaign here is a stand-in for the simulator: each recording's discrepancy a closed
function of the face's mass, so the refit's search and decisions are tested in milliseconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from stiffnet.campaign.simulate import FIT_SETTINGS_NUMERICAL
from stiffnet.effects.contact_damping import ContactDamping
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.measurement.discrepancy import campaign_discrepancy
from stiffnet.measurement.face_by_simulation import refine_face
from stiffnet.measurement.fitting import SUBSET_NUMERICAL, objective_value
from stiffnet.measurement.learned_law import _law_scored

#: A scaled face as the grid gives it (the material beam struck through 20 beta).
START = {"exponent": 1.0, "reference_penetration": 0.76, "face_mass": 0.15,
         "face_stiffness_ratio": 1.1, "face_damping": 0.05, "face_mass_exponent": -0.796,
         "face_reference_beta": 14.0}  # fmt: skip
#: Whether each batch of points ran on a Dask worker (a thread-based cluster's: one memory).
ON_WORKER: list[bool] = []


def _on_worker() -> bool:
    try:
        from distributed import get_worker

        get_worker()
    except (ImportError, ValueError):
        return False
    return True


#: Two repeatable recordings and one whose halves differ (weighed down, as the floors do).
WEIGHTS = [1.0, 1.0, 0.02]


@dataclass
class _Row:
    recording: str
    fs_hz: float = 1000.0


@dataclass
class FaceMassCampaign:
    """A campaign target whose recordings answer the face's mass alone: the repeatable ones
    best at 0.12, the non-repeatable one worse the lighter the face (its discrepancy is the
    larger: the unweighted mean follows it, the weighted one the others)."""

    rows: list[Any]
    weights: list[float] | None
    base_effects: list[Any] = field(default_factory=list)
    inclination: bool = False
    evaluations: int = 0
    #: (rows, settings) of each batch of points (:meth:`per_recording_points`).
    batches: list[tuple[int, Any]] = field(default_factory=list)

    def observed(self) -> dict[str, float]:
        return {}

    def subset(self, idx: Any) -> FaceMassCampaign:
        w = None if self.weights is None else [self.weights[i] for i in idx]
        return replace(self, rows=[self.rows[i] for i in idx], weights=w)

    def _per(self, effects: list[Any]) -> np.ndarray:
        self.evaluations += 1
        face = [e for e in effects if e.name == LearnedContact.name]
        if not face:
            return np.full(len(self.rows), 100.0)
        m = float(face[0].params.face_mass)
        repeatable = 1.0 + 10.0 * np.log(m / 0.12) ** 2
        chattering = 30.0 + 100.0 * np.log(0.15 / m)
        return np.array([chattering if "chatter" in r.recording else repeatable for r in self.rows])

    def per_recording(self, effects: Any, settings: Any, **_: Any) -> np.ndarray:
        return self._per(list(effects))

    def per_recording_points(
        self, effects: Any, name: str, points: Any, settings: Any, **_: Any
    ) -> list[np.ndarray]:
        self.batches.append((len(self.rows), settings))
        ON_WORKER.append(_on_worker())
        return [self._per([*effects, LearnedContact(**p)]) for p in points]


def campaign(repeatable: int = 2) -> FaceMassCampaign:
    rows = [*(_Row(f"r{i}.csv") for i in range(repeatable)), _Row("chatter.csv")]
    return FaceMassCampaign(rows, [1.0] * repeatable + [WEIGHTS[-1]])


def test_refit_keeps_a_face_its_sweeps_kept_by_the_weighted_objective():
    """The first sweep (of the face's mass) lowers the weighted objective while the
    non-repeatable recording, weighed 0.02, rises: the refit keeps it (its sweeps' objective,
    the one the fits and the verdict's weighted excess read), its first sweep ends no higher
    than its start, and the unweighted mean is reported beside it."""
    target = campaign()
    at_start = target.per_recording([LearnedContact(**START)], FIT_SETTINGS_NUMERICAL)
    out = refine_face(target, target.rows, [], START, at_start, FIT_SETTINGS_NUMERICAL)
    o0 = objective_value(at_start, WEIGHTS)
    assert out["improves"]
    assert out["first_sweeps"][0] <= o0
    assert out["objective_discovered"] == pytest.approx(o0)
    assert out["objective_refit"] < o0
    # the box's grid point nearest 0.12 on the repeatable recordings' side
    assert out["params"]["face_mass"] == pytest.approx(0.131, rel=0.01)
    # the unweighted mean rose (the non-repeatable recording): reported, not decisive
    assert out["discrepancy_refit"] > out["discrepancy_discovered"]
    assert out["discrepancy_refit"] == pytest.approx(campaign_discrepancy(out["per_recording"]))


def test_refit_without_weights_is_the_campaign_discrepancy():
    """With equal weights the objective is the campaign discrepancy: the refit that would
    raise it is not kept, and the start's values come back."""
    target = replace(campaign(), weights=None)
    at_start = target.per_recording([LearnedContact(**START)], FIT_SETTINGS_NUMERICAL)
    out = refine_face(target, target.rows, [], START, at_start, FIT_SETTINGS_NUMERICAL)
    assert out["objective_refit"] == pytest.approx(out["discrepancy_refit"])
    assert out["objective_refit"] <= out["objective_discovered"]
    assert out["first_sweeps"][0] <= campaign_discrepancy(at_start)


def test_refit_sweeps_simulate_every_recording_at_the_full_settings():
    """A campaign of more recordings than a numerical design's screen holds
    (``SUBSET_NUMERICAL``): each sweep's batch is every recording at the settings the start
    was scored with, not a screen (a subset, a short transient begun warm), and the face
    found is the one the full scoring ranks first."""
    target = campaign(repeatable=SUBSET_NUMERICAL + 3)
    settings = FIT_SETTINGS_NUMERICAL
    at_start = target.per_recording([LearnedContact(**START)], settings)
    out = refine_face(target, target.rows, [], START, at_start, settings)
    assert len(target.batches) == 5  # the mass, the scale, the exponent, damping and ratio
    assert all(n == len(target.rows) and st == settings for n, st in target.batches)
    assert out["params"]["face_mass"] == pytest.approx(0.1145, rel=0.01)


@dataclass
class DampedOrNotCampaign(FaceMassCampaign):
    """A campaign whose recordings answer whether the model holds a contact damper: with it
    the repeatable recordings fit better and the non-repeatable one worse."""

    def _per(self, effects: list[Any]) -> np.ndarray:
        damped = any(e.name == ContactDamping.name for e in effects)
        repeatable, chattering = (5.0, 10.0) if damped else (8.0, 1.0)
        return np.array([chattering if "chatter" in r.recording else repeatable for r in self.rows])


def test_a_discovered_law_joins_the_model_the_weighted_objective_prefers():
    """The discovered law on two models, the selection (a damper) and the base alone: the
    unweighted mean prefers the base (the non-repeatable recording fits it), the objective,
    which weighs that recording 0.02, the selection: the law joins the selection."""
    c = campaign()
    target = DampedOrNotCampaign(c.rows, c.weights)
    models = [[ContactDamping()], []]
    law = SimpleNamespace(effect_params={"exponent": 1.0, "reference_penetration": 0.76})
    trials = [target.per_recording(m, FIT_SETTINGS_NUMERICAL) for m in models]
    assert campaign_discrepancy(trials[1]) < campaign_discrepancy(trials[0])
    after, kept, params, refit = _law_scored(target, target.rows, models, law,
                                             FIT_SETTINGS_NUMERICAL)  # fmt: skip
    assert kept is models[0] and refit is None
    assert objective_value(after, target.weights) == pytest.approx(
        objective_value(trials[0], target.weights)
    )


def test_refit_in_a_pool_sweeps_both_starts_on_the_workers_with_the_same_answer():
    """The first sweeps from the two starts do not depend on each other: in an evaluation
    pool they run as two tasks on the workers, the later sweeps here, and the refit ends
    where the in-process one ends, to the bit."""
    distributed = pytest.importorskip("distributed")
    from stiffnet.measurement.evaluation_pool import evaluation_pool

    def run(client: Any) -> tuple[dict[str, Any], list[bool]]:
        target = campaign()
        other = {**START, "face_mass": 0.05}
        at = [target.per_recording([LearnedContact(**p)], FIT_SETTINGS_NUMERICAL)
              for p in (START, other)]  # fmt: skip
        ON_WORKER.clear()
        with evaluation_pool(client):
            out = refine_face(target, target.rows, [], START, at[0], FIT_SETTINGS_NUMERICAL,
                              other=(other, at[1]))  # fmt: skip
        return out, list(ON_WORKER)

    here, where_here = run(None)
    with distributed.Client(processes=False, n_workers=2, threads_per_worker=1,
                            dashboard_address=None) as client:  # fmt: skip
        there, where_there = run(client)
    assert not any(where_here)
    # two first sweeps (one batch each) on the workers, then the scaled face's other four
    assert where_there == [True, True, False, False, False, False]
    assert here["params"] == there["params"]
    assert here["first_sweeps"] == there["first_sweeps"]
    np.testing.assert_array_equal(here["per_recording"], there["per_recording"])

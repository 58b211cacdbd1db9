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
from stiffnet.measurement import face_by_simulation
from stiffnet.measurement.discrepancy import campaign_discrepancy
from stiffnet.measurement.face_by_simulation import (
    SWEEP_RECORDINGS,
    SWEEP_RESCORED,
    FaceRefitSettings,
    face_refit_settings,
    refine_face,
)
from stiffnet.measurement.fitting import objective_value
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
    beta: float | None = None
    gap: float | None = None
    amplitude: float | None = None
    frequency_ratio: float | None = None


@dataclass
class FaceMassCampaign:
    """A campaign target whose recordings answer the face's mass alone: the repeatable ones
    best at 0.12, the non-repeatable one worse the lighter the face (its discrepancy is the
    larger: the unweighted mean follows it, the weighted one the others)."""

    rows: list[Any]
    weights: list[float] | None
    base_effects: list[Any] = field(default_factory=list)
    inclination: bool = False
    #: Each recording's initial state (None: the first), as the campaign's target holds them.
    starts: list[int] | None = None
    evaluations: int = 0
    #: (rows, settings) of each batch of points (:meth:`per_recording_points`).
    batches: list[tuple[int, Any]] = field(default_factory=list)
    #: The recordings of each batch of points, and the rows of each model scored alone.
    batch_rows: list[list[str]] = field(default_factory=list)
    alone: list[int] = field(default_factory=list)
    #: The points of each batch.
    batch_points: list[list[dict[str, float]]] = field(default_factory=list)

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
        self.alone.append(len(self.rows))
        return self._per(list(effects))

    def per_recording_points(
        self, effects: Any, name: str, points: Any, settings: Any, **_: Any
    ) -> list[np.ndarray]:
        self.batches.append((len(self.rows), settings))
        self.batch_rows.append([r.recording for r in self.rows])
        self.batch_points.append([dict(p) for p in points])
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


def spread_campaign(repeatable: int = 11) -> FaceMassCampaign:
    """More recordings than a sweep ranks on, their betas (1 ... n) out of order."""
    betas = np.random.default_rng(3).permutation(np.arange(1.0, repeatable + 2))
    rows = [_Row(f"r{i}.csv", beta=float(b)) for i, b in enumerate(betas[:-1])]
    rows.append(_Row("chatter.csv", beta=float(betas[-1])))
    return FaceMassCampaign(rows, [1.0] * repeatable + [WEIGHTS[-1]])


def _refit(target: FaceMassCampaign) -> dict[str, Any]:
    settings = FIT_SETTINGS_NUMERICAL
    at_start = target.per_recording([LearnedContact(**START)], settings)
    target.alone.clear()
    return refine_face(target, target.rows, [], START, at_start, settings)


def test_refit_sweeps_rank_on_a_spread_subset_and_score_the_chosen_alone():
    """A campaign of more recordings than a sweep ranks on: each sweep's batch (the start and
    the grid) is ``SWEEP_RECORDINGS`` recordings at the settings the start was scored with
    (not a screen), spanning the campaign's betas, and at most ``SWEEP_RESCORED`` points per
    sweep are scored on every recording."""
    target = spread_campaign()
    out = _refit(target)
    settings = FIT_SETTINGS_NUMERICAL
    assert len(target.batches) == 5  # the mass, the scale, the exponent, damping and ratio
    assert all(n == SWEEP_RECORDINGS < len(target.rows) and st == settings
               for n, st in target.batches)  # fmt: skip
    beta = {r.recording: r.beta for r in target.rows}
    for names in target.batch_rows:  # the least and the largest beta in every ranking
        assert {min(beta.values()), max(beta.values())} <= {beta[n] for n in names}
    assert 1 <= len(target.alone) <= 5 * SWEEP_RESCORED
    assert all(n == len(target.rows) for n in target.alone)
    assert out["params"]["face_mass"] == pytest.approx(0.1145, rel=0.01)


def test_refit_on_a_subset_ends_where_the_full_sweeps_end_when_they_rank_alike(monkeypatch):
    """Where the subset ranks the grid as every recording does (the stand-in's recordings
    agree), the refit ends on the same face, to the bit, as with every sweep on every
    recording, for less: fewer rows simulated in the sweeps' batches."""
    subset = spread_campaign()
    on_subset = _refit(subset)
    monkeypatch.setattr(face_by_simulation, "SWEEP_RECORDINGS", 10**6)
    everywhere = spread_campaign()
    full = _refit(everywhere)
    assert all(n == len(everywhere.rows) for n, _ in everywhere.batches)
    assert on_subset["params"] == full["params"]
    np.testing.assert_array_equal(on_subset["per_recording"], full["per_recording"])
    assert sum(n for n, _ in subset.batches) < sum(n for n, _ in everywhere.batches)


def test_a_sweep_whose_start_ranks_first_scores_nothing_alone():
    """The start already best on the subset (a face at the repeatable recordings' best mass,
    its other parameters not read by them): no point is scored alone, the start is kept."""
    target = spread_campaign()
    start = {**START, "face_mass": 0.12}
    at_start = target.per_recording([LearnedContact(**start)], FIT_SETTINGS_NUMERICAL)
    target.alone.clear()
    out = refine_face(target, target.rows, [], start, at_start, FIT_SETTINGS_NUMERICAL)
    assert target.alone == []
    assert out["params"]["face_mass"] == 0.12
    assert not out["improves"]


def test_a_sweep_simulates_the_start_once():
    """A box centred on the start (the face's mass, damping and beta scale: log-scale, a
    factor either side) has the start's own value in its grid's middle: the batch holds the
    start once, the grid's other points beside it; a box the start is not the middle of (the
    support's ratio, the mass exponent clipped at -1) keeps its whole grid."""
    target = spread_campaign()
    _refit(target)
    first = target.batch_points[0]  # the face's mass: 0.15 within a factor 1.5
    masses = [p["face_mass"] for p in first]
    assert masses[0] == START["face_mass"]
    assert len(first) == face_by_simulation.FACE_REFIT_GRID  # the start and 6 grid points
    assert sum(np.isclose(masses, START["face_mass"], rtol=1e-9)) == 1
    assert min(masses) == pytest.approx(0.1) and max(masses) == pytest.approx(0.225)
    for points in target.batch_points:  # no sweep simulates one point twice
        keys = [tuple(sorted(p.items())) for p in points]
        assert len(set(keys)) == len(keys)
        values = np.array([[p[k] for k in sorted(p)] for p in points])
        for j in range(1, len(values)):
            assert not np.allclose(values[j], values[0], rtol=1e-9, atol=0.0)
    ratio = LearnedContact.fit_space_at(START, 1000.0)
    box = {fp.name: fp for fp in ratio.free}
    grid = face_by_simulation.sweep_grid(box["face_stiffness_ratio"], "face_stiffness_ratio",
                                         START)  # fmt: skip
    assert len(grid) == face_by_simulation.FACE_REFIT_GRID


def test_face_refit_settings_are_validated():
    """The shipped settings load (``configs/face_refit.yaml``) and a sweep that ranks on one
    recording, or rescores none, is refused."""
    shipped = face_refit_settings()
    assert (shipped.sweep_recordings, shipped.sweep_rescored) == (
        SWEEP_RECORDINGS,
        SWEEP_RESCORED,
    )
    with pytest.raises(ValueError):
        FaceRefitSettings(sweep_recordings=1)
    with pytest.raises(ValueError):
        FaceRefitSettings(sweep_rescored=0)


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
    after, kept, params, refit, scored = _law_scored(target, target.rows, models, law,
                                                     FIT_SETTINGS_NUMERICAL)  # fmt: skip
    assert kept is models[0] and refit is None and scored.starts == [0] * len(target.rows)
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

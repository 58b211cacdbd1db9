"""How the simulator runs: the one model of its solver settings and their defaults.

:class:`~stiffnet.simulator.simulator.Simulator` takes it; the dataset config's
``solver`` section (:class:`stiffnet.config.sim.SolverConfig`) and the campaign
simulations (:class:`stiffnet.campaign.simulate.CampaignSolverSettings`) extend it
with what only they need, so every default and range is written here once.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class SolverSettings(BaseModel):
    """Transient rule and integrator steps of a simulation (frozen: usable as a key).

    Attributes
    ----------
    settle_tolerance : float
        The transient lasts until free oscillations have decayed to this fraction,
        ``t = -ln(tol) / xi`` (in (0, 1)).
    min_transient_periods : float
        Lower bound of the transient, in forcing periods.
    substeps : int
        RK4 steps per sample of the numerical integrator (used only when an effect
        is not piecewise linear).
    oversampled : int
        The samples are this many times finer than the motion needs (a sensor chain
        simulated at a multiple of the logger's rate): the numerical engine integrates
        as for samples ``oversampled`` times coarser and fills the rest by RK4's dense
        output (:func:`~stiffnet.simulator.numerical.simulate_numerical`); the
        closed-form engine is exact at any sample and ignores it.
    warm_start : float
        0 (default): a cold start, the numerical engine integrates the whole transient.
        In (0, 1]: a warm start. The closed-form engine integrates the transient with the
        numerical effects at their piecewise-linear form (the linear contact ``beta delta``
        they reduce to, their extra states at rest) and hands its state to the numerical
        engine for the last stretch only: long enough for a difference of ``warm_start``
        times the orbit between the two laws' orbits to decay to ``settle_tolerance``,
        ``ln(warm_start / settle_tolerance) / xi``, and at least
        :data:`~stiffnet.simulator.simulator.WARM_MIN_PERIODS` forcing periods
        (:meth:`~stiffnet.simulator.simulator.Simulator.transient_split`). The value is the
        effects' size bound: the random initial state's offset (the whole orbit, 1) is
        settled by the closed form, what is left is how far the effects move the orbit.
        The closed-form engine ignores it.
    record_substeps : {"sample", "transient"}
        How finely the numerical engine integrates the recorded samples. ``"sample"``
        (default): ``substeps`` RK4 substeps per sample of the most coarsely sampled row
        (:func:`~stiffnet.simulator.numerical.recording_substeps`). ``"transient"``: no
        substep shorter than the transient's (``substeps`` per step of the contact's step
        cap, ``min(2 pi / 40, 1.5 / sqrt(1 + beta))``), at least one per sample: a record
        sampled at a few hundred times ``f_n`` is otherwise integrated 3-5 times finer than
        the transient that settled it. The state at the record's start is the same either
        way; the samples move by RK4's error at the transient's step
        (docs/measurement_loop.md, "Where a loop iteration's dataset spends its CPU"). Not
        applied to an oversampled record (``oversampled > 1``). The loop's operating-point
        datasets use ``transient`` (:mod:`stiffnet.measurement.operating_points`).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    settle_tolerance: float = Field(1e-3, gt=0.0, lt=1.0)
    min_transient_periods: float = Field(20.0, ge=0.0, le=1e4)
    substeps: int = Field(8, ge=1, le=256, description="RK4 steps per sample (numerical engine)")
    oversampled: int = Field(
        1, ge=1, le=64, description="samples per sample the motion needs (numerical engine)"
    )
    warm_start: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="0: cold start; else the orbit difference the numerical stretch settles",
    )
    record_substeps: Literal["sample", "transient"] = Field(
        "sample",
        description="the record's RK4 substep: per sample, or no finer than the transient's",
    )

    def solver_settings(self) -> SolverSettings:
        """Just these settings, without the fields a subclass adds."""
        return SolverSettings(**{k: getattr(self, k) for k in SolverSettings.model_fields})

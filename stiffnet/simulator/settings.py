"""How the simulator runs: the one model of its solver settings and their defaults.

:class:`~stiffnet.simulator.simulator.Simulator` takes it; the dataset config's
``solver`` section (:class:`stiffnet.config.sim.SolverConfig`) and the campaign
simulations (:class:`stiffnet.campaign.simulate.CampaignSolverSettings`) extend it
with what only they need, so every default and range is written here once.
"""

from __future__ import annotations

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
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    settle_tolerance: float = Field(1e-3, gt=0.0, lt=1.0)
    min_transient_periods: float = Field(20.0, ge=0.0, le=1e4)
    substeps: int = Field(8, ge=1, le=256, description="RK4 steps per sample (numerical engine)")
    oversampled: int = Field(
        1, ge=1, le=64, description="samples per sample the motion needs (numerical engine)"
    )

    def solver_settings(self) -> SolverSettings:
        """Just these settings, without the fields a subclass adds."""
        return SolverSettings(**{k: getattr(self, k) for k in SolverSettings.model_fields})

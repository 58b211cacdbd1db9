"""Simulate every recording of a campaign with its manifest's parameters, as one batch.

The mapping from a manifest row to the simulator is the one of
:func:`stiffnet.campaign.simulate_campaign` (its constants and
:func:`~stiffnet.campaign.sensor_gain` are reused): ``f_n`` defaults to the
paper's 9.48 Hz, ``noise`` to :data:`~stiffnet.campaign.DEFAULT_NOISE`,
``fs_ratio = fs_hz / f_n``, the transient is discarded and accelerations are
written in g. Only the batching differs: all rows go through
:class:`~stiffnet.simulator.Simulator` together (one call per objective
evaluation in :mod:`stiffnet.measurement.diagnose`), every row is simulated for
the longest row's number of samples and cut to its own length.

Common random numbers: the initial state of each row is drawn from
``(seed, crc32(recording))`` (independent of the batch), and the batch's
noise and measurement effects from ``(seed, 1)``. The same call therefore
gives the same signals, so an objective built on them is a deterministic,
piecewise-smooth function of the effect parameters. The seed must differ from
the one a synthetic campaign was made with (default 0), or the simulation would
reproduce its noise exactly; :data:`DEFAULT_SEED` does.
"""

from __future__ import annotations

import zlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from stiffnet.campaign import DEFAULT_NOISE, SIMULATION_COLUMNS, ManifestRow, sensor_gain
from stiffnet.effects.base import Effect
from stiffnet.errors import StiffnetError
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
from stiffnet.simulator.simulator import Simulator

#: Seed of the comparison simulations (not 0, the default of simulate-campaign).
DEFAULT_SEED = 20_241


@dataclass(frozen=True)
class SolverSettings:
    """How the comparison simulations are run.

    ``periods``: natural periods simulated per row (None: the recording's
    length). Statistics need only a few tens of impacts, and the numerical
    engine (Hertz contact, friction, restraint mass) costs about 0.1 ms per
    RK4 step and row, so the fitting loop simulates short records.
    """

    periods: float | None = None
    settle_tolerance: float = 1e-3
    min_transient_periods: float = 20.0
    substeps: int = 8


#: Settings of the fitting loop: 40 natural periods after the full transient (cheap in
#: closed form; a transient cut short leaves a free oscillation the spectrum sees).
FIT_SETTINGS = SolverSettings(
    periods=40.0, settle_tolerance=1e-3, min_transient_periods=10.0, substeps=2
)
#: Numerical engine in the fitting loop: 16 natural periods (cost, see SolverSettings; on 10
#: the free-flight harmonic fit is already off by several tolerances on a clean record), after
#: the full transient too (a shorter one leaves a decaying free oscillation that a dissipative
#: effect such as dry friction "explains", a false alarm on a clean campaign).
FIT_SETTINGS_NUMERICAL = SolverSettings(
    periods=16.0, settle_tolerance=1e-3, min_transient_periods=10.0, substeps=2
)


def check_rows(rows: Sequence[ManifestRow], where: str = "manifest") -> None:
    """Refuse rows the simulator cannot reproduce (a simulation column is missing)."""
    for row in rows:
        missing = [c for c in SIMULATION_COLUMNS if getattr(row, c) is None]
        if missing:
            raise StiffnetError(
                f"{where}: {row.recording}: column {', '.join(missing)} is needed to simulate it"
            )


def natural_frequency(row: ManifestRow) -> float:
    return row.natural_frequency_hz or PAPER_NATURAL_FREQUENCY_HZ


def rows_batch(rows: Sequence[ManifestRow]) -> OscillatorBatch:
    """The oscillator parameters of the rows."""
    check_rows(rows)
    return OscillatorBatch(
        np.array([r.beta for r in rows], float),
        np.array([r.gap for r in rows], float),
        np.array([r.amplitude for r in rows], float),
        np.array([r.frequency_ratio for r in rows], float),
        np.array([r.damping_ratio for r in rows], float),
        np.array([natural_frequency(r) for r in rows], float),
    )


def initial_states(
    rows: Sequence[ManifestRow],
    batch: OscillatorBatch,
    seed: int,
    starts: Sequence[int] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-row initial state drawn like the simulator's, from ``(seed, crc32(recording))``.

    ``starts[i]`` > 0 draws row ``i``'s state from ``(seed, crc32, starts[i])`` instead: another
    basin of attraction for a multistable orbit (a nuisance the diagnosis profiles).
    """
    starts = [0] * len(rows) if starts is None else list(starts)
    u = np.array(
        [
            np.random.default_rng(
                [int(seed), zlib.crc32(r.recording.encode())] + ([int(k)] if k else [])
            ).uniform(-1, 1, 2)
            for r, k in zip(rows, starts, strict=True)
        ]
    ).reshape(len(rows), 2)
    return u[:, 0] * batch.amplitude, u[:, 1] * batch.amplitude * batch.omega


def simulate_rows(
    rows: Sequence[ManifestRow],
    effects: Sequence[Effect],
    lengths: Sequence[int],
    seed: int = DEFAULT_SEED,
    settings: SolverSettings = SolverSettings(),
    starts: Sequence[int] | None = None,
    effect_params: dict[str, dict[str, np.ndarray]] | None = None,
) -> list[np.ndarray]:
    """Simulate the rows as one batch; returns each row's acceleration in g.

    Parameters
    ----------
    rows : sequence of ManifestRow
        Rows with ``beta``, ``gap``, ``amplitude``, ``frequency_ratio`` and ``damping_ratio``.
    effects : sequence of Effect
        The simulator's effects (parameters given as numbers or ranges; a range
        is drawn per row from the batch generator).
    lengths : sequence of int
        Samples wanted per row (the recordings' lengths); with
        ``settings.periods`` each is capped at that many natural periods.
    seed : int
        Common-random-number seed (see the module notes).
    settings : SolverSettings
    starts : sequence of int, optional
        Initial-state variant per row (see :func:`initial_states`).
    effect_params : dict, optional
        Per-row parameter arrays by effect name (:meth:`Simulator.simulate`), e.g. the
        points of a fit's design stacked into one batch.

    Returns
    -------
    list of numpy.ndarray
    """
    if not rows:
        return []
    batch = rows_batch(rows)
    fs_ratio = np.array([r.fs_hz for r in rows]) / batch.natural_frequency_hz
    n = np.asarray(lengths, dtype=np.int64)
    if settings.periods is not None:
        n = np.minimum(n, np.ceil(settings.periods * fs_ratio).astype(np.int64))
    noise = np.array([DEFAULT_NOISE if r.noise is None else r.noise for r in rows])
    x0, v0 = initial_states(rows, batch, seed, starts)
    sim = Simulator(
        list(effects),
        settle_tolerance=settings.settle_tolerance,
        min_transient_periods=settings.min_transient_periods,
        substeps=settings.substeps,
    )
    try:
        res = sim.simulate(
            batch,
            fs_ratio,
            int(n.max()),
            noise=noise,
            rng=np.random.default_rng([int(seed), 1]),
            x0=x0,
            v0=v0,
            effect_params=effect_params,
        )
    except StiffnetError as exc:
        raise StiffnetError(f"simulating the campaign: {exc}") from None
    gains = np.array([sensor_gain(natural_frequency(r)) for r in rows])
    return [res.accel[i, : n[i]] * gains[i] for i in range(len(rows))]


def simulated_contact(
    rows: Sequence[ManifestRow],
    effects: Sequence[Effect],
    seed: int = DEFAULT_SEED,
    periods: float = 40.0,
) -> list[dict[str, float]]:
    """Contact facts of the rows' simulated steady state (for the impact regime).

    Returns per row ``contact_fraction`` (fraction of samples in contact),
    ``impacts_per_period`` (per forcing period) and ``max_penetration_ratio``
    (largest penetration ``x - e`` over the amplitude of free motion ``max |x|``).
    """
    batch = rows_batch(rows)
    fs_ratio = np.array([r.fs_hz for r in rows]) / batch.natural_frequency_hz
    n = int(np.ceil(periods * fs_ratio.max()))
    x0, v0 = initial_states(rows, batch, seed)
    sim = Simulator(
        [e for e in effects if e.kind == "dynamics"],
        settle_tolerance=0.05,
        min_transient_periods=10.0,
        substeps=2,
    )
    res = sim.simulate(batch, fs_ratio, n, rng=np.random.default_rng([int(seed), 1]), x0=x0, v0=v0)
    out = []
    for i in range(len(rows)):
        k = int(np.ceil(periods * fs_ratio[i]))
        x = res.x[i, :k]
        pen = float(np.max(x - batch.gap[i]))
        forcing_periods = k / fs_ratio[i] * batch.omega[i]
        out.append(
            {
                "contact_fraction": float(np.mean(res.contact_force[i, :k] > 0)),
                "impacts_per_period": float(res.impacts[i, :k].sum() / forcing_periods),
                "max_penetration_ratio": pen / max(float(np.max(np.abs(x))), 1e-12),
            }
        )
    return out


def impact_regime(contact: dict[str, float], grazing_ratio: float = 0.05) -> str:
    """``no_contact``, ``grazing`` (penetration under ``grazing_ratio`` of the motion) or
    ``impacting``."""
    if contact["contact_fraction"] <= 0 and contact["impacts_per_period"] <= 0:
        return "no_contact"
    if contact["max_penetration_ratio"] < grazing_ratio:
        return "grazing"
    return "impacting"

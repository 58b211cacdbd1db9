"""Manifest rows -> simulator: the one mapping from a campaign row to a simulation.

A row is simulated with its own parameters (``beta``, ``gap``, ``amplitude``,
``frequency_ratio``, ``damping_ratio``: :data:`SIMULATION_COLUMNS`); ``f_n``
defaults to the paper's 9.48 Hz, ``noise`` to :data:`DEFAULT_NOISE`,
``fs_ratio = fs_hz / f_n``, the transient is discarded and accelerations are
written in g (:func:`sensor_gain`). Two callers, one mapping:

- :func:`simulate_row`, one row as one task, for ``simulate-campaign``
  (:mod:`stiffnet.campaign.synthetic`): everything random is drawn from
  ``(seed, crc32(recording))``, so a file depends on its row alone.
- :func:`simulate_rows`, all rows as one batch, for ``compare``, ``diagnose`` and
  ``evaluate`` (:mod:`stiffnet.measurement`): every row is simulated for the
  longest row's number of samples and cut to its own length.

Common random numbers in :func:`simulate_rows`: the initial state of each row is
drawn from ``(seed, crc32(recording))`` (independent of the batch), and the batch's
noise and measurement effects from ``(seed, 1)``. The same call therefore gives the
same signals, so an objective built on them is a deterministic, piecewise-smooth
function of the effect parameters. The seed must differ from the one a synthetic
campaign was made with (default 0), or the simulation would reproduce its noise
exactly; :data:`DEFAULT_SEED` does.
"""

from __future__ import annotations

import math
import os
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import Field

from stiffnet.campaign.manifest import (
    MANIFEST_NAME,
    MODEL_LENGTH_UNIT_M,
    STANDARD_GRAVITY,
    ManifestRow,
)
from stiffnet.effects.base import Effect, MeasurementEffect
from stiffnet.errors import StiffnetError
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ, OscillatorBatch
from stiffnet.simulator.settings import SolverSettings
from stiffnet.simulator.simulator import WHITE_NOISE_ORDER, Simulator

#: Columns a row needs to be simulated.
SIMULATION_COLUMNS = ("beta", "gap", "amplitude", "frequency_ratio", "damping_ratio")
#: White-noise level (fraction of ``a w^2``) of simulated rows without ``noise``.
DEFAULT_NOISE = 0.02
#: Seed of the comparison simulations (not 0, the default of simulate-campaign).
DEFAULT_SEED = 20_241


class CampaignSolverSettings(SolverSettings):
    """The simulator's settings (:class:`~stiffnet.simulator.settings.SolverSettings`)
    and how long the comparison simulations of :func:`simulate_rows` are.

    ``periods``: natural periods simulated per row (None: the recording's length).
    ``lead_in_tolerance``: see the field.
    Statistics need only a few tens of impacts, and the numerical engine (Hertz
    contact, friction, restraint mass) costs about 0.1 ms per RK4 step and row, so
    the fitting loop simulates short records.
    """

    periods: float | None = Field(None, gt=0.0)
    #: None: the analog chain's standard lead-in (:func:`lead_in_seconds`). A fraction: the
    #: lead-in of a simulation that only ranks candidates (a fit's screen), long enough for
    #: the chain's slowest free mode to decay to this fraction of its start-up transient
    #: (:func:`screen_lead_in_seconds`), never longer than the standard one.
    lead_in_tolerance: float | None = Field(None, gt=0.0, lt=1.0)


#: Settings of the fitting loop: 40 natural periods after the full transient (cheap in
#: closed form; a transient cut short leaves a free oscillation the spectrum sees).
FIT_SETTINGS = CampaignSolverSettings(periods=40.0, min_transient_periods=10.0, substeps=2)
#: Numerical engine in the fitting loop: 16 natural periods (cost, see
#: CampaignSolverSettings; on 10 the free-flight harmonic fit is already off by several
#: tolerances on a clean record), after the full transient too (a shorter one leaves a
#: decaying free oscillation that a dissipative effect such as dry friction "explains",
#: a false alarm on a clean campaign).
FIT_SETTINGS_NUMERICAL = CampaignSolverSettings(
    periods=16.0, min_transient_periods=10.0, substeps=2
)
#: Settings of :func:`simulated_contact`: a short transient is enough to tell whether
#: the motion touches the restraint.
CONTACT_SETTINGS = SolverSettings(settle_tolerance=0.05, min_transient_periods=10.0, substeps=2)


def sensor_gain(natural_frequency_hz: float) -> float:
    """Model acceleration to g, for a model length unit of 1 mm.

    Model time is ``2 pi f_n t``, so one model unit of acceleration is
    ``L (2 pi f_n)^2`` m/s^2 with ``L`` the length unit. Any positive factor
    would do: stiffnet does not depend on the sensor gain.
    """
    return MODEL_LENGTH_UNIT_M * (2 * math.pi * natural_frequency_hz) ** 2 / STANDARD_GRAVITY


def check_rows(
    rows: Sequence[ManifestRow], manifest: str | os.PathLike[str] = MANIFEST_NAME
) -> None:
    """Refuse rows the simulator cannot reproduce (a simulation column is missing).

    The message names the manifest, the row's line and recording (``ManifestRow.where``).
    """
    for row in rows:
        missing = [c for c in SIMULATION_COLUMNS if getattr(row, c) is None]
        if missing:
            raise StiffnetError(
                f"{row.where(manifest)}: column {', '.join(missing)} is required for simulation"
            )


def natural_frequency(row: ManifestRow) -> float:
    """The row's ``f_n`` in Hz, the paper's 9.48 Hz when the manifest gives none."""
    return row.natural_frequency_hz or PAPER_NATURAL_FREQUENCY_HZ


def row_noise(row: ManifestRow) -> float:
    """The row's white-noise level, :data:`DEFAULT_NOISE` when the manifest gives none."""
    return DEFAULT_NOISE if row.noise is None else row.noise


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


# ------------------------------------------------------------- one row, one task


@dataclass(frozen=True)
class RowJob:
    """One campaign row to simulate (a task: picklable, independent of the others)."""

    row: ManifestRow
    effects: list[Effect]
    seed: int
    default_duration_s: float
    where: str


def simulate_row(job: RowJob) -> tuple[np.ndarray, dict[str, Any]]:
    """Simulate one campaign row: the recording in g and its entry of the campaign card.

    Initial state, drawn effect parameters, noise and measurement effects all come from
    ``(seed, crc32(recording))``: the same seed gives the same file whatever the other
    rows. The simulator runs with its default settings.
    """
    row = job.row
    f_n = natural_frequency(row)
    duration = row.duration_s or job.default_duration_s
    noise = row_noise(row)
    entropy = [job.seed, zlib.crc32(row.recording.encode())]
    # analog hardware: simulated faster, filtered, sampled, after a lead-in (as simulate_rows)
    k = oversampling(job.effects)
    n = int(round(duration * row.fs_hz))
    lead = int(np.ceil(lead_in_seconds(job.effects) * row.fs_hz * k))
    try:
        res = Simulator(job.effects).simulate(
            rows_batch([row]),
            fs_ratio=row.fs_hz / f_n * k,
            n_samples=n * k + lead,
            noise=noise,
            rng=np.random.default_rng(entropy),
        )
    except StiffnetError as exc:
        raise StiffnetError(f"{job.where}: {exc}") from None
    gain = sensor_gain(f_n)
    accel = res.accel[0, lead : lead + n * k : k] * gain
    entry = {
        "recording": row.recording,
        "seed_entropy": entropy,
        "n_samples": int(accel.size),
        "fs_hz": row.fs_hz,
        "natural_frequency_hz": f_n,
        "fs_ratio": row.fs_hz / f_n,
        "noise": noise,
        "sensor_gain": gain,
        "engine": res.engine,
        "n_impacts": int(res.impacts.sum()),
        "effects": {
            name: {k: float(v[0]) for k, v in params.items()}
            for name, params in res.effect_params.items()
        },
    }
    return accel, entry


# ------------------------------------------------------------ all rows, one batch


def simulate_rows(
    rows: Sequence[ManifestRow],
    effects: Sequence[Effect],
    lengths: Sequence[int],
    seed: int = DEFAULT_SEED,
    settings: CampaignSolverSettings = CampaignSolverSettings(),
    starts: Sequence[int] | None = None,
    effect_params: dict[str, dict[str, np.ndarray]] | None = None,
    oversample: bool = True,
) -> list[np.ndarray]:
    """Simulate the rows as one batch; returns each row's acceleration in g (the arguments:
    :func:`simulate_rows_contact`, which also returns the motion's contact facts).
    """
    return _simulate_rows(
        rows, effects, lengths, seed, settings, starts, effect_params, oversample, False
    )[0]


def simulate_rows_contact(
    rows: Sequence[ManifestRow],
    effects: Sequence[Effect],
    lengths: Sequence[int],
    seed: int = DEFAULT_SEED,
    settings: CampaignSolverSettings = CampaignSolverSettings(),
    starts: Sequence[int] | None = None,
    effect_params: dict[str, dict[str, np.ndarray]] | None = None,
    oversample: bool = True,
) -> tuple[list[np.ndarray], list[dict[str, float]]]:
    """Simulate the rows as one batch: each row's acceleration in g, and the contact facts
    of its simulated record (:func:`motion_contact`, for the impact regime), so that a
    caller wanting both (the loop's evaluation and discrepancy) simulates the rows once.

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
    settings : CampaignSolverSettings
    starts : sequence of int, optional
        Initial-state variant per row (see :func:`initial_states`).
    effect_params : dict, optional
        Per-row parameter arrays by effect name (:meth:`Simulator.simulate`), e.g. the
        points of a fit's design stacked into one batch.
    oversample : bool
        False: analog effects filter at the logger's rate (:func:`oversampling`), a cheaper
        and slightly biased simulation, for screening only.

    Returns
    -------
    accels : list of numpy.ndarray
    contact : list of dict
        Per row :func:`motion_contact` of the motion over the record returned (the lead-in
        dropped), at the simulation's rate.
    """
    return _simulate_rows(
        rows, effects, lengths, seed, settings, starts, effect_params, oversample, True
    )


def _simulate_rows(
    rows: Sequence[ManifestRow],
    effects: Sequence[Effect],
    lengths: Sequence[int],
    seed: int,
    settings: CampaignSolverSettings,
    starts: Sequence[int] | None,
    effect_params: dict[str, dict[str, np.ndarray]] | None,
    oversample: bool,
    with_contact: bool,
) -> tuple[list[np.ndarray], list[dict[str, float]]]:
    """:func:`simulate_rows_contact`; the contact facts only ``with_contact`` (a fit's
    objective calls this hundreds of times and reads only the signals)."""
    if not rows:
        return [], []
    batch = rows_batch(rows)
    fs_ratio = np.array([r.fs_hz for r in rows]) / batch.natural_frequency_hz
    n = np.asarray(lengths, dtype=np.int64)
    if settings.periods is not None:
        n = np.minimum(n, np.ceil(settings.periods * fs_ratio).astype(np.int64))
    noise = np.array([row_noise(r) for r in rows])
    x0, v0 = initial_states(rows, batch, seed, starts)
    k = oversampling(effects) if oversample else 1
    if k > 1:  # the motion needs the logger's rate; the numerical engine fills the rest
        settings = settings.model_copy(update={"oversampled": k})
    sim = Simulator(list(effects), settings)
    rng = np.random.default_rng([int(seed), 1])
    # the analog chain had been running before the record began: its start-up transient
    # (a charge amplifier's high-pass rings down over ~1/f_h) falls in a dropped lead-in
    lead_s = lead_in_seconds(effects, LONGEST_COMPARISON_LEAD_IN_S)
    if settings.lead_in_tolerance is not None:
        lead_s = min(lead_s, screen_lead_in_seconds(effects, settings.lead_in_tolerance))
    # white noise at the end of the chain, drawn for the logger's samples only: not for the
    # k - 1 dropped between them (the same law, k times fewer draws), nor for the dropped
    # lead-in (the same noise whatever its length)
    late = (k > 1 or lead_s > 0) and all(
        e.order < WHITE_NOISE_ORDER for e in effects if isinstance(e, MeasurementEffect)
    )
    lead = np.ceil(lead_s * np.array([r.fs_hz for r in rows]) * k)
    lead = lead.astype(np.int64)
    try:
        res = sim.simulate(
            batch,
            fs_ratio * k,
            int((n * k + lead).max()),
            noise=0.0 if late else noise,
            rng=rng,
            x0=x0,
            v0=v0,
            effect_params=effect_params,
            row_samples=n * k + lead,  # each row at its own rate, to its own length
        )
    except StiffnetError as exc:
        raise StiffnetError(f"simulating the campaign: {exc}") from None
    gains = np.array([sensor_gain(natural_frequency(r)) for r in rows])
    out = [res.accel[i, lead[i] : lead[i] + n[i] * k : k] for i in range(len(rows))]
    if late and np.any(noise):
        white = rng.standard_normal((len(rows), int(n.max())))
        std = noise * batch.forcing_scale
        out = [a + white[i, : a.size] * std[i] for i, a in enumerate(out)]
    record = [slice(lead[i], lead[i] + n[i] * k) for i in range(len(rows))] if with_contact else []
    contact = [
        motion_contact(res.x[i, r], res.contact_force[i, r], res.impacts[i, r],
                       batch.gap[i], fs_ratio[i] * k, batch.omega[i])
        for i, r in enumerate(record)
    ]  # fmt: skip
    return [a * gains[i] for i, a in enumerate(out)], contact


#: The motion is simulated this many times faster than the logger's rate when an effect
#: models analog hardware (a sensor's mounted resonance, its filters): the hardware filters
#: the continuous signal and the logger samples its output, whereas a filter run on the
#: logger's samples misses what happens between them (a spike a few samples wide, the
#: response near Nyquist). Measured on an independent rig with an analog sensor chain
#: (237 Hz, 1-2 kHz logging): filtering at the logger's rate, the resonance fitted at
#: 244 Hz instead of 237 and every recording stayed at 13-580x its floor; at 8x the fit is
#: 237-239 Hz and the impact-aligned waveform at 1.25-2 kHz within 0.3 tolerances (0.4-0.9
#: at 4x).
ANALOG_OVERSAMPLING = 8


#: Seconds of lead-in simulated, then dropped, before a record whose effects model analog
#: hardware: the filters start from rest, the hardware had been running. Measured on the
#: independent rig (no high-pass) against the fitted sensor's 1-Hz charge-amplifier
#: high-pass started at the first sample: the start-up transient put power below the
#: forcing frequency that the recording lacks, the spectrum off by 3.2-3.7 tolerances on
#: the operating point whose orbit is cleanest (forcing at f_n), 0.6-1.1 without it.
ANALOG_LEAD_IN_S = 1.5


#: The longest lead-in of the comparison simulations (:func:`simulate_rows`): a fit sweeps
#: the sensor's high-pass corner down to 0, and seven time constants of a 0.05 Hz corner
#: (22 s at 8x oversampling) would cost several evaluations; below 0.37 Hz the start-up
#: drift that is left is a slow offset a fit of the corner avoids, and such a corner
#: hardly touches a forcing near 10 Hz (a 0.6 degree lead at 0.1 Hz).
LONGEST_COMPARISON_LEAD_IN_S = 3.0


def lead_in_seconds(effects: Sequence[Effect], longest: float = 20.0) -> float:
    """Seconds simulated and dropped before each row: :data:`ANALOG_LEAD_IN_S` for an analog
    effect with a high-pass (``highpass_hz`` > 0: seven of its time constants, at least that
    long, at most ``longest``), a tenth of a second for one without (a resonance rings in
    within ms), else 0."""
    out = 0.0
    for e in effects:
        if not getattr(e, "analog", False):
            continue
        hp = getattr(getattr(e, "params", None), "highpass_hz", 0.0)
        hp = min(hp) if isinstance(hp, list | tuple) else float(hp or 0.0)
        lead = max(ANALOG_LEAD_IN_S, 7.0 / (2 * math.pi * hp)) if hp > 0 else 0.1
        out = max(out, min(lead, longest))
    return out


def chain_time_constant(effect: Effect) -> float | None:
    """Seconds of the slowest free mode of an analog effect's stages, read off the parameters
    a sensor chain names (``highpass_hz``: ``1 / w_h``; ``resonance_hz`` with
    ``resonance_damping``: ``1 / (zeta_r w_r)``; ``lowpass_hz`` with ``lowpass_order``: the
    Butterworth's slowest pole, ``1 / (w_l sin(pi / 2n))``); None when it names none of them.
    A stage given as a range is taken at its slowest end."""
    p = getattr(effect, "params", None)

    def value(key: str, slowest: Any) -> float | None:
        v = getattr(p, key, None)
        if v is None:
            return None
        return float(slowest(v)) if isinstance(v, list | tuple) else float(v)

    taus = []
    f_h = value("highpass_hz", min)
    if f_h is not None and f_h > 0:
        taus.append(1.0 / (2 * math.pi * f_h))
    f_r, zeta = value("resonance_hz", min), value("resonance_damping", min)
    if f_r is not None and zeta is not None and f_r > 0 and zeta > 0:
        taus.append(1.0 / (zeta * 2 * math.pi * f_r))
    f_l, order = value("lowpass_hz", min), value("lowpass_order", max)
    if f_l is not None and f_l > 0:
        n = max(1, int(round(order or 1)))
        taus.append(1.0 / (2 * math.pi * f_l * math.sin(math.pi / (2 * n))))
    return max(taus) if taus else None


def screen_lead_in_seconds(effects: Sequence[Effect], tolerance: float) -> float:
    """The lead-in of a simulation that only ranks candidates: ``ln(1 / tolerance)`` times the
    slowest time constant of the analog effects' chains (:func:`chain_time_constant`), the
    start-up transient left at ``tolerance`` of its size; an analog effect whose chain is
    unknown keeps its standard lead-in (:func:`lead_in_seconds`), 0 without analog effects.

    Why this bound: the chain's state at the record's start depends on the motion before it
    only through modes that decay as ``exp(-t / tau)``; the filters start in the steady state
    for a constant input, so what is left to decay is a fraction of the signal's swing (a
    1-Hz high-pass under a 10-Hz forcing: about a tenth), and a screen settles the motion's
    own transient to the same tolerance
    (:data:`stiffnet.measurement.fitting.SCREEN_SETTLE_TOLERANCE`).
    """
    out = 0.0
    for e in effects:
        if not getattr(e, "analog", False):
            continue
        tau = chain_time_constant(e)
        lead = lead_in_seconds([e]) if tau is None else math.log(1.0 / tolerance) * tau
        out = max(out, lead)
    return out


def oversampling(effects: Sequence[Effect]) -> int:
    """How many times the logger's rate the rows are simulated at (see
    :data:`ANALOG_OVERSAMPLING`; 1 without an effect that declares ``analog = True``)."""
    return ANALOG_OVERSAMPLING if any(getattr(e, "analog", False) for e in effects) else 1


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
    sim = Simulator([e for e in effects if e.kind == "dynamics"], CONTACT_SETTINGS)
    res = sim.simulate(batch, fs_ratio, n, rng=np.random.default_rng([int(seed), 1]), x0=x0, v0=v0)
    out = []
    for i in range(len(rows)):
        k = int(np.ceil(periods * fs_ratio[i]))
        out.append(motion_contact(res.x[i, :k], res.contact_force[i, :k], res.impacts[i, :k],
                                  batch.gap[i], fs_ratio[i], batch.omega[i]))  # fmt: skip
    return out


def motion_contact(
    x: np.ndarray,
    contact_force: np.ndarray,
    impacts: np.ndarray,
    gap: float,
    fs_ratio: float,
    omega: float,
) -> dict[str, float]:
    """Contact facts of one row's simulated motion (samples at ``fs_ratio`` per natural
    period, forcing at ``omega``): ``contact_fraction``, ``impacts_per_period`` (per forcing
    period) and ``max_penetration_ratio`` (deepest ``x - e`` over ``max |x|``)."""
    pen = float(np.max(x - gap))
    forcing_periods = x.size / fs_ratio * omega
    return {
        "contact_fraction": float(np.mean(contact_force > 0)),
        "impacts_per_period": float(impacts.sum() / forcing_periods),
        "max_penetration_ratio": pen / max(float(np.max(np.abs(x))), 1e-12),
    }


def impact_regime(contact: dict[str, float], grazing_ratio: float = 0.05) -> str:
    """``no_contact``, ``grazing`` (penetration under ``grazing_ratio`` of the motion) or
    ``impacting``."""
    if contact["contact_fraction"] <= 0 and contact["impacts_per_period"] <= 0:
        return "no_contact"
    if contact["max_penetration_ratio"] < grazing_ratio:
        return "grazing"
    return "impacting"

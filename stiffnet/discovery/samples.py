"""The force-state samples of every impact, in the model's units.

The restoring-force map (:func:`~stiffnet.restoring_force.restoring_force_estimate`)
is in the record's own units, with time in forcing radians ``tau = w t``. With
the record's gain ``G`` (model acceleration to the record's unit; for a
campaign in g, :func:`stiffnet.campaign.sensor_gain`) and ``k = 1 / w**2`` the
free-flight stiffness of the map, the integrals scale as ``x_map = G w**2 x``
and ``v_map = G w v``, so (docs/simulator.md, model units)::

    x = x_map k / G,    v = v_map sqrt(k) / G,    F_c = F_map / G

A linear law's beta is a ratio of slopes of one map and needs no ``G``; every
other term (an exponent, a knee, a Hunt-Crossley coefficient) has a length
scale, which is why the samples must be in model units.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from stiffnet.discovery.chain_choice import (
    keeps_chain,
    rejected_chains_share_mount,
    settled_shared_chain_verdict,
    shared_chain_verdict,
    unexplained_force,
)
from stiffnet.discovery.lowpass_profile import profiled_lowpass
from stiffnet.errors import StiffnetError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.chain import shared_chain, shared_chain_sheet
from stiffnet.restoring_force.estimate import (
    CHAIN_FIT_WHEN_NEEDED,
    RestoringForceResult,
    impact_regions,
)
from stiffnet.restoring_force.free_flight import CONTACT_SIGMAS

#: Forcing periods read per recording (the predictor's cross-check reads as many).
PERIODS = 24.0
#: Samples kept around each contact, as a fraction of the forcing period (the estimate's).
MARGIN = 0.03
#: Recordings of a campaign that get their sensor chain fitted (where their record calls for
#: one) before the others are read: where none of them keeps its chain, the others are read as
#: recorded (:func:`campaign_readings`). Three, as the evidence's shared chain
#: (:data:`stiffnet.measurement.evidence.CHAIN_RECORDINGS`).
CHAIN_RECORDINGS = 3
#: How far (a factor either way) the recordings' unit may read from g before the samples are
#: rescaled to the unit the table's motion measures (:func:`unit_over_g`): the rig's
#: campaigns in g read 0.997-1.026, in m/s^2 9.80-10.6.
UNIT_FROM_G_FACTOR = 1.2


@dataclass(frozen=True)
class ContactSamples:
    """The samples near the impacts of one recording, in model units.

    Attributes
    ----------
    recording : str
    displacement, velocity, force : numpy.ndarray
        Relative displacement ``x`` (its zero is the map's, not the onset),
        velocity ``v`` and contact force ``F_c`` on the samples near impacts.
    impact : numpy.ndarray
        Impact number of each sample (1 ... n_impacts).
    index : numpy.ndarray or None
        Each sample's index in the record: the time between impacts, over which a face
        still ringing from one impact rings freely into the next.
    onset : float
        The restoring-force law's contact onset (a start for the discovery's own).
    beta : float
        The restoring-force law's beta (a start).
    """

    recording: str
    displacement: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    impact: np.ndarray
    onset: float
    beta: float
    #: Each sample's index in the record (None: unknown, every impact's face starts at rest).
    index: np.ndarray | None = None

    @property
    def n_impacts(self) -> int:
        return int(self.impact.max()) if self.impact.size else 0


def contact_samples(
    result: RestoringForceResult, gain: float, recording: str = "", margin: int = 3
) -> ContactSamples | None:
    """The impacts' samples of one restoring-force map in model units (None without a law).

    Parameters
    ----------
    result : RestoringForceResult
        The estimate on the record (its map and contact law).
    gain : float
        Model acceleration to the record's unit.
    recording : str
        Name carried along.
    margin : int
        Samples kept on either side of each contact.
    """
    law = result.law
    if law is None or result.force.size == 0 or not np.isfinite(result.free_stiffness):
        return None
    k = float(result.free_stiffness)
    f = np.asarray(result.force, float)
    sigma = 1.4826 * float(np.median(np.abs(f - np.median(f))))
    labels, n = impact_regions(f > CONTACT_SIGMAS * max(sigma, 1e-300), margin)
    if n < 2:
        return None
    near = labels > 0
    return ContactSamples(
        recording=recording,
        displacement=result.displacement[near] * k / gain,
        velocity=result.velocity[near] * np.sqrt(k) / gain,
        force=f[near] / gain,
        impact=labels[near].astype(int),
        onset=float(law.onset) * k / gain,
        beta=float(law.stiffness) / k,
        index=np.flatnonzero(near),
    )


def record_contact_samples(
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    forcing_frequency_hz: float | None,
    gain: float,
    recording: str = "",
    periods: float = PERIODS,
    fit_chain: bool | dict[str, float] = True,
) -> tuple[ContactSamples | None, RestoringForceResult]:
    """Run the restoring-force estimate on one record and return its samples (and the estimate).

    The sensor chain is fitted only where the record's contact law explains too little,
    and its inverse kept only where it makes the force a function of the state
    (:func:`~.chain_choice.keeps_chain`; a chain's refusal stands); the high-pass is never
    profiled by the library's law (that tunes the corner until the library's law fits,
    bending a law it lacks), and beta's interval is not read (the samples need none; a fitted
    chain's other readings, mapped for it, cost a third of the chain's reading). ``fit_chain``
    False reads the record as recorded (no chain fitted): what the discovery keeps on a
    campaign whose accelerometer showed no chain (:func:`campaign_readings`). A data sheet
    (:data:`~stiffnet.restoring_force.chain.SENSOR_KEYS`) reads the record through that chain,
    fitted to the campaign's recordings, and fits none (the campaign's shared chain,
    :func:`campaign_readings`).
    """
    options = dict(natural_frequency_hz=natural_frequency_hz,
                   forcing_frequency_hz=forcing_frequency_hz, max_periods=periods,
                   profile_highpass_below_r2=-np.inf, interval=False)  # fmt: skip
    if isinstance(fit_chain, dict):
        r = restoring_force_estimate(accel, fs_hz, sensor=fit_chain, sensor_fitted=True,
                                     chain_fit_below_r2=-np.inf, **options)  # fmt: skip
        return result_samples(r, fs_hz, gain, recording), r
    when = CHAIN_FIT_WHEN_NEEDED if fit_chain else -np.inf
    r = restoring_force_estimate(accel, fs_hz, chain_fit_below_r2=when, **options)
    s = result_samples(r, fs_hz, gain, recording)
    chain = r.sensor
    if s is not None and chain is not None and chain.applied and chain.source == "fitted":
        plain = restoring_force_estimate(accel, fs_hz, chain_fit_below_r2=-np.inf, **options)
        s_plain = result_samples(plain, fs_hz, gain, recording)
        if not keeps_chain(s_plain, s):
            # the record as recorded; its estimate reports the chain as fitted, not applied
            return s_plain, replace(plain, sensor=replace(chain, applied=False))
    return s, r


def chain_outcome(result: RestoringForceResult) -> str:
    """What :func:`record_contact_samples` did with a sensor chain: ``"kept"`` (fitted and
    its inverse read), ``"rejected"`` (fitted, the record read as recorded) or ``"none"``
    (no chain fitted: the record's law explained enough, or it had no contact)."""
    chain = result.sensor
    if chain is None or chain.source != "fitted":
        return "none"
    return "kept" if chain.applied and chain.has_dynamics else "rejected"


def campaign_readings(
    read: Callable[[int, bool], tuple[ContactSamples | None, RestoringForceResult]],
    n: int,
    chain_recordings: int | None = CHAIN_RECORDINGS,
) -> dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception]:
    """Every recording's reading, the sensor chain fitted on a few where none keeps it.

    A campaign has one accelerometer, so whether a chain's inverse belongs to its records
    is one question: the chain is fitted (where the record calls for one) on recordings
    spread over the campaign, in rounds, until ``chain_recordings`` of them have had one
    fitted. Where none of them keeps its chain (its inverse does not make the force a
    better function of the state, :func:`~.chain_choice.keeps_chain`) and their rejected
    fits do not agree on a mount's resonance
    (:func:`~.chain_choice.rejected_chains_share_mount`), the others are read
    as recorded, which is what their own fits would almost always give (a law the library
    lacks, Hunt-Crossley, calls for a chain on every record and each fit is rejected) at
    a few seconds of CPU less per recording. Where one keeps it, every recording gets its
    own chain fitted, as with ``chain_recordings`` None, and then every recording is read
    again through the chain the kept ones share (:func:`shared_chain_readings`): one sensor's
    chain undone on all of them, or each record's own reading where that does not make the
    force more of a function of the state.

    Parameters
    ----------
    read : callable
        ``read(i, fit_chain)``: recording ``i``'s :func:`record_contact_samples` (``fit_chain``
        True, False or a data sheet).
    n : int
        Recordings.
    chain_recordings : int or None
        Recordings with a fitted chain that decide (None: every recording fitted).

    Returns
    -------
    dict
        Recording index to its ``(samples, estimate)``, or the exception its reading raised.
    """
    out: dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception] = {}

    def take(i: int, fit_chain: bool) -> None:
        try:
            out[i] = read(i, fit_chain)
        except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            out[i] = exc

    def outcomes() -> list[str]:
        return [chain_outcome(v[1]) for v in out.values() if not isinstance(v, Exception)]

    def sensor_seen() -> bool:
        readings = [v[1] for v in out.values() if not isinstance(v, Exception)]
        rejected = [r.sensor.to_dict() for r in readings if chain_outcome(r) == "rejected"]
        return "kept" in outcomes() or rejected_chains_share_mount(rejected)

    left = list(range(n))
    while chain_recordings and left and not sensor_seen():
        fitted = sum(o == "rejected" for o in outcomes())
        if fitted >= chain_recordings:
            break
        for i in _spread(left, chain_recordings - fitted):
            take(i, True)
        left = [i for i in left if i not in out]
    as_recorded = bool(chain_recordings) and not sensor_seen()
    for i in left:
        take(i, not as_recorded)
    return shared_chain_readings(read, out)


def shared_chain_readings(
    read: Callable[[int, Any], tuple[ContactSamples | None, RestoringForceResult]],
    own: dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception],
) -> dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception]:
    """Every recording read through the chain its kept readings share, where that reads better.

    Each record's own fit decides its chain alone, and a law the library lacks bends the
    pulse the chain fit models as a linear contact: behind one 240 Hz mount, a two-stage
    restraint (knee 0.3 mm, ratio 2) read 10 of 24 records as recorded (the mount left in;
    a right 240 Hz chain among the rejected) and 5 of the 14 kept with a low-pass the sensor
    lacks (beta 215-235 for 69-83 on three); that mix hid the second stage (a linear spring,
    95.9 % of the force), where the chain the kept ones share, undone on all, found it (knee
    0.297, ratio 1.99).

    The shared chain (:func:`~stiffnet.restoring_force.chain.shared_chain`: each stage
    that at least half of the kept chains show, at their median) is undone on every
    recording as a data sheet fitted to the campaign; its readings replace the own ones
    where they answer on as many recordings and the force is more of a function of the state
    (:func:`~.chain_choice.shared_chain_verdict`, the rule the restoring-force evidence
    applies too). Where it makes the force clearly *less* a function of the state and fewer
    than half of the records kept it, the chain is no sensor's and they are read as recorded
    too: behind a 250 Hz low-pass, a power-law contact (exponent 1.6) read 23 of 24 records as
    recorded and one (beta 62) through a spurious 172 Hz resonance and 3.3 Hz high-pass (read
    as beta 5, onset -0.94 mm); that one record turned the pooled law into a linear spring
    (94.5 % of the force), where all 24 as recorded read a power law (exponent 1.71). The
    shared chain, undone on all, left 12 times the own readings' median unexplained force.
    The records are read through the shared chain only until that verdict is settled
    (:func:`_shared_verdict`): a refuted chain's readings are thrown away.

    Parameters
    ----------
    read : callable
        As :func:`campaign_readings`'s.
    own : dict
        Each recording's own reading (or the exception it raised).

    Returns
    -------
    dict
        `own`, or every recording's reading through the shared chain.
    """
    keeping = [i for i, v in own.items()
               if not isinstance(v, Exception) and chain_outcome(v[1]) == "kept"]  # fmt: skip
    sheet = shared_chain_sheet(shared_chain([own[i][1].sensor.to_dict() for i in keeping]))
    if sheet is None:
        return own
    answered = sum(not isinstance(v, Exception) for v in own.values())
    verdict = _shared_verdict(read, own, sheet, len(keeping), answered)
    if isinstance(verdict, dict):
        return verdict
    if verdict == "own":
        return own
    # a minority's chain and no sensor's: they are read as recorded, as the others
    out = dict(own)
    for i in keeping:
        try:
            out[i] = read(i, False)
        except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            out[i] = exc
    return out


def _shared_verdict(
    read: Callable[[int, Any], tuple[ContactSamples | None, RestoringForceResult]],
    own: dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception],
    sheet: dict[str, float],
    keeping: int,
    answered: int,
) -> dict[int, Any] | str:
    """The records read through the shared chain ``sheet`` until its verdict is settled
    (:func:`~.chain_choice.settled_shared_chain_verdict`): every reading (a dict) where the
    shared chain stands, else the verdict ``"own"`` or ``"recorded"``.

    The records are read spread over the campaign (first, last, middle, quarters, ...), so
    that the first read are not all of one beta. A refuted chain's readings are thrown
    away; on the power law behind a 250 Hz low-pass the 24 such readings cost more than the
    rest of the discovery's maps (58.6 of 107 s of the diagnosis' CPU).
    """

    def samples(got: Any) -> ContactSamples | None:
        return None if isinstance(got, Exception) else got[0]

    order = sorted(own)
    own_lost = [unexplained_force(samples(own[i])) for i in order]
    shared_lost: list[float | None] = [None] * len(order)
    unread = [True] * len(order)
    shared: dict[int, tuple[ContactSamples | None, RestoringForceResult] | Exception] = {}
    for k in _spread_order(list(range(len(order)))):
        i = order[k]
        try:
            shared[i] = read(i, sheet)
        except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            shared[i] = exc
        shared_lost[k], unread[k] = unexplained_force(samples(shared[i])), False
        settled = settled_shared_chain_verdict(own_lost, shared_lost, unread, keeping, answered)
        if settled is not None:
            return settled
    readings = [[samples(own[i]) for i in order], [samples(shared[i]) for i in order]]
    verdict = shared_chain_verdict(*readings, keeping, answered)
    return {i: shared[i] for i in own} if verdict == "shared" else verdict


def _spread_order(indices: list[int]) -> list[int]:
    """Every one of ``indices``, in an order that spreads each prefix over them (the ends,
    the middle, the quarters, ...)."""
    out: list[int] = []
    k = 2
    while len(out) < len(indices):
        out += [i for i in _spread(indices, k) if i not in out]
        k = 2 * k - 1
    return out


def _spread(indices: list[int], k: int) -> list[int]:
    """``k`` of ``indices`` evenly spread (first and last included)."""
    return sorted({indices[round(j * (len(indices) - 1) / max(k - 1, 1))] for j in range(k)})


def result_samples(
    r: RestoringForceResult, fs_hz: float, gain: float, recording: str = ""
) -> ContactSamples | None:
    """:func:`contact_samples` of one record's estimate, with the margin of
    :data:`MARGIN` forcing periods around each contact."""
    margin = max(2, int(MARGIN * fs_hz / r.forcing_frequency_hz))
    return contact_samples(r, gain, recording, margin)


def campaign_contact_samples(
    campaign: Any,
    rows: Sequence[Any],
    periods: float = PERIODS,
    chain_recordings: int | None = CHAIN_RECORDINGS,
    notes: list[str] | None = None,
    lowpass: dict[str, Any] | None = None,
) -> tuple[list[ContactSamples], list[dict[str, Any]]]:
    """Samples of every recording of a campaign whose map has a contact law, and why not others.

    ``rows`` are the campaign's rows with the natural frequency and forcing ratio
    resolved (diagnose's); recordings are read in g for a model length of 1 mm
    (:func:`stiffnet.campaign.sensor_gain`), unless the table's motion measures their unit
    more than :data:`UNIT_FROM_G_FACTOR` from g (:func:`unit_over_g`; the samples are then
    in that unit, and ``notes`` says so). The sensor chain is fitted as
    :func:`campaign_readings` says (``chain_recordings``); where no reading kept one and a
    rejected fit showed a low-pass, its corner is profiled by the law the maps read through it
    (:func:`~.lowpass_profile.profiled_lowpass`), and ``lowpass`` (when given) is filled with
    the low-pass kept (its corner, order and profile; left empty where none is).
    """
    from stiffnet.campaign import sensor_gain

    def read(i: int, fit_chain: bool) -> tuple[ContactSamples | None, RestoringForceResult]:
        row = rows[i]
        fn = row.natural_frequency_hz
        ff = fn * row.frequency_ratio if fn and row.frequency_ratio else None
        rec = campaign.recording(i)
        return record_contact_samples(
            rec.accel, rec.fs_hz, fn, ff, sensor_gain(fn), row.recording, periods, fit_chain
        )

    readings = campaign_readings(read, len(rows), chain_recordings)
    readings, profiled = profiled_lowpass(read, readings, [r.fs_hz for r in rows])
    if profiled is not None and lowpass is not None:
        lowpass.update(profiled)
    out, skipped, units = [], [], []
    for i, row in enumerate(rows):
        got = readings[i]
        if isinstance(got, Exception):
            skipped.append({"recording": row.recording, "reason": str(got)})
        elif got[0] is None:
            skipped.append({"recording": row.recording, "reason": got[1].reason})
        else:
            out.append(got[0])
            units.append(unit_over_g(got[1], getattr(row, "amplitude", None)))
    read_units = [u for u in units if u is not None]
    unit = float(np.median(read_units)) if read_units else 1.0
    if notes is not None and not read_units:
        notes.append("the recordings' acceleration taken to be in g (no forcing amplitude "
                     "to measure their unit against)")  # fmt: skip
    if not 1 / UNIT_FROM_G_FACTOR <= unit <= UNIT_FROM_G_FACTOR:
        out = [rescaled(s, unit) for s in out]
        if notes is not None:
            notes.append(f"the recordings' acceleration unit is {unit:.3g} g (the table's motion "
                         f"against the manifest's forcing, median of {len(read_units)}; 9.81: "
                         "m/s^2): the samples' lengths read in it, not in g")  # fmt: skip
    return out, skipped


def unit_over_g(result: RestoringForceResult, amplitude: float | None) -> float | None:
    """The record's acceleration unit in g, measured: the table's displacement amplitude at
    the forcing frequency on the map, in model lengths through :func:`sensor_gain`'s g,
    over the manifest's forcing amplitude ``a`` (model lengths). None without a law, the
    map's table or ``a``.

    The map's lengths scale with the record's unit (module notes): a campaign in g reads
    1 (0.997-1.026 on the independent rig's g campaigns, 4 of them), one in m/s^2 9.81
    (9.80-10.6 on its beam-tip campaign); read as g, that one's penetrations were 9.81 times
    deeper, out of the learned law's range.
    """
    pot = result.penetration_over_table
    if result.law is None or not pot or not amplitude or not np.isfinite(result.free_stiffness):
        return None
    from stiffnet.campaign import sensor_gain

    table_map = float(result.law.reference_penetration) / float(pot)
    gain = sensor_gain(result.natural_frequency_hz)
    ratio = table_map * float(result.free_stiffness) / (gain * float(amplitude))
    return ratio if np.isfinite(ratio) and ratio > 0 else None


def rescaled(samples: ContactSamples, unit: float) -> ContactSamples:
    """``samples`` read in g re-read in a unit of ``unit`` g: every length, velocity and
    force over ``unit`` (beta, a ratio of slopes, unchanged)."""
    return replace(samples, displacement=samples.displacement / unit,
                   velocity=samples.velocity / unit, force=samples.force / unit,
                   onset=samples.onset / unit)  # fmt: skip

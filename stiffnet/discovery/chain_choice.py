"""Which reading of a record the discovery keeps: with its fitted sensor chain undone, or not.

The restoring-force estimate, where the contact law explains too little, fits a
sensor chain to the impacts' pulses and keeps its inverse where the *library's*
contact law then explains more. A law the library lacks bends the pulse as a
chain would (a Hunt-Crossley contact reads as a low-pass near the contact's
frequency), so that test can keep a spurious chain, and its inverse (with a
high-pass re-fitted after it) bends the force-state samples into terms the rig
does not have: on the independent rig's Hunt-Crossley campaign, one of eight
recordings (beta 12 read as 0.36) turned the law into ``hinge + hunt_crossley``.

The discovery asks the question without a law: a chain is the record's where
undoing it makes the contact force a *function of the state*, i.e. where a
smooth static function of penetration and velocity (a full cubic in ``x`` and
``v``, which holds the linear spring, Kelvin-Voigt, Hunt-Crossley and any mild
curvature) predicts the force of held-out impacts better. A real low-pass left
in the record delays the force against the state (loops no static function
fits); a spurious one's inverse adds ringing and loops of its own. Whether a campaign's
shared chain stands is one rule (:func:`shared_chain_verdict`) for the discovery and the
restoring-force evidence (:mod:`stiffnet.measurement.evidence`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # samples.py asks this module which reading to keep
    from stiffnet.discovery.samples import ContactSamples

#: Folds of whole impacts for the held-out R2.
N_FOLDS = 4
#: The chain-undone reading is kept only where it leaves at most this share of the
#: unexplained force of the record as recorded (a real chain's inverse removes most of it).
MAX_UNEXPLAINED_RATIO = 0.9
#: Rejected chain fits whose resonances all lie within this factor of one another (highest
#: over lowest) agree on a mount (:func:`rejected_chains_share_mount`). Behind one 240 Hz mount
#: (zeta 0.04) a two-stage restraint's three first fits read 236.9 and 240.2 Hz (1.014) with
#: low-passes of 176 and 258 Hz (1.46: the contact's soft start, which tracks beta).
MOUNT_AGREEMENT = 1.05


def _cubic_design(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Every monomial ``x**i v**j`` with ``i + j <= 3`` of the standardised state."""
    xs = (x - x.mean()) / max(float(x.std()), 1e-300)
    vs = (v - v.mean()) / max(float(v.std()), 1e-300)
    return np.column_stack([xs**i * vs**j for i in range(4) for j in range(4 - i)])


def state_function_r2(samples: ContactSamples, n_folds: int = N_FOLDS) -> float:
    """Held-out R2 of the contact force as a static cubic function of ``(x, v)``.

    Parameters
    ----------
    samples : ContactSamples
        One recording's impacts (any units: the R2 is scale-free).
    n_folds : int
        Folds of whole impacts (impact ``i`` is in fold ``i mod n_folds``).

    Returns
    -------
    float
        ``1 - SSE_held_out / SST`` over the samples beyond the onset of every fold (``-inf``
        with fewer impacts than folds).
    """
    # beyond the law's onset: the clip at release (zero force before the onset) is a kink
    # no polynomial follows
    inside = samples.displacement > samples.onset
    f = np.asarray(samples.force, float)[inside]
    if samples.n_impacts < n_folds or f.size < 20:
        return -np.inf
    design = _cubic_design(samples.displacement[inside], samples.velocity[inside])
    fold = samples.impact[inside] % n_folds
    sse = 0.0
    for k in range(n_folds):
        test = fold == k
        coef = np.linalg.lstsq(design[~test], f[~test], rcond=None)[0]
        sse += float(np.sum((design[test] @ coef - f[test]) ** 2))
    sst = float(np.sum((f - f.mean()) ** 2))
    return 1.0 - sse / max(sst, 1e-300)


def keeps_chain(plain: ContactSamples | None, undone: ContactSamples | None) -> bool:
    """Rule: keep the chain-undone reading where it makes the force a function of the state.

    True where the record as recorded has no samples, or where the undone reading's
    held-out unexplained force (:func:`state_function_r2`) is at most
    :data:`MAX_UNEXPLAINED_RATIO` of the plain one's.
    """
    if undone is None:
        return False
    if plain is None:
        return True
    r2_plain, r2_undone = state_function_r2(plain), state_function_r2(undone)
    if not np.isfinite(r2_undone):
        return False
    if not np.isfinite(r2_plain):
        return True
    return 1.0 - r2_undone <= MAX_UNEXPLAINED_RATIO * (1.0 - r2_plain)


def unexplained_force(samples: ContactSamples | None) -> float | None:
    """A reading's held-out unexplained force, ``1 -`` :func:`state_function_r2` (None: no
    reading; ``inf`` where too few impacts to tell)."""
    return None if samples is None else 1.0 - state_function_r2(samples)


def shared_and_own_unexplained(
    own: Sequence[ContactSamples | None], shared: Sequence[ContactSamples | None]
) -> tuple[float, float] | None:
    """Median held-out unexplained force (:func:`state_function_r2`) of the own and the shared
    readings over the recordings both answer (None where none does)."""
    both = [(o, s) for o, s in zip(own, shared, strict=True) if o is not None and s is not None]
    lost = np.array([(1.0 - state_function_r2(o), 1.0 - state_function_r2(s)) for o, s in both])
    lost = lost[np.isfinite(lost).all(axis=1)] if lost.size else lost
    if not lost.size:
        return None
    own_median, shared_median = np.median(lost, axis=0)
    return float(own_median), float(shared_median)


def keeps_shared_chain(
    own: Sequence[ContactSamples | None], shared: Sequence[ContactSamples | None]
) -> bool:
    """Rule: a campaign's shared chain replaces the records' own readings where it answers on
    as many recordings and its median held-out unexplained force (:func:`state_function_r2`,
    over the recordings both readings answer) is at most :data:`MAX_UNEXPLAINED_RATIO` of
    the own readings' (a clear gain, as :func:`keeps_chain` asks of one record's chain)."""
    if sum(s is not None for s in shared) < sum(s is not None for s in own):
        return False
    medians = shared_and_own_unexplained(own, shared)
    return medians is not None and medians[1] <= MAX_UNEXPLAINED_RATIO * medians[0]


def refutes_shared_chain(
    own: Sequence[ContactSamples | None], shared: Sequence[ContactSamples | None]
) -> bool:
    """Rule: the campaign's records refute the chain its kept readings share where, undone on
    all of them, it leaves a median held-out unexplained force at least ``1 /``
    :data:`MAX_UNEXPLAINED_RATIO` times the own readings' (the mirror of
    :func:`keeps_shared_chain`: a clear loss).

    A sensor's chain acts on every record, so undoing the right one never makes the force
    clearly less a function of the state; a chain that does so is a reading of the records
    that kept it (a law the library lacks bending their pulses), not the sensor's.
    """
    medians = shared_and_own_unexplained(own, shared)
    return medians is not None and medians[1] * MAX_UNEXPLAINED_RATIO >= medians[0]


def rejected_chains_share_mount(chains: Sequence[dict | None]) -> bool:
    """Rule: whether chain fits each rejected on its own record (:func:`keeps_chain`) still
    agree on one mount's resonance, so the campaign's sensor has one.

    A record's own test can reject a right chain where a law the library lacks bends the
    pulse too (a two-stage restraint behind a 240 Hz mount: the first three records' fits
    all rejected, two with the mount at 236.9 and 240.2 Hz), and reading the campaign as
    recorded then leaves the mount's ring on every map (the hinge hidden: a linear spring,
    65.8 % of the force, where the mount undone reads the hinge at 99.4 %). A resonance
    that records of different beta read at one frequency is the sensor's; a stiffening
    contact's soft start reads as a low-pass whose corner follows beta, not as a resonance.

    Parameters
    ----------
    chains : sequence of dict or None
        The rejected fits' :meth:`~stiffnet.restoring_force.chain.SensorChain.to_dict`.

    Returns
    -------
    bool
        True where at least two of them, and at least half, carry a resonance, all within
        :data:`MOUNT_AGREEMENT` of one another.
    """
    seen = [c for c in chains if c]
    hz = [float(c["resonance_hz"]) for c in seen if c.get("resonance_hz")]
    if len(hz) < 2 or 2 * len(hz) < len(seen):
        return False
    return max(hz) <= MOUNT_AGREEMENT * min(hz)


def settled_shared_chain_verdict(
    own: Sequence[float | None],
    shared: Sequence[float | None],
    unread: Sequence[bool],
    keeping: int,
    answered: int,
) -> str | None:
    """The verdict :func:`shared_chain_verdict` will give once every record is read through the
    shared chain, where the records still unread cannot change it; else None.

    A shared chain the records refute, or that reads no better than their own readings, is
    thrown away: its readings of the records not yet read could only move the medians. Each
    unread record may yet read anything, from a perfect fit (no unexplained force) to none at
    all (leaving the comparison, its own reading with it), so the verdict is settled where it
    holds at the extremes: the shared median at its lowest (every unread record at zero)
    against the own median at its highest (the unread records with the largest own losses
    counted), and the reverse. ``"shared"`` is never settled early: it keeps every reading.

    Parameters
    ----------
    own, shared : sequence of float or None
        Each record's held-out unexplained force (:func:`unexplained_force`) as read alone and
        through the shared chain (None: no reading; ``shared`` is ignored where ``unread``).
    unread : sequence of bool
        The records not yet read through the shared chain.
    keeping, answered : int
        As :func:`shared_chain_verdict`'s.

    Returns
    -------
    str or None
        ``"recorded"`` or ``"own"`` where every outcome of the unread records gives it.
    """

    def finite(value: float | None) -> bool:
        return value is not None and bool(np.isfinite(value))

    pending = np.sort([o for o, u in zip(own, unread, strict=True) if u and finite(o)])
    pairs = [(o, s) for o, s, u in zip(own, shared, unread, strict=True)
             if not u and finite(o) and finite(s)]  # fmt: skip
    if not pairs and not pending.size:  # no medians, whatever the unread records read
        return "own"
    known_o = np.array([o for o, _ in pairs])
    known_s = np.array([s for _, s in pairs])

    def median(values: np.ndarray, extra: np.ndarray) -> float:
        both = np.concatenate([values, extra])
        return float(np.median(both)) if both.size else np.nan

    # the own median over the records compared: any number of unread records may join, those
    # with the largest (smallest) own losses at its highest (lowest)
    joined = range(pending.size + 1)
    own_high = np.nanmax([median(known_o, pending[pending.size - j :]) for j in joined])
    own_low = np.nanmin([median(known_o, pending[:j]) for j in joined])
    shared_low = median(known_s, np.zeros(pending.size))
    shared_high = median(known_s, np.full(pending.size, np.inf))
    shared_answers = sum(s is not None for s, u in zip(shared, unread, strict=True) if not u)
    own_answers = sum(o is not None for o in own)
    shared_possible = (shared_answers + sum(unread) >= own_answers
                       and shared_low <= MAX_UNEXPLAINED_RATIO * own_high)  # fmt: skip
    if shared_possible:
        return None
    if 2 * keeping >= answered:
        return "own"
    if known_s.size and shared_low * MAX_UNEXPLAINED_RATIO >= own_high:
        return "recorded"
    if not shared_high * MAX_UNEXPLAINED_RATIO >= own_low:
        return "own"
    return None


def shared_chain_verdict(
    own: Sequence[ContactSamples | None],
    shared: Sequence[ContactSamples | None],
    keeping: int,
    answered: int,
) -> str:
    """Rule: which reading of a campaign's records stands beside the chain its kept readings
    share, undone on every record.

    Parameters
    ----------
    own, shared : sequence of ContactSamples or None
        Each record's own reading (its kept chain undone, or as recorded) and its reading
        through the shared chain, in one order.
    keeping : int
        Records whose own fitted chain was kept (the shared chain's voters).
    answered : int
        Records read at all.

    Returns
    -------
    str
        ``"shared"`` where the shared chain reads clearly better (:func:`keeps_shared_chain`);
        ``"recorded"`` where fewer than half of the records kept a chain and the shared one
        makes the force clearly less a function of the state (:func:`refutes_shared_chain`):
        no sensor's chain, every record is read as recorded; else ``"own"``. Where most records
        keep a chain, their own readings are the campaign's account of its sensor (on the
        rig's beam campaign, m5, 5 of 8 kept theirs and the face learned on them removed 74 %
        of the discrepancy, on the 8 read as recorded 35 %).
    """
    if keeps_shared_chain(own, shared):
        return "shared"
    if 2 * keeping < answered and refutes_shared_chain(own, shared):
        return "recorded"
    return "own"

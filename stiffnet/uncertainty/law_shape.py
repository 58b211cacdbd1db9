r"""The contact law's shape within each impact: what a richer law explains on held-out impacts.

The restoring-force map (:mod:`stiffnet.restoring_force`) samples, within every impact,
the contact force against penetration ``delta`` and velocity ``v`` from first touch
(``delta = 0``) through the deepest point back to release. Across the impacts of one
steady record the peak penetration hardly varies (0.7-4.2 %, docs/crosscheck.md), but
within one impact it spans ``0 .. delta_max``: the curvature of the elastic law and the
way the dissipation scales are visible there even when every impact is alike.

The training world's laws (paper eqs 11-12 with Kelvin-Voigt ``contact_damping``, or
Hertz's exponent 3/2 via ``hertz_contact``) are linear in their parameters::

    F = a (delta/d_r)^q + b + c v          q = 1 (linear) or 1.5 (Hertz)

A richer law adds one term:

* ``curvature``: ``(delta/d_r)^(q+1)``: a stiffening law (two-stage restraint, a layer
  over a stiffer body, a power law above Hertz's) bends the loading branch;
* ``penetration_dissipation``: ``(delta/d_r) v``: Hunt & Crossley's (1975) dissipation,
  zero at first touch, growing with penetration.

A two-stage law (a restraint whose stiffness jumps at a knee ``delta_k``) is read apart
(:func:`stage_gain`): ``F = a (delta/d_r) + b (delta/d_r - k)_+ + c_0 + c v`` against the
best single power law ``a (delta/d_r)^q + c_0 + c v`` over a grid of ``q`` (linear, Hertz
and beyond): a power law bends smoothly from first touch, a two-stage law is straight on
both sides of its knee. Through a sensor chain, or on Hertz's law, a hinge takes a little
curvature too, but with a small stiffness ratio ``(a + b) / a`` across the knee.

A model trained with a learned Hunt-Crossley law has ``(delta/d_r) v`` in its world: its
base law (and both laws of :func:`stage_gain`) then carry that term, so the stiffening terms
are judged against the law the model knows; left out, a Hunt-Crossley contact's dissipation,
zero at first touch and largest mid-impact, bends the loading branch the curvature and the
hinge read.

Each is scored by leave-one-impact-out cross-validation (whole impacts held out, so the
reconstruction's smooth errors within an impact cannot be fitted by the extra term):
``gain = 1 - SSE_cv(richer) / SSE_cv(base)``. Samples where the base law pulls and the
restraint gives no force (both below a small fraction of the peak: a damped contact's
early release, where the restraint's ``max(0, .)`` clips) are left out, so the clip is
not read as a term. This
module is the curve (the gains); the rule that turns them into an alarm is
:mod:`stiffnet.uncertainty.unseen_law`. numpy only: the predictor imports it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Terms a richer law adds to the training world's, as functions of the normalised
#: penetration ``delta/d_r``, velocity ``v / std(v)`` and the base exponent ``q``.
RICHER_TERMS: dict[str, Callable[[np.ndarray, np.ndarray, float], np.ndarray]] = {
    "curvature": lambda d, v, q: d ** (q + 1.0),
    "penetration_dissipation": lambda d, v, q: d * v,
}
#: Fitted exponents at or above this are read as Hertz's (q = 1.5), below as linear.
HERTZ_FROM_EXPONENT = 1.25
#: Samples of the base law's force below this fraction of the peak force are left out.
CLIP_FRACTION = 0.05
#: Knees the two-stage law is tried at, in units of the reference penetration ``d_r``
#: (a first stage shorter than 0.2 d_r is within the fitted onset's error: a knee at 0.1
#: read ratio 4.4 on an in-prior sensor-chain record, 1.3 at 0.2).
STAGE_KNEES = tuple(np.linspace(0.2, 0.8, 7))
#: Exponents of the single power law the two-stage law must beat (linear, Hertz, beyond).
POWER_EXPONENTS = tuple(np.linspace(1.0, 2.6, 17))
#: Samples on each side of an impact read for a force before the fitted onset
#: (:func:`onset_toe`), and the margin beyond them taken as free flight for its scatter.
TOE_SAMPLES = 2
TOE_MARGIN = 6


def impact_runs(delta: np.ndarray, min_samples: int = 3) -> list[np.ndarray]:
    """Indices of each impact: runs of consecutive samples with ``delta > 0`` (at least
    `min_samples` long)."""
    idx = np.flatnonzero(np.asarray(delta) > 0)
    if idx.size == 0:
        return []
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    return [r for r in runs if r.size >= min_samples]


def depth_spread(dn: np.ndarray, groups: np.ndarray) -> float:
    """How far apart the impacts' depths lie: the 90th over the 10th percentile of the
    impacts' deepest penetration (1 where every impact reaches alike).

    A steady record's impacts reach within a few per cent of each other; a wandering or
    chattering one mixes grazes and deep impacts, and there the reconstruction's level,
    which wanders between impacts by up to the penetration of a shallow one, is read across
    impacts of different depths as a stiffness that changes with depth.

    Parameters
    ----------
    dn : numpy.ndarray
        In-contact penetrations (any unit: the ratio is unitless).
    groups : numpy.ndarray
        The impact (0 .. n-1, ascending) of each sample.
    """
    starts = np.flatnonzero(np.r_[True, np.diff(groups) != 0])
    peaks = np.maximum.reduceat(np.asarray(dn, float), starts)
    lo, hi = np.quantile(peaks, [0.1, 0.9])
    return float(hi / lo) if lo > 0 else float("inf")


def held_out_impact_sse(design: np.ndarray, force: np.ndarray, groups: np.ndarray) -> float:
    """Sum over impacts of the squared error of the least-squares law fitted on the others.

    The normal equations of all samples minus one impact's give each held-out fit; the
    impacts' Gram matrices are summed in one pass and their systems solved as one stack
    (pseudo-inverse: an impact whose removal leaves a column empty still gets a fit).
    """
    order = np.argsort(groups, kind="stable")
    a, f, g = design[order], force[order], groups[order]
    starts = np.flatnonzero(np.r_[True, np.diff(g) != 0])
    grams = np.add.reduceat(a[:, :, None] * a[:, None, :], starts, axis=0)
    rhs = np.add.reduceat(a * f[:, None], starts, axis=0)
    coef = np.einsum("gij,gj->gi", np.linalg.pinv(grams.sum(axis=0) - grams), rhs.sum(axis=0) - rhs)
    member = np.cumsum(np.r_[False, np.diff(g) != 0])
    resid = f - np.einsum("ij,ij->i", a, coef[member])
    return float(resid @ resid)


def stage_gain(
    dn: np.ndarray,
    vn: np.ndarray,
    f: np.ndarray,
    groups: np.ndarray,
    trained_dissipation: bool = False,
) -> tuple[float, float, float]:
    """Held-out-impact gain of a two-stage law over the best single power law.

    Parameters
    ----------
    dn, vn, f : numpy.ndarray
        In-contact samples: penetration over ``d_r``, normalised velocity, contact force.
    groups : numpy.ndarray
        The impact (0 .. n-1) of each sample; whole impacts are held out.
    trained_dissipation : bool
        Both laws carry a ``(delta/d_r) v`` term (the model's world has one).

    Returns
    -------
    tuple of float
        ``(gain, ratio, knee)``: ``1 - SSE_cv(two-stage) / min_q SSE_cv(power q)`` for the
        best knee of :data:`STAGE_KNEES` whose two stages are both stiff (``a, b > 0``),
        the stiffness ratio ``(a + b) / a`` across it and the knee; ``(0, 1, 0)`` when
        no knee gives a stiffening law.
    """
    one = np.ones_like(dn)
    extra = [dn * vn] if trained_dissipation else []
    power = min(
        held_out_impact_sse(np.column_stack([dn**q, one, vn, *extra]), f, groups)
        for q in POWER_EXPONENTS
    )
    best = (np.inf, 1.0, 0.0)
    for knee in STAGE_KNEES:
        design = np.column_stack([dn, one, vn, np.maximum(dn - knee, 0.0), *extra])
        coef = np.linalg.lstsq(design, f, rcond=None)[0]
        if not (coef[0] > 0 and coef[3] > 0):
            continue  # a softening or a sign-flipped first stage is no two-stage restraint
        sse = held_out_impact_sse(design, f, groups)
        if sse < best[0]:
            best = (sse, float((coef[0] + coef[3]) / coef[0]), float(knee))
    if not (np.isfinite(best[0]) and power > 0):
        return 0.0, 1.0, 0.0
    return 1.0 - best[0] / power, best[1], best[2]


def onset_toe(
    disp: np.ndarray,
    force: np.ndarray,
    onset: float,
    min_impacts: int = 4,
    damping_force: np.ndarray | None = None,
) -> tuple[float, float, float] | None:
    """Contact force just outside the fitted law's contact, in units of the free flight's
    force scatter: a soft first stage the law's onset cuts off.

    A law fitted with a free onset ``e`` to a two-stage restraint whose first stage is short
    or soft puts its onset where the stiff stage would start from zero force: the first
    stage's samples then lie at ``delta <= 0`` (outside the impact's run, so no within-impact
    term sees them) yet carry force. On a law the library has, the force there is the
    free flight's residual, zero on average.

    Parameters
    ----------
    disp, force : numpy.ndarray
        The restoring-force map's displacement and contact force (consecutive samples).
    onset : float
        The fitted contact law's ``e``.
    min_impacts : int
        Fewest impacts, with :data:`TOE_SAMPLES` samples on each side, to judge.
    damping_force : numpy.ndarray, optional
        The fitted law's dissipative force (its ``v`` term) on every sample of the map.

    Returns
    -------
    tuple of float or None
        ``(toe, least_side, damped_step)``: the median over impacts of the mean force on the
        :data:`TOE_SAMPLES` samples before and after each impact's run (``delta > 0``), and
        the lesser of the medians of each side alone, both over the standard deviation of
        the force on samples at least :data:`TOE_MARGIN` samples from any impact (a sensor
        chain's ringing leaves a negative force after the release, a first stage none),
        and the median over impacts of `damping_force` on each impact's first in-contact
        sample in the same unit (0 without it): a Kelvin-Voigt contact's force steps to
        ``c v`` at its onset, and an undone, band-limited chain's inverse rings that step
        onto the samples before it, a toe of a few per cent to a fifth of the step (an
        independent-rig Kelvin-Voigt campaign, zeta 0.15, behind a 320 Hz low-pass);
        None with too few impacts or no free-flight samples.
    """
    d = np.asarray(disp, float) - onset
    f = np.asarray(force, float)
    runs = [r for r in impact_runs(d) if r[0] >= TOE_SAMPLES and r[-1] + TOE_SAMPLES < d.size]
    if len(runs) < min_impacts:
        return None
    free = d <= 0
    for r in runs:
        free[max(r[0] - TOE_MARGIN, 0) : r[-1] + TOE_MARGIN + 1] = False
    if int(free.sum()) < 2 * min_impacts:
        return None
    scatter = float(np.std(f[free])) or 1e-300
    side = np.arange(1, TOE_SAMPLES + 1)
    before = np.array([f[r[0] - side].mean() for r in runs])
    after = np.array([f[r[-1] + side].mean() for r in runs])
    # which side of an impact a short first stage's samples fall on depends on the sampling
    # phase: the two sides are read together, and apart for a sign
    toe = float(np.median(0.5 * (before + after))) / scatter
    least_side = float(min(np.median(before), np.median(after))) / scatter
    step = 0.0
    if damping_force is not None:
        step = float(np.median([damping_force[r[0]] for r in runs])) / scatter
    return toe, least_side, step


def law_shape_gains(
    disp: np.ndarray,
    vel: np.ndarray,
    force: np.ndarray,
    onset: float,
    reference_penetration: float,
    exponent: float = 1.0,
    min_samples: int = 3,
    min_impacts: int = 4,
    trained_dissipation: bool = False,
) -> dict[str, float] | None:
    """Held-out-impact gain of each richer term over the training world's law.

    Parameters
    ----------
    disp, vel, force : numpy.ndarray
        The restoring-force map's displacement, velocity and contact force.
    onset, reference_penetration, exponent : float
        The fitted contact law's ``e``, ``d_r`` and ``p``
        (:class:`~stiffnet.restoring_force.contact_law.ContactLaw`); ``p`` picks the
        base exponent (Hertz's 1.5 from :data:`HERTZ_FROM_EXPONENT`, else 1).
    min_samples, min_impacts : int
        Fewest in-contact samples per impact, and impacts, to judge.
    trained_dissipation : bool
        The model's world has a ``(delta/d_r) v`` term (a learned Hunt-Crossley law): the
        base law of the stiffening terms (``curvature``, ``stage``) carries it; the
        ``penetration_dissipation`` gain is still read against the Kelvin-Voigt law.

    Returns
    -------
    dict or None
        ``{term: gain}`` for every :data:`RICHER_TERMS` entry, ``{term}_share`` (the
        term's coefficient over the sum of its and the base law's matching coefficient in
        magnitude at ``d_r``: the elastic one for ``curvature``, the ``v`` one for
        ``penetration_dissipation``; positive for a stiffening law, a dissipation growing
        with penetration), ``stage`` / ``stage_ratio`` / ``stage_knee``
        (:func:`stage_gain`), ``misfit`` (the base law's held-out SSE over the force's
        variance), ``n_impacts``, ``depth_spread`` (:func:`depth_spread`) and ``toe`` /
        ``toe_least_side`` / ``toe_damped_step`` (:func:`onset_toe`, the damped step from
        the base law's ``v`` coefficient, where it can be read); None with too few impacts
        or no positive reference penetration.
    """
    if not reference_penetration > 0:
        return None
    d = np.asarray(disp, float) - onset
    runs = impact_runs(d, min_samples)
    if len(runs) < min_impacts:
        return None
    idx = np.concatenate(runs)
    groups = np.repeat(np.arange(len(runs)), [r.size for r in runs])
    q = 1.5 if exponent >= HERTZ_FROM_EXPONENT else 1.0
    dn, f = d[idx] / reference_penetration, np.asarray(force, float)[idx]
    v = np.asarray(vel, float)[idx]
    vn = v / (float(np.std(v)) or 1.0)
    base = np.column_stack([dn**q, np.ones_like(dn), vn])
    # where the law would pull and the restraint gives nothing, its max(0, .) clipped: the
    # clip is not a term (a first stage the linear law cuts off, with force, is kept)
    base_coef = np.linalg.lstsq(base, f, rcond=None)[0]
    pulls = base @ base_coef
    keep = np.maximum(pulls, f) > CLIP_FRACTION * float(np.max(f))
    groups = np.unique(groups[keep], return_inverse=True)[1]
    if int(groups.max(initial=-1)) + 1 < min_impacts:
        return None
    base, dn, vn, f = base[keep], dn[keep], vn[keep], f[keep]
    sse_base = held_out_impact_sse(base, f, groups)
    if not sse_base > 0:
        return None
    # the stiffening terms against the law the model knows
    known = np.column_stack([base, dn * vn]) if trained_dissipation else base
    sse_known = held_out_impact_sse(known, f, groups) if trained_dissipation else sse_base
    out: dict[str, float] = {}
    for name, term in RICHER_TERMS.items():
        against, sse_against = (base, sse_base) if name != "curvature" else (known, sse_known)
        design = np.column_stack([against, term(dn, vn, q)])
        out[name] = 1.0 - held_out_impact_sse(design, f, groups) / max(sse_against, 1e-300)
        # the term's coefficient against the base law's own (elastic for the curvature,
        # dissipative for delta v) at the reference penetration: its sign says stiffening
        # or softening, dissipation growing or shrinking with penetration
        coef = np.linalg.lstsq(design, f, rcond=None)[0]
        own = coef[0] if name == "curvature" else coef[2]
        out[name + "_share"] = float(coef[-1] / (abs(own) + abs(coef[-1]) + 1e-300))
    out["stage"], out["stage_ratio"], out["stage_knee"] = stage_gain(
        dn, vn, f, groups, trained_dissipation
    )
    out["misfit"] = sse_base / max(float(np.sum((f - f.mean()) ** 2)), 1e-300)
    out["n_impacts"] = float(int(groups.max()) + 1)
    out["depth_spread"] = depth_spread(dn, groups)
    damping_force = base_coef[2] * np.asarray(vel, float) / (float(np.std(v)) or 1.0)
    toe = onset_toe(disp, force, onset, min_impacts, damping_force)
    if toe is not None:
        out["toe"], out["toe_least_side"], out["toe_damped_step"] = toe
    return out

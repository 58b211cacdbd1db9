"""Which terms the contact law needs: a forward path, whole impacts held out, bootstrap.

Sparse regression in the SINDy sense with a greedy (orthogonal-matching-pursuit
style) path, because the candidate terms carry nonlinear parameters (an
exponent, a knot) and every recording its own beta and onset, which puts the
problem outside the linear sparse regressors (STLSQ, Lasso): starting from the
linear spring, every remaining term is fitted jointly with the ones already in;
the best by an information criterion (BIC) enters **if** it lowers the error on
impacts held out (4 folds of whole impacts, every recording keeping impacts in
each training set) by at least :data:`MIN_HELD_OUT_GAIN` on the median recording
(:func:`held_out_gain`); else the path stops.
The order of entry is the term path. The selected law is refitted once with each
recording weighted by how well it fits (:func:`reweighted`). Coefficients get
intervals by a bootstrap over impacts (whole impacts drawn with replacement, the
law refitted from the estimate).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from stiffnet.discovery.face import face_starts, second_mode_starts
from stiffnet.discovery.face_scaled import scaled_face_starts
from stiffnet.discovery.law import DiscoveredLaw, is_new_term
from stiffnet.discovery.samples import ContactSamples
from stiffnet.discovery.terms import (
    FACE_TERMS,
    LIBRARY_TERMS,
    TERM_PARAMS,
    TERMS,
    Data,
    Fit,
    explained_fraction,
    fit_law,
    predict,
    recordings_subset,
    stack,
)
from stiffnet.effects.learned_contact import LearnedContact
from stiffnet.errors import StiffnetError

#: A term enters only if it lowers the held-out error by this fraction of the current one.
MIN_HELD_OUT_GAIN = 0.15
#: Folds of whole impacts.
N_FOLDS = 4
#: Bootstrap replicates over impacts.
N_BOOTSTRAP = 30
#: Relative change of the cost that ends a replicate's fit: the replicates scatter by percents,
#: and stopping at 1e-6 rather than scipy's 1e-8 left the two-stage campaign's 5-95 % quantiles
#: of knee, ratio and betas the same to four digits for 0.7 of the bootstrap's CPU seconds.
BOOTSTRAP_FTOL = 1e-6
#: Knots tried as starts of a hinge, as quantiles of the peak penetrations.
KNOT_QUANTILES = (0.15, 0.4, 0.7)
#: Impacts of a recording that must pass a hinge's knot for the recording to count as
#: reaching it (:func:`knot_is_shared`).
KNOT_MIN_IMPACTS = 2
#: Residual evaluations of the short fits that screen the face term's starts.
FACE_SCREEN_NFEV = 12
#: Recordings (spread over the campaign's betas) the face's starts are screened on; the best
#: start is then fitted on all of them. The face is the restraint's, shared by every
#: recording, and its thirteen screens were half the discovery's time on 24 recordings.
SCREEN_RECORDINGS = 8
#: Residual evaluations of a face law's fit on all recordings after its fit on those
#: (:func:`fitted_face`).
FACE_POLISH_NFEV = 40
#: Systematic part of the intervals (relative): a floor and a term growing with the law's
#: misfit, as the restoring-force estimate's (the bootstrap over impacts sees the scatter
#: between impacts, not the reconstruction's bias they share). The floor is the shared bias
#: measured on the two-stage and power-law campaigns (3-6 % on the ratio and exponent).
SYSTEMATIC_FLOOR = 0.05
SYSTEMATIC_PER_MISFIT = 4.0
#: Recordings needed.
MIN_RECORDINGS = 2


def reference_penetration(data: Data) -> float:
    """``d_r``: the median peak penetration over the campaign, to two significant digits."""
    peaks = []
    for imp in np.unique(data.impact):
        sel = data.impact == imp
        peaks.append(float(np.max(data.x[sel] - data.onset0[data.rec[sel][0]])))
    med = float(np.median(peaks)) if peaks else 0.5
    med = med if med > 0 else 0.5
    return float(f"{med:.2g}")


def check_penetration_scale(dr: float) -> None:
    """Rule: the impacts' median peak penetration ``d_r`` (model lengths: mm for a record in
    g, :func:`~stiffnet.campaign.sensor_gain`) must lie in the range the learned law accepts
    (``learned_contact``'s ``reference_penetration``), else the discovery refuses in one line.

    The samples' lengths scale with the record's unit: a record in m/s^2 read as g is 9.81
    times deeper. On the independent rig's beam tip written in m/s^2 (penetrations about
    2 mm) d_r read 19, and diagnose, which simulates the law, stopped with the effect's range
    error after its whole run (241 CPU s), the library's diagnosis lost with it.
    """
    spec = LearnedContact.Params.model_fields["reference_penetration"].json_schema_extra or {}
    lo, hi = float(spec.get("ge", 0.0)), float(spec.get("le", np.inf))
    if not lo <= dr <= hi:
        raise StiffnetError(
            f"the impacts' median peak penetration reads {dr:.3g} model lengths (mm for a "
            f"record in g), outside the learned law's {lo:g}-{hi:g}: the recordings' "
            "acceleration is probably not in g (a record in m/s^2 reads 9.81 times deeper)"
        )


def fold_masks(data: Data, n_folds: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Test masks of ``n_folds`` folds of whole impacts, each recording's impacts spread."""
    fold_of = np.zeros(int(data.impact.max()) + 1, dtype=int)
    for r in range(data.n_rec):
        imps = np.unique(data.impact[data.rec == r])
        fold_of[rng.permutation(imps)] = np.arange(imps.size) % n_folds
    folds = fold_of[data.impact]
    return [folds == k for k in range(n_folds)]


def held_out_error(data: Data, fit: Fit, tests: list[np.ndarray]) -> np.ndarray:
    """Weighted squared error on held-out impacts per recording (R,), each fold fitted on the
    others."""
    start = fit.shared
    per = fit.theta[: 2 * fit.n_rec]
    total = np.zeros(data.n_rec)
    for test in tests:
        f = fit_law(data, fit.terms, fit.dr, start, per, mask=~test, max_nfev=60)
        res = (predict(data, f.terms, f.theta, f.dr) - data.f) * data.weight
        total += np.bincount(data.rec[test], res[test] ** 2, minlength=data.n_rec)
    return total


def held_out_gain(before: np.ndarray, after: np.ndarray) -> float:
    """Rule: the median over recordings of the relative fall of the held-out error.

    A shared term must help most recordings; a median is not moved by one
    recording whose map is poor (another orbit, a grazing contact), whose squared
    errors would dominate a campaign total either way.
    """
    return float(np.median(1.0 - after / np.maximum(before, 1e-300)))


def _bic(fit: Fit) -> float:
    return fit.n * np.log(max(fit.sse, 1e-300) / fit.n) + fit.n_params * np.log(fit.n)


def _candidates(
    data: Data, current: Fit, dr: float, screened: dict[str, dict], screen_on: np.ndarray
) -> list[Fit]:
    """Every remaining term added to the current law, fitted (several knots for a hinge).

    ``screened``: the faces the path's earlier steps screened (:func:`face_term_starts`),
    filled at the first step that screens each. ``screen_on``: the recordings a face's
    starts are screened on (:func:`screen_recordings`).
    """
    out = []
    per = current.theta[: 2 * current.n_rec]
    peaks = np.maximum(data.x - current.onsets[data.rec], 0.0)
    top = np.quantile(peaks[peaks > 0], 0.95) if np.any(peaks > 0) else dr
    first_face = None
    for term in TERMS:
        if term in current.terms or not faces_go_together(current.terms, term):
            continue
        terms = current.terms | {term}
        starts = [dict(current.shared)]
        if term == "hinge":
            starts = [{**current.shared, "knee": q * top} for q in KNOT_QUANTILES]
        if term == "face2" and "face" not in current.terms:
            if first_face is None:
                continue
            # both modes at once: one mode of a beam's tip may describe it worse than none
            terms = terms | {"face"}
        if term in FACE_TERMS:  # a short fit from every start, then the best to the end
            kind = "+".join(sorted(terms - current.terms))
            starts = face_term_starts(kind, current, first_face, screened)
            best = screened_face(data, terms, dr, starts, per, screen_on)
            if len(starts) > 1 and kind in ("face", "face+face2", "face_scaled"):
                screened.setdefault(kind, {k: best.shared[k] for k in _face_keys(terms)})
            first_face = best if term == "face" else first_face
            if best.sse > (1 - MIN_HELD_OUT_GAIN) * current.sse:
                # no face lowers the error by what a term must: the screen is its candidate
                out.append(best)
                continue
            out.append(fitted_face(data, terms, dr, best, screen_on))
            continue
        fits = [fit_law(data, terms, dr, s, per) for s in starts]
        best_fit = min(fits, key=lambda f: f.sse)
        if term == "hinge" and not knot_is_shared(data, best_fit):
            continue
        out.append(best_fit)
    return out


def faces_go_together(terms: frozenset[str], term: str) -> bool:
    """Rule: the scaled face (each recording's own restraint) and the shared one (the rig's)
    are two accounts of one restraint: a law holds one of them, never both."""
    if term == "face_scaled":
        return not terms & {"face", "face2"}
    return not (term in ("face", "face2") and "face_scaled" in terms)


def screen_recordings(data: Data, n: int | None = None) -> np.ndarray:
    """Rule: ``n`` (:data:`SCREEN_RECORDINGS`) recordings evenly spaced in the order of their
    betas (all when there are at most ``n``): the face's screens see the soft and the stiff
    contacts alike."""
    n = SCREEN_RECORDINGS if n is None else n
    order = np.argsort(data.beta0, kind="stable")
    if order.size <= n:
        return np.sort(order)
    return np.sort(order[np.round(np.linspace(0, order.size - 1, n)).astype(int)])


def screened_face(
    data: Data,
    terms: frozenset[str],
    dr: float,
    starts: list[dict[str, float]],
    per: np.ndarray,
    screen_on: np.ndarray,
) -> Fit:
    """The best of short fits (:data:`FACE_SCREEN_NFEV`) of a face law from each start.

    With several starts and more recordings than ``screen_on``, the starts are screened on
    those recordings alone and the best one's short fit is then run on all: a face's
    starts differ by the restraint's frequency and stiffness, which every recording shares.
    """
    if len(starts) == 1 or screen_on.size == data.n_rec:
        short = [fit_law(data, terms, dr, s, per, max_nfev=FACE_SCREEN_NFEV) for s in starts]
        return min(short, key=lambda f: f.sse)
    r = data.n_rec
    sub = recordings_subset(data, screen_on)
    per_sub = np.concatenate([per[:r][screen_on], per[r : 2 * r][screen_on]])
    short = [fit_law(sub, terms, dr, s, per_sub, max_nfev=FACE_SCREEN_NFEV) for s in starts]
    best = min(short, key=lambda f: f.sse)
    return fit_law(data, terms, dr, best.shared, per, max_nfev=FACE_SCREEN_NFEV)


def fitted_face(data: Data, terms: frozenset[str], dr: float, screen: Fit, on: np.ndarray) -> Fit:
    """A face law fitted from its screen's best (``screen``): to the end on the recordings
    ``on``, then :data:`FACE_POLISH_NFEV` evaluations on all from there.

    The face's full fit is the discovery's costliest (150-odd Jacobians of a law whose
    every evaluation filters the force through each mode: 7.6 of 21 CPU seconds on a
    24-recording Hunt-Crossley campaign, where the face is a candidate, not the answer);
    the shared face converges on a third of the recordings as on all, and the polish
    refits every recording's beta and onset to it.
    """
    r = data.n_rec
    per = screen.theta[: 2 * r]
    if on.size == r:
        return fit_law(data, terms, dr, screen.shared, per)
    sub = recordings_subset(data, on)
    part = fit_law(sub, terms, dr, screen.shared, np.concatenate([per[:r][on], per[r:][on]]))
    start = per.copy()
    start[on], start[r + on] = part.theta[: on.size], part.theta[on.size : 2 * on.size]
    return fit_law(data, terms, dr, part.shared, start, max_nfev=FACE_POLISH_NFEV)


def face_term_starts(
    kind: str, current: Fit, first_face: Fit | None, screened: dict[str, dict]
) -> list[dict[str, float]]:
    """Starts of a face candidate: ``face`` (one mode), ``face+face2`` (both modes at once) or
    ``face2`` (a second mode on a face in the law).

    Rule: a face is screened from its grid of starts (:func:`~.face.face_starts`, then
    :func:`~.face.second_mode_starts` above the best first mode) at the first step it is a
    candidate; at the later steps it starts from that screen's best alone. The face's mode
    is the restraint's dynamics, which the law's other terms barely move, and the screens
    were three fifths of the discovery's time (cProfile of the two-stage campaign: the
    step after the hinge entered screened the same faces again). A second mode on a face
    the law holds starts from the second mode of the screen of both modes, where one was
    made, on the face the law holds; else it is screened from starts above that face.
    """
    if kind in screened:
        return [{**current.shared, **screened[kind]}]
    if kind == "face2" and "face+face2" in screened:
        # the second mode of the screen of both modes, on the face the law now holds
        second = {k: v for k, v in screened["face+face2"].items() if k.startswith("face2")}
        return [{**current.shared, **second}]
    if kind == "face":
        return [{**current.shared, **s} for s in face_starts(current.betas)]
    if kind == "face_scaled":
        return [{**current.shared, **s} for s in scaled_face_starts(current.betas)]
    base = first_face.shared if kind == "face+face2" and first_face is not None else current.shared
    return [{**current.shared, **base, **s} for s in second_mode_starts(base)]


def _face_keys(terms: frozenset[str]) -> list[str]:
    return [p[0] for t in FACE_TERMS if t in terms for p in TERM_PARAMS[t]]


def knot_is_shared(data: Data, fit: Fit) -> bool:
    """Rule: a hinge's knot must be passed by at least :data:`KNOT_MIN_IMPACTS` impacts in at
    least half of the recordings (a shared term acts on the median recording).

    A knot beyond most recordings' reach is one recording's misfit absorbed, not a second
    stage: on the independent rig's Hunt-Crossley campaign, with one recording's map bent by
    a spurious sensor chain, a softening "hinge" at 1.06 (ratio 0.05) passed by the impacts
    of 2 of 8 recordings lowered the median held-out error by 18 %; the true two-stage
    campaigns have their knot passed in 7 of 8.
    """
    delta = data.x - fit.onsets[data.rec]
    peaks = np.full(int(data.impact.max()) + 1, -np.inf)
    np.maximum.at(peaks, data.impact, delta)
    rec_of = np.zeros(peaks.size, dtype=int)
    rec_of[data.impact] = data.rec
    passed = np.bincount(rec_of[peaks > fit.shared["knee"]], minlength=data.n_rec)
    return int(np.sum(passed >= KNOT_MIN_IMPACTS)) >= 0.5 * data.n_rec


def forward_path(
    data: Data, dr: float, rng: np.random.Generator, linear: Fit | None = None
) -> tuple[Fit, list[dict]]:
    """The greedy path from the linear spring (``linear``, its fit where already made);
    returns the selected fit and the path."""
    tests = fold_masks(data, N_FOLDS, rng)
    current = fit_law(data, frozenset(), dr) if linear is None else linear
    cv = held_out_error(data, current, tests)
    first = {
        "step": 0,
        "term": "linear",
        "entered": True,
        "bic": _bic(current),
        "held_out_error": float(cv.sum()),
        "explained_fraction": explained_fraction(data, current),
    }
    path = [first]
    screened: dict[str, dict] = {}
    screen_on = screen_recordings(data)
    while len(current.terms) < len(TERMS):
        cands = _candidates(data, current, dr, screened, screen_on)
        best = min(cands, key=_bic)
        if scaled_face_short_of_gain(current, best):
            path.append(refused_unheld(len(path), "face_scaled", best, data))
            break
        cv_new = held_out_error(data, best, tests)
        one = [c for c in cands if c.terms == current.terms | {"face"}]
        if best.terms - current.terms == {"face_scaled"} and one:
            # two accounts of one restraint: the recordings' own faces (one parameter more)
            # only where they beat the rig's shared face as a term must
            cv_one = held_out_error(data, one[0], tests)
            if not scaled_face_beats_shared(cv_one, cv_new):
                best, cv_new = one[0], cv_one
        if len(best.terms - current.terms) == 2 and one:
            # a face's two modes at once: the second must lower the held-out error of the
            # first alone as a term must, else the first alone is the candidate
            cv_one = held_out_error(data, one[0], tests)
            if held_out_gain(cv_one, cv_new) < MIN_HELD_OUT_GAIN:
                best, cv_new = one[0], cv_one
        term = _ordered(best.terms - current.terms)[-1]  # a face's two modes: face2
        gain = held_out_gain(cv, cv_new)
        entered = bool(_bic(best) < _bic(current) and gain >= MIN_HELD_OUT_GAIN)
        path.append({"step": len(path), "term": term, "entered": entered, "bic": _bic(best),
                     "held_out_error": float(cv_new.sum()), "held_out_gain": gain,
                     "explained_fraction": explained_fraction(data, best)})  # fmt: skip
        if not entered:
            break
        current, cv = best, cv_new
    return current, path


def scaled_face_short_of_gain(current: Fit, best: Fit) -> bool:
    """Rule: a scaled face (``face_scaled`` the path's next term) that lowers the fitted
    error by less than :data:`MIN_HELD_OUT_GAIN` of the current law's is refused without its
    held-out test: :func:`_candidates` then keeps its screen, not fitted to the end.

    Its held-out folds filter every recording's force at every recording's own face on
    every evaluation: 4.4 of the 8.4 CPU seconds of a 23-recording material beam's
    discovery where it explained 1 % more (held-out gain 0.003). The shared face keeps
    its held-out test (its laws and paths as they were).
    """
    added = best.terms - current.terms
    return added == {"face_scaled"} and best.sse > (1 - MIN_HELD_OUT_GAIN) * current.sse


def scaled_face_beats_shared(cv_shared: np.ndarray, cv_scaled: np.ndarray) -> bool:
    """Rule: the scaled face (each recording's own restraint) is taken over the shared face
    (the rig's, one parameter fewer) only where it lowers the shared face's held-out error
    per recording by :data:`MIN_HELD_OUT_GAIN` on the median recording (:func:`held_out_gain`).

    The path's information criterion alone picks the better fit, and on 15,000 correlated
    samples one parameter costs it nothing: on the independent rig's shared beam tip behind a
    high-pass (one tip mode of 0.15 m at 7.5 f_n, half the maps poor) the scaled face won by
    57.5 % against 56.5 % of the force with its mass exponent at its bound (-1), while the
    shared face read the tip within 16 % (mass 0.141, support 10.9 for 0.15, 8.44).
    """
    return held_out_gain(cv_shared, cv_scaled) >= MIN_HELD_OUT_GAIN


def refused_unheld(step: int, term: str, fit: Fit, data: Data) -> dict[str, Any]:
    """The path's step of a candidate refused before its held-out test
    (:func:`scaled_face_short_of_gain`): no held-out error or gain."""
    return {"step": step, "term": term, "entered": False, "bic": _bic(fit),
            "held_out_error": None, "held_out_gain": None,
            "explained_fraction": explained_fraction(data, fit)}  # fmt: skip


def recording_factors(data: Data, fit: Fit) -> np.ndarray:
    """Rule: each recording's weight factor (R,): the median recording's residual RMS over its
    own, capped at 1 (a recording the law fits worse than most counts less, none more).

    The force scales of :func:`~.terms.stack` make every recording count alike; but a map
    whose impacts disagree with each other (an orbit that is not periodic leaves each impact's
    reconstructed penetration its own offset) spreads the onset between impacts, which flattens
    a power law: on the independent rig's n = 2.5 campaign one such recording (its impacts'
    onsets spread 0.07 mm) pulled the shared exponent to 2.28; weighted by its fit, 2.45.
    """
    res = (predict(data, fit.terms, fit.theta, fit.dr) - data.f) * data.weight
    n = np.maximum(np.bincount(data.rec, minlength=data.n_rec), 1)
    rms = np.sqrt(np.bincount(data.rec, res**2, minlength=data.n_rec) / n)
    return np.minimum(1.0, float(np.median(rms)) / np.maximum(rms, 1e-300))


def reweighted(data: Data, fit: Fit) -> tuple[Data, Fit]:
    """The samples with each recording weighted by :func:`recording_factors` (a feasible
    weighted least squares, one step) and the selected law refitted on them."""
    w = data.weight * recording_factors(data, fit)[data.rec]
    wdata = data.weighted(w)
    return wdata, fit_law(wdata, fit.terms, fit.dr, fit.shared, fit.theta[: 2 * fit.n_rec])


def library_fit(data: Data, dr: float, linear: Fit | None = None) -> Fit:
    """The best law of the library's own (linear, Kelvin-Voigt, Hertz with damping);
    ``linear``: the linear spring's fit where already made (the forward path's start)."""
    fits = [fit_law(data, frozenset(t), dr) for t in (("damping",), ("hertz", "damping"))]
    fits.insert(0, fit_law(data, frozenset(), dr) if linear is None else linear)
    return min(fits, key=lambda f: f.sse)


def bootstrap(
    data: Data, fit: Fit, rng: np.random.Generator, n_boot: int
) -> tuple[np.ndarray, np.ndarray]:
    """Shared parameters and betas refitted on impacts drawn with replacement: (B, S), (B, R)."""
    imps = np.unique(data.impact)
    shared, betas = [], []
    per = fit.theta[: 2 * fit.n_rec]
    for _ in range(n_boot):
        draw = rng.choice(imps, imps.size)
        counts = np.bincount(draw, minlength=int(imps.max()) + 1)
        w = counts[data.impact].astype(float)
        sel = w > 0
        boot = data.weighted(data.weight * np.sqrt(w))
        f = fit_law(
            boot, fit.terms, fit.dr, fit.shared, per, mask=sel, max_nfev=40, ftol=BOOTSTRAP_FTOL
        )
        shared.append(f.theta[2 * fit.n_rec :])
        betas.append(f.betas)
    return np.array(shared), np.array(betas)


def discover_contact_law(
    samples: Sequence[ContactSamples],
    *,
    n_boot: int = N_BOOTSTRAP,
    coverage: float = 0.9,
    seed: int = 0,
) -> DiscoveredLaw:
    """Discover the contact law shared by a campaign's recordings.

    Parameters
    ----------
    samples : sequence of ContactSamples
        Each recording's impacts in model units (:func:`.campaign_contact_samples`).
    n_boot : int
        Bootstrap replicates over impacts for the intervals (0: none).
    coverage : float
        Nominal coverage of the intervals.
    seed : int
        Seed of the folds and the bootstrap.

    Returns
    -------
    DiscoveredLaw

    Raises
    ------
    StiffnetError
        With fewer than two recordings whose maps have impacts.
    """
    if len(samples) < MIN_RECORDINGS:
        raise StiffnetError(
            f"contact-law discovery needs the impacts of {MIN_RECORDINGS} recordings, "
            f"got {len(samples)}"
        )
    rng = np.random.default_rng(seed)
    data = stack(samples)
    dr = reference_penetration(data)
    check_penetration_scale(dr)
    linear = fit_law(data, frozenset(), dr)  # the path's start and a law of the library's
    fit, path = forward_path(data, dr, rng, linear)
    wdata, fit = reweighted(data, fit)
    lib = library_fit(data, dr, linear)
    explained = explained_fraction(data, fit)
    intervals: dict[str, Any] = {}
    beta_iv: list[Any] = [None] * data.n_rec
    if n_boot > 0:
        shared, betas = bootstrap(wdata, fit, rng, n_boot)
        a = 0.5 * (1 - coverage)
        sys_rel = float(np.hypot(SYSTEMATIC_FLOOR, SYSTEMATIC_PER_MISFIT * (1 - explained)))
        for j, n in enumerate(fit.shared):
            intervals[n] = widened(fit.shared[n], *np.quantile(shared[:, j], [a, 1 - a]), sys_rel)
        for r in range(data.n_rec):
            lo, hi = np.quantile(betas[:, r], [a, 1 - a])
            beta_iv[r] = widened(float(fit.betas[r]), lo, hi, sys_rel)
    return law_from_fit(data, fit, path, lib, intervals, beta_iv, coverage)


def law_from_fit(
    data: Data,
    fit: Fit,
    path: list[dict[str, Any]],
    lib: Fit,
    intervals: dict[str, Any] | None = None,
    beta_intervals: Sequence[Any] | None = None,
    coverage: float = 0.9,
) -> DiscoveredLaw:
    """The :class:`DiscoveredLaw` of a fit on the stacked samples, beside the library's best."""
    new = tuple(t for t in _ordered(fit.terms) if is_new_term(t, fit.params))
    return DiscoveredLaw(
        terms=_ordered(fit.terms),
        params=fit.params,
        intervals=dict(intervals or {}),
        recordings=data.names,
        betas=tuple(float(b) for b in fit.betas),
        beta_intervals=tuple(beta_intervals or [None] * data.n_rec),
        onsets=tuple(float(e) for e in fit.onsets),
        explained_fraction=explained_fraction(data, fit),
        library_explained_fraction=explained_fraction(data, lib),
        library_terms=_ordered(lib.terms),
        path=path,
        new_terms=new,
        n_impacts=int(np.unique(data.impact).size),
        coverage=coverage,
        library_params=lib.params,
        library_betas=tuple(float(b) for b in lib.betas),
        library_onsets=tuple(float(e) for e in lib.onsets),
    )


def widened(value: float, lo: float, hi: float, sys_rel: float) -> tuple[float, float]:
    """The bootstrap interval around ``value`` with a relative systematic half-width added in
    quadrature (on the scale of the value's magnitude; a parameter at 0 keeps its own)."""
    lo, hi = min(float(lo), value), max(float(hi), value)
    s = abs(value) * sys_rel
    return value - float(np.hypot(value - lo, s)), value + float(np.hypot(hi - value, s))


def _ordered(terms: frozenset[str]) -> tuple[str, ...]:
    order = [*TERMS, "hertz"]
    return tuple(sorted(terms, key=order.index))


__all__ = ["LIBRARY_TERMS", "TERM_PARAMS", "discover_contact_law"]

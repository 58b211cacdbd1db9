"""A campaign's sensor chain: one accelerometer, identified on some recordings, used on all.

The predictor's restoring-force check identifies the accelerometer's chain per recording,
and only where the record's contact law needs one (R² below
:data:`~stiffnet.restoring_force.estimate.CHAIN_FIT_WHEN_NEEDED`): behind one sensor, many
recordings of a campaign identify none, and the model reads them as recorded. The
recordings of a campaign share their accelerometer, so the chains identified on some of
them are the chain of all. :func:`campaign_chain` pools them with the rule ``diagnose``'s
evidence uses (:func:`~stiffnet.restoring_force.chain.shared_chain`: per stage the median
over the recordings that show it, where at least half of them do), and the caller predicts
every recording again with the pooled chain as its data sheet (the predictor's ``sensor``),
which :func:`labelled` then marks ``source: "campaign"``; a recording whose own contact law
reads much worse through the pooled chain keeps its first reading (:func:`reads_alone`).

Pooled only where the identifications agree, stage by stage: a resonance or low-pass is
pooled where its value on at least :data:`MIN_AGREEING_SHARE` of the recordings that show
it lies within :data:`FIT_SCATTER` of the pooled one (or the pooled one within that
recording's interval), and at least :data:`MIN_IDENTIFIED` recordings identified a chain.
A stage they disagree on is left out and named; where no stage is left nothing is pooled
and the reason says why: recordings behind different sensors (or a chain the fits cannot
pin down) are each read with their own. The pooled chain is then kept only where it reads
the campaign's contact laws about as well as the first reading did (:func:`confirmed`:
the median R² lost at most
:data:`~stiffnet.restoring_force.chain.CHAIN_CONFIRMED_SHORTFALL`, the rule diagnose's
evidence confirms its shared chain by): recordings of different sensors whose fitted
resonances happen to cluster (the bottom of a prior) agree in frequency, yet their clean
recordings read through the pooled chain lose 0.16 of R² (median, the bench's
``sensor_chains``), where a campaign's own chain loses 0.01-0.03. An ideal campaign
identifies no resonance or low-pass and gets no pooled chain. A recording's own data sheet
always wins.

The high-pass is pooled as the other stages are (the median, where at least half of the
identified chains show one); where none is pooled the sheet's ``highpass_hz`` is
:data:`~stiffnet.restoring_force.chain.HIGHPASS_FITTED`, so each recording's map fits its
own charge-amplifier corner behind the pooled chain, as it does without a sheet. A sheet's
corner is held, not refitted, and the chain fits that pool nothing often missed a corner
(0-4 Hz found for a true 3.6 Hz on the rig's campaigns): a pooled 0 held every map at no
high-pass, which read the rig's beta 0.3-0.9 off and cost a campaign its pooled chain
(median R² lost 0.12). The corner is not left to the record everywhere: fitted behind a
chain of another sensor, its profile by the contact law tunes it until the law fits again,
and the confirmation no longer sees the wrong chain (the bench's per-recording
``sensor_chains``: median R² lost 0.001 instead of 0.16, and the pooled chain kept).
A pooled corner is then profiled over the campaign (:func:`campaign_highpass`): the median of
the corners the recordings' own checks fitted reads up to 37 % low behind a low-pass (each was
fitted behind the recording's own chain, whose contact law is read without the band its
inverse keeps), so the corner held for all is the one at which the campaign's contact laws,
read through the pooled chain, fit best (the median over the recordings of each one's misfit
against its own best corner).
The low-pass is profiled the same way, before the high-pass (:func:`campaign_lowpass`), where
the identified chains show one the pool left out: a recording's chain fit trades the
low-pass corner against its contact's damping, so the per-recording corners scatter, and
where they disagree the pool left the stage out (a rig campaign behind a 187 Hz low-pass
read without one). A low-pass the recordings agree on keeps its pooled median (profiled,
the rig's damped campaigns moved away from the truth). The corner is shared and the contacts
are not: candidate corners around the recordings' fitted ones (and orders 2-4 where the
fitted orders disagree) are each held for the whole campaign, and the one at which the
campaign's contact laws read best is kept, with its interval (:func:`corner_interval`) in
the sheet as ``lowpass_low_hz`` / ``lowpass_high_hz`` (beta's interval spans the readings at
its ends). A campaign whose stages all disagreed but whose chains show a low-pass is pooled
with the profiled low-pass alone; :func:`confirmed` still judges it. The high-pass corner is
then profiled through the chosen low-pass.
A pooled resonance near the contacts (below :data:`RESONANCE_NEAR_CONTACT` times the stiffest
contact's frequency) is profiled the same way, in frequency and damping, after the high-pass
(:func:`campaign_resonance`), and only where the pool refuses a recording whose contact law
it fitted: pooled from two or three fits that trade the damping against the frequency, a
mount 2-4 % off in frequency and a third off in damping leaves ringing around each pulse,
and the contacts read as lasting too long (refused). A refused reading counts as force
unexplained, the candidate that reads the most recordings wins, and the pool is kept unless
one reads more than it does: a pool that reads every recording is never moved.
A low-pass that fewer than half the identified chains show is no pooled stage; it is then
profiled the same way over the pooled chain as it stands (:func:`campaign_lowpass_minority`),
with "no low-pass" a candidate, and kept only where it reads the contact laws better: well
above the contacts only the recordings whose laws asked for a chain fit show it (the rig's
371 Hz order 3 behind a 217 Hz mount, shown by one fit of three).
Where the gated fits identify too few chains to pool (:data:`MIN_IDENTIFIED`), the chain is
fitted again regardless of the gate on every recording that fitted none
(:func:`identify_regardless`), and those fits are pooled as above. The gate spares a single
recording a fit its contact law does not ask for, but behind a second-order low-pass a few
contact frequencies up every recording's law still reads R² 0.99 (a softer contact; the rig's
106 Hz order 2 read β 19.5 for 38.9): the campaign is the evidence no recording gives alone.
Numpy only at import (the predictor imports it); the corner's profile imports scipy and
the restoring-force estimate when it runs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from stiffnet.restoring_force.chain import (
    CHAIN_CONFIRMED_SHORTFALL,
    HIGHPASS_FITTED,
    LOWPASS_ENDS,
    shared_chain,
    shared_chain_sheet,
    shared_chain_shortfall,
)

#: A campaign chain needs at least this many recordings that identified one (a single fit
#: is no campaign's evidence: on an ideal record it may be a spurious stage).
MIN_IDENTIFIED = 2
#: Relative scatter of a fitted corner or resonance that still counts as the same stage
#: (the chain fit's own scatter: 2-10 % in frequency on simulated chains).
FIT_SCATTER = 0.10
#: Share of the recordings showing a stage whose value must agree with the pooled one.
MIN_AGREEING_SHARE = 2 / 3
#: The stages whose frequency the guard compares (the high-pass is read as pooled, or left
#: to each recording where none is: ``highpass_hz`` :data:`HIGHPASS_FITTED`).
STAGES = ("resonance_hz", "lowpass_hz")
#: The parameter each stage carries with it.
PARTNER = {"resonance_hz": "resonance_damping", "lowpass_hz": "lowpass_order"}
#: The low-pass orders :func:`campaign_lowpass` profiles where the recordings' fitted orders
#: disagree (a charge amplifier's low-pass: the lab prior's orders), beside the fitted ones.
LOWPASS_ORDERS = (2, 3, 4)
#: The low-pass profile's grid: steps of :data:`FIT_SCATTER` in frequency from this many steps
#: below the lowest fitted corner (a recording's fit reads its corner high: 14-16 % on the
#: rig's campaigns, the pulse model's bias) to this many above the highest.
LOWPASS_STEPS_BELOW = 3
LOWPASS_STEPS_ABOVE = 1
#: At most this many corners per order on the coarse grid (wider spreads get coarser steps):
#: the profile reads every recording at each (or a subset: :func:`profiled_subset`).
MAX_LOWPASS_GRID = 16
#: Evaluations of the bounded refinement between the best grid corner's neighbours.
LOWPASS_REFINE_ITER = 8
#: The high-pass profile's refinement: its bounded search's iterations.
HIGHPASS_REFINE_ITER = 12
#: :func:`campaign_resonance` profiles a pooled resonance only below this many times the
#: stiffest contact's frequency (``f_n sqrt(1 + beta)`` at the classes' top beta, 96 Hz on the
#: rig): a mount ringing there overlaps the contact pulse, whose spectrum reaches a few times
#: its own frequency, and a resonance undone 2-4 % off in frequency and a third off in damping
#: leaves ringing that the contact law reads as contacts lasting 2.7-5.5 half periods (the
#: rig's held-out campaigns behind 198 and 217 Hz); far above it the inverse barely touches
#: the pulse and the profile would cost about 60 readings per recording for nothing.
RESONANCE_NEAR_CONTACT = 3.0
#: The resonance profile's grid: frequency steps of this relative size, as many on each side
#: of the pooled resonance as make :data:`FIT_SCATTER` (the fits' own scatter) ...
RESONANCE_STEP = 0.02
#: ... at the pooled damping times each of these (the recordings' fits read the rig's mount
#: damping 0.67-0.77 of the truth, and trade it against the frequency) ...
RESONANCE_DAMPING_FACTORS = (0.5, 0.7, 1.0, 1.4, 2.0)
#: ... and the best point refined on this many points (ends included) between its grid
#: neighbours, in frequency then in damping: a grid, not a scalar search, because the
#: candidates are ranked first by the recordings they read, then by their misfit.
RESONANCE_REFINE_POINTS = 7
#: :func:`campaign_resonance_minority` reads the campaign through at most this many of the
#: resonances the chain fits showed behind a low-pass (their largest groups): each costs a
#: reading of every recording, and a spurious fit (a ring read as a slow resonance beside a
#: faster low-pass) stands alone.
MAX_RESONANCE_CANDIDATES = 3
#: The stages a candidate chain of :func:`campaign_resonance_minority` carries whole.
STAGE_KEYS = ("resonance_hz", "resonance_damping", "lowpass_hz", "lowpass_order")
#: :func:`campaign_highpass_damped` reads the free flight at a trial corner at most this many
#: times: the first step from the contact laws' corner, a second where that step moved the
#: corner by more than :data:`FREE_FLIGHT_STEP_TOL` (the free damping's slope in the corner
#: differs from ``1 / (2 f_n)``: 0.049 per Hz measured for 0.053 on the rig's campaign behind
#: 4.48 Hz, so one step leaves under a tenth of itself).
FREE_FLIGHT_STEPS = 2
#: ... relative step below which the first step's corner is kept unread.
FREE_FLIGHT_STEP_TOL = 0.02
#: Error assumed on the free flight's damping against the rig's given one: a lab's free-decay
#: test reads the damping ratio to about 0.005, and the free flight read through a pooled chain
#: whose low-pass or mount is off reads it off by as much again (on the bench's six campaign
#: sets' campaigns where it was read, the campaign's median at the true corner moved by -0.003
#: to +0.008 from the true chain's to the pooled one's: read from that bench, not independent
#: of it). The corner moves by ``2 f_n`` times it (0.19 Hz on the rig), which the sheet's
#: interval spans.
FREE_DAMPING_TOLERANCE = 0.01
#: The most recording readings one campaign profile spends on its candidates and their
#: refinement (each a whole restoring-force estimate, about 1 s CPU on the rig): a
#: 24-recording campaign's low-pass profile over three orders read every recording on 48
#: candidates and 8 refinements, 1,340 readings, and its high-pass profile 550 more, over
#: half an hour of one evaluation. Beyond it the profile reads a spread subset of the
#: recordings (:func:`profiled_subset`).
MAX_PROFILE_READINGS = 200
#: ... but never fewer recordings than this: the profile's criterion is their median (the
#: bench's campaigns hold six recordings, read whole).
MIN_PROFILED_RECORDINGS = 6
#: The most recordings whose chain is fitted again regardless of the gate (each fit 5-15 s CPU
#: on the rig: 24 of them were six minutes of an evaluation); the pool needs a consensus,
#: which this many spread over the campaign give.
MAX_FITTED_REGARDLESS = 8


def profiled_subset(todo: Sequence[int], n_candidates: int, kept: Sequence[int] = ()) -> list[int]:
    """Rule: the recordings a campaign profile reads on each of its `n_candidates`: all of
    `todo` where that stays within :data:`MAX_PROFILE_READINGS` readings, else as many as the
    budget allows, at least :data:`MIN_PROFILED_RECORDINGS` (:func:`spread_subset`, `kept`
    the recordings the profile is for). The profiles' criterion is a median over the
    recordings, which a spread subset estimates; the cost of one stays bounded whatever the
    campaign's size."""
    keep = max(MIN_PROFILED_RECORDINGS, MAX_PROFILE_READINGS // max(int(n_candidates), 1))
    return spread_subset(todo, keep, kept)


def spread_subset(todo: Sequence[int], keep: int, kept: Sequence[int] = ()) -> list[int]:
    """Rule: `todo` where it holds at most `keep` recordings, else `keep` of them: those of
    `kept`, and the others evenly spaced in the campaign's order; returned in `todo`'s order."""
    if len(todo) <= keep:
        return list(todo)
    wanted = set(kept)
    first = [i for i in todo if i in wanted][:keep]
    rest = [i for i in todo if i not in set(first)]
    n_rest = keep - len(first)
    picks = np.unique(np.round(np.linspace(0, len(rest) - 1, n_rest)).astype(int)) if n_rest else []
    chosen = {*first, *(rest[int(k)] for k in picks)}
    return [i for i in todo if i in chosen]


def identified(sensor: dict | None) -> dict | None:
    """The chain a recording's check fitted and applied with a resonance or a low-pass
    (None: a data sheet, a rejected fit, or no dynamics in the band)."""
    if not sensor or sensor.get("source") != "fitted" or sensor.get("applied") is False:
        return None
    return sensor if sensor.get("resonance_hz") or sensor.get("lowpass_hz") else None


def _agrees(sensor: dict, key: str, pooled: float) -> bool:
    """Whether `sensor`'s stage `key` is the pooled one: within :data:`FIT_SCATTER` of it,
    or its own interval (widened as much) holds it."""
    value = float(sensor[key])
    if abs(np.log(value / pooled)) <= np.log1p(FIT_SCATTER):
        return True
    low, high = (sensor.get("intervals") or {}).get(key) or (value, value)
    return low / (1 + FIT_SCATTER) <= pooled <= high * (1 + FIT_SCATTER)


def campaign_chain(
    sensors: Sequence[dict | None],
    names: Sequence[str],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """The chain a campaign's recordings share, or why none is pooled.

    Parameters
    ----------
    sensors : sequence of dict or None
        Each recording's restoring-force ``sensor`` (the check's, without a data sheet;
        None where the recording could not be read).
    names : sequence of str
        The recordings' names, for the report.
    sheets : sequence of dict or None, optional
        Each recording's own data sheet (a recording with one is read with it and does not
        vote).

    Returns
    -------
    dict
        ``pooled`` (bool), ``sensor`` (the pooled chain as a data sheet, None when not
        pooled), ``identified_on`` (names of the recordings whose chains were pooled),
        ``n_identified``, ``n`` (recordings), ``stages`` (per pooled stage: value, 10-90 %
        range, recordings agreeing / showing it), ``reason`` (one line).
    """
    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    votes = [(name, identified(s)) for name, s, sheet in zip(names, sensors, sheets, strict=True)
             if sheet is None]  # fmt: skip
    votes = [(name, s) for name, s in votes if s is not None]
    out: dict[str, Any] = {"pooled": False, "sensor": None, "n": len(sensors),
                           "n_identified": len(votes),
                           "identified_on": [name for name, _ in votes], "stages": {}}  # fmt: skip
    if len(votes) < MIN_IDENTIFIED:
        out["reason"] = (f"a sensor chain identified on {len(votes)} recording(s): at least "
                         f"{MIN_IDENTIFIED} are needed to pool one")  # fmt: skip
        return out
    shared = shared_chain([s for _, s in votes])
    sheet = shared_chain_sheet(shared)
    if sheet is None:
        out["reason"] = "the identified chains share no resonance or low-pass"
        return out
    if not shared.get("highpass_hz"):  # none pooled is no corner known, not a corner of 0
        sheet["highpass_hz"] = HIGHPASS_FITTED
    apart, kept = [], []
    for key in STAGES:
        if not shared.get(key):
            continue
        showing = [s for _, s in votes if s.get(key)]
        agree = sum(_agrees(s, key, shared[key]) for s in showing)
        out["stages"][key] = {"value": shared[key], "range": shared[f"{key}_range"],
                              "agreeing": agree, "showing": len(showing)}  # fmt: skip
        if agree >= MIN_AGREEING_SHARE * len(showing):
            kept.append(key)
            continue
        low, high = shared[f"{key}_range"]
        apart.append(f"{key} {low:.0f}-{high:.0f} Hz ({agree} of {len(showing)} within "
                     f"{FIT_SCATTER:.0%} of {shared[key]:.0f} Hz)")  # fmt: skip
        sheet.update({key: 0.0, PARTNER[key]: 0.0})  # a stage they disagree on is no one's
    if not kept:
        out["reason"] = ("the recordings' identified chains disagree, not pooled: "
                         + "; ".join(apart))  # fmt: skip
        out["unpooled_sheet"] = sheet  # what :func:`campaign_lowpass` may still complete
        return out
    words = " and ".join(k.removesuffix("_hz").replace("lowpass", "low-pass") for k in kept)
    out.update(pooled=True, sensor=sheet,
               reason=f"one sensor chain ({words}) pooled over the {len(votes)} recordings "
               f"that identified one, used on all {sum(s is None for s in sheets)} without a "
               "data sheet")  # fmt: skip
    if apart:
        out["reason"] += "; left out, the recordings disagree: " + "; ".join(apart)
    return out


def gated_out(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    sheets: Sequence[dict | None] | None = None,
) -> list[int]:
    """Rule: the recordings whose chain is fitted again regardless of the contact law's R²:
    where `chain` pooled nothing because fewer than :data:`MIN_IDENTIFIED` recordings
    identified one, each recording without a data sheet whose check fitted no chain (its law
    read above the gate; a fit that ran and was rejected or found no stage is kept)."""
    if chain["pooled"] or chain["n_identified"] >= MIN_IDENTIFIED:
        return []
    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    return [i for i, (s, sheet) in enumerate(zip(sensors, sheets, strict=True))
            if sheet is None and (not s or s.get("source") != "fitted")]  # fmt: skip


def identify_regardless(
    sensors: Sequence[dict | None],
    names: Sequence[str],
    sheets: Sequence[dict | None] | None,
    identify: Callable[[int], dict | None],
) -> tuple[dict[str, Any], list[dict | None]]:
    """The campaign's chain (:func:`campaign_chain`), with the chain fitted regardless of the
    gate (`identify`: recording index to the restoring-force ``sensor`` of a check that always
    fits one) on the recordings :func:`gated_out` names (at most :data:`MAX_FITTED_REGARDLESS`,
    spread over the campaign: :func:`spread_subset`), where the gated fits pool nothing for
    want of identified chains. Returns the decision (``fitted_regardless``: those recordings'
    names) and the sensors it pooled."""
    chain = campaign_chain(sensors, names, sheets)
    todo = spread_subset(gated_out(chain, sensors, sheets), MAX_FITTED_REGARDLESS)
    if not todo:
        return chain, list(sensors)
    sensors = list(sensors)
    for i in todo:
        sensors[i] = identify(i)
    chain = campaign_chain(sensors, names, sheets)
    chain["fitted_regardless"] = [names[i] for i in todo]
    chain["reason"] += (f" (the chain fitted regardless of the contact law's R² on {len(todo)} "
                        "recording(s) whose gated check fitted none)")  # fmt: skip
    return chain, sensors


def chain_fitted_regardless(accel: Any, fs_hz: float, fn_hz: float, predictor: Any) -> dict | None:
    """The restoring-force ``sensor`` of `predictor`'s check on a recording with the chain
    fitted regardless of the gate (the samples checked and scaled as the predictor's own);
    the `identify` of :func:`identify_regardless`; None where the reading fails, as the
    check then reports none. Raises what the predictor's input check raises.

    Only the chain is kept, so the estimate is read without beta's interval and without the
    check's law-shape readings, its chain's unexcluded low-passes still profiled
    (``chain_profile``): the same chain as the whole check fits (an estimate without an
    interval reads the same map and chain), for about 70 % of its CPU (two rig records behind
    a low-pass: 4.6 -> 3.4 and 5.5 -> 3.9 s). Where a part of the whole check after the chain
    fails (the interval's fits, the impact onsets) the check reports no chain; this reading
    still reports the chain it fitted."""
    from serving.checks import checked_recording
    from serving.restoring_force_check import RESTORING_FORCE_PERIODS
    from stiffnet.errors import StiffnetError
    from stiffnet.restoring_force import restoring_force_estimate

    a = checked_recording(accel, fs_hz, fn_hz, predictor.window_periods, "recording")[0]
    try:
        r = restoring_force_estimate(
            a, fs_hz, natural_frequency_hz=fn_hz, max_periods=RESTORING_FORCE_PERIODS,
            chain_fit_below_r2=np.inf, interval=False, chain_profile=True,  # always fitted
            stage_ratio=predictor.stage_ratio,
            penetration_dissipation=predictor.penetration_dissipation,
        )  # fmt: skip
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    return r.sensor.to_dict() if r.sensor is not None else None


def campaign_highpass(
    chain: dict[str, Any],
    contact_r2: Callable[[int, dict[str, Any]], float | None],
    fn_hz: Sequence[float | None],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with its pooled high-pass corner profiled over the campaign: the one corner
    that reads the campaign's contact laws best through the pooled chain.

    The pooled corner is the median of the corners the recordings' own checks fitted, and
    each was fitted behind a chain of that recording's own, whose contact law is read without
    the band the inverse keeps (a fitted chain is judged by that law's R², so its map keeps
    the plain fit). On a pulse a low-pass has rounded, that law fits best at a corner below
    the true one, and the corner's veto and profile in
    :func:`~stiffnet.restoring_force.estimate.restoring_force_estimate` follow it: the rig's
    damped campaigns pooled 2.54 Hz for 4.04 and 3.34 for 4.52, and three recordings of the
    second, read through their true chain without the band, fit their laws best near 3.5 Hz,
    with it near 4.5. The pooled chain is read as a known chain, its law fitted through the
    kept band, so the corner is profiled there: on each candidate corner every recording
    without its own data sheet (`sheets`) is read through the pooled chain with that corner
    held (`contact_r2`: recording index and data sheet to the contact law's R², None without
    a law, which counts as R² 0), and the corner chosen is the one at which the median over
    the recordings of ``log((1 - R²) / (1 - R²_best))`` is least, ``R²_best`` each
    recording's best candidate: the recordings' joint misfit, each on its own scale (a
    contact read at R² 0.9999 has as much say as one read at 0.99), and the median, as the
    confirmation judges the campaign (:func:`confirmed`), so a recording whose map jumps with
    the corner (a soft contact that barely stands out) does not move it. Candidates: the
    estimate's corner grid (:data:`~stiffnet.restoring_force.estimate.HIGHPASS_GRID`, forcing
    frequencies, at the recordings' median natural frequency `fn_hz`) and the pooled corner,
    refined by a bounded search between the best one's neighbours. A chain that pooled
    nothing, or no corner (``"auto"``: each recording fits its own), is returned as it is.
    ``stages["highpass_hz"]`` reports the profiled and the pooled corner.
    """
    from scipy import optimize

    from stiffnet.restoring_force.estimate import HIGHPASS_GRID

    sheet = chain.get("sensor") if chain.get("pooled") else None
    pooled = (sheet or {}).get("highpass_hz")
    sheets = list(sheets) if sheets is not None else [None] * len(fn_hz)
    todo = [i for i, own in enumerate(sheets) if own is None]
    # behind the contacts' own dissipation the recordings' corners were profiled by the
    # Kelvin-Voigt law, which reads a Hunt-Crossley pulse best at no corner: no pooled corner
    # is no evidence there, and the grid alone is profiled
    # so were they behind a chain the campaign completed with a stage their fits lacked (a
    # mount behind the low-pass, :func:`campaign_resonance_minority`): each recording's own
    # corner, fitted behind it, read the rig's none as 3.1 Hz and beta 28 for 75
    unpooled = pooled == HIGHPASS_FITTED and bool(
        chain.get("contact_dissipation") or chain.get("completed_stage")
    )
    if not unpooled and (not isinstance(pooled, int | float) or not pooled > 0) or not todo:
        return chain
    scale = np.nanmedian([fn_hz[i] if fn_hz[i] is not None else np.nan for i in todo])
    if not np.isfinite(scale):
        return chain
    grid = np.unique(np.r_[HIGHPASS_GRID * float(scale), [] if unpooled else [pooled]])
    todo = profiled_subset(todo, grid.size + HIGHPASS_REFINE_ITER)
    memo: dict[float, np.ndarray] = {}

    def misfit(corner: float) -> np.ndarray:  # each recording's share of force unexplained
        if corner not in memo:
            at = {**sheet, "highpass_hz": corner}
            r2 = np.array([contact_r2(i, at) or 0.0 for i in todo])  # no law explains nothing
            memo[corner] = np.maximum(1.0 - r2, np.finfo(float).eps)
        return memo[corner]

    table = np.array([misfit(float(c)) for c in grid])  # corners x recordings
    read = table.min(axis=0) < 1.0  # a recording with no law at any corner has no say
    if not read.any():
        return chain
    least = table.min(axis=0)

    def median_misfit(corner: float) -> float:  # log: each recording against its own best
        return float(np.median(np.log(misfit(corner) / least)[read]))

    i = int(np.argmin([median_misfit(float(c)) for c in grid]))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    sol = optimize.minimize_scalar(
        lambda u: median_misfit(float(np.exp(u))), bounds=(np.log(lo), np.log(hi)),
        method="bounded", options={"xatol": 0.02, "maxiter": HIGHPASS_REFINE_ITER},
    )  # fmt: skip
    corner = float(np.exp(sol.x)) if sol.fun < median_misfit(float(grid[i])) else float(grid[i])
    low, high = corner_interval(memo, read, corner)
    out = {**chain, "sensor": {**sheet, "highpass_hz": corner, "highpass_low_hz": low,
                               "highpass_high_hz": high}}  # fmt: skip
    out["stages"] = {**chain.get("stages", {}), "highpass_hz": {
        "value": corner, "interval": [low, high],
        "pooled_median": None if unpooled else float(pooled),
        "profiled_on": int(read.sum()), "median_log_misfit": median_misfit(corner),
        "source": "contact_r2_profile"}}  # fmt: skip
    fits = ("each recording's own" if unpooled
            else f"the median of the recordings' own fits {float(pooled):.2f} Hz")  # fmt: skip
    out["reason"] = (f"{chain['reason']}; the high-pass corner profiled over the campaign's "
                     f"contact laws: {corner:.2f} Hz [{low:.2f}, {high:.2f}] ({fits})")  # fmt: skip
    return out


def campaign_highpass_damped(
    chain: dict[str, Any],
    free_damping: Callable[[int, dict[str, Any]], float | None],
    fn_hz: Sequence[float | None],
    rig_damping: Sequence[float | None],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with its profiled high-pass corner taken from the free flight where the
    campaign's rows give the rig's damping ratio (the manifest's ``damping_ratio``).

    Why. On a damped contact the contact laws' R² barely tells corners apart
    (:func:`campaign_highpass` read 4.07 Hz for a true 4.48, and a Kelvin-Voigt law moves
    beta about -1 % per +1 % of corner). The free flight does: a corner undone off by a
    fraction ``delta`` leaves ``delta`` times the recorded velocity in the acceleration, which
    the free-flight law ``x'' + 2 zeta x' + x = forcing`` reads as damping,
    ``zeta_free ~ zeta_rig + delta f_h / (2 f_n)``. The free damping and the corner are one
    parameter to the record, so the rig's own damping (a free-decay test) must be given.

    The rule. Every recording without its own data sheet (`sheets`) whose row gives a damping
    (`rig_damping`) and a natural frequency (`fn_hz`) is read through the pooled chain with
    the trial corner held (`free_damping`: recording index and data sheet to the free
    flight's own damping ratio, :func:`free_damping_through`; None without one); each implies
    the corner ``f_h' + 2 f_n (zeta_free - zeta_rig)`` and the campaign's is their median,
    read again once from there where the step exceeds :data:`FREE_FLIGHT_STEP_TOL`
    (:data:`FREE_FLIGHT_STEPS`). Its interval is the median's over the recordings drawn again
    with replacement (:func:`_median_interval`) widened to hold the contact laws' corner (the
    bootstrap knows neither the given damping's error nor the formula's) and by ``2 f_n``
    times :data:`FREE_DAMPING_TOLERANCE` either side (an error the recordings share: the given
    damping's, and the free flight's own through a pooled low-pass or mount that is off,
    which moves it, mostly up), in the sheet as ``highpass_low_hz`` / ``highpass_high_hz``.
    ``stages["highpass_hz"]["source"]`` says which corner the sheet holds:
    ``"free_flight_damping"`` or ``"contact_r2_profile"``.

    The guard: a given damping can be wrong (a lab writes 0.04 for 0.02: the corner moves by
    ``2 f_n`` times the error, 0.38 Hz on the rig), and recordings can disagree. The profile
    is kept, with the reason under ``stages["highpass_hz"]["free_flight"]`` and in the
    chain's ``reason``, where fewer than :data:`MIN_IDENTIFIED` recordings read a free
    damping, where the implied corner lies outside the profile's interval widened by
    :data:`FIT_SCATTER` (the contact laws' plausible range: a damping off by 0.02 moves the
    corner less than that on the rig and is not caught), or where the free flight's interval
    spans more than :data:`FIT_SCATTER` either side (``high / low > (1 + FIT_SCATTER)²``,
    the chain fits' own scatter, beyond which the recordings do not read one corner) or is
    no narrower than the profile's (the free flights tell the corner no better than the
    contact laws).

    It runs last, after :func:`campaign_resonance`: read through a pooled resonance near the
    contacts that is off (the rig's 205.9 Hz zeta 0.034 for a true 197.8 Hz 0.051), the mount
    rings through the flight and the free damping read a corner of 6.85 Hz for 4.48; through
    the profiled one (197.9 Hz zeta 0.054) 4.49. The resonance is profiled at the contact
    laws' corner and not again.

    Returned as it is: a chain whose corner was not profiled (:func:`campaign_highpass`: no
    pool, or each recording's own corner) and a campaign whose rows give no damping.
    """
    stage = (chain.get("stages") or {}).get("highpass_hz")
    sheet = chain.get("sensor") if chain.get("pooled") else None
    sheets = list(sheets) if sheets is not None else [None] * len(fn_hz)
    todo = [i for i, own in enumerate(sheets) if own is None and fn_hz[i] and rig_damping[i]]
    if not stage or not sheet or not todo:
        return chain
    fn = np.array([float(fn_hz[i]) for i in todo])
    zeta_rig = np.array([float(rig_damping[i]) for i in todo])
    trial, profiled = float(stage["value"]), float(stage["value"])
    held = {k: v for k, v in sheet.items() if k not in ("highpass_low_hz", "highpass_high_hz")}
    for step in range(FREE_FLIGHT_STEPS):
        at = {**held, "highpass_hz": trial}  # held: the profile's interval need not hold it
        zeta = np.array([np.nan if (z := free_damping(i, at)) is None else z for i in todo])
        implied = trial + 2.0 * fn * (zeta - zeta_rig)
        ok = np.isfinite(implied)
        corner = float(np.median(implied[ok])) if ok.sum() >= MIN_IDENTIFIED else np.nan
        last = step == FREE_FLIGHT_STEPS - 1
        if last or not corner > 0 or abs(np.log(corner / trial)) <= FREE_FLIGHT_STEP_TOL:
            break
        trial = corner
    given = float(np.median(zeta_rig))
    low_p, high_p = stage["interval"]
    report: dict[str, Any] = {"corner": corner if np.isfinite(corner) else None,
                              "rig_damping": given, "read_on": int(ok.sum()),
                              "free_damping": [None if not np.isfinite(z) else float(z)
                                               for z in zeta], "trial": trial}  # fmt: skip
    if ok.sum() < MIN_IDENTIFIED:
        why = f"the free flight read a damping on {int(ok.sum())} recording(s)"
    elif not low_p / (1 + FIT_SCATTER) <= corner <= high_p * (1 + FIT_SCATTER):
        why = (f"the corner the free flight implies at the given damping {given:g} "
               f"({corner:.2f} Hz) lies outside the contact laws' range [{low_p:.2f}, "
               f"{high_p:.2f}] Hz widened by {FIT_SCATTER:.0%}: is the damping right?")  # fmt: skip
    else:
        low, high = _median_interval(implied[ok], corner)
        report["interval"] = [low, high]
        spread = np.log(high / low)
        if spread > 2.0 * np.log1p(FIT_SCATTER) or spread >= np.log(high_p / low_p):
            why = (f"the recordings' free flights disagree: {low:.2f}-{high:.2f} Hz (wider "
                   f"than {FIT_SCATTER:.0%} either side, or than the contact laws' "
                   f"[{low_p:.2f}, {high_p:.2f}] Hz)")  # fmt: skip
        else:
            why = None
    if why is not None:
        kept = {**stage, "source": "contact_r2_profile", "free_flight": {**report, "kept": why}}
        out = {**chain, "stages": {**chain["stages"], "highpass_hz": kept}}
        out["reason"] = f"{chain['reason']}; the profiled corner kept: {why}"
        return out
    # the sheet's interval spans both identifiers: the free flight's median is read at a
    # given damping taken as exact and its formula's slope, so its bootstrap is not the
    # corner's whole uncertainty, and the contact laws' corner is the other reading of it;
    # and it spans the corners a free damping off by the tolerance implies: the bootstrap
    # knows the recordings' scatter, not an error they share (the given damping, the band)
    low, high = min(low, profiled), max(high, profiled)
    slack = 2.0 * float(np.median(fn)) * FREE_DAMPING_TOLERANCE
    low, high = max(low - slack, 0.0), high + slack
    report["tolerance"] = FREE_DAMPING_TOLERANCE
    out = {**chain, "sensor": {**sheet, "highpass_hz": corner, "highpass_low_hz": low,
                               "highpass_high_hz": high}}  # fmt: skip
    out["stages"] = {**chain["stages"], "highpass_hz": {
        **stage, "value": corner, "interval": [low, high], "profiled": profiled,
        "profiled_interval": [low_p, high_p], "source": "free_flight_damping",
        "free_flight": report}}  # fmt: skip
    out["reason"] = (f"{chain['reason']}; the corner from the free flight at the rig's "
                     f"damping {given:g}: {corner:.2f} Hz [{low:.2f}, {high:.2f}] on "
                     f"{int(ok.sum())} recordings (the contact laws' {profiled:.2f} Hz; "
                     f"the free damping taken to +-{FREE_DAMPING_TOLERANCE:g})")  # fmt: skip
    return out


def _median_interval(values: np.ndarray, centre: float, seed: int = 0) -> tuple[float, float]:
    """The interval at :data:`~stiffnet.restoring_force.chain.COVERAGE` of the median of
    `values` (the recordings' implied corners) over the recordings drawn again with
    replacement, widened to hold `centre` (the rule of :func:`corner_interval`)."""
    from stiffnet.restoring_force.chain import COVERAGE
    from stiffnet.restoring_force.estimate import N_BOOTSTRAP

    draws = np.random.default_rng(seed).integers(0, values.size, (N_BOOTSTRAP, values.size))
    medians = np.median(values[draws], axis=1)
    alpha = 0.5 * (1.0 - COVERAGE)
    low, high = np.quantile(medians, [alpha, 1.0 - alpha])
    return min(float(low), centre), max(float(high), centre)


def campaign_lowpass(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    contact_r2: Callable[[int, dict[str, Any]], float | None],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with its low-pass profiled over the campaign: the corner (and order) that reads
    the campaign's contact laws best through the pooled chain, where the recordings'
    identified chains show a low-pass that the pool left out because their corners disagree.

    A recording's chain fit trades the low-pass corner against its contact's damping (one rig
    record: least-squares corner 95.7 Hz for a true 85.9, its contact read at zeta 0.62 for
    0.196), so per-recording corners scatter and read high, and the pool takes their median or
    leaves the stage out. The corner is shared and the contacts are not: the campaign tells
    them apart. On each candidate every recording without its own data sheet (`sheets`) is
    read through the pooled chain with that corner and order held (`contact_r2`, as in
    :func:`campaign_highpass`; None counts as R² 0), and the one chosen is the one at which
    the median over the recordings of ``log((1 - R²) / (1 - R²_best))`` is least (the rule of
    :func:`campaign_highpass`). Candidates: corners in steps of :data:`FIT_SCATTER` around
    the recordings' fitted ones (:data:`LOWPASS_STEPS_BELOW` steps below the lowest,
    :data:`LOWPASS_STEPS_ABOVE` above the highest, at most :data:`MAX_LOWPASS_GRID` per
    order), at the fitted order where the recordings agree on one, else at each of
    :data:`LOWPASS_ORDERS` and the fitted ones; the best refined by a bounded search between
    its neighbours at its order. The corner's interval is :func:`corner_interval`'s over the
    corners read at the chosen order, put in the sheet as ``lowpass_low_hz`` /
    ``lowpass_high_hz`` (beta's interval spans the readings at its ends). A campaign whose
    stages all disagree but whose chains show a low-pass is pooled with the profiled
    low-pass alone (:func:`confirmed` still judges it).

    Returned as it is: a campaign whose identified chains show no low-pass; one whose
    recordings agree on a low-pass (pooled: profiled too, the rig's damped campaigns moved
    three of four pooled corners away from the truth, 147 -> 155 Hz for 141.6, 561 -> 633
    for 511, order 4 -> 3 for a true 4, and read fewer betas right: through a known chain the
    contact laws' R² favours a corner a little high, so the profile is kept for the stage the
    median cannot give); and one whose pool leaves the high-pass to each recording
    (:data:`~stiffnet.restoring_force.chain.HIGHPASS_FITTED`: every reading would profile its
    own corner, 4-9 s CPU a reading on the rig against 0.1-0.3 s with a corner held).

    Parameters
    ----------
    chain : dict
        :func:`campaign_chain`'s decision.
    sensors : sequence of dict or None
        The restoring-force ``sensor`` per recording that the decision pooled (the second
        return of :func:`identify_regardless`).
    contact_r2 : callable
        Recording index and data sheet to that recording's contact-law R² (None: no law).
    sheets : sequence of dict or None, optional
        Each recording's own data sheet (read with it, not profiled).

    Returns
    -------
    dict
        `chain`, with the low-pass profiled into its ``sensor`` and
        ``stages["lowpass_hz"]`` (value, order, interval, the median the pool compared, the
        fitted corners, the recordings profiled on), and the reason extended.
    """
    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    base = chain.get("sensor") if chain.get("pooled") else chain.get("unpooled_sheet")
    todo = [i for i, own in enumerate(sheets) if own is None]
    fits = [s for i, s in enumerate(sensors) if i in todo and identified(s) and s.get("lowpass_hz")]
    if not base or "lowpass_hz" not in chain.get("stages", {}) or not fits:
        return chain
    if chain.get("pooled") and base.get("lowpass_hz"):  # the recordings agreed: kept (below)
        return chain
    if base.get("highpass_hz") == HIGHPASS_FITTED:  # each reading would profile its own corner
        return chain
    corners = np.array([float(s["lowpass_hz"]) for s in fits])
    fitted_orders = {int(round(s.get("lowpass_order") or 2)) for s in fits}
    best = _profiled_lowpass(base, todo, contact_r2, corners, fitted_orders)
    if best is None:
        return chain
    order, corner, interval, read, misfit, _ = best
    return _with_lowpass(chain, base, corners, order, corner, interval, read, misfit)


def campaign_lowpass_minority(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    contact_r2: Callable[[int, dict[str, Any]], float | None],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with a low-pass that fewer than half of the identified chains show profiled over
    the campaign, "no low-pass" a candidate beside it, where the pool holds none.

    The pool counts a stage only where at least half the identified chains show it
    (:func:`~stiffnet.restoring_force.chain.shared_chain`), and :func:`campaign_lowpass` profiles
    only a stage the pool counted. A recording's chain fit shows a low-pass well above the
    contacts only where its contact law asks for one: behind the rig's 371 Hz order-3 low-pass
    (contacts up to 96 Hz), one of a campaign's three fits showed it (345 Hz order 2), and the
    campaign was read without it. Its contact laws do see it once the resonance is right: read
    through the profiled resonance, their median log-misfit was 0.33 without a low-pass and
    0.09 with the true one. So it runs after :func:`campaign_resonance`, on the pooled chain as
    it stands. A single fit may also be a spurious stage, so the pool without a low-pass is a
    candidate, and a low-pass is added only where one reads the contact laws better (the rule
    of :func:`campaign_lowpass`; every order of :data:`LOWPASS_ORDERS` beside the fitted ones,
    since one or two fits agree on no order). Either way the stage is reported
    (``stages["lowpass_hz"]``: the fits that showed it, the best corner and its misfit, the
    misfit without one) and the reason says which was kept.

    Returned as it is: an unpooled chain, one whose pool holds a low-pass or whose low-pass
    :func:`campaign_lowpass` already judged, one whose identified chains show none, and one
    whose pool leaves the high-pass to each recording
    (:data:`~stiffnet.restoring_force.chain.HIGHPASS_FITTED`: every reading would profile its
    own corner).

    Parameters
    ----------
    chain : dict
        The campaign's decision (:func:`campaign_chain`, after the profiles).
    sensors : sequence of dict or None
        The restoring-force ``sensor`` per recording that the decision pooled.
    contact_r2 : callable
        Recording index and data sheet to that recording's contact-law R² (None: no law).
    sheets : sequence of dict or None, optional
        Each recording's own data sheet (read with it, not profiled).

    Returns
    -------
    dict
        `chain`, with the low-pass profiled into its ``sensor`` where one reads best, its
        ``stages["lowpass_hz"]`` and the reason extended either way.
    """
    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    base = chain.get("sensor") if chain.get("pooled") else None
    todo = [i for i, own in enumerate(sheets) if own is None]
    if not base or base.get("lowpass_hz") or "lowpass_hz" in chain.get("stages", {}) or not todo:
        return chain
    if base.get("highpass_hz") == HIGHPASS_FITTED:
        return chain
    votes = [s for i, s in enumerate(sensors) if i in todo and identified(s)]
    fits = [s for s in votes if s.get("lowpass_hz")]
    if not fits:
        return chain
    corners = np.array([float(s["lowpass_hz"]) for s in fits])
    orders = {*(int(round(s.get("lowpass_order") or 2)) for s in fits), *LOWPASS_ORDERS}
    best = _profiled_lowpass(base, todo, contact_r2, corners, orders, none_too=True)
    if best is None:
        return chain
    order, corner, interval, read, misfit, none = best
    shown = f"shown by {len(fits)} of the {len(votes)} identified chains"
    stage = {"value": float(np.median(corners)), "showing": len(fits), "identified": len(votes),
             "none_median_log_misfit": none}  # fmt: skip
    if none <= misfit:  # the pool without a low-pass reads the contact laws as well
        stage.update(value=None, fitted=sorted(float(c) for c in corners), best=corner,
                     best_order=order, best_median_log_misfit=misfit,
                     profiled_on=int(read.sum()))  # fmt: skip
        out = {**chain, "stages": {**chain["stages"], "lowpass_hz": stage}}
        out["reason"] = (f"{chain['reason']}; a low-pass {shown} "
                         f"({corners.min():.0f}-{corners.max():.0f} Hz) not kept: the campaign's "
                         f"contact laws read as well without one (median log-misfit {none:.2f}; "
                         f"{misfit:.2f} at {corner:.0f} Hz order {order})")  # fmt: skip
        return out
    grid = _lowpass_grid(corners)
    if np.isclose(corner, grid[0]) or np.isclose(corner, grid[-1]):  # the laws may read beyond
        stage["at_grid_end"] = True
        shown += (f"; at the end of the corners profiled, {grid[0]:.0f}-{grid[-1]:.0f} Hz: the "
                  "interval does not reach beyond it")  # fmt: skip
    chain = {**chain, "stages": {**chain["stages"], "lowpass_hz": stage}}
    return _with_lowpass(chain, base, corners, order, corner, interval, read, misfit, shown)


def campaign_resonance_minority(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    contact_r2: Callable[..., float | None],
    sheets: Sequence[dict | None] | None = None,
    identify: Callable[[int], dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with a mounted resonance behind its pooled low-pass, where a fit showed one and
    the campaign's contact laws read better through it.

    Behind a low-pass a few contact frequencies up, a mount's ring reaches the record only on
    the stiffest contacts, whose pulses have a spectrum there: on the rig's campaign behind a
    280 Hz mount and a 120 Hz 4th-order low-pass, 3 of 24 chain fits showed the resonance
    (281-287 Hz, zeta 0.028-0.034, with their low-pass at 120.7-121.8 Hz), the others a
    low-pass alone at 111-134 Hz, and the gate fitted none of the three. The pool counts a
    stage only where half the chains show it, so the campaign was read through a 126.7 Hz
    low-pass alone: its laws explained 0.83-0.99 of the contact force and beta read 5.4 for
    27, 24.4 for 84; through the truth 0.98-1.0 and every class but one on an edge right.
    A resonance fitted jointly with a low-pass moves its corner (126.7 -> 120.7 Hz here, and
    the resonance undone with the pooled corner read 16.6 for 55), so a candidate is a fit's
    whole chain: its resonance and its low-pass.

    The rule. Where the pool holds a low-pass and no resonance, the recordings the gate spared
    are fitted regardless of it (`identify`, at most :data:`MAX_FITTED_REGARDLESS`, spread
    over the campaign); the chains that show a resonance and a low-pass are grouped by
    resonance (within :data:`FIT_SCATTER`), each group's median chain a candidate (the
    :data:`MAX_RESONANCE_CANDIDATES` largest groups). The pool as it stands and each candidate
    are read on every recording without its own data sheet (`contact_r2` with refusals as
    force unexplained), ranked by the median log-misfit of :func:`campaign_highpass`, and a
    candidate replaces the pooled low-pass only where it reads the laws better than the pool.
    ``stages["resonance_hz"]`` reports the fits that showed one and the misfits either way;
    ``completed_stage`` marks a kept one (the recordings' own high-pass corners were fitted
    behind chains without it: :func:`campaign_highpass` then profiles the campaign's corner).
    """
    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    base = chain.get("sensor") if chain.get("pooled") else None
    todo = [i for i, own in enumerate(sheets) if own is None]
    if not base or not base.get("lowpass_hz") or base.get("resonance_hz") or not todo:
        return chain
    sensors = list(sensors)
    spared = [i for i in todo if (sensors[i] or {}).get("source") != "fitted"]
    for i in spread_subset(spared, MAX_FITTED_REGARDLESS) if identify is not None else []:
        sensors[i] = identify(i)
    fits = [s for i, s in enumerate(sensors) if i in todo and identified(s)
            and s.get("resonance_hz") and s.get("lowpass_hz")]  # fmt: skip
    if not fits:
        return chain
    plain = {k: v for k, v in base.items() if k not in LOWPASS_ENDS}
    candidates = [{**plain, **{k: float(s[k]) for k in STAGE_KEYS}}
                  for s in _resonance_groups(fits)]  # fmt: skip
    subset = profiled_subset(todo, len(candidates) + 1)
    table = np.array([[contact_r2(i, sheet, True) or 0.0 for i in subset]
                      for sheet in [base, *candidates]])  # fmt: skip
    misfit = np.maximum(1.0 - table, np.finfo(float).eps)
    say = misfit.min(axis=0) < 1.0
    if not say.any():
        return chain
    medians = np.median(np.log(misfit / misfit.min(axis=0))[:, say], axis=1)
    best = int(np.argmin(medians))
    shown = sorted(float(s["resonance_hz"]) for s in fits)
    stage = {"fitted": shown, "candidates": [c["resonance_hz"] for c in candidates],
             "median_log_misfit": [float(m) for m in medians], "profiled_on": int(say.sum()),
             "kept": bool(best)}  # fmt: skip
    out = {**chain, "stages": {**chain.get("stages", {}), "resonance_hz": stage}}
    words = f"a resonance behind the low-pass shown by {len(fits)} chain fit(s) ({shown[0]:.0f}"
    words += f"-{shown[-1]:.0f} Hz)" if len(shown) > 1 else " Hz)"
    if not best:
        out["reason"] = (f"{chain['reason']}; {words} not kept: the campaign's contact laws read"
                         f" as well without it (median log-misfit {medians[0]:.2f}; "
                         f"{medians[1:].min():.2f} through it)")  # fmt: skip
        return out
    sheet = candidates[best - 1]
    stage.update(value=sheet["resonance_hz"], damping=sheet["resonance_damping"])
    out.update(sensor=sheet, completed_stage="resonance_hz")
    out["reason"] = (f"{chain['reason']}; {words} kept: {sheet['resonance_hz']:.1f} Hz zeta "
                     f"{sheet['resonance_damping']:.3f} with its low-pass "
                     f"{sheet['lowpass_hz']:.1f} Hz order {sheet['lowpass_order']:.0f} "
                     f"(median log-misfit of the campaign's contact laws {medians[best]:.2f}; "
                     f"{medians[0]:.2f} through the pool)")  # fmt: skip
    return out


def _resonance_groups(fits: Sequence[dict]) -> list[dict]:
    """Rule: `fits` grouped by resonance (a step over :data:`FIT_SCATTER` between neighbours
    starts a group), each group's median member by resonance, the largest
    :data:`MAX_RESONANCE_CANDIDATES` groups (the lower resonance first on a tie)."""
    ranked = sorted(fits, key=lambda s: float(s["resonance_hz"]))
    groups: list[list[dict]] = [[ranked[0]]]
    for s in ranked[1:]:
        ratio = float(s["resonance_hz"]) / float(groups[-1][-1]["resonance_hz"])
        if np.log(ratio) > np.log1p(FIT_SCATTER):
            groups.append([])
        groups[-1].append(s)
    groups.sort(key=len, reverse=True)
    return [g[(len(g) - 1) // 2] for g in groups[:MAX_RESONANCE_CANDIDATES]]


def campaign_dissipation(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    contact_r2: Callable[..., float | None],
    dissipation_share: Callable[[int, dict[str, Any]], float | None],
    sheets: Sequence[dict | None] | None = None,
) -> dict[str, Any]:
    """`chain` with the identified low-pass weighed against the contacts' own dissipation:
    where a dissipation growing with penetration (Hunt-Crossley's) reads the campaign's
    contact laws better with no low-pass than through the identified one, the low-pass is
    the contacts' dissipation, and the pool holds none.

    Why. A recording's chain fit models the contact pulse as a Kelvin-Voigt contact's, whose
    force jumps to ``c_c v0`` at first touch; a Hunt-Crossley contact's rises from zero, and
    the fit reads that rounding as a low-pass. Behind a 4th-order 600 Hz low-pass and a 2 Hz
    high-pass at 2 kHz (contacts at 28-73 Hz) the independent rig's Hunt-Crossley recordings
    fitted low-passes of 94-324 Hz, orders 1-3, and the campaign profiled corners near 110 Hz
    that hide the contacts (the soft-contact fit then read beta 4.2 for 9). Read with the
    ``delta v`` term free and no low-pass, the same recordings' laws explain 0.994-0.9997 of
    the contact force; through the identified low-pass 0.72-0.99 or refused; and through a
    true low-pass the test keeps it (a power law behind 250 Hz order 2 reads better through
    it, and a power law fits no ``delta v`` term: its readings are compared as they are).

    The rule. Every recording without its own data sheet (`sheets`; a spread subset,
    :func:`profiled_subset`) is read with the dissipation free (`contact_r2`,
    `dissipation_share`: :func:`dissipation_readers`) through the identified chain without a
    low-pass and with the identified one (the median corner and order of the recordings
    whose chain shows one). The low-pass is the contacts' dissipation where, over the
    recordings with a say, the median of ``log((1 - R²_none) / (1 - R²_low-pass))`` is not
    positive (the rule of :func:`campaign_highpass`, no law counted as R² 0), the median
    R²_none reaches :data:`~stiffnet.restoring_force.estimate.CHAIN_FIT_WHEN_NEEDED` (the
    contact law then needs no chain) and the median share of the dissipation growing with
    penetration reaches the ``contact_law`` check's
    :attr:`~stiffnet.uncertainty.unseen_law.UnseenLawThresholds.penetration_dissipation_min_share`
    (the dissipation the low-pass stood for is there). The decision is then pooled without a
    low-pass (``contact_dissipation``: the campaign is read with the dissipation free), the
    weighing reported under ``stages["lowpass_hz"]["dissipation"]``; where it is not, under
    ``dissipation_weighed``, the stages left as they were. The low-pass is read only where
    the readings without it pass the R² and share tests (a power law fits no ``delta v``
    term: its campaign spends one reading a recording on the test).

    Returned as it is: a chain that shows no identified low-pass, one with a resonance (a
    mount's ringing is no contact's dissipation, and its profile reads through it), and one
    with no recording to read.
    """
    from stiffnet.restoring_force.estimate import CHAIN_FIT_WHEN_NEEDED
    from stiffnet.uncertainty.unseen_law import unseen_law_thresholds

    sheets = list(sheets) if sheets is not None else [None] * len(sensors)
    base = chain.get("sensor") if chain.get("pooled") else chain.get("unpooled_sheet")
    todo = [i for i, own in enumerate(sheets) if own is None]
    fits = [s for i, s in enumerate(sensors) if i in todo and identified(s) and s.get("lowpass_hz")]
    if not base or not fits or not todo or base.get("resonance_hz"):
        return chain
    corner = float(np.median([float(s["lowpass_hz"]) for s in fits]))
    order = float(max(1, round(float(np.median([s.get("lowpass_order") or 2 for s in fits])))))
    none = {k: v for k, v in base.items() if k not in LOWPASS_ENDS}
    none.update(lowpass_hz=0.0, lowpass_order=0.0)
    low = {**none, "lowpass_hz": corner, "lowpass_order": order}
    todo = profiled_subset(todo, 2)
    r2_none = np.array([contact_r2(i, none) or 0.0 for i in todo])
    shares = [dissipation_share(i, none) for i in todo]
    read = r2_none > 0.0  # a recording with no law has no say
    share = np.nan_to_num(np.array([np.nan if v is None else v for v in shares], float), nan=0.0)
    median_share = float(np.median(share[read])) if read.any() else 0.0
    median_r2 = float(np.median(r2_none[read])) if read.any() else 0.0
    weighed = {"lowpass_hz": corner, "lowpass_order": order, "read_on": int(read.sum()),
               "median_r2_none": median_r2, "median_dissipation_share": median_share}  # fmt: skip
    min_share = unseen_law_thresholds().penetration_dissipation_min_share
    is_dissipation = median_r2 >= CHAIN_FIT_WHEN_NEEDED and median_share >= min_share
    if is_dissipation:  # only then is the low-pass read: a law without the term is kept cheaply
        r2_low = np.array([contact_r2(i, low) or 0.0 for i in todo])
        eps = np.finfo(float).eps
        m_none, m_low = np.maximum(1.0 - r2_none, eps), np.maximum(1.0 - r2_low, eps)
        say = np.minimum(m_none, m_low) < 1.0
        log_ratio = float(np.median(np.log(m_none / m_low)[say]))
        weighed.update(median_r2_lowpass=float(np.median(r2_low[say])),
                       median_log_misfit_ratio=log_ratio)  # fmt: skip
        is_dissipation = log_ratio <= 0.0
    if not is_dissipation:  # reported beside the stages, which the profiles after it read
        return {**chain, "dissipation_weighed": weighed}
    stage = {**chain.get("stages", {}).get("lowpass_hz", {}), "dissipation": weighed,
             "value": None}  # fmt: skip
    out = {k: v for k, v in chain.items() if k != "unpooled_sheet"}
    out.update(pooled=True, sensor=none, contact_dissipation=True,
               stages={**chain.get("stages", {}), "lowpass_hz": stage})  # fmt: skip
    said = (f"the identified low-pass ({corner:.0f} Hz order {order:.0f}, median of "
            f"{len(fits)} fits) is the contacts' dissipation: read with a dissipation growing "
            f"with penetration and no low-pass the contact laws explain {median_r2:.4f} "
            f"(median), through it {weighed['median_r2_lowpass']:.4f}; pooled without a "
            f"low-pass, beta read with the Hunt-Crossley law")  # fmt: skip
    out["reason"] = (f"{chain['reason']}; {said}" if chain.get("pooled") else
                     f"one sensor chain over the {chain['n_identified']} recordings that "
                     f"identified one ({chain['reason']}); {said}")  # fmt: skip
    return out


def profiled_campaign_chain(
    chain: dict[str, Any],
    sensors: Sequence[dict | None],
    contact_r2: Callable[..., float | None],
    free_damping: Callable[[int, dict[str, Any]], float | None],
    fn_hz: Callable[[], Sequence[float | None]],
    rig_damping: Sequence[float | None],
    sheets: Sequence[dict | None] | None = None,
    dissipation: tuple[Callable[..., float | None], ...] | None = None,
    identify: Callable[[int], dict | None] | None = None,
) -> dict[str, Any]:
    """The campaign's pooled decision (:func:`identify_regardless`) with its stages profiled
    over the campaign's contact laws, in their order: the low-pass the fits disagree on
    (:func:`campaign_lowpass`), a resonance behind the pooled low-pass that a minority of the
    fits show (:func:`campaign_resonance_minority`, `identify` fitting the chain regardless of
    the gate on the recordings it spared; None fits none), the high-pass corner
    (:func:`campaign_highpass`), a resonance near the contacts that refuses a recording
    (:func:`campaign_resonance`), a low-pass fewer than half the chains show
    (:func:`campaign_lowpass_minority`), last the corner from the free flight where the rows
    give the rig's damping (:func:`campaign_highpass_damped`).

    `contact_r2` is recording index, data sheet and ``refused_as_unexplained`` to the contact
    law's R² (:func:`contact_r2_through`); `free_damping` recording index and sheet to the
    free flight's damping (:func:`free_damping_through`); `fn_hz` gives each recording's
    natural frequency, asked for only where the chain is pooled (every stage after the
    low-pass profiles a pool).

    `dissipation`: the `contact_r2`, `free_damping` and `dissipation_share` of readings with
    the contact's dissipation growing with penetration fitted free
    (:func:`dissipation_readers`). Where given, the identified low-pass is first weighed
    against that dissipation (:func:`campaign_dissipation`); where the dissipation reads the
    contacts better the low-pass is not profiled and the profiles after it read the
    campaign's contact laws with the dissipation free, as the second reading then does
    (``contact_dissipation`` in the decision)."""
    if dissipation is not None:
        chain = campaign_dissipation(chain, sensors, dissipation[0], dissipation[2], sheets)
    if chain.get("contact_dissipation"):
        contact_r2, free_damping = dissipation[0], dissipation[1]
    else:
        chain = campaign_lowpass(chain, sensors, contact_r2, sheets)
    if not chain["pooled"]:
        return chain
    if not chain.get("contact_dissipation"):
        chain = campaign_resonance_minority(chain, sensors, contact_r2, sheets, identify)
    fns = fn_hz()
    chain = campaign_highpass(chain, contact_r2, fns, sheets)
    chain = campaign_resonance(chain, lambda i, sheet: contact_r2(i, sheet, True), fns, sheets)
    chain = campaign_lowpass_minority(chain, sensors, contact_r2, sheets)
    return campaign_highpass_damped(chain, free_damping, fns, rig_damping, sheets)


def _lowpass_grid(corners: np.ndarray) -> np.ndarray:
    """The low-pass profile's candidate corners around the fitted `corners`: steps of
    :data:`FIT_SCATTER` from :data:`LOWPASS_STEPS_BELOW` below the lowest to
    :data:`LOWPASS_STEPS_ABOVE` above the highest, at most :data:`MAX_LOWPASS_GRID`."""
    step = np.log1p(FIT_SCATTER)
    lo = np.log(corners.min()) - LOWPASS_STEPS_BELOW * step
    hi = np.log(corners.max()) + LOWPASS_STEPS_ABOVE * step
    return np.exp(np.linspace(lo, hi, int(min(MAX_LOWPASS_GRID, np.ceil((hi - lo) / step) + 1))))


def _profiled_lowpass(
    base: dict[str, Any],
    todo: list[int],
    contact_r2: Callable[[int, dict[str, Any]], float | None],
    corners: np.ndarray,
    fitted_orders: set[int],
    none_too: bool = False,
) -> tuple[int, float, tuple[float, float], np.ndarray, float, float | None] | None:
    """The low-pass that reads the campaign's contact laws best through `base` (the rule of
    :func:`campaign_lowpass`, its candidates around the fitted `corners`): its order, corner,
    interval, the recordings with a say, its median log-misfit, and with `none_too` the
    median log-misfit of `base` read with no low-pass (the least misfits taken over it too;
    else None). None where no candidate reads a recording."""
    from scipy import optimize

    orders = sorted(fitted_orders if len(fitted_orders) == 1 else fitted_orders | {*LOWPASS_ORDERS})
    grid = _lowpass_grid(corners)
    keys = [(o, float(c)) for o in orders for c in grid]
    todo = profiled_subset(todo, len(keys) + int(none_too) + LOWPASS_REFINE_ITER)
    memo: dict[tuple[int, float], np.ndarray] = {}

    def misfit(order: int, corner: float) -> np.ndarray:  # each recording's share unexplained
        if (order, corner) not in memo:
            at = {**base, "lowpass_hz": corner, "lowpass_order": float(order)}
            if not order:  # no low-pass: the sheet's own ends go with it
                at = {k: v for k, v in at.items() if k not in ("lowpass_low_hz", "lowpass_high_hz")}
                at.update(lowpass_hz=0.0, lowpass_order=0.0)
            r2 = np.array([contact_r2(i, at) or 0.0 for i in todo])
            memo[order, corner] = np.maximum(1.0 - r2, np.finfo(float).eps)
        return memo[order, corner]

    table = np.array([misfit(*k) for k in [*keys, *([(0, 0.0)] if none_too else [])]])
    read = table.min(axis=0) < 1.0
    if not read.any():
        return None
    least = table.min(axis=0)

    def median_misfit(order: int, corner: float) -> float:
        return float(np.median(np.log(misfit(order, corner) / least)[read]))

    best = int(np.argmin([median_misfit(*k) for k in keys]))
    order, j = keys[best][0], best % grid.size
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]
    sol = optimize.minimize_scalar(
        lambda u: median_misfit(order, float(np.exp(u))), bounds=(np.log(a), np.log(b)),
        method="bounded", options={"xatol": 0.02, "maxiter": LOWPASS_REFINE_ITER},
    )  # fmt: skip
    corner = keys[best][1]
    if sol.fun < median_misfit(order, corner):
        corner = float(np.exp(sol.x))
    at_order = {c: m for (o, c), m in memo.items() if o == order}
    interval = corner_interval(at_order, read, corner)
    none = median_misfit(0, 0.0) if none_too else None
    return order, corner, interval, read, median_misfit(order, corner), none


def campaign_resonance(
    chain: dict[str, Any],
    contact_read: Callable[[int, dict[str, Any]], float | None],
    fn_hz: Sequence[float | None],
    sheets: Sequence[dict | None] | None = None,
    top_beta: float | None = None,
) -> dict[str, Any]:
    """`chain` with its pooled resonance (frequency and damping) profiled over the campaign,
    where it lies near the contacts' band and refuses a recording: the resonance that reads
    the most of the campaign's recordings, and among those the one that reads their contact
    laws best, through the pooled chain.

    The pool takes the median of the recordings' fitted resonances, often from two or three
    fits that trade the damping against the frequency: the rig's held-out campaigns pooled
    220.7 Hz zeta 0.053 for a true 216.8 Hz 0.068, and 205.9 Hz 0.034 for 197.8 Hz 0.051.
    Undone so, a mount ringing about twice the stiffest contact's frequency leaves ringing
    around each pulse: the contacts "last" 2.7-5.5 half periods of their law (refused) or the
    law explains 22-55 % of the force, where the true resonance reads every one of them at
    R² 0.993-0.9999; the true damping alone, or the true frequency alone, does not.

    The rule. Where the pooled resonance lies below :data:`RESONANCE_NEAR_CONTACT` times the
    stiffest contact's frequency (``f_n sqrt(1 + top_beta)``, the recordings' median
    `fn_hz`), every recording without its own data sheet (`sheets`) is read through the
    pooled chain (`contact_read`: the law's R² where the reading gives beta, 0 where it
    refuses after fitting its law, None without a law; :func:`contact_r2_through` with
    ``refused_as_unexplained``). Only where one of them is refused is the resonance profiled
    (a pool that reads every recording has nothing to gain: the contact laws' R² alone trades
    the mount's damping for a little fit, and moved a right pool, rig_campaigns_damped
    campaign 2's 192.6 Hz zeta 0.060 for a true 192.7 Hz 0.061, to zeta 0.046, where its
    beta-99.5 contact was refused). On each candidate resonance held in the pooled chain
    every recording is read again; a candidate ranks first by the recordings it reads, then
    by the median over the recordings of ``log((1 - R²) / (1 - R²_best))`` (the rule of
    :func:`campaign_highpass`, a refusal counted as R² 0: force unexplained). The pool is kept
    unless a candidate reads more recordings than it does, so the profile never trades a
    reading for a refusal. Candidates: frequencies in steps of :data:`RESONANCE_STEP` within
    :data:`FIT_SCATTER` of the pooled one, each at the pooled damping times
    :data:`RESONANCE_DAMPING_FACTORS`; the best frequency then refined on
    :data:`RESONANCE_REFINE_POINTS` between its neighbours at its damping, then the damping
    at that frequency. ``stages["resonance_hz"]`` reports the profiled and the pooled
    resonance, the recordings read through each, and the frequency interval
    (:func:`corner_interval` over the frequencies read at the chosen damping; reported, not
    carried into beta's interval).

    Returned as it is: a chain that pooled no resonance, one whose resonance lies far above
    the contacts, one that pooled no high-pass corner
    (:data:`~stiffnet.restoring_force.chain.HIGHPASS_FITTED`: every reading would profile
    its own, as in :func:`campaign_lowpass`), one without a natural frequency, one whose pool
    refuses no recording whose law it fitted, and one where no candidate reads more
    recordings than the pool.
    """
    from stiffnet.geometry.calibration import DEFAULT_CLASSES

    sheet = chain.get("sensor") if chain.get("pooled") else None
    f0 = float((sheet or {}).get("resonance_hz") or 0.0)
    z0 = float((sheet or {}).get("resonance_damping") or 0.0)
    sheets = list(sheets) if sheets is not None else [None] * len(fn_hz)
    todo = [i for i, own in enumerate(sheets) if own is None]
    if not f0 > 0 or not z0 > 0 or not todo or sheet.get("highpass_hz") == HIGHPASS_FITTED:
        return chain
    fn = np.nanmedian([fn_hz[i] if fn_hz[i] is not None else np.nan for i in todo])
    top = float(top_beta if top_beta is not None else DEFAULT_CLASSES[-1][2])
    if not np.isfinite(fn) or f0 > RESONANCE_NEAR_CONTACT * fn * np.sqrt(1.0 + top):
        return chain
    memo: dict[tuple[float, float], np.ndarray] = {}  # each recording's read R² (nan: no law)

    def r2_at(f: float, z: float) -> np.ndarray:
        if (f, z) not in memo:
            at = {**sheet, "resonance_hz": f, "resonance_damping": z}
            got = [contact_read(i, at) for i in todo]
            memo[f, z] = np.array([np.nan if r is None else r for r in got], dtype=float)
        return memo[f, z]

    pooled = r2_at(f0, z0)
    if not np.any(pooled == 0.0):  # no refusal after a fitted law: the pool is right
        return chain
    n_steps = int(round(np.log1p(FIT_SCATTER) / np.log1p(RESONANCE_STEP)))
    freqs = f0 * (1.0 + RESONANCE_STEP) ** np.arange(-n_steps, n_steps + 1.0)
    freqs[n_steps] = f0
    dampings = z0 * np.asarray(RESONANCE_DAMPING_FACTORS)
    keys = [(float(f), float(z)) for z in dampings for f in freqs]
    refused = [i for i, r2 in zip(todo, pooled, strict=True) if r2 == 0.0]
    subset = profiled_subset(todo, len(keys) + RESONANCE_REFINE_POINTS + len(dampings), refused)
    if len(subset) < len(todo):  # the profile reads the subset only, the pool's reading too
        memo[f0, z0] = pooled[np.isin(todo, subset)]
        todo[:] = subset
    for k in keys:
        r2_at(*k)
    return _profiled_resonance(chain, sheet, memo, keys, freqs, dampings, r2_at)


def _profiled_resonance(
    chain: dict[str, Any],
    sheet: dict[str, Any],
    memo: dict[tuple[float, float], np.ndarray],
    keys: list[tuple[float, float]],
    freqs: np.ndarray,
    dampings: np.ndarray,
    r2_at: Callable[[float, float], np.ndarray],
) -> dict[str, Any]:
    """:func:`campaign_resonance`'s choice over its read grid (`memo`, `keys`): the pool kept
    where no candidate reads more recordings, else the best candidate refined, reported."""
    f0, z0 = float(sheet["resonance_hz"]), float(sheet["resonance_damping"])

    def misfit(f: float, z: float) -> np.ndarray:  # each recording's share unexplained
        r2 = np.nan_to_num(r2_at(f, z), nan=0.0)  # no law explains nothing
        return np.maximum(1.0 - r2, np.finfo(float).eps)

    least = np.min([misfit(*k) for k in keys], axis=0)
    say = least < 1.0  # a recording read at no candidate has no say
    if not say.any():  # no candidate reads a recording: nothing to rank them by
        return chain

    def rank(f: float, z: float) -> tuple[int, float]:  # most readings, then least misfit
        n_read = int(np.sum(r2_at(f, z) > 0.0))
        return -n_read, float(np.median(np.log(misfit(f, z) / least)[say]))

    as_pooled = rank(f0, z0)
    f, z = min(keys, key=lambda k: rank(*k))
    if rank(f, z)[0] >= as_pooled[0]:  # nothing reads more recordings than the pool
        stage = {**chain.get("stages", {}).get("resonance_hz", {}), "kept": True,
                 "read": -as_pooled[0], "profiled_on": int(say.sum())}  # fmt: skip
        return {**chain, "stages": {**chain.get("stages", {}), "resonance_hz": stage}}
    f = _refined(lambda u: rank(u, z), f, freqs)
    low, high = corner_interval({c: misfit(c, d) for c, d in memo if d == z}, say, f)
    z = _refined(lambda u: rank(f, u), z, dampings)
    out = {**chain, "sensor": {**sheet, "resonance_hz": f, "resonance_damping": z}}
    out["stages"] = {**chain.get("stages", {}), "resonance_hz": {
        **chain.get("stages", {}).get("resonance_hz", {}), "value": f, "damping": z,
        "interval": [low, high], "pooled": f0, "pooled_damping": z0,
        "read": -rank(f, z)[0], "read_pooled": -as_pooled[0], "profiled_on": int(say.sum()),
        "median_log_misfit": rank(f, z)[1]}}  # fmt: skip
    out["reason"] = (f"{chain['reason']}; the resonance profiled over the campaign's contact "
                     f"laws: {f:.1f} Hz zeta {z:.3f} [{low:.1f}, {high:.1f}] Hz (pooled "
                     f"{f0:.1f} Hz zeta {z0:.3f}, which read {-as_pooled[0]} recordings of "
                     f"{say.size}; {-rank(f, z)[0]} read through the profiled one)")  # fmt: skip
    return out


def _refined(rank: Callable[[float], Any], best: float, grid: np.ndarray) -> float:
    """`best` (a point of the ascending `grid`) refined on :data:`RESONANCE_REFINE_POINTS`
    spaced in log between its grid neighbours by `rank` (least wins, `best` on a tie)."""
    j = int(np.argmin(np.abs(np.log(grid / best))))
    a, b = grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]
    fine = [float(u) for u in np.geomspace(a, b, RESONANCE_REFINE_POINTS)] if b > a else []
    return min([best, *fine], key=rank)


def _with_lowpass(
    chain: dict[str, Any],
    base: dict[str, Any],
    fitted: np.ndarray,
    order: int,
    corner: float,
    interval: tuple[float, float],
    read: np.ndarray,
    misfit: float,
    why: str = "left out of the pool",
) -> dict[str, Any]:
    """`chain` pooled with the profiled low-pass in `base` (its sheet), reported (`why`: why
    the pool did not hold it)."""
    low, high = interval
    stage = chain["stages"]["lowpass_hz"]
    sheet = {**base, "lowpass_hz": corner, "lowpass_order": float(order), "lowpass_low_hz": low,
             "lowpass_high_hz": high}  # fmt: skip
    out = {k: v for k, v in chain.items() if k != "unpooled_sheet"}
    out.update(pooled=True, sensor=sheet)
    out["stages"] = {**chain["stages"], "lowpass_hz": {
        **stage, "value": corner, "order": order, "interval": [low, high],
        "median": stage["value"],
        "fitted": sorted(float(f) for f in fitted), "profiled_on": int(read.sum()),
        "median_log_misfit": misfit}}  # fmt: skip
    said = (f"the low-pass profiled over the campaign's contact laws: {corner:.0f} Hz order "
            f"{order} [{low:.0f}, {high:.0f}] (the recordings' own fits "
            f"{fitted.min():.0f}-{fitted.max():.0f} Hz, {why})")  # fmt: skip
    if chain.get("pooled"):
        out["reason"] = f"{chain['reason']}; {said}"
    else:
        out["reason"] = (f"one sensor chain (low-pass) over the {chain['n_identified']} "
                         f"recordings that identified one ({chain['reason']}); {said}")  # fmt: skip
    return out


def corner_interval(
    memo: dict[float, np.ndarray], read: np.ndarray, corner: float, seed: int = 0
) -> tuple[float, float]:
    """The high-pass corners a campaign's contact laws cannot tell apart: the interval at
    :data:`~stiffnet.restoring_force.chain.COVERAGE` of the corner
    :func:`campaign_highpass` would choose from the campaign's recordings drawn again with
    replacement (its rule on every corner it read, `memo`: corner to each recording's share
    of force unexplained; `read`: the recordings with a say), widened to hold `corner`.

    The recordings are the campaign's replicates: where their laws disagree on the corner
    (each fits best at its own), the choice moves with which recordings the campaign holds,
    and beta read at the interval's ends (the estimate spans them,
    :func:`~stiffnet.restoring_force.estimate.restoring_force_estimate`) carries it. A
    likelihood-ratio band on the contact laws' R² would not: their misfit is the laws' own
    shape error, not noise, and such a band spans a percent of the corner.
    """
    from stiffnet.restoring_force.chain import COVERAGE
    from stiffnet.restoring_force.estimate import N_BOOTSTRAP

    corners = np.array(sorted(memo))
    table = np.array([memo[c] for c in corners])[:, read]  # corners x recordings
    logs = np.log(table / table.min(axis=0))
    draws = np.random.default_rng(seed).integers(0, logs.shape[1], (N_BOOTSTRAP, logs.shape[1]))
    chosen = corners[np.argmin(np.median(logs[:, draws], axis=2), axis=0)]
    alpha = 0.5 * (1.0 - COVERAGE)
    low = float(np.quantile(chosen, alpha, method="lower"))
    high = float(np.quantile(chosen, 1.0 - alpha, method="higher"))
    return min(low, corner), max(high, corner)


def contact_r2_through(
    accel: Any,
    fs_hz: float,
    fn_hz: float,
    predictor: Any,
    sheet: dict[str, Any],
    refused_as_unexplained: bool = False,
) -> float | None:
    """The contact law's R² of a recording read through `sheet` (the campaign's pooled chain
    as a data sheet, its corner held) as `predictor`'s restoring-force check reads it with
    that chain (``sensor_fitted``), without the interval; None where
    no law was fitted or the reading fails. The `contact_r2` of :func:`campaign_highpass`.
    With `refused_as_unexplained`, a reading refused after its law was fitted (the law
    explains too little, the contacts last too long) gives 0: no beta, its force counted
    unexplained (the `contact_read` of :func:`campaign_resonance`)."""
    r = read_through(accel, fs_hz, fn_hz, predictor, sheet)
    return contact_r2_of(r, refused_as_unexplained)


def contact_r2_of(r: Any, refused_as_unexplained: bool = False) -> float | None:
    """:func:`contact_r2_through` of a reading `r` (:func:`read_through`'s): the R² of the
    law that read beta (the Hunt-Crossley law's where the reading fitted one)."""
    if r is None or r.law is None or not np.isfinite(r.contact_r2):
        return None
    if refused_as_unexplained and not r.ok:
        return 0.0
    hc = getattr(r, "hunt_crossley", None)
    return float(hc.r2) if hc is not None and np.isfinite(hc.r2) else float(r.contact_r2)


def dissipation_share_of(r: Any) -> float | None:
    """The share of a reading's contact dissipation that grows with penetration (its
    Hunt-Crossley law's ``dissipation_share``); None where the reading fitted no such law."""
    hc = None if r is None else getattr(r, "hunt_crossley", None)
    return float(hc.dissipation_share) if hc is not None else None


def free_damping_through(
    accel: Any, fs_hz: float, fn_hz: float, predictor: Any, sheet: dict[str, Any]
) -> float | None:
    """The free flight's own damping ratio
    (:attr:`~stiffnet.restoring_force.estimate.RestoringForceResult.free_damping_fitted`) of
    a recording read through `sheet` as :func:`contact_r2_through` reads it; None where the
    reading fails or the free-flight law explains too little to be read. The `free_damping`
    of :func:`campaign_highpass_damped`."""
    return free_damping_of(read_through(accel, fs_hz, fn_hz, predictor, sheet))


def free_damping_of(r: Any) -> float | None:
    """:func:`free_damping_through` of a reading `r` (:func:`read_through`'s)."""
    from stiffnet.restoring_force.estimate import MIN_FREE_R2

    if r is None or not np.isfinite(r.free_damping_fitted) or not r.free_r2 >= MIN_FREE_R2:
        return None
    return float(r.free_damping_fitted)


def read_through(
    accel: Any,
    fs_hz: float,
    fn_hz: float,
    predictor: Any,
    sheet: dict[str, Any],
    penetration_dissipation: bool = False,
) -> Any:
    """`predictor`'s restoring-force reading of a recording through `sheet`, a sheet fitted
    to recordings (``sensor_fitted``), without the interval; None where it fails.
    `penetration_dissipation`: the contact law read with a free ``delta v`` dissipation
    (:func:`campaign_dissipation`'s readings); a corner the sheet leaves to the record
    (``"auto"``) is then the free flight's, not profiled by the library's contact law: that
    profile tunes the corner until the Kelvin-Voigt law fits (0 Hz on the rig's Hunt-Crossley
    records for 2 Hz), bends the law it is weighed against, and was 91 % of
    :func:`campaign_dissipation`'s CPU (48 readings, 172 s)."""
    from serving.checks import checked_recording
    from serving.restoring_force_check import RESTORING_FORCE_PERIODS
    from stiffnet.errors import StiffnetError
    from stiffnet.restoring_force import restoring_force_estimate

    a = checked_recording(accel, fs_hz, fn_hz, predictor.window_periods, "recording")[0]
    try:
        return restoring_force_estimate(
            a, fs_hz, natural_frequency_hz=fn_hz, sensor=sheet, sensor_fitted=True,
            max_periods=RESTORING_FORCE_PERIODS, interval=False,
            stage_ratio=predictor.stage_ratio, penetration_dissipation=penetration_dissipation,
            profile_highpass_below_r2=-np.inf if penetration_dissipation else None,
        )  # fmt: skip
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def read_once(read: Callable[[int, dict[str, Any]], Any]) -> Callable[[int, dict[str, Any]], Any]:
    """`read` (recording index and data sheet to a reading, :func:`read_through`) with each
    recording read once per sheet: the profiles read some recordings through the same sheet
    more than once (the free flight at the corner the contact laws chose, where the high-pass
    profile read those recordings already). A sheet is its items, so two sheets with the same
    entries are one reading; a reading is a deterministic function of the recording and the
    sheet, so the repeat is the same result. Scoped to the caller (one campaign's pooling):
    nothing is kept across campaigns."""
    readings: dict[tuple[int, tuple], Any] = {}

    def once(i: int, sheet: dict[str, Any]) -> Any:
        key = (i, tuple(sorted(sheet.items())))
        if key not in readings:
            readings[key] = read(i, sheet)
        return readings[key]

    return once


def profile_readers(
    read: Callable[[int, dict[str, Any]], Any],
) -> tuple[Callable[..., float | None], Callable[[int, dict[str, Any]], float | None]]:
    """The `contact_r2` and `free_damping` of :func:`profiled_campaign_chain` from `read`
    (recording index and data sheet to a reading, :func:`read_through`), both over one
    :func:`read_once` of it: what a campaign's pooling passes its profiles."""
    contact_r2, free_damping, _ = _readers(read_once(read))
    return contact_r2, free_damping


def dissipation_readers(
    read: Callable[[int, dict[str, Any]], Any],
) -> tuple[Callable[..., float | None], Callable[[int, dict[str, Any]], float | None],
           Callable[[int, dict[str, Any]], float | None]]:  # fmt: skip
    """:func:`profile_readers` of `read` (recording index and data sheet to a reading with the
    contact's dissipation growing with penetration fitted free: :func:`read_through` with
    ``penetration_dissipation``), with the readings' :func:`dissipation_share_of` beside them,
    over one :func:`read_once`: the readers :func:`campaign_dissipation` and the profiles
    after it take."""
    return _readers(read_once(read))


def _readers(once: Callable[[int, dict[str, Any]], Any]) -> tuple:
    """The contact R², free damping and dissipation share of the readings `once` gives."""

    def contact_r2(
        i: int, sheet: dict[str, Any], refused_as_unexplained: bool = False
    ) -> float | None:
        return contact_r2_of(once(i, sheet), refused_as_unexplained)

    def free_damping(i: int, sheet: dict[str, Any]) -> float | None:
        return free_damping_of(once(i, sheet))

    def dissipation_share(i: int, sheet: dict[str, Any]) -> float | None:
        return dissipation_share_of(once(i, sheet))

    return contact_r2, free_damping, dissipation_share


def confirmed(
    chain: dict[str, Any], first: Sequence[dict | None], again: Sequence[dict | None]
) -> dict[str, Any]:
    """`chain` after its second reading: kept where the recordings read through it (their
    restoring-force checks `first` alone and `again` through the pooled chain) lose a
    median R² of at most :data:`~stiffnet.restoring_force.chain.CHAIN_CONFIRMED_SHORTFALL`,
    else no longer pooled, with the reason. ``shortfall`` holds that median."""
    shortfall = shared_chain_shortfall(list(first), list(again))
    out = {**chain, "shortfall": shortfall}
    if shortfall is not None and shortfall > CHAIN_CONFIRMED_SHORTFALL:
        out.update(pooled=False, sensor=None,
                   reason=f"the pooled chain read the recordings' contact laws worse than "
                   f"they read alone (median R² lost {shortfall:.2f} > "
                   f"{CHAIN_CONFIRMED_SHORTFALL:g}): not one sensor, not pooled")  # fmt: skip
    return out


def reads_alone(first: dict | None, again: dict | None) -> bool:
    """Rule: whether a recording keeps its own first reading in a campaign whose pooled chain
    was confirmed: its contact law, read through the pooled chain (`again`, its
    restoring-force check), loses more than
    :data:`~stiffnet.restoring_force.chain.CHAIN_CONFIRMED_SHORTFALL` of R² against its first
    reading (`first`).

    The confirmation judges the campaign by its median; one recording may still read much
    worse through the pooled chain (on the rig, a pooled 353 Hz order-3 low-pass for a true
    284 Hz order 4: one recording's law fell from R² 0.998 to 0.54 and refused, and the
    restoring_force_class alarm its own reading had raised on a wrong class went silent;
    another fell from 0.96 to 0.82 and the model read it medium instead of very hard). The
    R² are :func:`~stiffnet.restoring_force.chain.shared_chain_shortfall`'s: a first reading
    refused after its contact law was fitted counts that law's R², one without a law (no
    impact stands out, no reading) counts 0 and so loses nothing.
    """
    lost = shared_chain_shortfall([first], [again])
    return lost is not None and lost > CHAIN_CONFIRMED_SHORTFALL


def campaign_sheets(chain: dict[str, Any], sheets: Sequence[dict | None]) -> list[dict | None]:
    """Each recording's data sheet for the second reading: its own, else the pooled chain
    (None everywhere when nothing was pooled)."""
    pooled = chain.get("sensor") if chain.get("pooled") else None
    return [sheet if sheet is not None else pooled for sheet in sheets]


def labelled(result: dict[str, Any], from_campaign: bool) -> dict[str, Any]:
    """A copy of `result` with the chain it was read through named: ``source: "campaign"``
    on its restoring-force ``sensor`` and ``chain_undone`` where the pooled chain was its
    sheet, and ``chain_source`` (``"campaign"``, ``"data sheet"``, ``"fitted"`` or None)."""
    out = dict(result)
    check = dict(out.get("restoring_force") or {})
    if from_campaign:
        if check.get("sensor"):
            check["sensor"] = {**check["sensor"], "source": "campaign"}
            out["restoring_force"] = check
        if out.get("chain_undone"):
            out["chain_undone"] = {**out["chain_undone"], "source": "campaign"}
    out["chain_source"] = (check.get("sensor") or {}).get("source")
    return out

"""The campaign's own noise floor and the verdict on what is left unexplained.

A perfect simulator does not score zero: the statistics of a finite, noisy
record scatter. How much they scatter is measured on the campaign itself,
by **split-half repeatability**: each recording's statistics on its first
and second halves are compared like a simulation with a measurement
(:func:`stiffnet.measurement.discrepancy.recording_discrepancy`), which gives
``D_half``. A statistic's variance falls as one over the record length, so
two independent halves of ``L`` natural periods differ by ``4 c / L`` and a
simulation of ``P`` periods against the whole recording by ``c (1/P + 1/L)``:
the floor of a recording is ``D_half L (1/P + 1/L) / 4`` (:class:`Floors`).

**Each recording is judged against its own floor.** A recording whose halves
differ far more than the campaign's typical one (:data:`NON_REPEATABLE_FACTOR`
times the median floor: a wandering or chaotic orbit, a long transient,
near-grazing impacts) is *non-repeatable*: it is reported as such, judged
against its own large floor, and weighs less in the fits' objective and the
tests (:meth:`Floors.weights`). The campaign is at its floor unless more
repeatable recordings sit above :data:`AT_FLOOR_FACTOR` times their own floor
than chance allows (:meth:`Floors.judge`: a one-sided binomial sign test against
:data:`CHANCE_ABOVE`, the share a model at the floor shows, since one
split-half draw per recording scatters); the summaries are robust (medians,
trimmed means), so a few non-repeatable recordings neither create nor hide
missing physics. The campaign's ``noise_floor`` reported is the median floor.
Halves are short, so edge effects (a spike more or less, fewer Welch
segments) make each floor a conservative, upper estimate.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import binom

from stiffnet.campaign import ManifestRow
from stiffnet.campaign.simulate import natural_frequency
from stiffnet.errors import SignalError
from stiffnet.measurement.discrepancy import (
    WHERE,
    normalised_differences,
    recording_discrepancy,
    where_sums,
)
from stiffnet.measurement.statistics import SignalStatistics, signal_statistics

#: A model is at a recording's floor when its discrepancy there is within this many floors.
AT_FLOOR_FACTOR = 2.0
#: Share of recordings a model at the floor still shows above ``AT_FLOOR_FACTOR`` times their
#: own floor (a split-half floor is one noisy draw per recording): the sign test's chance.
CHANCE_ABOVE = 0.1
#: The campaign is above its floor when that many recordings are above theirs at this level
#: (one-sided binomial test against :data:`CHANCE_ABOVE`).
ABOVE_LEVEL = 0.05
#: A recording whose halves differ by more than this many times the campaign's median floor
#: is *non-repeatable* (a wandering or chaotic orbit, a long transient, near-grazing impacts).
NON_REPEATABLE_FACTOR = 4.0
#: A recording's floor is taken as at least this share of the campaign's median (a single
#: split-half draw can be near zero by chance) ...
MIN_FLOOR_SHARE = 0.25
#: ... and at least this discrepancy: an RMS difference of a fifth of a visible one
#: (:data:`~stiffnet.measurement.discrepancy.TOLERANCES`) per statistic is not called
#: missing physics. A clean periodic record repeats to 0.002-0.01 between its halves, while
#: the right model with its fitted values scored 0.01-0.08 on such records of an
#: independent rig (its analog sensor chain against the simulator's oversampled filter).
VISIBLE_FLOOR = 0.04


@dataclass(frozen=True)
class Floors:
    """Each recording's own noise floor at one simulated length, and the rules that judge
    per-recording discrepancies against them (see the module notes).

    Attributes
    ----------
    per_recording : numpy.ndarray
        Floor of each recording (NaN where its halves could not be analysed).
    where : tuple of dict
        Each recording's floor per :data:`WHERE` group (empty where unknown).
    """

    per_recording: np.ndarray
    where: tuple[dict[str, float], ...] = ()
    #: The campaign's median floor when these are a subset of its recordings.
    reference: float | None = None

    @classmethod
    def uniform(cls, floor: float, n: int) -> Floors:
        """One floor for every recording (a campaign-level number)."""
        return cls(np.full(n, float(floor)))

    @property
    def median(self) -> float:
        """The campaign's floor: the median over recordings with a floor."""
        if self.reference is not None:
            return self.reference
        f = self.per_recording[np.isfinite(self.per_recording)]
        return float(np.median(f)) if f.size else 0.0

    def effective(self) -> np.ndarray:
        """Each recording's floor as judged: its own (at least :data:`MIN_FLOOR_SHARE` of the
        median and :data:`VISIBLE_FLOOR`), the median where unknown."""
        med = self.median
        f = np.where(np.isfinite(self.per_recording), self.per_recording, med)
        return np.maximum(f, max(MIN_FLOOR_SHARE * med, VISIBLE_FLOOR))

    def non_repeatable(self) -> np.ndarray:
        """Recordings whose halves differ far more than the campaign's typical recording."""
        f = self.per_recording
        return np.isfinite(f) & (f > NON_REPEATABLE_FACTOR * self.median)

    def weights(self) -> np.ndarray:
        """Weights in the objective and the tests: 1, less for a non-repeatable recording
        (in proportion to how far its floor exceeds the non-repeatable threshold)."""
        limit = NON_REPEATABLE_FACTOR * self.median
        f = self.effective()
        return np.where(f > limit, limit / np.maximum(f, 1e-300), 1.0) if limit > 0 else f * 0 + 1

    def ratios(self, per: np.ndarray) -> np.ndarray:
        """Each recording's discrepancy over its own floor."""
        return np.asarray(per, float) / np.maximum(self.effective(), 1e-300)

    def excess(self, per: np.ndarray) -> float:
        """Weighted mean of each recording's discrepancy above its own floor."""
        w = self.weights()
        e = np.maximum(np.asarray(per, float) - self.effective(), 0.0)
        ok = np.isfinite(e)
        return float(np.sum(w[ok] * e[ok]) / np.sum(w[ok])) if ok.any() else 0.0

    def judge(self, per: np.ndarray) -> dict[str, Any]:
        """The campaign against its floors, robustly: how many recordings sit above
        ``AT_FLOOR_FACTOR`` times their own floor, and whether that is more than chance.

        Returns
        -------
        dict
            ``above`` (per recording), ``n_above`` of ``n`` (the repeatable recordings),
            ``p_value`` (one-sided binomial test of ``n_above`` against
            :data:`CHANCE_ABOVE`), ``median_ratio`` and ``at_floor`` (the test does not
            reject).
        """
        r = self.ratios(per)
        ok = np.isfinite(r)
        above = ok & (r > AT_FLOOR_FACTOR)
        # a non-repeatable recording is reported, not counted: its own floor is one draw of
        # a wandering orbit, so it can neither make nor hide a campaign's missing physics
        counted = ok & ~self.non_repeatable()
        n, k = int(counted.sum()), int((above & counted).sum())
        p = float(binom.sf(k - 1, n, CHANCE_ABOVE)) if n and k else 1.0
        return {
            "above": above,
            "n_above": k,
            "n": n,
            "p_value": p,
            "median_ratio": float(np.median(r[ok])) if n else float("nan"),
            "at_floor": p >= ABOVE_LEVEL,
        }

    def at_floor(self, per: np.ndarray) -> bool:
        """True when the campaign's recordings are at their own floors (:meth:`judge`)."""
        return bool(self.judge(per)["at_floor"])

    def subset(self, idx: Sequence[int]) -> Floors:
        """The floors of the recordings ``idx``."""
        idx = [int(i) for i in idx]
        where = tuple(self.where[i] for i in idx) if self.where else ()
        return Floors(self.per_recording[idx], where, self.median)


def robust_summary(per: np.ndarray) -> dict[str, float]:
    """Mean, median and 10 %-trimmed mean of per-recording discrepancies."""
    from scipy.stats import trim_mean

    v = np.asarray(per, float)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"mean": float("nan"), "median": float("nan"), "trimmed_mean": float("nan")}
    return {
        "mean": float(np.mean(v)),
        "median": float(np.median(v)),
        "trimmed_mean": float(trim_mean(v, 0.1)),
    }


def split_half(
    accel: np.ndarray, row: ManifestRow, inclination: bool = True
) -> tuple[SignalStatistics, SignalStatistics] | None:
    """Statistics of the two halves of a recording (None when a half is too short)."""
    h = accel.size // 2
    try:
        return tuple(  # type: ignore[return-value]
            signal_statistics(
                part, row.fs_hz, natural_frequency(row), row.frequency_ratio, inclination
            )
            for part in (accel[:h], accel[h : 2 * h])
        )
    except SignalError:
        return None


def noise_floor(
    signals: Sequence[np.ndarray],
    rows: Sequence[ManifestRow],
    simulated_periods: float | None,
    inclination: bool = True,
) -> dict[str, Any]:
    """The campaign's noise floor by split-half repeatability (see the module notes).

    Parameters
    ----------
    signals : sequence of numpy.ndarray
        The recordings.
    rows : sequence of ManifestRow
        Their rows (sampling rate, ``f_n``, forcing frequency).
    simulated_periods : float or None
        Natural periods simulated per row in the comparison (None: the recording's length).
    inclination : bool
        Whether the discrepancy includes the inclination statistics.

    Returns
    -------
    dict
        ``floor`` (campaign), ``per_recording``, ``split_half`` (``D_half`` per
        recording; NaN when too short) and ``where`` (the floor per :data:`WHERE`
        group, in the units of :func:`~stiffnet.measurement.discrepancy.where_sums`).
    """
    halves, where = [], []
    for accel, row in zip(signals, rows, strict=True):
        pair = split_half(np.asarray(accel, float), row, inclination)
        if pair is None:
            halves.append(float("nan"))
            where.append({})
            continue
        halves.append(recording_discrepancy(normalised_differences(*pair)))
        where.append(where_sums(*pair))
    info = {
        "split_half": [None if not np.isfinite(v) else float(v) for v in halves],
        "split_half_where": where,
    }
    floors = recording_floors(info, signals, rows, simulated_periods)
    per = floors.per_recording
    return {
        **info,
        "floor": floors.median,
        "per_recording": [None if not np.isfinite(v) else float(v) for v in per],
        "where": {
            g: float(np.median([w[g] for w in floors.where if w])) if any(floors.where) else 0.0
            for g in WHERE
        },
        "floors": floors,
    }


def _length_scale(accel: np.ndarray, row: ManifestRow, simulated_periods: float | None) -> float:
    """``L (1/P + 1/L) / 4``: a split-half discrepancy scaled to a simulation of ``P`` natural
    periods against the whole recording of ``L`` (see the module notes)."""
    length = len(accel) * natural_frequency(row) / row.fs_hz  # natural periods
    p = length if simulated_periods is None else min(length, simulated_periods)
    return length * (1.0 / p + 1.0 / length) / 4.0


def recording_floors(
    info: dict[str, Any],
    signals: Sequence[np.ndarray],
    rows: Sequence[ManifestRow],
    simulated_periods: float | None,
) -> Floors:
    """Each recording's floor (:class:`Floors`) from :func:`noise_floor`'s split halves, for a
    simulation of ``simulated_periods`` natural periods (None: the recording's length)."""
    per, where = [], []
    for i, (d, accel, row) in enumerate(zip(info["split_half"], signals, rows, strict=True)):
        scale = _length_scale(accel, row, simulated_periods)
        per.append(float("nan") if d is None else d * scale)
        w = info.get("split_half_where", [{}] * len(rows))[i]
        where.append({g: v * scale for g, v in w.items()})
    return Floors(np.asarray(per, float), tuple(where))


def verdict(
    baseline: np.ndarray,
    residual: np.ndarray,
    floors: Floors,
    selected: Sequence[str],
    residual_where: Sequence[dict[str, float] | None],
) -> dict[str, Any]:
    """What the selected effects explain, and where the rest lives, recording by recording.

    Each recording is judged against its own floor (:meth:`Floors.judge`): the base model
    is ``nothing_missing`` when no more recordings sit above ``AT_FLOOR_FACTOR`` times
    their floor than chance allows; ``explained`` when effects were selected and the model
    with them passes that test; otherwise ``partially_explained`` (also when nothing in the
    library helps: the missing physics is not in the library).

    Parameters
    ----------
    baseline, residual : numpy.ndarray
        Per-recording discrepancies of the base and of the final model.
    floors : Floors
        The recordings' floors at the final model's simulated length.
    selected : sequence of str
        The selected effects.
    residual_where : sequence of dict or None
        Per recording, the final model's squared differences per :data:`WHERE` group.

    Returns
    -------
    dict
        ``verdict``, ``residual_discrepancy`` (mean), ``residual_summary`` and
        ``baseline_summary`` (mean, median, trimmed mean), ``explained_fraction`` (of the
        baseline's weighted excess over the recordings' own floors), ``noise_floor``
        (median), ``recordings_above_floor`` (``n_above`` of ``n``, ``p_value``,
        ``median_ratio``), ``unexplained_where`` (share of the excess over the floors per
        group, over the recordings above theirs; None when nothing is left), ``summary``.
    """
    baseline, residual = np.asarray(baseline, float), np.asarray(residual, float)
    e_base, e_res = floors.excess(baseline), floors.excess(residual)
    explained = float(np.clip(1.0 - e_res / e_base, 0.0, 1.0)) if e_base > 0 else 1.0
    base_j, res_j = floors.judge(baseline), floors.judge(residual)
    shares = _where_shares(res_j["above"], floors, residual_where)
    floor = floors.median
    med_b, med_r = float(np.nanmedian(baseline)), float(np.nanmedian(residual))
    above = (
        f"{res_j['n_above']} of {res_j['n']} recordings above {AT_FLOOR_FACTOR:g}x their own "
        f"floor, p = {res_j['p_value']:.2g}"
    )
    if base_j["at_floor"]:
        v, shares = "nothing_missing", None
        text = (
            f"the base model is at the recordings' own noise floors ({base_j['n_above']} of "
            f"{base_j['n']} above {AT_FLOOR_FACTOR:g}x theirs, p = {base_j['p_value']:.2g}; "
            f"median discrepancy {med_b:.3g}, median floor {floor:.3g})"
        )
    elif selected and res_j["at_floor"]:
        v, shares = "explained", None
        text = (
            f"{', '.join(selected)} bring the discrepancy to the recordings' floors (median "
            f"{med_b:.3g} -> {med_r:.3g}, median floor {floor:.3g}; {above})"
        )
    else:
        v = "partially_explained"
        where = max(shares, key=shares.get) if shares else "unknown"
        what = ", ".join(selected) if selected else "no effect of the library"
        text = (
            f"{what} explain{'s' if len(selected) <= 1 else ''} {explained:.0%} of the "
            f"discrepancy above the recordings' floors; {above} (median {med_r:.3g}, median "
            f"floor {floor:.3g}), mostly in {where.replace('_', ' ')}: physics the "
            "candidates lack"
        )
    return {
        "verdict": v,
        "residual_discrepancy": float(np.nanmean(residual)),
        "residual_summary": robust_summary(residual),
        "baseline_summary": robust_summary(baseline),
        "explained_fraction": explained,
        "noise_floor": float(floor),
        "recordings_above_floor": {
            k: res_j[k] for k in ("n_above", "n", "p_value", "median_ratio")
        },
        "unexplained_where": shares,
        "summary": text,
    }


def _where_shares(
    above: np.ndarray, floors: Floors, residual_where: Sequence[dict[str, float] | None]
) -> dict[str, float] | None:
    """Shares of the weighted excess over the floors per :data:`WHERE` group, over the
    recordings above their floors (over all of them when none is)."""
    w = floors.weights()
    pick = np.flatnonzero(above) if above.any() else np.arange(len(residual_where))
    left = dict.fromkeys(WHERE, 0.0)
    for i in pick:
        res = residual_where[i] or {}
        fl = floors.where[i] if floors.where and floors.where[i] else {}
        for g in WHERE:
            left[g] += w[i] * max(0.0, res.get(g, 0.0) - fl.get(g, 0.0))
    total = sum(left.values())
    return {g: v / total for g, v in left.items()} if total > 0 else None

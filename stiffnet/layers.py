"""Layers along a record: change points of a noisy series and the segments between them.

A drill bit crossing rock layers sees the stiffness ratio beta jump; the
predictor reads ``log beta`` on a sliding window (one point per hop), and this
module splits that series into **layers**, segments of constant mean, by
penalised least squares (optimal partitioning with the linear kernel of
``ruptures.KernelCPD``, Killick et al. 2012's PELT objective for a change in
mean). The series is scaled by its robust noise level first (:func:`noise_scale`),
so one penalty (:data:`PENALTY_PER_WINDOW`, per window length of points: the
points of overlapping windows are correlated, a spurious change gains about as many
of them) serves every level and noise; it is calibrated on constant-beta records
(``benchmarks/bench_log.py``).

Online and offline are one algorithm (:class:`LayerSegmenter`): points arrive one
by one, the detector runs every :attr:`LayerSegmenter.check_every` points on the
open part of the series, and a change becomes final once enough points follow it
(:attr:`LayerSegmenter.confirm_points`); a whole record is the same stream fed at
once. The layers therefore do not depend on how a stream was chunked, and memory
stays bounded: closed layers keep sums, the open one at most
:attr:`LayerSegmenter.max_points` points (older ones are folded into its sums).

Numpy and ruptures only (the predictor imports it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import ruptures as rpt

#: Penalty of one change in units of the scaled series' variance, per window length of
#: points (calibrated: benchmarks/bench_log.py; <= 1 false change per 10 min at the
#: training world's noise).
PENALTY_PER_WINDOW = 8.0
#: Relative half-width of the band around a class edge inside which a layer keeps the
#: class of its neighbour (hysteresis): a beta 10 % either side of an edge is the same
#: rock to the model's accuracy.
EDGE_MARGIN = 0.10
#: Profile-likelihood threshold of the change-time interval (chi-square, 1 dof, 95 %).
CHANGE_TIME_CHI2 = 3.84
#: A layer's beta drifts when its pooled points' log beta trends by at least this much
#: across it (a factor 1.22: twice the edge margin) ...
DRIFT_MIN_LOG = 0.2
#: ... with a slope this many standard errors from zero, the error inflated by the
#: points per window (overlapping windows are correlated over one window).
DRIFT_MIN_T = 4.0


def noise_scale(x: np.ndarray, lag: int) -> float:
    """Robust standard deviation of a piecewise-constant series' noise.

    Differences at ``lag`` points (at least a window apart, so the overlapping
    windows' correlation does not hide the noise) cancel the mean except at a
    change; the MAD of the differences ignores those few.
    """
    x = np.asarray(x, dtype=np.float64)
    lag = max(1, min(int(lag), x.size - 1)) if x.size > 1 else 1
    if x.size <= lag:
        return float(np.std(x)) or 1.0
    d = x[lag:] - x[:-lag]
    s = 1.4826 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0)
    return s if s > 0 else (float(np.std(x)) or 1.0)


def series_noise(x: np.ndarray, lag: int) -> float:
    """The noise level a change must stand out from: the largest :func:`noise_scale` at
    lags ``lag, 2 lag, 4 lag, 8 lag`` (those within a quarter of the series).

    The model's error is not white: windows that see the same phase of a periodic
    orbit err alike, so short-lag differences alone understate the wander a false
    change would be made of.
    """
    n = np.asarray(x).size
    lags = [lag * 2**k for k in range(4) if lag * 2**k <= max(lag, n // 4)]
    return max(noise_scale(x, g) for g in lags)


def change_points(x: np.ndarray, penalty: float, min_size: int) -> list[int]:
    """Indices where a new segment starts (penalised least squares on a mean change).

    Parameters
    ----------
    x : numpy.ndarray
        The series, already scaled to unit noise variance.
    penalty : float
        Cost of one change (in units of the noise variance).
    min_size : int
        Fewest points of a segment.

    Returns
    -------
    list of int
        Sorted start indices of every segment but the first (empty: no change).
    """
    x = np.asarray(x, dtype=np.float64).reshape(-1, 1)
    if x.shape[0] < 2 * min_size:
        return []
    algo = rpt.KernelCPD(kernel="linear", min_size=max(2, int(min_size))).fit(x)
    return [int(b) for b in algo.predict(pen=float(penalty))[:-1]]


def split_gain(x: np.ndarray, lo: int, k: int, hi: int, half: int) -> float:
    """Residual sum of squares a change at ``k`` saves in ``x[lo:hi]``, leaving out the
    ``half`` points either side of it and of the neighbouring changes ``lo`` and ``hi``
    (the windows that straddle a change; the record's ends straddle nothing)."""
    n = np.asarray(x).size
    start = lo + half if lo > 0 else lo
    stop = hi - half if hi < n else hi
    a = np.asarray(x[start : max(start, k - half)], dtype=np.float64)
    b = np.asarray(x[min(stop, k + half) : stop], dtype=np.float64)
    if a.size == 0 or b.size == 0:
        return 0.0
    return float(a.size * b.size / (a.size + b.size) * (a.mean() - b.mean()) ** 2)


def prune_transitions(
    x: np.ndarray, cps: list[int], half: int, penalty: float, min_gap: int = 1
) -> list[int]:
    """Drop changes that only the windows straddling a neighbouring change explain.

    On a quiet record the windows that straddle a change (and, on a real rig, the
    orbit settling into the new layer) form a ramp whose misfit outweighs a
    penalty: least squares buys it a short "layer" of its own. Without those
    windows the two sides of such a change do not differ (the gain of
    :func:`split_gain` is below the penalty); removing it, weakest first, leaves the
    real change, whose position is then the best split between its neighbours.
    Two changes closer than `min_gap` after that are one change seen twice: the
    weaker goes, and the rest is split again.
    """
    cps = list(cps)
    n = len(x)
    while True:
        while cps:
            bounds = [0, *cps, n]
            gains = [split_gain(x, bounds[i], bounds[i + 1], bounds[i + 2], half)
                     for i in range(len(cps))]  # fmt: skip
            i = int(np.argmin(gains))
            if gains[i] >= penalty:
                break
            del cps[i]
        bounds = [0, *cps, n]
        cps = [best_split(x, bounds[i], bounds[i + 2], min_gap) for i in range(len(cps))]
        close = [i for i in range(len(cps) - 1) if cps[i + 1] - cps[i] < min_gap]
        if not close:
            return cps
        i = close[0]
        bounds = [0, *cps, n]
        weak = [split_gain(x, bounds[j], bounds[j + 1], bounds[j + 2], 0) for j in (i, i + 1)]
        del cps[i if weak[0] <= weak[1] else i + 1]


def best_split(x: np.ndarray, lo: int, hi: int, min_size: int = 1) -> int:
    """The index splitting ``x[lo:hi]`` into two means with the least squares, each side at
    least `min_size` long when there is room for that."""
    sse = _split_sse(np.asarray(x[lo:hi], dtype=np.float64))
    j = np.arange(1, hi - lo)
    room = (j >= min_size) & (hi - lo - j >= min_size)
    if room.any():
        sse = np.where(room, sse, np.inf)
    return lo + 1 + int(np.argmin(sse))


def _split_sse(seg: np.ndarray) -> np.ndarray:
    """Two-mean residual sum of squares of ``seg`` split before each of ``1..n-1``."""
    n = seg.size
    c1 = np.cumsum(seg)
    c2 = np.cumsum(seg**2)
    j = np.arange(1, n)
    left = c2[j - 1] - c1[j - 1] ** 2 / j
    right = (c2[-1] - c2[j - 1]) - (c1[-1] - c1[j - 1]) ** 2 / (n - j)
    return left + right


def change_interval(x: np.ndarray, k: int, lo: int, hi: int, inflation: float) -> tuple[int, int]:
    """Profile interval of a change at ``k`` between neighbouring changes ``lo`` and ``hi``.

    The split positions ``j`` of ``x[lo:hi]`` whose two-mean residual sum of squares
    exceeds the best by less than :data:`CHANGE_TIME_CHI2` (x scaled to unit noise,
    times `inflation` for the correlation of overlapping windows).
    """
    seg = np.asarray(x[lo:hi], dtype=np.float64)
    n = seg.size
    if n < 3:
        return k, k
    sse = _split_sse(seg)
    ok = (sse - sse[k - lo - 1]) <= CHANGE_TIME_CHI2 * inflation
    # the interval is the connected run of accepted splits around the change
    i = k - lo - 1
    a = i
    while a > 0 and ok[a - 1]:
        a -= 1
    b = i
    while b < n - 2 and ok[b + 1]:
        b += 1
    return lo + a + 1, lo + b + 1


def trend(t: np.ndarray, y: np.ndarray, window_points: int) -> float | None:
    """The change of ``y`` across ``t`` along a least-squares line where it trends
    (:data:`DRIFT_MIN_LOG`, :data:`DRIFT_MIN_T`), else None."""
    n = t.size
    if n < max(5, window_points + 2) or t[-1] <= t[0]:
        return None
    tc, yc = t - t.mean(), y - y.mean()
    sxx = float(tc @ tc)
    slope = float(tc @ yc) / sxx
    residual = float(np.sum((yc - slope * tc) ** 2)) / (n - 2)
    se = math.sqrt(residual / sxx * max(1, window_points))
    change = slope * float(t[-1] - t[0])
    if abs(change) < DRIFT_MIN_LOG or (se > 0 and abs(slope) < DRIFT_MIN_T * se):
        return None
    return change


def layer_drift(
    t: np.ndarray, log_beta: np.ndarray, window_points: int
) -> tuple[float, float, float, float] | None:
    """Where a layer's log beta drifts: ``(first t, last t, fitted log beta at each)`` of the
    stretch that trends (:func:`trend`), else None: a gradual transition, which one mean
    beta does not describe. The whole layer is tried, then its first and its last two
    windows of points (a layer's shortest), where the segmenter cut a ramp in two and each
    half ends in a plateau."""
    t, y = np.asarray(t, dtype=np.float64), np.asarray(log_beta, dtype=np.float64)
    edge = 2 * max(1, window_points)
    for sel in (slice(None), slice(None, edge), slice(-edge, None)):
        ts, ys = t[sel], y[sel]
        change = trend(ts, ys, window_points)
        if change is not None:
            mid = float(ys.mean())  # the line passes the mean at the mean time
            at = float(change / (ts[-1] - ts[0]))
            return (float(ts[0]), float(ts[-1]), mid + at * float(ts[0] - ts.mean()),
                    mid + at * float(ts[-1] - ts.mean()))  # fmt: skip
    return None


def class_of(beta: float, classes: Sequence[Sequence[Any]]) -> str:
    """The class whose ``[lo, hi)`` holds beta (the nearest end class outside them)."""
    for name, lo, hi in classes:
        if lo <= beta < hi:
            return str(name)
    return str(classes[0][0] if beta < classes[0][1] else classes[-1][0])


def class_with_hysteresis(
    beta: float,
    previous: str | None,
    classes: Sequence[Sequence[Any]],
    margin: float = EDGE_MARGIN,
) -> tuple[str, bool]:
    """A beta's class, keeping `previous` while beta stays within `margin` of their edge.

    Returns the class and whether beta lies within the margin of a class edge.
    """
    cls = class_of(beta, classes)
    near = any(abs(beta / lo - 1.0) < margin for _, lo, _ in classes[1:])
    names = [str(c[0]) for c in classes]
    if previous in names and previous != cls and abs(names.index(previous) - names.index(cls)) == 1:
        i, j = sorted((names.index(previous), names.index(cls)))
        edge = float(classes[j][1])  # the edge between the two neighbours
        if abs(beta / edge - 1.0) < margin:
            return str(previous), True
    return cls, near


@dataclass
class LayerSums:
    """Running sums of a layer's points (what its pooled beta and interval need)."""

    n: int = 0
    n_pooled: int = 0
    s1: float = 0.0
    s2: float = 0.0
    own: float = 0.0
    contact: int = 0
    alarms: int = 0
    proba: np.ndarray | None = None

    def add(self, p: dict[str, Any], pooled: bool) -> None:
        self.n += 1
        self.contact += int(p["contact"])
        self.alarms += int(bool(p.get("alarm")))
        pr = np.asarray(p["proba"], dtype=np.float64)
        self.proba = pr.copy() if self.proba is None else self.proba + pr
        if pooled and p["contact"]:
            lb = float(p["log_beta"])
            self.n_pooled += 1
            self.s1 += lb
            self.s2 += lb * lb
            self.own += math.exp(2.0 * float(p.get("log_scale", 0.0)))

    def pooled(self) -> tuple[float | None, float | None]:
        """Mean log beta and its error scale ``sqrt(mean own^2 + var)`` (as the recording's)."""
        if self.n_pooled == 0:
            return None, None
        m = self.s1 / self.n_pooled
        var = max(0.0, self.s2 / self.n_pooled - m * m)
        return m, math.sqrt(self.own / self.n_pooled + var)


@dataclass
class LayerSegmenter:
    """Points in, closed layers out: the same layers whether fed at once or in chunks.

    Each point is a dict with ``index``, ``t`` (window centre, s), ``log_beta``,
    ``log_scale``, ``contact``, ``proba`` and ``alarm``. :meth:`push` returns the
    layers it closed; :meth:`finish` closes the rest.

    Parameters
    ----------
    window_points : int
        Points per window length (hops per window): the correlation length.
    hop_s : float
        Time between points.
    half_window_s : float
        Half a window (points closer than this to a change mix two layers: not pooled).
    penalty : float
        Change penalty per window length of points.
    """

    window_points: int
    hop_s: float
    half_window_s: float
    penalty: float = PENALTY_PER_WINDOW
    check_every: int = 20
    max_points: int = 4800
    points: list[dict[str, Any]] = field(default_factory=list)
    sums: LayerSums = field(default_factory=LayerSums)
    start_t: float | None = None
    start_sd: float = 0.0
    n_seen: int = 0

    @property
    def min_points(self) -> int:
        """Fewest points of a layer: two windows (the windows straddling a change form a
        ramp about one window long, which must not pass for a layer of its own)."""
        return max(3, 2 * self.window_points)

    @property
    def confirm_points(self) -> int:
        """Points after a change before it is final (later points no longer move it)."""
        return 3 * self.min_points

    def push(self, point: dict[str, Any]) -> list[dict[str, Any]]:
        """Add one point; the layers this closes (usually none)."""
        if self.start_t is None:
            self.start_t = float(point["t"]) - self.half_window_s
        self.points.append(point)
        self.n_seen += 1
        closed: list[dict[str, Any]] = []
        if self.n_seen % self.check_every == 0:
            closed = self._confirm(final=False)
            if len(self.points) > self.max_points:
                self._fold(len(self.points) - self.max_points // 2)
        return closed

    def finish(self, end_t: float) -> list[dict[str, Any]]:
        """Close every open layer at the end of the stream (time `end_t`, s)."""
        closed = self._confirm(final=True)
        if self.points or self.sums.n:
            closed.append(self._close(len(self.points), end_t, 0.0))
        return closed

    def _series(self) -> np.ndarray:
        return np.array([p["log_beta"] for p in self.points], dtype=np.float64)

    def _confirm(self, final: bool) -> list[dict[str, Any]]:
        closed = []
        while True:
            # the first window after a change is the ramp of the windows straddling it and
            # the orbit settling into the new layer: no change is sought there
            skip = 0
            if self.start_sd > 0 and self.start_t is not None:
                while (
                    skip < len(self.points)
                    and self.points[skip]["t"] - self.start_t < 2 * self.half_window_s
                ):
                    skip += 1  # fmt: skip
            x = self._series()[skip:]
            if len(x) < 2 * self.min_points:
                break
            z = x / series_noise(x, self.window_points)
            pen = self.penalty * self.window_points
            cps = change_points(z, pen, self.min_points)
            half = (self.window_points + 1) // 2 + 1
            cps = prune_transitions(z, cps, half, pen, self.min_points)
            limit = len(z) if final else len(z) - self.confirm_points
            cps = [c for c in cps if c <= limit]
            if not cps:
                break
            k = cps[0]
            hi = cps[1] if len(cps) > 1 else len(z)
            a, b = change_interval(z, k, 0, hi, float(self.window_points))
            k, a, b = k + skip, a + skip, b + skip
            t = 0.5 * (self.points[k - 1]["t"] + self.points[k]["t"])
            sd = 0.5 * (self.points[b]["t"] - self.points[a - 1]["t"]) if b > a - 1 else 0.0
            sd = max(sd, 0.5 * self.hop_s)
            closed.append(self._close(k, t, sd))
        return closed

    def _fold(self, n: int) -> None:
        """Move the oldest `n` points into the open layer's sums (bounded memory)."""
        for p in self.points[:n]:
            self.sums.add(p, self._poolable(p))
        del self.points[:n]

    def _poolable(self, p: dict[str, Any], end_t: float | None = None) -> bool:
        """Whether a point's window lies inside its layer (mixed windows are not pooled)."""
        if self.start_t is not None and self.sums.n + len(self.points) > 0:
            if p["t"] - self.start_t < self.half_window_s and self.start_sd > 0:
                return False
        return not (end_t is not None and end_t - p["t"] < self.half_window_s)

    def _close(self, k: int, end_t: float, end_sd: float) -> dict[str, Any]:
        sums = self.sums
        for p in self.points[:k]:
            sums.add(p, self._poolable(p, end_t if end_sd > 0 else None))
        if sums.n_pooled == 0:  # a short layer: every window is mixed, pool them anyway
            for p in self.points[:k]:
                if p["contact"]:
                    sums.n_pooled += 1
                    sums.s1 += float(p["log_beta"])
                    sums.s2 += float(p["log_beta"]) ** 2
                    sums.own += math.exp(2.0 * float(p.get("log_scale", 0.0)))
        mean, scale = sums.pooled()
        kept = [
            p
            for p in self.points[:k]
            if p["contact"] and self._poolable(p, end_t if end_sd > 0 else None)
        ]
        times = np.array([p["t"] for p in kept])
        drift = layer_drift(times, np.array([p["log_beta"] for p in kept]), self.window_points)
        layer = {
            "start_s": float(self.start_t if self.start_t is not None else 0.0),
            "start_sd_s": float(self.start_sd),
            "end_s": float(end_t),
            "end_sd_s": float(end_sd),
            "n_points": sums.n,
            "n_pooled": sums.n_pooled,
            "contact_fraction": sums.contact / sums.n if sums.n else 0.0,
            "alarm_fraction": sums.alarms / sums.n if sums.n else 0.0,
            "log_beta": mean,
            "log_beta_scale": scale,
            "log_beta_drift": drift,
            "proba": None if sums.proba is None else (sums.proba / max(1, sums.n)).tolist(),
        }
        del self.points[:k]
        self.sums = LayerSums()
        self.start_t, self.start_sd = float(end_t), float(end_sd)
        return layer

"""The stiffness log: beta along a record, its layers and their change times.

``stiffnet log`` (and ``POST /log``, and :func:`stiffness_log` from Python) slides
the model's window (16 natural periods) along the record with a hop of at most
0.5 s. Each **point** (the window's centre) carries the model's beta with its
per-window split-conformal interval (``exp(log beta +- q)``, ``q`` the model's
``conformal_quantile``), its class with hysteresis at class edges, and the alarm
evaluated on that window (the model's embedding distance, ambiguity, beta
uncertainty and class edge, against the thresholds calibrated per recording: one
window is a short recording). Every :data:`RESTORING_FORCE_EVERY_S` seconds
(``configs/log.yaml``) a point also carries the restoring-force cross-check on the window it ends
(:func:`serving.restoring_force_check.restoring_force_check`). The accelerometer's chain is
one sensor's: the checks identify it once (on the record's start, or where the start's
contact law needed none, at the first check whose law does: a harder layer shortens the
pulse into a low-pass the soft start never showed) and read every later window through it
without fitting it again (:meth:`StiffnessLogger._check`; a chain fit costs 1-3 s, the
check through a known chain ~30 ms).

The **layers** are the segments of constant mean log beta found by
:class:`stiffnet.layers.LayerSegmenter` (penalised change in mean, penalty
calibrated on constant-beta records). Each layer has its start and end with a
profile-likelihood uncertainty, beta pooled over its windows (windows that
straddle a change are left out) with the recording interval of the model
(``exp(mean +- q_rec s)``, as :mod:`serving.aggregate`), a class from that beta
with hysteresis (a beta within 10 % of an edge keeps the previous layer's class),
the share of its points that raised the alarm and the restoring-force checks that
fell inside it.

:class:`StiffnessLogger` is the online form: samples in (any chunking), points
and closed layers out, memory bounded by one window of samples and the open
layer's points; the offline log feeds the whole record through the same object,
so a stream gives the same layers as the file.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from serving.campaign_chain import identified
from serving.chain_spread import plausible_chains
from serving.chain_undo import chain_to_undo, undone_stages, undone_windows, window_margin
from serving.checks import dropout_samples, dropout_words, held_runs
from serving.restoring_force_check import (
    RESTORING_FORCE_PERIODS,
    check_sensor_sheet,
    restoring_force_check,
)
from serving.verdict import model_facts, rule_checks, widened_interval
from stiffnet import progress
from stiffnet.errors import StiffnetError
from stiffnet.features.windows import window_length
from stiffnet.geometry.calibration import DEFAULT_CLASSES
from stiffnet.inputs import sensor_given
from stiffnet.layers import LayerSegmenter, class_with_hysteresis
from stiffnet.restoring_force.chain import shared_chain_sheet
from stiffnet.uncertainty import RecordingEstimate, beta_interval
from stiffnet.uncertainty.alarm import recording_checks

#: Largest hop between points (s): a window is 16 natural periods, so points overlap and the
#: change-point search sees every window a change touches.
MAX_HOP_S = 0.5
#: The log's shipped settings file under ``configs/``.
LOG_CONFIG = "log.yaml"


class LogSettings(BaseModel):
    """The stiffness log's defaults (``configs/log.yaml``).

    Attributes
    ----------
    hop_s : float
        Seconds between points (at most :data:`MAX_HOP_S`).
    restoring_force_every_s : float or None
        Seconds between restoring-force cross-checks along the record (None: none).
    max_restoring_force_checks : int
        Checks an open layer keeps for its median (the latest): an endless stream's bound.
    layer_alarm_share : float
        Share of a layer's points with the alarm above which the layer is flagged.
    batch : int
        Windows per ONNX Runtime call.
    """

    model_config = ConfigDict(extra="forbid")

    hop_s: float = Field(0.5, gt=0.0, le=MAX_HOP_S)
    restoring_force_every_s: float | None = Field(10.0, gt=0.0)
    max_restoring_force_checks: int = Field(1000, ge=1)
    layer_alarm_share: float = Field(0.5, gt=0.0, le=1.0)
    batch: int = Field(128, ge=1, le=4096)


@lru_cache(maxsize=1)
def log_settings() -> LogSettings:
    """The shipped settings: ``configs/log.yaml``, else the defaults."""
    from stiffnet.config import shipped_settings

    return shipped_settings(LogSettings, LOG_CONFIG)


#: Seconds between points by default (``configs/log.yaml``).
DEFAULT_HOP_S = log_settings().hop_s
#: Seconds between two restoring-force cross-checks along the record by default.
RESTORING_FORCE_EVERY_S = log_settings().restoring_force_every_s
#: Natural periods at the start of the record the accelerometer's chain is identified on
#: (what one restoring-force check reads: a stream's first point waits for them).
CHAIN_FIT_PERIODS = RESTORING_FORCE_PERIODS


class StiffnessLogger:
    """Samples in, points and closed layers out (see the module notes).

    Parameters
    ----------
    predictor : serving.predictor.Predictor
        The loaded model.
    fs_hz, natural_frequency_hz : float
        Sampling rate and natural frequency (range-checked by the caller).
    hop_s : float
        Time between points (<= :data:`MAX_HOP_S`).
    restoring_force_every_s : float or None
        Seconds between restoring-force cross-checks (None: none).
    penalty : float, optional
        Change penalty per window length (default
        :data:`stiffnet.layers.PENALTY_PER_WINDOW`, calibrated).
    sensor : dict, optional
        The accelerometer chain's data sheet (checked here:
        :func:`serving.restoring_force_check.check_sensor_sheet`).
    fit_chain : bool
        Without a data sheet, identify the chain from the record's first
        :data:`CHAIN_FIT_PERIODS` natural periods, as ``predict`` does on a recording (False:
        the record is read as recorded).
    """

    def __init__(
        self,
        predictor: Any,
        fs_hz: float,
        natural_frequency_hz: float,
        *,
        hop_s: float = DEFAULT_HOP_S,
        restoring_force_every_s: float | None = RESTORING_FORCE_EVERY_S,
        penalty: float | None = None,
        sensor: dict | None = None,
        fit_chain: bool = True,
    ) -> None:
        from serving.checks import rate_warnings
        from stiffnet.inputs import natural_frequency, sampling_rate

        if not (math.isfinite(hop_s) and 0 < hop_s <= MAX_HOP_S):
            raise StiffnetError(f"hop must be in (0, {MAX_HOP_S}] s, got {hop_s}")
        self.p = predictor
        self.fs = sampling_rate(fs_hz)
        self.fn = natural_frequency(natural_frequency_hz)
        #: the rate checks of the predictor (a rate below the training data's is refused)
        self.warnings = rate_warnings(self.fs, self.fn, "record")
        self.n_win = window_length(self.fs, self.fn, predictor.window_periods)
        self.hop = hop_samples(hop_s, self.fs)
        self.hop_s = self.hop / self.fs
        self.restoring_force_every = (
            None
            if not restoring_force_every_s
            else max(self.hop, int(round(restoring_force_every_s * self.fs)))
        )
        self.buf = np.empty(0)
        self.buf_start = 0  # absolute index of buf[0]
        self.n_total = 0
        self.next_window = 0
        self.previous_class: str | None = None
        self.previous_layer_class: str | None = None
        self.layers: list[dict[str, Any]] = []
        self.restoring_force: list[dict[str, Any]] = []  # checks not yet assigned to a layer
        self.segmenter = LayerSegmenter(
            window_points=max(1, int(math.ceil(self.n_win / self.hop))),
            hop_s=self.hop_s,
            half_window_s=0.5 * self.n_win / self.fs,
            **({} if penalty is None else {"penalty": float(penalty)}),
        )
        names = predictor.class_names
        self.nc = names.index("no_contact") if "no_contact" in names else None
        self.q_window = predictor.model.conformal_quantile
        edges = predictor.alarm.info.get("class_edges") if predictor.alarm is not None else None
        self.edges = edges
        self.classes = _classes(edges)
        self.facts = model_facts(predictor)
        self.n_widened = 0  # points whose interval the alarm widened (said once, in warnings)
        # runs of a held value (a dropout): start sample -> stop, their value, flagged points
        self.dropout_n = dropout_samples(self.fs, self.fn)
        self.dropouts: dict[int, int] = {}
        self.dropout_value = 0.0
        self.widened_layers: list[int] = []  # flagged layers whose interval was widened
        # the accelerometer's chain: identified on the record's start, then divided out of
        # every window the model reads (as predict divides it out of a recording)
        self.sheet = None if sensor is None else check_sensor_sheet(sensor, self.fs)
        self.chain_fit_n = int(math.ceil(CHAIN_FIT_PERIODS * self.fs / self.fn))
        self.chain_pending = sensor is not None or fit_chain
        self.sensor: dict[str, Any] | None = None  # the chain identified (its check's)
        self.undone: dict[str, Any] | None = None  # what the model's reading divides out
        self.chain: Any = None  # its SensorChain
        self.other_chains: dict[str, Any] = {}  # the readings a fitted chain stands for
        self.margin = 0  # samples read past a window's end before it is read
        # what the restoring-force checks along the record read through (the data sheet, or
        # the chain the first fit identified: a sheet, or no stage and a held high-pass)
        self.check_sheet = self.sheet
        self.check_sheet_fitted = False  # the held fit, not the user's sheet (its inverse's weight)
        self.check_highpass: float | None = None
        self.check_chain_known = self.sheet is not None
        self.spreads: list[tuple[float, float, float]] = []  # (t, low, high) log-beta offsets
        # a chain with stages the start did not show, (its check's sensor, when); the checks a
        # whole record's scan ran, by window (:meth:`scan_chain`)
        self.found_late: tuple[dict[str, Any], float] | None = None
        self.checks_ahead: dict[int, dict[str, Any]] = {}
        self.scanning = False

    @property
    def window_s(self) -> float:
        return self.n_win / self.fs

    def feed(self, samples: np.ndarray) -> list[tuple[str, dict[str, Any]]]:
        """Add samples; the points and closed layers they complete, in order."""
        x = np.asarray(samples, dtype=np.float64).reshape(-1)
        if x.size and not np.all(np.isfinite(x)):
            bad = int(np.argmax(~np.isfinite(x)))
            raise StiffnetError(f"sample {self.n_total + bad} is NaN or inf")
        self.buf = np.concatenate([self.buf, x]) if self.buf.size else x.copy()
        self.n_total += x.size
        if self.chain_pending:
            if self.n_total < self.chain_fit_n:
                return []  # nothing is dropped before the chain is known
            self._identify_chain(self.buf[: self.chain_fit_n])
        events = self._drain(self.margin)
        # keep what the next window (and the record it reads either side) needs
        keep_from = self.next_window * self.hop - self.margin
        drop = max(0, keep_from - self.buf_start)
        if drop:
            self.buf = self.buf[drop:]
            self.buf_start += drop
        return events

    def _drain(self, margin: int) -> list[tuple[str, dict[str, Any]]]:
        """The points of every window with `margin` samples of record after it."""
        events: list[tuple[str, dict[str, Any]]] = []
        while True:
            end = self.n_total - margin - self.n_win - self.next_window * self.hop
            ready = end // self.hop + 1
            if ready <= 0:
                return events
            events.extend(self._windows(min(int(ready), log_settings().batch)))

    def _identify_chain(self, head: np.ndarray) -> None:
        """The accelerometer's chain from the record's start (the restoring-force check's, or
        the data sheet's), what the model's reading divides out, and the other chains a
        fitted one stands for (:func:`serving.chain_spread.plausible_chains`)."""
        self.chain_pending = False
        if head.size < self.n_win:
            return
        self._read_through(self._check(head, 0.0).get("sensor"))

    def _read_through(self, sensor: dict[str, Any] | None) -> None:
        """Divide the chain `sensor` (a check's) out of every window the model reads from now
        on, with the other chains a fitted one stands for."""
        self.sensor = sensor
        priors = self.facts["priors"]
        self.chain = chain_to_undo(sensor, priors, self.fs, self.fn, self.p.undo_chain)
        if self.chain is None:
            return
        self.undone = undone_stages(self.chain)
        others = plausible_chains(sensor, self.undone, self.p.chain_spread)
        self.other_chains = {
            name: None
            if other is None
            else chain_to_undo(other, priors, self.fs, self.fn, self.p.undo_chain)
            for name, other in others.items()
        }
        self.margin = window_margin(self.n_win)

    def scan_chain(self, record: np.ndarray) -> None:
        """Identify the chain on a whole record before any window is read: the start's, else
        the first restoring-force check along the record that fits one (a harder layer's
        shorter pulse shows a resonance or low-pass a soft start hides). The model then reads
        the whole record through it, and the checks run here are kept for the points they
        belong to (the same checks, in the same order, a stream would run)."""
        if not self.chain_pending or self.sheet is not None:
            return
        self._identify_chain(record[: self.chain_fit_n])
        if self.check_chain_known or not self.restoring_force_every:
            return
        self.scanning = True
        windows = list(self._check_windows(record.size))
        # a line of its own: the log's bar waits at zero until the scan ends
        with progress.task("looking for the sensor chain", total=len(windows)) as bar:
            for j, end in windows:
                t = (j * self.hop + 0.5 * self.n_win) / self.fs
                self.checks_ahead[j] = self._check(record[end - self.n_win : end], t)
                bar.advance()
                if self.check_chain_known:
                    break
        self.scanning = False
        if self.found_late is None:
            return
        self._read_through(self.found_late[0])
        # a chain the model does not divide out is said here (log_result says one it does)
        if self.chain is None:
            read = "the later checks read through it, the model reads the record as recorded"
            self.warnings.append(self._found_late_words(read))

    def _check_windows(self, n: int) -> Iterator[tuple[int, int]]:
        """(window index, end sample) of the windows of an `n`-sample record that carry a
        restoring-force check (:meth:`_emit`'s rule)."""
        every = self.restoring_force_every
        for j in range(max(0, (n - self.n_win) // self.hop + 1)):
            end = j * self.hop + self.n_win
            if end // every > (end - self.hop) // every:
                yield j, end

    def _check(self, seg: np.ndarray, t: float) -> dict[str, Any]:
        """The restoring-force check of `seg` (ending at `t` s) through the record's chain,
        which the first check that fits one decides (:meth:`_hold_chain`)."""
        check = restoring_force_check(
            seg, self.fs, self.fn, self.check_sheet, self.p.stage_ratio,
            highpass_hz=self.check_highpass, penetration_dissipation=self.p.penetration_dissipation,
            sensor_fitted=self.check_sheet_fitted,
        )  # fmt: skip
        if not self.check_chain_known:
            self._hold_chain(check.get("sensor"), t, read=check.get("beta") is not None)
        return check

    def _hold_chain(self, sensor: dict[str, Any] | None, t: float, read: bool = True) -> None:
        """Rule: the chain a check fitted (``source: "fitted"``; none is fitted where the
        contact law explains enough as recorded) is the record's from then on: its resonance
        and low-pass as a data sheet with the high-pass corner it read, or, where it applied
        none, no stage and that corner. A fit the check rejected where it could not read the
        record at all (`read` false: a start-up's transient, no steady impacts yet) says
        nothing of the sensor, and a later check decides: held, it left a mounted drilling
        record as recorded throughout (a 240 Hz mount's layer of beta 60 read 92.5, every
        check refused). A stage found after the start, which the model does not divide out,
        is said in the warnings."""
        if not sensor or sensor.get("source") != "fitted":
            return
        if not read and sensor.get("applied") is False:
            return
        self.check_chain_known = True
        stages = identified(sensor)
        if stages is None:
            self.check_highpass = float(sensor.get("highpass_hz") or 0.0)
            return
        self.check_sheet = shared_chain_sheet(stages)
        self.check_sheet_fitted = True
        if self.chain is None and t > 0:
            self.found_late = (sensor, t)
            if not self.scanning:
                self.warnings.append(self._found_late_words("the later checks read through it, "
                                     "the model reads the record as recorded (a data sheet, "
                                     f"{sensor_given()}, undoes it everywhere)"))  # fmt: skip

    def _found_late_words(self, consequence: str) -> str:
        """The warning of a chain the record's start did not show."""
        sensor, t = self.found_late
        stages = identified(sensor) or {}
        words = ", ".join(f"{k.removesuffix('_hz').replace('lowpass', 'low-pass')} "
                          f"{stages[k]:.4g} Hz" for k in ("resonance_hz", "lowpass_hz")
                          if stages.get(k))  # fmt: skip
        return (
            f"the restoring-force check at {t:.4g} s identified the accelerometer's chain "
            f"({words}) that the record's start did not show: {consequence}"
        )

    def finish(self) -> list[tuple[str, dict[str, Any]]]:
        """Close the stream: the last points and layers."""
        if self.chain_pending:  # a record shorter than the chain's stretch: all of it
            self._identify_chain(self.buf[: self.n_total - self.buf_start])
        events = self._drain(0)  # the windows that waited for record after them
        if self.segmenter.n_seen == 0:
            raise StiffnetError(
                f"the record is shorter than one model window ({self.window_s:.3g} s: "
                f"{self.p.window_periods:g} natural periods at f_n {self.fn:.4g} Hz)"
            )
        end_t = (self.n_total) / self.fs
        return events + [("layer", self._layer(x)) for x in self.segmenter.finish(end_t)]

    # ------------------------------------------------------------ internals

    def _windows(self, n: int) -> list[tuple[str, dict[str, Any]]]:
        starts = (self.next_window + np.arange(n)) * self.hop
        ok = varying_windows(self.buf, starts - self.buf_start, self.n_win)
        out: dict[str, np.ndarray] = {}
        emb = None
        others: list[dict[str, np.ndarray]] = []
        if ok.any():
            out = self._model(starts[ok] - self.buf_start, self.chain)
            emb = window_embedding_scores(self.p.alarm, out)
            others = [
                self._model(starts[ok] - self.buf_start, c) for c in self.other_chains.values()
            ]
        return self._emit(starts, ok, out, emb, others)

    def _model(self, starts: np.ndarray, chain: Any) -> dict[str, np.ndarray]:
        """The model's outputs on the buffer's windows at `starts`, `chain` divided out of
        each (None: as recorded). No geometric cross-check along the log: only what the
        model's input needs."""
        a, at = self.buf, starts
        if chain is not None:
            a = undone_windows(self.buf, starts, self.n_win, self.fs, chain).reshape(-1)
            at = np.arange(len(starts)) * self.n_win
        out, _, _ = self.p._run_model(a, at, self.n_win, self.fs, self.fn, geometric_windows=0)
        return out

    def replay(
        self,
        accel: np.ndarray,
        ok: np.ndarray,
        out: dict[str, np.ndarray],
        emb: np.ndarray | None,
    ) -> list[tuple[str, dict[str, Any]]]:
        """The events of a whole record whose windows the model has already read.

        `accel` is the record, `ok` which of its windows (``window_starts(accel.size,
        n_win, hop)``) are not constant, `out` and `emb` the model's outputs and the
        embedding distances of those windows in order. The same points and layers as
        :meth:`feed` followed by :meth:`finish`, without running the model again: what
        ``predict`` uses, having run the model over these windows for the recording's
        own estimate.
        """
        if self.n_total:
            raise RuntimeError("replay() needs a fresh logger")
        self.buf = np.asarray(accel, dtype=np.float64).reshape(-1)
        self.n_total = self.buf.size
        starts = np.arange(len(ok)) * self.hop
        events = self._emit(starts, ok, out, emb)
        return events + self.finish()

    def _emit(
        self,
        starts: np.ndarray,
        ok: np.ndarray,
        out: dict[str, np.ndarray],
        emb: np.ndarray | None,
        others: Sequence[dict[str, np.ndarray]] = (),
    ) -> list[tuple[str, dict[str, Any]]]:
        """Points (and the layers they close) of the windows at `starts`, in order (`others`:
        the model's outputs on the same windows through the other chains)."""
        events: list[tuple[str, dict[str, Any]]] = []
        k = 0
        for i in range(len(starts)):
            j = self.next_window + i
            end = int(starts[i]) + self.n_win
            if not ok[i]:
                continue  # a constant window (a dropped-out sensor) gives no point
            point = self._point(j, out, k, None if emb is None else emb[k])
            point["spread"] = self._spread(point, others, k)
            k += 1
            ph = None
            if self.restoring_force_every and end // self.restoring_force_every > (
                end - self.hop
            ) // (self.restoring_force_every):
                ph = self.checks_ahead.pop(j, None)
                if ph is None:
                    seg = self.buf[end - self.n_win - self.buf_start : end - self.buf_start]
                    ph = self._check(seg, point["t"])
                point["restoring_force"] = _restoring_force_fields(ph)
                self.restoring_force.append({"t": point["t"], **point["restoring_force"]})
                del self.restoring_force[
                    : -log_settings().max_restoring_force_checks
                ]  # an endless layer: bounded
            self._verdict(point, ph)
            self._flag_dropout(point, end)
            events.append(("point", _public(point)))
            for layer in self.segmenter.push(point):
                events.append(("layer", self._layer(layer)))
        self.next_window += len(starts)
        return events

    def _flag_dropout(self, point: dict[str, Any], end: int) -> None:
        """Flag the point whose window (ending at sample `end`) holds a dropout, a value held
        for a natural period or longer (:func:`serving.checks.held_runs`): the model read it as
        the rig's motion. Each run is kept once, by its samples, for the warning."""
        lo = end - self.n_win
        seg = self.buf[lo - self.buf_start : end - self.buf_start]
        runs = held_runs(seg, self.dropout_n)
        if not runs:
            return
        point["alarm"] = [*point["alarm"], "dropout"]
        if not self.dropouts:
            self.dropout_value = float(seg[runs[0][0]])
        for start, stop in runs:
            start, stop = lo + start, lo + stop
            self.dropouts[start] = max(stop, self.dropouts.get(start, stop))

    def _point(self, j: int, out: dict[str, np.ndarray], k: int, emb: float | None) -> dict:
        proba = out["probabilities"][k]
        lb = float(out["log_beta"][k])
        s = float(out["log_beta_scale"][k]) if "log_beta_scale" in out else 0.0
        label = int(np.argmax(proba))
        contact = label != self.nc
        t = (j * self.hop + 0.5 * self.n_win) / self.fs
        beta = math.exp(lb)
        if contact:
            cls, near = class_with_hysteresis(beta, self.previous_class, self.classes)
            self.previous_class = cls
        else:
            cls, near = "no_contact", False
        alarm = None
        if self.p.alarm is not None:
            est = RecordingEstimate(proba, label, lb if contact else None, math.exp(s), 1)
            alarm = self.p.alarm.evaluate(recording_checks(est, emb, None, self.edges))
        q = self.q_window
        return {
            "index": j,
            "t": t,
            "log_beta": lb,
            "log_scale": s,
            "contact": contact,
            "proba": proba,
            "beta": beta if contact else None,
            "beta_interval": [math.exp(lb - q), math.exp(lb + q)] if contact and q else None,
            "class": cls,
            "near_edge": near,
            "alarm": alarm,
        }

    def _spread(
        self, point: dict[str, Any], others: Sequence[dict[str, np.ndarray]], k: int
    ) -> tuple[float, float] | None:
        """How far the readings through the other chains move the point's log beta (lowest,
        highest offset, 0 included; None: no other chain, or no contact). Kept for the
        layers the point falls in."""
        lbs = [float(o["log_beta"][k]) for o in others
               if int(np.argmax(o["probabilities"][k])) != self.nc]  # fmt: skip
        if not point["contact"] or not lbs:
            return None
        low = min(0.0, min(lbs) - point["log_beta"])
        high = max(0.0, max(lbs) - point["log_beta"])
        self.spreads.append((point["t"], low, high))
        del self.spreads[: -self.segmenter.max_points]  # an endless layer: bounded
        return low, high

    def _verdict(self, point: dict[str, Any], restoring_force: dict[str, Any] | None) -> None:
        """The point's alarm with the predictor's rule checks (:func:`serving.verdict.rule_checks`,
        the restoring-force ones where the point carries a cross-check) on the model's own
        interval; then the interval spans the readings through the other chains a fitted one
        stands for and, when the alarm fires, is widened as the predictor widens a flagged
        recording's (:func:`serving.verdict.widened_interval`). Its ``alarm`` becomes the
        fired checks."""
        alarm = rule_checks(point["alarm"], point["class"], point["beta_interval"],
                            restoring_force, self.facts, self.fs, self.fn)  # fmt: skip
        point["beta_interval"] = spread_by(point["beta_interval"], point["spread"])
        point["alarm"] = list(alarm["fired"]) if alarm is not None else []
        if alarm is not None and alarm["flag"] and point["contact"]:
            wide, said = widened_interval(point["beta_interval"], restoring_force, self.facts)
            if said:
                point["beta_interval"] = wide
                self.n_widened += 1

    def _layer(self, raw: dict[str, Any]) -> dict[str, Any]:
        names = self.p.class_names
        proba = np.asarray(raw["proba"] if raw["proba"] is not None else np.zeros(len(names)))
        contact = raw["contact_fraction"] >= 0.5 and raw["log_beta"] is not None
        est = RecordingEstimate(
            proba,
            int(np.argmax(proba)),
            raw["log_beta"] if contact else None,
            raw["log_beta_scale"],
            raw["n_points"],
        )
        interval = beta_interval(est, self.p.metadata, self.q_window) if contact else None
        inside = [(lo, hi) for t, lo, hi in self.spreads if raw["start_s"] <= t <= raw["end_s"]]
        self.spreads = [s for s in self.spreads if s[0] > raw["end_s"]]
        if inside:  # the layer's pooled reading moves as its points' readings move, on average
            interval = spread_by(interval, tuple(np.mean(inside, axis=0)))
        beta = math.exp(raw["log_beta"]) if contact else None
        if beta is not None:
            cls, near = class_with_hysteresis(beta, self.previous_layer_class, self.classes)
            self.previous_layer_class = cls
        else:
            cls, near = "no_contact", False
        inside = [
            c
            for c in self.restoring_force
            if raw["start_s"] + self.window_s <= c["t"] <= raw["end_s"] - 0.5 * self.window_s
        ]
        self.restoring_force = [c for c in self.restoring_force if c["t"] > raw["end_s"]]
        layer = {
            "index": len(self.layers),
            "start_s": raw["start_s"],
            "start_sd_s": raw["start_sd_s"],
            "end_s": raw["end_s"],
            "end_sd_s": raw["end_sd_s"],
            "class": cls,
            "near_edge": near,
            "beta": beta,
            "beta_interval": interval,
            "beta_interval_coverage": self.p.metadata.get("conformal_coverage"),
            "probabilities": {n: float(v) for n, v in zip(names, proba, strict=True)},
            "n_points": raw["n_points"],
            "n_pooled": raw["n_pooled"],
            "alarm_fraction": raw["alarm_fraction"],
            "alarm": raw["alarm_fraction"] > log_settings().layer_alarm_share,
            "restoring_force": _layer_restoring_force(inside, cls),
            "drift": _layer_drift(raw) if beta is not None else None,
        }
        if layer["drift"] is not None:
            d = layer["drift"]
            self.warnings.append(
                f"layer {layer['index']} ({raw['start_s']:.1f}-{raw['end_s']:.1f} s): beta drifts "
                f"from {d['from_beta']:.3g} to {d['to_beta']:.3g} along it ({d['from_s']:.1f}-"
                f"{d['to_s']:.1f} s): a gradual transition, not a layer of one beta; its beta "
                f"{beta:.3g} is the stretch's mean and its change times bound the ramp"
            )
        if layer["alarm"] and layer["restoring_force"]["beta"] is not None:
            # a flagged layer is a flagged recording: its interval behind the alarm, as predict's
            wide, said = widened_interval(interval, layer["restoring_force"], self.facts)
            if said:
                layer["beta_interval"] = wide
                self.widened_layers.append(layer["index"])
        self.layers.append(layer)
        return layer


def _layer_drift(raw: dict[str, Any]) -> dict[str, float] | None:
    """A layer's drifting stretch (:func:`stiffnet.layers.layer_drift`) in seconds and beta."""
    drift = raw.get("log_beta_drift")
    if drift is None:
        return None
    t0, t1, lo, hi = drift
    return {"from_s": t0, "to_s": t1, "from_beta": math.exp(lo), "to_beta": math.exp(hi)}


def spread_by(interval: list[float] | None, spread: tuple[float, float] | None) -> list | None:
    """`interval` with its ends moved out by the log-beta offsets `spread` (low <= 0 <= high)."""
    if interval is None or spread is None:
        return interval
    return [interval[0] * math.exp(spread[0]), interval[1] * math.exp(spread[1])]


def merged_runs(runs: dict[int, int]) -> list[tuple[int, int]]:
    """The ``start -> stop`` runs as seen by overlapping windows (a run cut by a window's
    edge is seen shorter there), merged into disjoint ``(start, stop)`` runs in order."""
    merged: list[tuple[int, int]] = []
    for start, stop in sorted(runs.items()):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(stop, merged[-1][1]))
        else:
            merged.append((start, stop))
    return merged


def hop_samples(hop_s: float, fs_hz: float) -> int:
    """The log's hop in samples (the predictor's windows use the same)."""
    return max(1, int(round(hop_s * fs_hz)))


def varying_windows(a: np.ndarray, starts: np.ndarray, n_win: int) -> np.ndarray:
    """Which windows of `n_win` samples of `a` at `starts` are not constant.

    A constant window (a dropped-out sensor) gives no model output. Exact (a window
    varies iff two neighbouring samples in it differ) and without cutting the
    windows out of the record.
    """
    starts = np.asarray(starts, dtype=np.int64)
    changes = np.flatnonzero(a[1:] != a[:-1])  # a[i + 1] differs from a[i]
    if changes.size == 0:
        return np.zeros(starts.size, dtype=bool)
    k = np.minimum(np.searchsorted(changes, starts), changes.size - 1)
    return (changes[k] >= starts) & (changes[k] <= starts + n_win - 2)


def window_embedding_scores(alarm: Any, out: dict[str, np.ndarray]) -> np.ndarray | None:
    """Each window's embedding distance to the training data (None when not checked)."""
    if alarm is None or "embedding" not in out or "embedding" not in alarm.thresholds:
        return None
    return alarm.embedding_scores(out["embedding"])


def _classes(edges: list[float] | None) -> tuple[tuple[str, float, float], ...]:
    if edges and len(edges) == len(DEFAULT_CLASSES) + 1:
        return tuple(
            (name, float(lo), float(hi))
            for (name, _, _), lo, hi in zip(DEFAULT_CLASSES, edges[:-1], edges[1:], strict=True)
        )
    return DEFAULT_CLASSES


def _restoring_force_fields(ph: dict[str, Any]) -> dict[str, Any]:
    return {
        "class": ph["class"],
        "beta": ph["beta"],
        "beta_interval": ph["beta_interval"],
        "contact_r2": ph.get("contact_r2"),
        "reason": ph["reason"],
    }


def _layer_restoring_force(checks: list[dict[str, Any]], cls: str) -> dict[str, Any]:
    """The restoring-force checks inside a layer: median beta and interval, agreement."""
    got = [c for c in checks if c["beta"] is not None and c["beta_interval"]]
    if not got:
        why = checks[0]["reason"] if checks else "no restoring-force check inside this layer"
        return {"beta": None, "beta_interval": None, "n_checks": len(checks), "agreement": None,
                "reason": why}  # fmt: skip
    beta = float(np.median([c["beta"] for c in got]))
    lo = float(np.median([c["beta_interval"][0] for c in got]))
    hi = float(np.median([c["beta_interval"][1] for c in got]))
    r2 = [c["contact_r2"] for c in got if c.get("contact_r2") is not None]
    votes = [c["class"] for c in got]
    top = max(set(votes), key=votes.count)
    return {
        "beta": beta,
        "beta_interval": [lo, hi],
        "n_checks": len(checks),
        "class": top,
        "agreement": top == cls,
        "contact_r2": float(np.median(r2)) if r2 else None,
        "reason": f"median of {len(got)} restoring-force check(s) inside the layer",
    }


def _public(point: dict[str, Any]) -> dict[str, Any]:
    """A point as the log reports it (no internals)."""
    out = {
        "t_s": point["t"],
        "class": point["class"],
        "beta": point["beta"],
        "beta_interval": point["beta_interval"],
        "near_edge": point["near_edge"],
        "alarm": bool(point["alarm"]),
        "alarm_fired": list(point["alarm"]),
    }
    if "restoring_force" in point:
        out["restoring_force"] = point["restoring_force"]
    return out


def stiffness_log(
    predictor: Any,
    accel: Any,
    fs_hz: float,
    natural_frequency_hz: float,
    *,
    hop_s: float = DEFAULT_HOP_S,
    restoring_force_every_s: float | None = RESTORING_FORCE_EVERY_S,
    penalty: float | None = None,
    source: str = "",
    progress: Callable[[int, int], None] | None = None,
    sensor: dict | None = None,
) -> dict[str, Any]:
    """The stiffness log of a whole record: points, layers, change times.

    Parameters
    ----------
    predictor : serving.predictor.Predictor
        The loaded model.
    accel : array_like
        1-D acceleration samples (any unit and sign).
    fs_hz, natural_frequency_hz : float
        Sampling rate and natural frequency in Hz.
    hop_s : float
        Time between points (<= 0.5 s).
    restoring_force_every_s : float or None
        Seconds between restoring-force cross-checks (None: none).
    penalty : float, optional
        Change penalty per window length (default: the calibrated one).
    source : str
        The record's name, echoed.
    progress : callable, optional
        ``progress(done_samples, total_samples)``.
    sensor : dict, optional
        The accelerometer chain's data sheet (default: identified from the record's start,
        as ``predict`` does; :class:`StiffnessLogger`).

    Returns
    -------
    dict
        ``points``, ``layers``, ``changes`` (times with uncertainty), the settings
        and the model's identity (JSON-ready).
    """
    from serving.checks import finite_samples

    a = finite_samples(accel, source or "recording")
    log = StiffnessLogger(predictor, fs_hz, natural_frequency_hz, hop_s=hop_s, penalty=penalty,
                          restoring_force_every_s=restoring_force_every_s,
                          sensor=sensor)  # fmt: skip
    if a.size < log.n_win:
        raise StiffnetError(
            f"{source or 'recording'}: {a.size / fs_hz:.3g} s is shorter than one model window "
            f"({log.window_s:.3g} s)"
        )
    from serving.checks import clipping_warning

    log.scan_chain(a)
    points, layers = [], []
    step = max(log.hop, int(60 * log.fs))  # a minute of record per progress step
    for lo in range(0, a.size, step):
        for kind, item in log.feed(a[lo : lo + step]):
            (points if kind == "point" else layers).append(item)
        if progress is not None:
            progress(min(a.size, lo + step), a.size)
    layers.extend(item for _, item in log.finish())
    if clipped := clipping_warning(a):
        log.warnings.append(clipped)
    return log_result(log, points, layers, source, a.size / log.fs)


def log_result(
    log: StiffnessLogger,
    points: list[dict[str, Any]],
    layers: list[dict[str, Any]],
    source: str,
    duration_s: float,
) -> dict[str, Any]:
    """The log's JSON document."""
    p = log.p
    changes = [
        {"t_s": la["start_s"], "sd_s": la["start_sd_s"],
         "from": layers[i - 1]["class"], "to": la["class"],
         "from_beta": layers[i - 1]["beta"], "to_beta": la["beta"]}
        for i, la in enumerate(layers) if i > 0
    ]  # fmt: skip
    warnings = list(log.warnings)
    if log.n_widened:
        warnings.append(
            f"the alarm widened the beta interval of {log.n_widened} point(s) to span the "
            "restoring-force interval: the model's calibration does not hold there"
        )
    if log.widened_layers:
        warnings.append(
            "the beta interval of flagged layer(s) "
            + ", ".join(map(str, log.widened_layers))
            + " is widened to span their restoring-force interval"
        )
    if log.undone is not None and log.other_chains:
        where = (
            f"on the record's first {log.chain_fit_n / log.fs:.3g} s"
            if log.found_late is None
            else f"by the check at {log.found_late[1]:.4g} s (the start showed none)"
        )
        warnings.append(
            f"the accelerometer's chain was fitted {where} and divided out of every window; the "
            "beta intervals also span the readings through "
            + ", ".join(log.other_chains)
            + f" (a data sheet, {sensor_given()}, reads it once)"
        )
    if log.dropouts:
        flagged = sum("dropout" in p["alarm_fired"] for p in points)
        warnings.append(
            f"{dropout_words(merged_runs(log.dropouts), log.fs, log.dropout_value)}: the "
            f"{flagged} point(s) whose windows cover it are flagged (dropout)"
        )
    if len(layers) > 1:
        warnings.append(f"beta changes along this record: {len(layers)} layers")
    flagged = [la["index"] for la in layers if la["alarm"]]
    if flagged:
        warnings.append(
            "the alarm fired on most windows of layer(s) " + ", ".join(map(str, flagged))
        )
    return {
        "source": source,
        "duration_s": duration_s,
        "fs_hz": log.fs,
        "natural_frequency_hz": log.fn,
        "window_s": log.window_s,
        "hop_s": log.hop_s,
        "model": {"name": p.name, "sha256": p.sha256, "kind": p.kind},
        "n_points": len(points),
        "layers": layers,
        "changes": changes,
        "points": points,
        # the accelerometer's chain identified on the record's start (or the data sheet's)
        # and what was divided out of every window the model read (None: nothing)
        "sensor": log.sensor,
        "chain_undone": log.undone,
        "chain_readings": list(log.other_chains) or None,
        "warnings": warnings,
    }


def iter_events(
    log: StiffnessLogger, chunks: Iterator[np.ndarray]
) -> Iterator[tuple[str, dict[str, Any]]]:
    """Points and closed layers of a stream of sample chunks, as they happen."""
    for chunk in chunks:
        yield from log.feed(chunk)
    yield from log.finish()


#: The alarm check a record with several layers fires (its score: the number of changes).
LAYERS_CHECK = "layers"


def record_layers(
    predictor: Any,
    accel: np.ndarray,
    fs_hz: float,
    natural_frequency_hz: float,
    windows: tuple[np.ndarray, dict[str, np.ndarray], np.ndarray | None] | None = None,
) -> list[dict[str, Any]]:
    """The layers of a recording as ``stiffnet log`` finds them (no restoring-force checks).

    What ``predict`` uses to say that beta changes along the record instead of
    reporting a blend in silence: the same sliding windows (hop 0.5 s) and the same
    calibrated segmenter as the log, so both commands name the same layers.
    `windows` is ``(ok, out, emb)`` of :meth:`StiffnessLogger.replay` when the model
    has already read the log's windows (the predictor's one pass); without it the
    model reads them here.
    """
    # `accel` is the record the model reads: any chain is already divided out of it
    log = StiffnessLogger(predictor, fs_hz, natural_frequency_hz, restoring_force_every_s=None,
                          fit_chain=False)  # fmt: skip
    if accel.size < log.n_win:
        return []
    if windows is not None:
        layers = [item for kind, item in log.replay(accel, *windows) if kind == "layer"]
    else:
        layers = [item for kind, item in log.feed(accel) if kind == "layer"]
        layers += [item for _, item in log.finish()]
    keep = ("index", "start_s", "start_sd_s", "end_s", "end_sd_s", "class", "near_edge", "beta",
            "beta_interval", "n_points", "alarm_fraction")  # fmt: skip
    return [{k: la[k] for k in keep} for la in layers]


def reported_changes(layers: list[dict[str, Any]]) -> int:
    """How many times what the layers report changes along the record: a boundary between
    two layers without contact (``no_contact``, no beta) changes nothing, whatever the
    segmenter saw in the windows' raw outputs there (a record without any impact splits on
    the beta head's output, which means nothing without contact)."""
    return sum(
        1
        for a, b in zip(layers, layers[1:], strict=False)
        if not (a["beta"] is None and b["beta"] is None and a["class"] == b["class"])
    )


def with_layers_alarm(
    alarm: dict[str, Any] | None, layers: list[dict[str, Any]]
) -> dict[str, Any] | None:
    """The alarm with the layers check: fires when beta changes along the record
    (:func:`reported_changes`; neighbouring layers without contact change nothing)."""
    changes = reported_changes(layers)
    if changes == 0:
        return alarm
    if alarm is None:
        alarm = {"flag": False, "fired": [], "scores": {}, "thresholds": {}, "message": ""}
    alarm = {**alarm, "scores": dict(alarm["scores"]), "thresholds": dict(alarm["thresholds"])}
    alarm["scores"][LAYERS_CHECK] = float(changes)
    alarm["thresholds"][LAYERS_CHECK] = 0.0
    alarm["fired"] = [*alarm["fired"], LAYERS_CHECK]
    alarm["flag"] = True
    text = layers_text(layers)
    previous = alarm.get("message") or ""
    alarm["message"] = (
        f"UNRELIABLE: {text}" if not previous.startswith("UNRELIABLE") else f"{previous}; {text}"
    )
    return alarm


def layers_text(layers: list[dict[str, Any]]) -> str:
    """One line naming the layers: 'beta changes along this record: soft 10 (0-30 s) -> ...'."""
    parts = [
        f"{la['class']} {la['beta']:.3g}" if la["beta"] is not None else la["class"]
        for la in layers
    ]
    spans = [f"{p} ({la['start_s']:.0f}-{la['end_s']:.0f} s)" for p, la in zip(parts, layers,
             strict=True)]  # fmt: skip
    return "beta changes along this record (the overall beta is a blend): " + " -> ".join(spans)

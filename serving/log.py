"""The stiffness log: beta along a record, its layers and their change times.

``stiffnet log`` (and ``POST /log``, and :func:`stiffness_log` from Python) slides
the model's window (16 natural periods) along the record with a hop of at most
0.5 s. Each **point** (the window's centre) carries the model's beta with its
per-window split-conformal interval (``exp(log beta +- q)``, ``q`` the model's
``conformal_quantile``), its class with hysteresis at class edges, and the alarm
evaluated on that window (the model's embedding distance, ambiguity, beta
uncertainty and class edge, against the thresholds calibrated per recording: one
window is a short recording). Every :data:`RESTORING_FORCE_EVERY_S` seconds a point also
carries the restoring-force cross-check on the window it ends
(:func:`serving.restoring_force_check.restoring_force_check`).

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
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from serving.restoring_force_check import restoring_force_check
from serving.verdict import model_facts, rule_checks, widened_interval
from stiffnet.errors import StiffnetError
from stiffnet.features.windows import window_length
from stiffnet.geometry.calibration import DEFAULT_CLASSES
from stiffnet.layers import LayerSegmenter, class_with_hysteresis
from stiffnet.uncertainty import RecordingEstimate, beta_interval
from stiffnet.uncertainty.alarm import recording_checks

#: Largest hop between points (s).
MAX_HOP_S = 0.5
#: Seconds between two restoring-force cross-checks along the record (~30 ms each).
RESTORING_FORCE_EVERY_S = 10.0
#: Restoring-force checks an open layer keeps for its median (the latest; ~3 h at 10 s).
MAX_RESTORING_FORCE_CHECKS = 1000
#: Windows per ONNX Runtime call in the log.
LOG_BATCH = 128
#: Share of a layer's points with the alarm above which the layer is flagged.
LAYER_ALARM_SHARE = 0.5


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
    """

    def __init__(
        self,
        predictor: Any,
        fs_hz: float,
        natural_frequency_hz: float,
        *,
        hop_s: float = MAX_HOP_S,
        restoring_force_every_s: float | None = RESTORING_FORCE_EVERY_S,
        penalty: float | None = None,
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
        self.widened_layers: list[int] = []  # flagged layers whose interval was widened

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
        events: list[tuple[str, dict[str, Any]]] = []
        while True:
            ready = (self.n_total - self.n_win - self.next_window * self.hop) // self.hop + 1
            if ready <= 0:
                break
            events.extend(self._windows(min(int(ready), LOG_BATCH)))
        # keep what the next window and the next restoring-force check need
        keep_from = self.next_window * self.hop
        drop = max(0, keep_from - self.buf_start)
        if drop:
            self.buf = self.buf[drop:]
            self.buf_start += drop
        return events

    def finish(self) -> list[tuple[str, dict[str, Any]]]:
        """Close the stream: the last layers."""
        if self.segmenter.n_seen == 0:
            raise StiffnetError(
                f"the record is shorter than one model window ({self.window_s:.3g} s: "
                f"{self.p.window_periods:g} natural periods at f_n {self.fn:.4g} Hz)"
            )
        end_t = (self.n_total) / self.fs
        return [("layer", self._layer(x)) for x in self.segmenter.finish(end_t)]

    # ------------------------------------------------------------ internals

    def _windows(self, n: int) -> list[tuple[str, dict[str, Any]]]:
        starts = (self.next_window + np.arange(n)) * self.hop
        ok = varying_windows(self.buf, starts - self.buf_start, self.n_win)
        out: dict[str, np.ndarray] = {}
        emb = None
        if ok.any():
            # no geometric cross-check along the log: only what the model's input needs
            out, _, _ = self.p._run_model(self.buf, starts[ok] - self.buf_start, self.n_win,
                                          self.fs, self.fn, geometric_windows=0)  # fmt: skip
            emb = window_embedding_scores(self.p.alarm, out)
        return self._emit(starts, ok, out, emb)

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
    ) -> list[tuple[str, dict[str, Any]]]:
        """Points (and the layers they close) of the windows at `starts`, in order."""
        events: list[tuple[str, dict[str, Any]]] = []
        k = 0
        for i in range(len(starts)):
            j = self.next_window + i
            end = int(starts[i]) + self.n_win
            if not ok[i]:
                continue  # a constant window (a dropped-out sensor) gives no point
            point = self._point(j, out, k, None if emb is None else emb[k])
            k += 1
            ph = None
            if self.restoring_force_every and end // self.restoring_force_every > (
                end - self.hop
            ) // (self.restoring_force_every):
                seg = self.buf[end - self.n_win - self.buf_start : end - self.buf_start]
                ph = restoring_force_check(seg, self.fs, self.fn, stage_ratio=self.p.stage_ratio)
                point["restoring_force"] = _restoring_force_fields(ph)
                self.restoring_force.append({"t": point["t"], **point["restoring_force"]})
                del self.restoring_force[:-MAX_RESTORING_FORCE_CHECKS]  # an endless layer: bounded
            self._verdict(point, ph)
            events.append(("point", _public(point)))
            for layer in self.segmenter.push(point):
                events.append(("layer", self._layer(layer)))
        self.next_window += len(starts)
        return events

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

    def _verdict(self, point: dict[str, Any], restoring_force: dict[str, Any] | None) -> None:
        """The point's alarm with the predictor's rule checks (:func:`serving.verdict.rule_checks`,
        the restoring-force ones where the point carries a cross-check) and, when it fires, its
        interval widened as the predictor widens a flagged recording's
        (:func:`serving.verdict.widened_interval`). Its ``alarm`` becomes the fired checks."""
        alarm = rule_checks(point["alarm"], point["class"], point["beta_interval"],
                            restoring_force, self.facts, self.fs, self.fn)  # fmt: skip
        point["alarm"] = list(alarm["fired"]) if alarm is not None else []
        if alarm is not None and alarm["flag"] and point["contact"]:
            wide, said = widened_interval(point["beta_interval"], restoring_force)
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
            "alarm": raw["alarm_fraction"] > LAYER_ALARM_SHARE,
            "restoring_force": _layer_restoring_force(inside, cls),
        }
        if layer["alarm"] and layer["restoring_force"]["beta"] is not None:
            # a flagged layer is a flagged recording: its interval behind the alarm, as predict's
            wide, said = widened_interval(interval, layer["restoring_force"])
            if said:
                layer["beta_interval"] = wide
                self.widened_layers.append(layer["index"])
        self.layers.append(layer)
        return layer


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
    hop_s: float = MAX_HOP_S,
    restoring_force_every_s: float | None = RESTORING_FORCE_EVERY_S,
    penalty: float | None = None,
    source: str = "",
    progress: Callable[[int, int], None] | None = None,
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

    Returns
    -------
    dict
        ``points``, ``layers``, ``changes`` (times with uncertainty), the settings
        and the model's identity (JSON-ready).
    """
    from serving.checks import finite_samples

    a = finite_samples(accel, source or "recording")
    log = StiffnessLogger(predictor, fs_hz, natural_frequency_hz, hop_s=hop_s, penalty=penalty,
                          restoring_force_every_s=restoring_force_every_s)  # fmt: skip
    if a.size < log.n_win:
        raise StiffnetError(
            f"{source or 'recording'}: {a.size / fs_hz:.3g} s is shorter than one model window "
            f"({log.window_s:.3g} s)"
        )
    from serving.checks import clipping_warning

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
    log = StiffnessLogger(predictor, fs_hz, natural_frequency_hz, restoring_force_every_s=None)
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


def with_layers_alarm(
    alarm: dict[str, Any] | None, layers: list[dict[str, Any]]
) -> dict[str, Any] | None:
    """The alarm with the layers check: fires when beta changes along the record."""
    if len(layers) <= 1:
        return alarm
    if alarm is None:
        alarm = {"flag": False, "fired": [], "scores": {}, "thresholds": {}, "message": ""}
    alarm = {**alarm, "scores": dict(alarm["scores"]), "thresholds": dict(alarm["thresholds"])}
    alarm["scores"][LAYERS_CHECK] = float(len(layers) - 1)
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

"""The lightweight ONNX predictor: one recording in, class, beta, cross-check and OOD out.

Imports numpy, scipy, onnxruntime, pydantic and stiffnet's numpy-only modules
(recordings, features, geometry, nlts) - never torch, scikit-learn or mlflow
(a test checks ``sys.modules``). See ``docs/serving.md`` for the user's view.

Pipeline of :meth:`Predictor.predict`:

1. **Checks.** Finite 1-D samples, ``fs > 0``, a known natural frequency
   ``f_n``; ``fs >= MIN_SAMPLES_PER_PERIOD * f_n`` (the lowest rate of the
   training data: slower recordings do not resolve the impact spikes the models
   and the geometric method read); at least one window; not constant. A
   clipped signal (samples piled up at the extremes) and rates above the
   training range only add warnings.
2. **Windows** of ``window_periods`` natural periods (16) at the recording's
   rate, non-overlapping (:mod:`stiffnet.features.windows`), windows constant on their own
   dropped with a warning.
3. **Model.** CNN: canonical windows (resampled to 32 samples per natural
   period, spikes up, unit std, delay channels) exactly as at training time;
   GBM: the inclination features of each window. Per-window probabilities and
   log beta.
4. **Aggregation** (:func:`stiffnet.uncertainty.aggregate_windows`, the same
   function that calibrated the model on whole training trajectories). Class
   probabilities: the mean of the windows' probabilities (robust to one odd
   window, unlike a product of probabilities); class: its arg-max. Beta: ``exp``
   of the mean log beta over the windows whose own class has contact. Its
   interval: ``exp(mean +- q s)``, ``s`` the recording's error scale (the
   model's own scale output plus the disagreement of the windows) and ``q`` the
   model's normalised split-conformal quantile calibrated with one score per
   trajectory (metadata ``conformal_quantile_recording``); models without it
   fall back to the per-window quantile ``exp(mean +- q)``. **Segments**
   aggregate ``segment_windows`` consecutive windows the same way.
5. **Cross-check** by the geometric method (:func:`stiffnet.features.features_and_estimate`
   with the shipped calibration) on ``geometric_windows`` windows spread evenly
   over the recording (all windows for the GBM, which computes their features
   anyway): contact if at least half of them have contact, then the mean of
   their inclinations through the calibration gives beta and class.
   ``agreement`` is ``model class == geometric class``. Bounding the number of
   windows keeps a 60 s recording under ~60 ms on one core.
   A second, physical cross-check (:mod:`serving.physical`): the restoring-force
   estimate on 24 forcing periods from the middle of the recording:
   ``physical_class``, ``physical_beta`` and its bootstrap interval,
   ``physical_agreement`` (null when that method refused, with its reason).
6. **Alarm** (:mod:`stiffnet.uncertainty.alarm`): checks on what the model
   looks at - the distance of the windows to the training data in the model's
   own embedding, the class ambiguity, the beta uncertainty - each against a
   threshold calibrated on in-distribution trajectories (the model's
   ``NAME.alarm.npz``, verified by its SHA-256). A model without one falls
   back to the inclination-feature OOD score (:mod:`serving.ood`). ``ood_flag``
   is the alarm; ``ood_score`` its largest score relative to its threshold.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from serving.model import LoadedModel, load_model
from serving.ood import OODReference, load_reference
from serving.physical import physical_check
from serving.schemas import PredictionResult
from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.errors import SignalError, StiffnetError
from stiffnet.features.windows import window_length, window_starts, window_tensor
from stiffnet.inputs import natural_frequency, rate_ratio, read_json, real_number, sampling_rate
from stiffnet.io_utils import sha256_file
from stiffnet.shipped import REPO_MODELS_DIR, shipped_file
from stiffnet.uncertainty import RecordingEstimate, aggregate_windows
from stiffnet.uncertainty.alarm import AlarmReference, load_alarm, recording_checks

#: Minimum sampling rate in samples per natural period: the training data's lowest rate.
MIN_SAMPLES_PER_PERIOD = 50.0
#: Rates above this many samples per natural period are beyond the training data (warning).
MAX_TRAINED_SAMPLES_PER_PERIOD = 500.0
#: Default natural periods per window when the model metadata does not say (the dataset's).
DEFAULT_WINDOW_PERIODS = float(WINDOW_PERIODS)
#: Default number of consecutive windows aggregated into one segment.
SEGMENT_WINDOWS = 4
#: Default number of windows the geometric cross-check and the OOD score analyse (CNN).
GEOMETRIC_WINDOWS = 3
#: Windows per ONNX Runtime call (bounds memory on very long recordings).
BATCH = 256
#: A signal is reported as clipped when this fraction of samples (and >= 3) sits at an extreme.
CLIP_FRACTION = 1e-3
#: Default OOD reference file name in ``models/``.
OOD_REFERENCE_FILE = "ood_reference.json"
#: Suffix of the sidecar JSON of a recording: ``run01.csv`` -> ``run01.csv.json``.
SIDECAR_SUFFIX = ".json"


def _finite_positive(value: Any, what: str) -> float:
    v = real_number(value, what)  # a bool or a string is not a number
    if not v > 0:
        raise StiffnetError(f"{what} must be a finite number > 0, got {value!r}")
    return v


def clipping_warning(a: np.ndarray) -> str | None:
    """A warning if many samples sit exactly at the maximum or minimum (a saturated sensor)."""
    n = a.size
    need = max(3, int(CLIP_FRACTION * n))
    parts = []
    for name, value in (("maximum", a.max()), ("minimum", a.min())):
        count = int(np.count_nonzero(a == value))
        if count >= need:
            parts.append(f"{count} samples at the {name} {value:.6g}")
    if not parts:
        return None
    return f"signal looks clipped ({', '.join(parts)}): impacts may be flattened"


def read_sidecar(recording: str | Path) -> tuple[float | None, Path]:
    """Natural frequency from the recording's sidecar ``<recording>.json``, if present.

    The sidecar is a JSON object with at least ``natural_frequency_hz`` (Hz); any
    other keys (provenance, rig notes) are ignored here.

    Returns
    -------
    (float or None, Path)
        The value (None when there is no sidecar or it has no such key) and the sidecar path.

    Raises
    ------
    StiffnetError
        If the sidecar exists but is not valid JSON or the value is not a number > 0.
    """
    p = Path(str(recording) + SIDECAR_SUFFIX)
    if not p.is_file():
        return None, p
    d = read_json(p, "sidecar")  # bounded, finite, depth-checked
    if not isinstance(d, dict) or d.get("natural_frequency_hz") is None:
        return None, p
    return natural_frequency(d["natural_frequency_hz"], f"{p}: natural_frequency_hz"), p


#: What each alarm check means, for the warning a user reads.
ALARM_WORDS = {
    "embedding": "the recording does not look like the training data to the model",
    "ambiguity": "the model cannot decide between classes",
    "beta_uncertainty": "the beta estimate is uncertain (the windows disagree or the model "
    "expects a large error)",
    "class_edge": "beta sits on a class edge within its uncertainty (the class is a guess)",
    "features": "the recording's inclination features are unlike the training data",
}


def alarm_message(fired: list[str]) -> str:
    """The alarm's verdict in words."""
    if not fired:
        return "no alarm: the recording looks like the data the model was calibrated on"
    return "UNRELIABLE: " + "; ".join(ALARM_WORDS.get(f, f) for f in fired)


class Predictor:
    """A verified model plus the OOD reference and the geometric calibration.

    Use :meth:`load`. Thread-safe: :meth:`predict` keeps no state between calls.

    Attributes
    ----------
    name, sha256, kind : str
        Model identity (file stem, SHA-256 of the ONNX file, ``cnn`` / ``gbm``).
    metadata : dict
        The model's decoded ``metadata_props``.
    """

    def __init__(
        self,
        model: LoadedModel,
        ood: OODReference | None,
        *,
        alarm: AlarmReference | None = None,
        segment_windows: int = SEGMENT_WINDOWS,
        geometric_windows: int = GEOMETRIC_WINDOWS,
    ) -> None:
        from stiffnet.geometry.calibration import load_calibration

        self.model = model
        self.ood = ood
        if alarm is None and ood is not None:  # older models: the feature OOD score alone
            alarm = AlarmReference(thresholds={"features": ood.threshold})
        self.alarm = alarm
        self.segment_windows = max(1, int(segment_windows))
        self.geometric_windows = max(1, int(geometric_windows))
        self.calibration = load_calibration()
        self.name, self.sha256, self.kind = model.name, model.sha256, model.kind
        self.metadata = model.metadata
        self.class_names = model.class_names
        self._nc = (
            self.class_names.index("no_contact") if "no_contact" in self.class_names else None
        )
        periods = self.metadata.get("window_periods")
        if periods is None and ood is not None:
            periods = ood.info.get("window_periods")
        self.window_periods = float(periods or DEFAULT_WINDOW_PERIODS)
        self.training_natural_frequency, self.training_natural_frequency_from = self._training_fn()
        self.ood_warning = None
        if ood is not None:
            want = self.metadata.get("training_data_sha256")
            have = ood.info.get("training_data_sha256")
            if want and have and want != have:
                self.ood_warning = (
                    "the OOD reference was fitted on other data than the model's training data"
                )

    @classmethod
    def load(
        cls,
        model_path: str | Path | None = None,
        *,
        threads: int = 1,
        ood_reference: str | Path | None = None,
    ) -> Predictor:
        """Verify and load a model (default ``models/cnn.onnx``) and its OOD reference.

        Parameters
        ----------
        model_path : str or Path, optional
            The ``.onnx`` file; its card ``NAME.card.json`` must sit beside it.
        threads : int, optional
            ONNX Runtime intra-op threads.
        ood_reference : str or Path, optional
            Inclination-feature OOD reference JSON, for models without their own
            alarm reference; default ``ood_reference.json`` beside the model, else in
            the repository's ``models/`` (no alarm without one).

        Raises
        ------
        StiffnetError
            Model missing, modified (SHA-256), corrupt, or not a stiffnet model.
        """
        model = load_model(model_path, threads)
        alarm = _load_model_alarm(model)
        if ood_reference is not None:
            ood = load_reference(ood_reference)
        elif alarm is not None:
            ood = None  # the model's own alarm replaces the feature OOD score
        else:
            ood = None
            for path in (model.path.parent / OOD_REFERENCE_FILE, shipped_file(OOD_REFERENCE_FILE)):
                if path.is_file():
                    ood = load_reference(path)
                    break
        return cls(model, ood, alarm=alarm)

    def _training_fn(self) -> tuple[float | None, str]:
        """Training data f_n: from the metadata, model card, OOD reference or data card."""
        v = self.metadata.get("natural_frequency_hz")
        if isinstance(v, int | float) and v > 0:
            return float(v), "model metadata"
        v = (self.model.card.get("data") or {}).get("natural_frequency_hz")
        if isinstance(v, int | float) and not isinstance(v, bool) and v > 0:
            return float(v), "model card (training data)"
        sha = self.metadata.get("training_data_sha256")
        if self.ood is not None and self.ood.info.get("natural_frequency_hz"):
            if not sha or self.ood.info.get("training_data_sha256") == sha:
                return float(self.ood.info["natural_frequency_hz"]), "OOD reference"
        rel = (self.model.card.get("data") or {}).get("path")
        if rel:
            for base in (REPO_MODELS_DIR.parent, Path.cwd()):
                card = base / rel / "card.json"
                if card.is_file():
                    try:
                        d = json.loads(card.read_text())
                        v = d["config"]["sweep"]["natural_frequency_hz"]
                        return _finite_positive(v, "natural_frequency_hz"), str(card)
                    except (OSError, ValueError, KeyError, TypeError, StiffnetError):
                        continue
        return None, ""

    def info(self) -> dict[str, Any]:
        """Model identity and the predictor's settings (``GET /model``)."""
        return {
            "name": self.name,
            "sha256": self.sha256,
            "kind": self.kind,
            "class_names": self.class_names,
            "window_periods": self.window_periods,
            "min_samples_per_natural_period": MIN_SAMPLES_PER_PERIOD,
            "training_natural_frequency_hz": self.training_natural_frequency,
            "segment_windows": self.segment_windows,
            "geometric_windows": self.geometric_windows,
            "ood_reference": self.ood is not None,
            "ood_threshold": self.ood.threshold if self.ood is not None else None,
            "alarm_thresholds": self.alarm.thresholds if self.alarm is not None else None,
            "metadata": self.metadata,
        }

    # ------------------------------------------------------------------ predict

    def predict(
        self,
        accel: np.ndarray,
        fs_hz: float,
        *,
        natural_frequency_hz: float | None = None,
        source: str = "",
        natural_frequency_source: str | None = None,
    ) -> dict[str, Any]:
        """Predict one recording (see the module notes).

        Parameters
        ----------
        accel : numpy.ndarray
            1-D acceleration samples, any unit and sign.
        fs_hz : float
            Sampling rate in Hz.
        natural_frequency_hz : float, optional
            Natural frequency of the rig; default: the training data's.
        source : str, optional
            Name of the recording, echoed in the result.
        natural_frequency_source : str, optional
            Label reported for a given `natural_frequency_hz` (default ``"argument"``).

        Returns
        -------
        dict
            JSON-ready, the fields of :class:`serving.schemas.PredictionResult`
            (key ``class``, not ``class_``).

        Raises
        ------
        StiffnetError
            Unusable input, with a one-line message.
        """
        warnings: list[str] = []
        fs = sampling_rate(fs_hz)  # physical ranges (stiffnet.inputs)
        if natural_frequency_hz is not None:
            fn = natural_frequency(natural_frequency_hz)
            fn_source = natural_frequency_source or "argument"
        elif self.training_natural_frequency is not None:
            fn, fn_source = self.training_natural_frequency, "training_data"
        else:
            raise StiffnetError(
                "natural frequency unknown: give it (--fn HZ, natural_frequency_hz, or a sidecar)"
            )
        a = self._check_samples(accel, source)
        what = source or "recording"
        ratio = fs / fn
        if ratio < MIN_SAMPLES_PER_PERIOD:  # first: its message names a unit mistake
            from stiffnet.recordings import unit_mistake_hint

            hint = unit_mistake_hint(
                fs, MIN_SAMPLES_PER_PERIOD * fn, 4 * MAX_TRAINED_SAMPLES_PER_PERIOD * fn
            )
            raise StiffnetError(
                f"{what}: sampling rate {fs:.6g} Hz is below the minimum "
                f"{MIN_SAMPLES_PER_PERIOD * fn:.6g} Hz ({MIN_SAMPLES_PER_PERIOD:g} x the natural "
                f"frequency {fn:.6g} Hz){hint}"
            )
        rate_ratio(fs, fn, what)  # the physical upper bound
        if ratio > MAX_TRAINED_SAMPLES_PER_PERIOD:
            warnings.append(
                f"sampling rate is {ratio:.3g} x the natural frequency, above the training data's "
                f"{MAX_TRAINED_SAMPLES_PER_PERIOD:g} x"
            )
        # Scale by a power of two so that the peak lies in [0.5, 1): exact in floating
        # point (the results do not change), and std/mean cannot overflow for 1e300 inputs.
        peak = float(np.max(np.abs(a)))
        if peak > 0:
            a = np.ldexp(a, -int(np.frexp(peak)[1]))
        if not a.std() > 0:
            raise StiffnetError(f"{what}: recording is constant (no signal)")
        need = self.window_periods * fs / fn  # samples in one window
        if not (math.isfinite(need) and a.size >= round(need)):
            raise StiffnetError(
                f"{what}: recording is too short ({a.size / fs:.3g} s): one window of "
                f"{self.window_periods:g} natural periods needs {need / fs:.3g} s "
                f"({round(need) if need < 1e15 else f'{need:.3g}'} samples at {fs:.6g} Hz)"
            )
        n_win = window_length(fs, fn, self.window_periods)
        clip = clipping_warning(a)
        if clip:
            warnings.append(clip)
        if self.ood_warning:
            warnings.append(self.ood_warning)

        starts = window_starts(a.size, n_win, n_win)
        W = a[starts[:, None] + np.arange(n_win)[None, :]]
        ok = W.std(axis=1) > 0
        if not ok.all():
            warnings.append(f"{int((~ok).sum())} constant window(s) skipped")
            W, starts = W[ok], starts[ok]
            if len(W) == 0:
                raise StiffnetError(f"{what}: every window is constant")

        try:
            out, feats, geo = self._run_model(W, fs, fn)
        except SignalError as exc:
            raise StiffnetError(f"{what}: {exc}") from None
        names = self.class_names
        est = self._aggregate(out)
        cls = names[est.label]
        beta = math.exp(est.log_beta) if est.log_beta is not None else None
        interval = self._interval(est)

        segments = []
        for k, lo in enumerate(range(0, len(W), self.segment_windows)):
            hi = min(len(W), lo + self.segment_windows)
            seg = self._aggregate({name: v[lo:hi] for name, v in out.items()})
            segments.append(
                {
                    "index": k,
                    "start_s": float(starts[lo] / fs),
                    "end_s": float((starts[hi - 1] + n_win) / fs),
                    "n_windows": hi - lo,
                    "class": names[seg.label],
                    "probabilities": self._named(seg.probabilities),
                    "beta": math.exp(seg.log_beta) if seg.log_beta is not None else None,
                }
            )
        seg_classes = [s["class"] for s in segments]
        if len(set(seg_classes)) > 1:
            warnings.append(f"class changes over time: {' -> '.join(seg_classes)}")

        geometric = self._geometric(geo)
        alarm = self._alarm(est, out, feats)
        physical = physical_check(a, fs, fn)
        if alarm is not None and alarm["flag"]:
            warnings.append(alarm["message"])
        # the alarm as one number: its largest score over its threshold (fires above 1)
        ratios = [
            v / alarm["thresholds"][k]
            for k, v in (alarm or {}).get("scores", {}).items()
            if alarm["thresholds"].get(k)
        ]
        result = {
            "source": source,
            "class": cls,
            "probabilities": self._named(est.probabilities),
            "beta": beta,
            "beta_interval": interval,
            "beta_interval_coverage": self.metadata.get("conformal_coverage"),
            "geometric": geometric,
            "agreement": geometric["class"] == cls,
            "physical": physical,
            "physical_class": physical["class"],
            "physical_beta": physical["beta"],
            "physical_beta_interval": physical["beta_interval"],
            "physical_agreement": None if physical["class"] is None else physical["class"] == cls,
            "contact_detected": cls != "no_contact",
            "ood_score": max(ratios) if ratios else None,
            "ood_threshold": 1.0 if ratios else None,
            "ood_flag": bool(alarm is not None and alarm["flag"]),
            "alarm": alarm,
            "n_windows": int(len(W)),
            "window_s": n_win / fs,
            "hop_s": n_win / fs,
            "duration_s": a.size / fs,
            "fs_hz": fs,
            "segments": segments,
            "model": {"name": self.name, "sha256": self.sha256, "kind": self.kind},
            "natural_frequency_hz": fn,
            "natural_frequency_source": fn_source,
            "warnings": warnings,
        }
        return PredictionResult.model_validate(result).model_dump(by_alias=True)

    @staticmethod
    def _check_samples(accel: Any, source: str) -> np.ndarray:
        what = source or "recording"
        try:
            a = np.asarray(accel, dtype=np.float64)
        except (TypeError, ValueError):
            raise StiffnetError(f"{what}: samples are not numbers") from None
        if a.ndim != 1:
            raise StiffnetError(f"{what}: expected 1-D samples, got shape {a.shape}")
        if a.size < 2:
            state = "is empty" if a.size == 0 else "has only one sample"
            raise StiffnetError(f"{what}: recording {state} (need at least 2 samples)")
        bad = ~np.isfinite(a)
        if bad.any():
            raise StiffnetError(
                f"{what}: {int(bad.sum())} NaN/inf samples (first at sample {int(np.argmax(bad))})"
            )
        return a

    def _named(self, p: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.class_names, p, strict=True)}

    def _aggregate(self, out: dict[str, np.ndarray]) -> RecordingEstimate:
        return aggregate_windows(
            out["probabilities"], out["log_beta"], out.get("log_beta_scale"), self._nc
        )

    def _interval(self, est: RecordingEstimate) -> list[float] | None:
        """Per-recording normalised interval, else the card's per-window one."""
        if est.log_beta is None:
            return None
        q_rec = self.metadata.get("conformal_quantile_recording")
        if isinstance(q_rec, int | float) and math.isfinite(q_rec) and est.scale is not None:
            half = float(q_rec) * est.scale
        elif self.model.conformal_quantile:
            half = self.model.conformal_quantile
        else:
            return None
        return [math.exp(est.log_beta - half), math.exp(est.log_beta + half)]

    def _alarm(self, est: RecordingEstimate, out: dict[str, np.ndarray], feats: np.ndarray):
        if self.alarm is None:
            return None
        emb = None
        if "embedding" in out and "embedding" in self.alarm.thresholds:
            emb = self.alarm.embedding_scores(out["embedding"])
        feat = None
        if self.ood is not None and len(feats) and "features" in self.alarm.thresholds:
            feat = float(np.median(self.ood.scores(feats)))
        edges = self.alarm.info.get("class_edges")
        result = self.alarm.evaluate(recording_checks(est, emb, feat, edges))
        result["scores"] = {k: v for k, v in result["scores"].items() if v is not None}
        result["message"] = alarm_message(result["fired"])
        return result

    def _run_model(self, W: np.ndarray, fs: float, fn: float):
        """Per-window model outputs (by ONNX output name), OOD features, geometric results."""
        from stiffnet.features import features_and_estimate

        def feature_rows(idx):
            rows, ests = [], []
            for i in idx:
                f, est = features_and_estimate(W[i], fs, fn, calibration=self.calibration)
                rows.append(f)
                ests.append(est)
            return np.array(rows).reshape(len(rows), -1), ests

        sess, name = self.model.session, self.model.input_name
        if self.kind == "gbm":
            use_fn = self.metadata.get("requires_natural_frequency", True)
            feats, geo = feature_rows(range(len(W)))
            X = feats
            if not use_fn:
                from stiffnet.features import FEATURE_NAMES

                X = feats.copy()
                X[:, FEATURE_NAMES.index("period_natural")] = -1.0
            X = X.astype(np.float32)
        else:
            m = self.metadata
            X = window_tensor(
                W, fs, fn, int(m["canonical_rate"]), int(m["window_periods"]), m["delays"]
            )
            k = min(self.geometric_windows, len(W))
            idx = np.unique(np.round(np.linspace(0, len(W) - 1, k)).astype(int))
            feats, geo = feature_rows(idx)
        wanted = [o for o in MODEL_OUTPUTS if o in self.model.output_names]
        parts: dict[str, list[np.ndarray]] = {o: [] for o in wanted}
        for lo in range(0, len(X), BATCH):
            for o, v in zip(wanted, sess.run(wanted, {name: X[lo : lo + BATCH]}), strict=True):
                parts[o].append(v)
        out = {o: np.concatenate(v).astype(np.float64) for o, v in parts.items()}
        for o in ("log_beta", "log_beta_scale"):
            if o in out:
                out[o] = out[o].reshape(-1)
        return out, feats, geo

    def _geometric(self, results: list) -> dict[str, Any]:
        """Aggregate the per-window geometric results (contact in >= half the windows)."""
        contact = [r for r in results if r is not None and r.contact_detected]
        n = len(results)
        out: dict[str, Any] = {
            "class": "no_contact",
            "beta": None,
            "inclination_before_deg": None,
            "inclination_after_deg": None,
            "contact_detected": False,
            "n_windows": n,
            "n_windows_with_contact": len(contact),
            "polarity": 0,
        }
        if not contact or 2 * len(contact) < n:
            return out
        before = float(np.mean([r.inclination_before_deg for r in contact]))
        after = float(np.mean([r.inclination_after_deg for r in contact]))
        beta, cls = self.calibration.predict((before, after))
        pol = int(np.sign(sum(r.polarity for r in contact))) or contact[0].polarity
        out.update(
            {
                "class": str(cls),
                "inclination_before_deg": before,
                "inclination_after_deg": after,
                "contact_detected": True,
                "polarity": pol,
                "beta": float(beta) if np.isfinite(beta) else None,
            }
        )
        return out


#: Outputs the predictor reads, when the model has them (older models: the first two).
MODEL_OUTPUTS = ("probabilities", "log_beta", "log_beta_scale", "embedding")


def _load_model_alarm(model: LoadedModel) -> AlarmReference | None:
    """The model's alarm reference (metadata ``alarm_reference``), verified by SHA-256."""
    name = model.metadata.get("alarm_reference")
    if not name:
        return None
    path = model.path.parent / Path(str(name)).name  # beside the model, never elsewhere
    if not path.is_file():
        raise StiffnetError(f"{model.path.name}: its alarm reference {path} is missing")
    want = model.metadata.get("alarm_sha256")
    if want and sha256_file(path) != want:
        raise StiffnetError(f"{path}: SHA-256 does not match the model's metadata (modified?)")
    return load_alarm(path)


_LOADED: dict[tuple, Predictor] = {}


def _cached_load(model_path: str | Path | None) -> Predictor:
    """:meth:`Predictor.load` once per version of the model file and its card (size, mtime).

    Repeated :func:`predict_recording` calls (a measurement loop) then skip the
    session start-up; a file changed on disk is loaded and verified again.
    """
    from serving.model import default_model_path

    path = Path(model_path) if model_path is not None else default_model_path()
    try:
        st, cst = path.stat(), path.with_suffix(".card.json").stat()
        key = (str(path.resolve()), st.st_size, st.st_mtime_ns, cst.st_mtime_ns)
    except OSError:
        return Predictor.load(path)  # reports the missing file
    if key not in _LOADED:
        if len(_LOADED) >= 4:
            _LOADED.clear()
        _LOADED[key] = Predictor.load(path)
    return _LOADED[key]


def predict_recording(
    path: str | os.PathLike[str],
    *,
    fs_hz: float | None = None,
    natural_frequency_hz: float | None = None,
    model_path: str | Path | None = None,
    predictor: Predictor | None = None,
    columns: str | None = None,
    time_unit: str | None = None,
) -> dict[str, Any]:
    """Read a recording file and predict it.

    The natural frequency is, in this order: `natural_frequency_hz`; the
    sidecar ``<recording>.json``'s ``natural_frequency_hz``; the model's
    training data's (``natural_frequency_source`` says which).

    Parameters
    ----------
    path : str or os.PathLike
        CSV ``t,accel``, ``.npy`` (needs `fs_hz`), WAV or TDMS.
    fs_hz : float, optional
        Sampling rate (required for ``.npy``; checked against the file otherwise).
    natural_frequency_hz : float, optional
        Natural frequency of the rig in Hz.
    model_path : str or Path, optional
        Model to load (ignored when `predictor` is given).
    predictor : Predictor, optional
        An already loaded predictor.
    columns, time_unit : str, optional
        CSV layout, as :func:`stiffnet.recordings.read_recording`.

    Returns
    -------
    dict
        As :meth:`Predictor.predict`.
    """
    from stiffnet.recordings import read_recording

    pred = predictor or _cached_load(model_path)
    rec = read_recording(path, fs_hz=fs_hz, columns=columns, time_unit=time_unit)
    fn_source = "argument"
    if natural_frequency_hz is None:
        natural_frequency_hz, sidecar = read_sidecar(path)
        fn_source = f"sidecar:{sidecar}"
    return pred.predict(
        rec.accel,
        rec.fs_hz,
        natural_frequency_hz=natural_frequency_hz,
        source=rec.source,
        natural_frequency_source=fn_source,
    )

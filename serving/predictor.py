"""The lightweight ONNX predictor: one recording in, class, beta, cross-check and OOD out.

Imports numpy, scipy, onnxruntime, pydantic and stiffnet's numpy-only modules
(recordings, features, geometry, nlts) - never torch, scikit-learn or mlflow
(``tests/test_import_rules.py`` checks every module it reaches). See
``docs/serving.md`` for the user's view.

:meth:`Predictor.predict` runs five steps, each in its own module:

1. **Check** (:mod:`serving.checks`): finite samples, sampling rate and natural
   frequency in range, at least one window, not constant; clipping and rates
   above the training data only warn.
   The restoring-force cross-check (step 4) runs next: where it identified the sensor
   chain, or was given its data sheet, the model reads the record with that chain's
   resonance and low-pass divided out (:mod:`serving.chain_undo`, ``undo_chain``;
   ``chain_undone`` in the result), and so do the interval and the alarm. A model whose
   card names its own mode (the loop's, trained behind the campaign's fitted chain:
   ``outside_priors``) is read that way.
2. **Windows** of ``window_periods`` natural periods (16) at the recording's
   rate, non-overlapping (:func:`stiffnet.features.windows.window_length`, the
   dataset's rule), windows constant on their own dropped with a warning.
3. **Model** (:mod:`serving.families`): the model's family says which windows
   the geometric cross-check reads (their inclination features) and what the
   ONNX input is (CNN: canonical delay-embedded windows exactly as at training
   time; GBM: the inclination features of every window); ONNX Runtime gives
   per-window probabilities, log beta and, when the model has them, the
   log-beta scale and the embedding.
4. **Aggregate** (:mod:`serving.aggregate`): recording and segment estimates
   and the beta interval; the geometric cross-check
   (:func:`stiffnet.features.features_and_estimate` with the shipped
   calibration; ``agreement`` is ``model class == geometric class``; bounding
   its windows keeps a 60 s recording under ~60 ms on one core); the restoring-force
   cross-check (:mod:`serving.restoring_force_check`: the restoring-force estimate,
   ``restoring_force_class``, ``restoring_force_beta`` with its bootstrap interval,
   ``restoring_force_agreement``, null when that method refused, with its reason);
   the alarm (:mod:`stiffnet.uncertainty.alarm_verdict`: ``ood_flag`` is the alarm, ``ood_score``
   its largest score relative to its threshold).
5. **Result**: :class:`serving.schemas.PredictionResult`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from serving.aggregate import geometric_verdict, named, segments
from serving.chain_spread import (
    ChainSpreadConfig,
    chain_class_share,
    chain_spread_config,
    contact_frequencies,
    plausible_chains,
    spread_interval,
)
from serving.chain_undo import UNDO_MODES, chain_as_read, model_record, trained_undo_chain
from serving.checks import MIN_SAMPLES_PER_PERIOD, checked_recording
from serving.log import (
    DEFAULT_HOP_S,
    RESTORING_FORCE_EVERY_S,
    hop_samples,
    record_layers,
    varying_windows,
    window_embedding_scores,
    with_layers_alarm,
)
from serving.model import LoadedModel, load_model
from serving.restoring_force_check import (
    check_sensor_sheet,
    restoring_force_check,
    sidecar_sensor,
    trained_penetration_dissipation,
    trained_stage_ratio,
)
from serving.schemas import PredictionResult
from serving.verdict import model_facts, rule_checks, widened_interval
from stiffnet.config.window import WINDOW_PERIODS
from stiffnet.errors import SignalError, StiffnetError
from stiffnet.features.windows import window_length, window_starts
from stiffnet.inputs import (
    natural_frequency,
    read_json,
    real_number,
    sampling_rate,
    where_given,
)
from stiffnet.recordings import natural_frequency_of
from stiffnet.shipped import REPO_MODELS_DIR, shipped_file
from stiffnet.uncertainty import RecordingEstimate, aggregate_windows, beta_interval
from stiffnet.uncertainty.alarm import AlarmReference
from stiffnet.uncertainty.alarm_verdict import (
    CHAIN_CLASS_THRESHOLD,
    alarm_ratio,
    alarm_verdict,
    load_model_alarm,
    weak_restoring_force_fit,
    with_rule_check,
)
from stiffnet.uncertainty.class_decision import ClassDecision, decide_class, family_rule
from stiffnet.uncertainty.ood import OODReference, load_reference

#: Default number of consecutive windows aggregated into one segment.
SEGMENT_WINDOWS = 4
#: Default number of windows the geometric cross-check and the OOD score analyse (CNN).
GEOMETRIC_WINDOWS = 3
#: Windows per ONNX Runtime call (bounds memory on very long recordings).
BATCH = 256
#: Samples cut per model call at most (4 MB of float64): a window of 16 natural periods
#: at a high rate is long, and the model's input is built from float64 copies of it.
CHUNK_SAMPLES = 2**19
#: Default OOD reference file name in ``models/``.
OOD_REFERENCE_FILE = "ood_reference.json"
#: Which identified sensor chain the model reads undone (:mod:`serving.chain_undo`).
UNDO_CHAIN = "chain"
#: Outputs the predictor reads, when the model has them (older models: the first two).
MODEL_OUTPUTS = ("probabilities", "log_beta", "log_beta_scale", "embedding")


def _finite_positive(value: Any, what: str) -> float:
    v = real_number(value, what)  # a bool or a string is not a number
    if not v > 0:
        raise StiffnetError(f"{what} must be a finite number > 0, got {value!r}")
    return v


#: Why f_n is never guessed from a record (measured: docs/field.md).
FN_NOT_GUESSED = (
    "A steady-state record does not show it (its motion is at the forcing frequency) and "
    "the training data's value is not assumed"
)


def fn_unknown() -> str:
    """The refusal without f_n, naming what the user can give where they are: the option
    and the sidecar on the command line, the manifest's column for a campaign, the field
    over HTTP (:func:`stiffnet.inputs.where_given`)."""
    how = where_given(
        cli="--fn HZ, or a sidecar <recording>.json with natural_frequency_hz, or the "
        "natural_frequency_hz column of the campaign manifest listing the recording",
        manifest="the manifest's column natural_frequency_hz, or a sidecar "
        "<recording>.json with natural_frequency_hz",
        http="the field natural_frequency_hz",
    )
    return f"natural frequency unknown: give it ({how}). {FN_NOT_GUESSED}"


def record_natural_frequency(
    recording: str | Path | None,
    natural_frequency_hz: float | None,
    **listed: Any,
) -> tuple[float, str]:
    """f_n of a recording and where it came from: the option, else its sidecar, else its
    campaign's row (``listed``: :func:`natural_frequency_of`'s ``campaign_row`` and
    ``find_row``), else refuse.

    Raises
    ------
    StiffnetError
        Neither is there (:func:`fn_unknown`), or the value is out of range.
    """
    value, source = natural_frequency_of(recording, natural_frequency_hz, **listed)
    if value is not None:
        return value, source
    where = f"{recording}: " if recording is not None else ""
    raise StiffnetError(where + fn_unknown())


@dataclass(frozen=True)
class WindowReading:
    """What the model read from a recording's windows (one pass), aggregated."""

    estimate: RecordingEstimate
    decision: ClassDecision
    outputs: dict[str, np.ndarray]
    features: np.ndarray
    geometric: dict[str, Any]
    n_windows: int
    window_s: float
    hop_s: float
    segments: list[dict[str, Any]]
    layers: list[dict[str, Any]]
    embedding_scores: np.ndarray | None = None


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
        undo_chain: str | None = None,
        chain_spread: ChainSpreadConfig | None = None,
    ) -> None:
        from stiffnet.geometry.calibration import load_calibration

        undo_chain = undo_chain or trained_undo_chain(model.card) or UNDO_CHAIN
        if undo_chain not in UNDO_MODES:
            raise StiffnetError(f"undo_chain must be one of {', '.join(UNDO_MODES)}")
        self.undo_chain = undo_chain
        #: which other chains a fitted one stands for (configs/chain_spread.yaml by default)
        self.chain_spread = chain_spread if chain_spread is not None else chain_spread_config()

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
        self.window_periods = float(periods or WINDOW_PERIODS)
        self.training_natural_frequency, self.training_natural_frequency_from = self._training_fn()
        #: the learned two-stage law the model was trained with: the restoring-force check
        #: reads beta in its sense (its first-stage slope)
        self.stage_ratio = trained_stage_ratio(model_facts(self)["priors"])
        #: ... and a learned dissipation growing with penetration: read with that term free
        self.penetration_dissipation = trained_penetration_dissipation(model_facts(self)["priors"])
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
        undo_chain: str | None = None,
        chain_spread: ChainSpreadConfig | None = None,
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
        undo_chain : str, optional
            Which identified sensor chain the model reads undone, one of
            :data:`serving.chain_undo.UNDO_MODES` (default: the model card's, else
            :data:`UNDO_CHAIN`; :func:`trained_undo_chain`).
        chain_spread : ChainSpreadConfig, optional
            Which other chains a fitted chain stands for in the interval
            (:mod:`serving.chain_spread`; default ``configs/chain_spread.yaml``).

        Raises
        ------
        StiffnetError
            Model missing, modified (SHA-256), corrupt, or not a stiffnet model.
        """
        model = load_model(model_path, threads)
        alarm = load_model_alarm(model)
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
        return cls(model, ood, alarm=alarm, undo_chain=undo_chain, chain_spread=chain_spread)

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
                    try:  # bounded in size and depth (a card may point anywhere)
                        d = read_json(card, "data card")
                        v = d["config"]["sweep"]["natural_frequency_hz"]
                        return _finite_positive(v, "natural_frequency_hz"), str(card)
                    except (KeyError, TypeError, StiffnetError):
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
        sensor: dict | None = None,
        sensor_fitted: bool = False,
        penetration_dissipation: bool | None = None,
    ) -> dict[str, Any]:
        """Predict one recording: check -> windows -> model -> aggregate -> result.

        Parameters
        ----------
        accel : numpy.ndarray
            1-D acceleration samples, any unit and sign.
        fs_hz : float
            Sampling rate in Hz.
        natural_frequency_hz : float
            Natural frequency of the rig (required: never the training data's in silence;
            None raises a :class:`StiffnetError` saying how to give it).
        source : str, optional
            Name of the recording, echoed in the result.
        natural_frequency_source : str, optional
            Label reported for a given `natural_frequency_hz` (default ``"argument"``).
        sensor : dict, optional
            The sensor chain's data sheet (``resonance_hz``, ``resonance_damping``,
            ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``): the restoring-force check
            undoes it instead of fitting one (:mod:`serving.restoring_force_check`).
        sensor_fitted : bool, optional
            `sensor` was fitted, not read off a data sheet (a campaign's pooled chain,
            :mod:`serving.campaign_chain`): the interval spans the model's readings through
            the other chains the fit allows, as for a chain fitted on this record
            (:mod:`serving.chain_spread`), and the restoring-force check weights its inverse
            as a fitted chain's.
        penetration_dissipation : bool, optional
            Read the restoring-force check's beta with a free ``delta v`` dissipation (the
            Hunt-Crossley law's elastic slope at first contact): a campaign whose identified
            low-pass was its contacts' dissipation
            (:func:`serving.campaign_chain.campaign_dissipation`). None (default): as the
            model's learned law asks
            (:func:`~serving.restoring_force_check.trained_penetration_dissipation`).

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
        what = source or "recording"
        a, fs, fn, fn_source, sensor, warnings = self._checked_input(
            accel, fs_hz, natural_frequency_hz, natural_frequency_source, sensor, what
        )
        dissipation = (self.penetration_dissipation if penetration_dissipation is None
                       else bool(penetration_dissipation))  # fmt: skip
        restoring_force = restoring_force_check(
            a, fs, fn, sensor, self.stage_ratio,
            penetration_dissipation=dissipation,
            sensor_fitted=sensor_fitted and sensor is not None,
        )  # fmt: skip
        read, undone = model_record(a, fs, fn, restoring_force, model_facts(self)["priors"],
                                    self.undo_chain)  # fmt: skip
        if undone and sensor_fitted:
            undone = {**undone, "source": "campaign"}
        reading = self._read_windows(read, fs, fn, what, warnings)
        interval = beta_interval(reading.estimate, self.metadata, self.model.conformal_quantile)
        log_beta = reading.estimate.log_beta
        # the contact the model reads through the chain: is the fit's resonance clear of it?
        contact = contact_frequencies(None if log_beta is None else math.exp(log_beta),
                                      interval, fn)  # fmt: skip
        others = self._chain_readings(a, fs, fn, restoring_force.get("sensor"), undone, what,
                                      contact)  # fmt: skip
        sensor_read = chain_as_read(restoring_force.get("sensor"), undone)
        # the checks judge the model's own reading; the answer's interval spans the others
        alarm = self._alarm(reading, interval, restoring_force, fs, fn, sensor_read, others)
        interval = spread_interval(interval, others)
        if alarm is not None and alarm["flag"]:
            warnings.append(alarm["message"])
            interval = self._interval_behind_alarm(interval, restoring_force, warnings,
                                                   model_facts(self))  # fmt: skip
        if weak := weak_restoring_force_fit(restoring_force):
            warnings.append(weak)
        result = self._result(reading, interval, restoring_force, alarm)
        result.update(source=source, duration_s=a.size / fs, fs_hz=fs, natural_frequency_hz=fn,
                      natural_frequency_source=fn_source, warnings=warnings,
                      chain_undone=undone, chain_readings=others or None)  # fmt: skip
        return PredictionResult.model_validate(result).model_dump(by_alias=True)

    def _checked_input(
        self,
        accel: Any,
        fs_hz: Any,
        natural_frequency_hz: Any,
        natural_frequency_source: str | None,
        sensor: dict | None,
        what: str,
    ) -> tuple[np.ndarray, float, float, str, dict | None, list[str]]:
        """Is the input usable: samples, rates, f_n's source, sensor sheet, first warnings."""
        if natural_frequency_hz is None:
            from serving.checks import finite_samples

            finite_samples(accel, what)  # the samples' own faults first
        fs, fn, fn_source = self._rates(fs_hz, natural_frequency_hz, natural_frequency_source)
        sensor = None if sensor is None else check_sensor_sheet(sensor, fs)
        a, warnings = checked_recording(accel, fs, fn, self.window_periods, what)
        if self.ood_warning:
            warnings.append(self.ood_warning)
        return a, fs, fn, fn_source, sensor, warnings

    def _read_windows(
        self, a: np.ndarray, fs: float, fn: float, what: str, warnings: list[str]
    ) -> WindowReading:
        """What the model says: one pass over the log's windows, aggregated three ways
        (the recording, its segments, its layers)."""
        starts, ok, n_win, hop = self._windows(a, fs, fn, what, warnings)
        try:
            out, feats, geo = self._run_model(a, starts[ok], n_win, fs, fn)
        except SignalError as exc:
            raise StiffnetError(f"{what}: {exc}") from None
        emb = window_embedding_scores(self.alarm, out)
        names, nc = self.class_names, self._nc
        est = aggregate_windows(
            out["probabilities"], out["log_beta"], out.get("log_beta_scale"), nc
        )
        segs = segments(out, starts[ok], n_win, a.size, fs, self.segment_windows, names, nc,
                        self.decide_class)  # fmt: skip
        return WindowReading(
            estimate=est,
            decision=self.decide_class(est),
            outputs=out,
            features=feats,
            geometric=geometric_verdict(geo, self.calibration),
            n_windows=int(ok.sum()),
            window_s=n_win / fs,
            hop_s=hop / fs,
            segments=segs,
            # > 1 layer: the alarm says so (warnings too); the model's outputs are shared
            layers=record_layers(self, a, fs, fn, windows=(ok, out, emb)),
            embedding_scores=emb,  # the alarm reads them too: computed once
        )

    def _chain_readings(
        self,
        a: np.ndarray,
        fs: float,
        fn: float,
        sensor: dict | None,
        undone: dict | None,
        what: str,
        contact_read: list[float] | None = None,
    ) -> list[dict[str, Any]]:
        """The model's class, beta and interval through each other chain a fitted one stands
        for (:func:`serving.chain_spread.plausible_chains`, given the contact frequency the
        model read through it, `contact_read`; none for a data sheet or no chain).
        One model pass each, without the geometric windows, segments or layers."""
        out = []
        chains = plausible_chains(sensor, undone, self.chain_spread, contact_read)
        for name, chain in chains.items():
            read = a
            if chain is not None:
                read, _ = model_record(a, fs, fn, {"sensor": chain},
                                       model_facts(self)["priors"], self.undo_chain)  # fmt: skip
            starts, ok, n_win, _ = self._windows(read, fs, fn, what, [])
            try:
                outputs, _, _ = self._run_model(read, starts[ok], n_win, fs, fn, 0)
            except SignalError as exc:
                raise StiffnetError(f"{what}: {exc}") from None
            est = aggregate_windows(outputs["probabilities"], outputs["log_beta"],
                                    outputs.get("log_beta_scale"), self._nc)  # fmt: skip
            out.append({
                "chain": name,
                "class": self.class_names[self.decide_class(est).label],
                "beta": math.exp(est.log_beta) if est.log_beta is not None else None,
                "beta_interval": beta_interval(est, self.metadata,
                                               self.model.conformal_quantile),
            })  # fmt: skip
        return out

    def decide_class(self, estimate: RecordingEstimate) -> ClassDecision:
        """The class of aggregated windows: the class head's, or the beta head's near an edge
        (:func:`stiffnet.uncertainty.class_decision.decide_class`, this model family's rule)."""
        return decide_class(estimate, self.class_names, self.metadata.get("class_edges"),
                            family_rule(self.kind))  # fmt: skip

    def _alarm(
        self,
        reading: WindowReading,
        interval: list[float] | None,
        restoring_force: dict[str, Any],
        fs: float,
        fn: float,
        sensor_read: dict | None = None,
        chain_readings: list[dict[str, Any]] | None = None,
    ) -> dict[str, Any] | None:
        """How far to trust the answer: the model's checks, its class against its own beta,
        then the restoring-force gap, the unseen contact law, the layers and the sensor chain
        (as the model read it: `sensor_read`, the identified one less the stages undone; and
        the classes it reads through the other chains a fitted one allows)."""
        alarm = alarm_verdict(self.alarm, self.ood, reading.estimate, reading.outputs,
                              reading.features, reading.embedding_scores)  # fmt: skip
        head = self.class_names[reading.estimate.label]  # class_beta: the heads against each other
        answered = self.class_names[reading.decision.label]
        alarm = rule_checks(alarm, answered, interval, restoring_force, model_facts(self), fs, fn,
                            head_class=head, sensor_read=sensor_read,
                            geometric_class=(reading.geometric or {}).get("class"))  # fmt: skip
        alarm = with_rule_check(alarm, "chain_class",
                                chain_class_share(answered, chain_readings or []),
                                CHAIN_CLASS_THRESHOLD)  # fmt: skip
        return with_layers_alarm(alarm, reading.layers)

    @staticmethod
    def _interval_behind_alarm(
        interval: list[float] | None,
        restoring_force: dict[str, Any],
        warnings: list[str],
        model: dict[str, Any] | None = None,
    ) -> list[float] | None:
        """A flagged recording's beta interval spans the restoring-force one too, and what a
        learned face allows (:func:`serving.verdict.widened_interval`), said in a warning."""
        wide, said = widened_interval(interval, restoring_force, model)
        if said:
            warnings.append(said)
        return wide

    def _result(
        self,
        reading: WindowReading,
        interval: list[float] | None,
        restoring_force: dict[str, Any],
        alarm: dict[str, Any] | None,
    ) -> dict[str, Any]:
        """The answer's fields (the caller adds the recording's own)."""
        est, geometric = reading.estimate, reading.geometric
        cls = self.class_names[reading.decision.label]
        score = alarm_ratio(alarm)
        return {
            "class": cls,
            "class_decided_by": reading.decision.decided_by,
            "probabilities": named(self.class_names, est.probabilities),
            "beta": math.exp(est.log_beta) if est.log_beta is not None else None,
            "beta_interval": interval,
            "beta_interval_coverage": self.metadata.get("conformal_coverage"),
            "geometric": geometric,
            "agreement": geometric["class"] == cls,
            "restoring_force": restoring_force,
            "restoring_force_class": restoring_force["class"],
            "restoring_force_beta": restoring_force["beta"],
            "restoring_force_beta_interval": restoring_force["beta_interval"],
            "restoring_force_agreement": None
            if restoring_force["class"] is None
            else restoring_force["class"] == cls,
            "contact_detected": cls != "no_contact",
            "ood_score": score,
            "ood_threshold": 1.0 if score is not None else None,
            "ood_flag": bool(alarm is not None and alarm["flag"]),
            "alarm": alarm,
            "n_windows": reading.n_windows,
            "window_s": reading.window_s,
            "hop_s": reading.hop_s,
            "segments": reading.segments,
            "layers": reading.layers,
            "model": {"name": self.name, "sha256": self.sha256, "kind": self.kind},
        }

    def log(
        self,
        accel: np.ndarray,
        fs_hz: float,
        *,
        natural_frequency_hz: float,
        hop_s: float = DEFAULT_HOP_S,
        restoring_force_every_s: float | None = RESTORING_FORCE_EVERY_S,
        source: str = "",
        sensor: dict | None = None,
    ) -> dict[str, Any]:
        """The stiffness log of a record: beta along it, its layers and change times.

        :func:`serving.log.stiffness_log` with this model (``stiffnet log``'s JSON:
        ``points``, ``layers``, ``changes``, ``warnings``).

        Parameters
        ----------
        accel : numpy.ndarray
            1-D acceleration samples, any unit and sign.
        fs_hz, natural_frequency_hz : float
            Sampling rate and the rig's natural frequency in Hz.
        hop_s : float, optional
            Time between points (<= 0.5 s; default ``configs/log.yaml``).
        restoring_force_every_s : float or None, optional
            Seconds between restoring-force cross-checks (None: none; default
            ``configs/log.yaml``).
        source : str, optional
            The record's name, echoed.
        sensor : dict, optional
            The accelerometer chain's data sheet (default: identified from the record's
            start and divided out of every window, as :meth:`predict` does).
        """
        from serving.log import stiffness_log

        return stiffness_log(
            self, accel, fs_hz, natural_frequency_hz, hop_s=hop_s,
            restoring_force_every_s=restoring_force_every_s, source=source, sensor=sensor,
        )  # fmt: skip

    def predict_file(
        self,
        path: str | os.PathLike[str],
        *,
        fs_hz: float | None = None,
        natural_frequency_hz: float | None = None,
        **layout: Any,
    ) -> dict[str, Any]:
        """Read a recording file (any registered format) and predict it with this model.

        :func:`predict_recording`: f_n from the argument, else the sidecar
        ``<recording>.json``, else a one-line refusal; `layout` takes ``columns``,
        ``time_unit``, ``channel`` and ``sensor``.
        """
        return predict_recording(path, fs_hz=fs_hz, natural_frequency_hz=natural_frequency_hz,
                                 predictor=self, **layout)  # fmt: skip

    def _rates(
        self, fs_hz: Any, natural_frequency_hz: Any, natural_frequency_source: str | None
    ) -> tuple[float, float, str]:
        """Sampling rate, natural frequency and where the latter came from (range-checked)."""
        fs = sampling_rate(fs_hz)  # physical ranges (stiffnet.inputs)
        if natural_frequency_hz is not None:
            return (
                fs,
                natural_frequency(natural_frequency_hz),
                natural_frequency_source or "argument",
            )
        raise StiffnetError(fn_unknown())

    def _windows(
        self, a: np.ndarray, fs: float, fn: float, what: str, warnings: list[str]
    ) -> tuple[np.ndarray, np.ndarray, int, int]:
        """The log's sliding windows of the recording: starts, which vary, length, hop.

        One set of windows serves the recording's estimate and its layers
        (:func:`serving.log.record_layers`): the model reads each window once.
        Constant windows are dropped (warned).
        """
        n_win = window_length(fs, fn, self.window_periods)
        hop = hop_samples(DEFAULT_HOP_S, fs)  # the log's, which replays these windows
        starts = window_starts(a.size, n_win, hop)
        ok = varying_windows(a, starts, n_win)
        if not ok.all():
            if not ok.any():
                raise StiffnetError(f"{what}: every window is constant")
            warnings.append(f"{int((~ok).sum())} constant window(s) skipped")
        return starts, ok, n_win, hop

    def _run_model(
        self,
        a: np.ndarray,
        starts: np.ndarray,
        n_win: int,
        fs: float,
        fn: float,
        geometric_windows: int | None = None,
    ) -> tuple[dict[str, np.ndarray], np.ndarray, list]:
        """Per-window model outputs (by ONNX output name), inclination features, geometric results.

        The windows are the `n_win` samples of `a` at `starts` (none constant), cut
        at most :data:`BATCH` windows and :data:`CHUNK_SAMPLES` samples at a time, so that
        memory stays bounded on long records and at high rates. The
        model's family picks the windows whose inclination features are computed
        (those of the geometric cross-check, at most `geometric_windows`, default the
        predictor's; 0 for none, as along the log) and builds the ONNX input.
        """
        from stiffnet.features import features_and_estimate

        family = self.model.family
        gw = self.geometric_windows if geometric_windows is None else geometric_windows
        idx = np.asarray(family.feature_windows(len(starts), gw), dtype=np.int64)
        rows, geo = [], []
        for i in idx:
            f, est = features_and_estimate(a[starts[i] : starts[i] + n_win], fs, fn,
                                           calibration=self.calibration)  # fmt: skip
            rows.append(f)
            geo.append(est)
        feats = np.array(rows).reshape(len(rows), -1) if rows else np.empty((0, 0))
        sess, name = self.model.session, self.model.input_name
        wanted = [o for o in MODEL_OUTPUTS if o in self.model.output_names]
        parts: dict[str, list[np.ndarray]] = {o: [] for o in wanted}
        step = np.arange(n_win)[None, :]
        per_call = max(1, min(BATCH, CHUNK_SAMPLES // n_win))
        for lo in range(0, len(starts), per_call):
            chunk = starts[lo : lo + per_call]
            X = family.model_input(a[chunk[:, None] + step], fs, fn,
                                   feats[(idx >= lo) & (idx < lo + per_call)])  # fmt: skip
            for o, v in zip(wanted, sess.run(wanted, {name: X}), strict=True):
                parts[o].append(v)
        out = {o: np.concatenate(v).astype(np.float64) for o, v in parts.items()}
        for o in ("log_beta", "log_beta_scale"):
            if o in out:
                out[o] = out[o].reshape(-1)
        return out, feats, geo


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
    channel: str | int | None = None,
    sensor: dict | None = None,
    sensor_fitted: bool = False,
    natural_frequency_source: str | None = None,
    campaign_row: tuple[Path, Any] | None = None,
    find_row: bool = True,
    penetration_dissipation: bool | None = None,
) -> dict[str, Any]:
    """Read a recording file and predict it.

    The natural frequency is, in this order: `natural_frequency_hz`; the
    sidecar ``<recording>.json``'s ``natural_frequency_hz``; else a one-line
    refusal (``natural_frequency_source`` says which; the training data's value is
    never assumed).

    Parameters
    ----------
    path : str or os.PathLike
        A recording of any registered format (:mod:`stiffnet.recordings`).
    fs_hz : float, optional
        Sampling rate (required for a format without one; checked against the file's
        own otherwise).
    natural_frequency_hz : float, optional
        Natural frequency of the rig in Hz.
    model_path : str or Path, optional
        Model to load (ignored when `predictor` is given).
    predictor : Predictor, optional
        An already loaded predictor.
    columns, time_unit : str, optional
        CSV layout, as :func:`stiffnet.recordings.read_recording`.
    channel : str or int, optional
        Channel of a multi-channel file (required when it has several).
    sensor : dict, optional
        The sensor chain's data sheet; default: the sidecar's ``sensor`` entry, if any.
    sensor_fitted : bool, optional
        `sensor` is a campaign's pooled fits, not a data sheet (:meth:`Predictor.predict`).
    natural_frequency_source : str, optional
        Where `natural_frequency_hz` came from (a manifest row, an option), as the result's
        ``natural_frequency_source`` says it; default ``"argument"``.
    campaign_row, find_row
        The recording's campaign row already read (``predict``), and whether to look for
        one (:func:`stiffnet.recordings.sidecar.natural_frequency_of`).
    penetration_dissipation : bool, optional
        Read the restoring-force check's beta with a free ``delta v`` dissipation (a
        campaign whose pooled low-pass was its contacts' dissipation,
        :meth:`Predictor.predict`); None: as the model's learned law asks.

    Returns
    -------
    dict
        As :meth:`Predictor.predict`.
    """
    from stiffnet.recordings import read_recording

    pred = predictor or _cached_load(model_path)
    rec = read_recording(path, fs_hz=fs_hz, channel=channel, columns=columns,
                         time_unit=time_unit)  # fmt: skip
    fn_source = natural_frequency_source or "argument"
    if natural_frequency_hz is None:  # after reading: a bad file is named before a missing f_n
        natural_frequency_hz, fn_source = record_natural_frequency(
            path, None, campaign_row=campaign_row, find_row=find_row
        )
    return pred.predict(
        rec.accel,
        rec.fs_hz,
        natural_frequency_hz=natural_frequency_hz,
        source=rec.source,
        natural_frequency_source=fn_source,
        sensor=sensor if sensor is not None else sidecar_sensor(path),
        sensor_fitted=sensor_fitted and sensor is not None,
        penetration_dissipation=penetration_dissipation,
    )

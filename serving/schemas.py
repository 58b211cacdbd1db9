"""Pydantic models of the predictor's output and of the HTTP request (the OpenAPI schema)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class ModelInfo(BaseModel):
    """Identity of the model that produced a prediction."""

    name: str = Field(description="File stem of the model (cnn, gbm).")
    sha256: str = Field(description="SHA-256 of the ONNX file (verified against its card).")
    kind: str = Field(description="Model family: cnn or gbm.")


class GeometricCheck(BaseModel):
    """The paper's geometric inclination method on the same recording (the cross-check)."""

    model_config = ConfigDict(populate_by_name=True)

    class_: str = Field(alias="class", description="Class from the calibrated inclinations.")
    beta: float | None = Field(description="Geometric beta; null without contact.")
    inclination_before_deg: float | None = Field(
        description="Mean inclination of the free-flight plane (polynomial approach)."
    )
    inclination_after_deg: float | None = Field(
        description="Mean inclination of the contact plane (polynomial approach)."
    )
    contact_detected: bool = Field(description="Contact in at least half the checked windows.")
    n_windows: int = Field(description="Windows the geometric method analysed.")
    n_windows_with_contact: int
    polarity: int = Field(description="-1: impact spikes point down, +1: up, 0: no contact.")


class RestoringForceCheck(BaseModel):
    """The restoring-force (force-state mapping) estimate on the same recording."""

    model_config = ConfigDict(populate_by_name=True)

    class_: str | None = Field(
        alias="class", description="Class of the restoring-force beta; no_contact; null if refused."
    )
    beta: float | None = Field(description="Contact over free-flight stiffness of the fitted map.")
    beta_interval: list[float] | None = Field(description="Bootstrap interval over impacts.")
    reading_interval: list[float] | None = Field(
        default=None,
        description="A stiffening law's own bootstrap interval, before beta_interval spans the "
        "linear springs it stands for; what the model's interval is judged against.",
    )
    beta_interval_coverage: float | None = None
    contact_damping_ratio: float | None = Field(
        default=None, description="Kelvin-Voigt damping ratio of the contact."
    )
    exponent: float | None = Field(default=None, description="Contact exponent (1 linear).")
    penetration_over_table: float | None = Field(
        default=None,
        description="The impacts' median peak penetration (where beta is the secant) over the "
        "table's displacement amplitude at the forcing frequency (gain-free).",
    )
    impact_onsets: dict[str, float] | None = Field(
        default=None,
        description="The contact law refitted with an onset per impact: exponent, r2, "
        "onset_spread (over the reference penetration), n_impacts, and with Hunt-Crossley's "
        "dissipation on the elastic force dissipation_r2, dissipation_share.",
    )
    n_impacts: int | None = None
    contact_r2: float | None = Field(default=None, description="Goodness of the contact law.")
    duration_ratio: float | None = Field(
        default=None, description="Impact duration over the fitted law's half period."
    )
    samples_per_contact: float | None = Field(
        default=None, description="Median samples in contact per impact."
    )
    highpass_hz: float | None = Field(
        default=None, description="Sensor high-pass corner fitted and undone (0: none)."
    )
    resonance_hz: float | None = Field(
        default=None, description="Accelerometer mount resonance divided out (null: none seen)."
    )
    sensor: dict[str, Any] | None = Field(
        default=None,
        description="Sensor chain undone before the map (fitted from the impacts or the data "
        "sheet's): resonance_hz, resonance_damping, lowpass_hz, lowpass_order, highpass_hz, "
        "source, applied, intervals (90 %), contact_hz.",
    )
    chain_contact_ratio: list[float] | None = Field(
        default=None,
        description="A fitted chain's contact pulse frequency (sensor.contact_hz) over the "
        "fitted law's f_n sqrt(1 + beta), [low, high] over both 90 % intervals; null without "
        "a fitted resonance or low-pass.",
    )
    dissipation_gain: float | None = Field(
        default=None, description="Share of the contact law's misfit a delta*v term removes."
    )
    dissipation_share: float | None = Field(
        default=None, description="Share of the contact's dissipation that delta*v term carries."
    )
    law_shape: dict[str, float] | None = Field(
        default=None,
        description="Held-out-impact gain of a richer contact law's terms over the linear/Hertz "
        "Kelvin-Voigt law: curvature, penetration_dissipation (each with its _share); stage "
        "(a two-stage law's gain), stage_ratio (its stiffness ratio across the knee), "
        "stage_knee (the knee over the reference penetration); toe (the median force on the "
        "samples just outside each impact over the free flight's scatter: a soft first stage), "
        "toe_least_side and toe_damped_step (the fitted law's damping force on each impact's "
        "first in-contact sample, same unit: a damped step an undone chain rings before the "
        "onset); where a fitted low-pass barely helped the law, the record as recorded: "
        "recorded_penetration_dissipation (with its _share) and recorded_r2_loss; misfit, "
        "n_impacts.",
    )
    impact_peaks: dict[str, float] | None = Field(
        default=None,
        description="Whether the contact force rises more than once within an impact (a "
        "restraint that rings: stiffnet.uncertainty.restraint_dynamics): second_peak (the "
        "median over impacts of the second-largest peak prominence over the impact's peak "
        "force; 0: one peak per impact, as every law of the training world gives), "
        "second_peak_impacts (the share of impacts at or above the alarm's threshold), "
        "n_impacts; null where the impacts are too few or too short to judge.",
    )
    stage: dict[str, Any] | None = Field(
        default=None,
        description="Where the model was trained with a learned two-stage law: beta is that "
        "law's first-stage slope, fitted with its stage ratio held (ratio) and the knee free; "
        "resolved (the map shows the knee; false: one slope, read as impacts short of the "
        "knee), knee_fraction (the knee over the median peak penetration), r2, "
        "beyond_knee_interval (not resolved: beta's interval had every impact been beyond "
        "the knee, the slope over the ratio, which the map cannot exclude).",
    )
    hunt_crossley: dict[str, Any] | None = Field(
        default=None,
        description="Where the model was trained with a learned law whose dissipation grows "
        "with penetration (Hunt-Crossley): beta is that law's elastic slope at first contact, "
        "fitted with its delta*v term free; onset (map units), dissipation_share (the delta*v "
        "term's share of the dissipation at the reference penetration), r2.",
    )
    reason: str = Field(description="What was estimated, or why not.")


class Segment(BaseModel):
    """Aggregate over consecutive windows: a change of formation shows as a change here."""

    model_config = ConfigDict(populate_by_name=True)

    index: int
    start_s: float
    end_s: float
    n_windows: int
    class_: str = Field(alias="class")
    class_decided_by: Literal["class_head", "beta_head"] = Field(
        default="class_head",
        description="Which head named the class: class_head (arg-max of probabilities) or "
        "beta_head (beta lies in a neighbouring class near their edge and the class head's top "
        "probability is not decisive; configs/class_decision.yaml, per model family).",
    )
    probabilities: dict[str, float]
    beta: float | None


class Layer(BaseModel):
    """A stretch of the record with one beta (a change point on each side)."""

    model_config = ConfigDict(populate_by_name=True)

    index: int
    start_s: float = Field(description="Start (s): the change point before it (0: the start).")
    start_sd_s: float = Field(description="Uncertainty of start_s (s; 0 at the record's start).")
    end_s: float
    end_sd_s: float
    class_: str = Field(alias="class", description="Class of the layer's beta (hysteresis).")
    near_edge: bool = Field(description="Beta lies within 10 % of a class edge.")
    beta: float | None = Field(description="exp(mean log beta) over the layer's windows.")
    beta_interval: list[float] | None
    n_points: int = Field(description="Windows (points of the log, hop 0.5 s) in the layer.")
    alarm_fraction: float = Field(description="Share of the layer's windows with the alarm.")
    drift: dict[str, float] | None = Field(
        default=None,
        description="Where log beta trends along the layer (a gradual transition, not one "
        "beta): from_s, to_s, from_beta, to_beta of the fitted line; null where it does not.",
    )


class AlarmResult(BaseModel):
    """The unreliability alarm: checks on what the model looks at (``stiffnet.uncertainty``)."""

    flag: bool = Field(description="Some check exceeded its threshold: do not trust the result.")
    fired: list[str] = Field(description="The checks that exceeded their thresholds.")
    scores: dict[str, float | None] = Field(
        description="Each check's score: embedding (distance of the windows to the training "
        "data in the model's embedding), ambiguity (1 - top class probability), "
        "beta_uncertainty (scale of the log-beta error), features (inclination-feature OOD), "
        "restoring_force (log-gap between the model's and the restoring-force beta intervals; "
        "fires above 0, i.e. when they are disjoint)."
    )
    thresholds: dict[str, float] = Field(
        description="Thresholds calibrated on in-distribution trajectories (restoring_force: 0)."
    )
    message: str = Field(description="The verdict in words.")


class PredictionResult(BaseModel):
    """Prediction for one recording (``stiffnet predict``, ``POST /predict``)."""

    model_config = ConfigDict(populate_by_name=True)

    source: str = Field(description="Where the samples came from.")
    class_: str = Field(alias="class", description="Predicted stiffness class.")
    class_decided_by: Literal["class_head", "beta_head"] = Field(
        default="class_head",
        description="Which head named the class: class_head (arg-max of probabilities) or "
        "beta_head (beta lies in a neighbouring class near their edge and the class head's top "
        "probability is not decisive; configs/class_decision.yaml, per model family).",
    )
    probabilities: dict[str, float] = Field(description="Mean of the per-window probabilities.")
    beta: float | None = Field(description="exp(mean per-window log beta); null for no_contact.")
    beta_interval: list[float] | None = Field(
        description="[lo, hi]: split-conformal interval around beta, calibrated per "
        "recording (one normalised score per trajectory) for models that carry it."
    )
    beta_interval_coverage: float | None = Field(
        description="Nominal coverage of beta_interval over recordings like the training data."
    )
    geometric: GeometricCheck
    agreement: bool = Field(description="Model class == geometric class.")
    restoring_force: RestoringForceCheck
    restoring_force_class: str | None = Field(
        description="restoring_force.class, at the top level."
    )
    restoring_force_beta: float | None = Field(
        description="restoring_force.beta, at the top level."
    )
    restoring_force_beta_interval: list[float] | None
    restoring_force_agreement: bool | None = Field(
        description="Model class == restoring-force class; null when that method refused."
    )
    chain_undone: dict[str, Any] | None = Field(
        default=None,
        description="The sensor-chain stages the model read divided out of the record "
        "(resonance_hz, resonance_damping, lowpass_hz, lowpass_order, highpass_hz, source: "
        "fitted, campaign or data sheet; serving.chain_undo); null where it read the record "
        "as recorded. The chain itself is restoring_force.sensor.",
    )
    chain_readings: list[dict[str, Any]] | None = Field(
        default=None,
        description="Where the chain undone was fitted (not a data sheet): the model's class, "
        "beta and beta interval read through each other chain the fit allows (chain: as "
        "recorded, a lower low-pass corner; serving.chain_spread); beta_interval spans them, "
        "and the chain_class alarm fires where one lands in another class. Null otherwise.",
    )
    contact_detected: bool = Field(description="The model's class is not no_contact.")
    ood_score: float | None = Field(
        description="The alarm's largest check score relative to its threshold "
        "(max over checks of score / threshold); above ood_threshold the alarm fires."
    )
    ood_threshold: float | None
    ood_flag: bool = Field(description="The alarm fired: the prediction is unreliable.")
    alarm: AlarmResult | None = Field(description="The alarm's checks; null without a reference.")
    n_windows: int = Field(description="Windows the model predicted (and aggregated).")
    window_s: float
    hop_s: float
    duration_s: float
    fs_hz: float
    segments: list[Segment]
    layers: list[Layer] = Field(
        default_factory=list,
        description="Stretches of constant beta (change points of stiffnet log); more "
        "than one fires the alarm's 'layers' check: the overall beta is then a blend.",
    )
    model: ModelInfo
    natural_frequency_hz: float
    natural_frequency_source: str = Field(
        description="option / argument / request / sidecar:<path> / manifest:<manifest>: line N "
        "(<recording>) (predict on a recording its campaign's manifest lists)"
    )
    warnings: list[str]


class LogLayer(Layer):
    """A layer of the stiffness log, with its share of alarms and restoring-force checks."""

    beta_interval_coverage: float | None = None
    probabilities: dict[str, float]
    n_pooled: int = Field(description="Points pooled into beta (mixed windows left out).")
    alarm: bool = Field(description="The alarm fired on more than half of its windows.")
    restoring_force: dict[str, Any] = Field(
        description="The restoring-force checks inside the layer: median beta and interval, "
        "class, agreement with the layer, or why there is none."
    )


class LogPoint(BaseModel):
    """One window of the log (its centre ``t_s``)."""

    model_config = ConfigDict(populate_by_name=True)

    t_s: float
    class_: str = Field(alias="class")
    beta: float | None
    beta_interval: list[float] | None = Field(description="Per-window conformal interval.")
    near_edge: bool
    alarm: bool
    alarm_fired: list[str]
    restoring_force: dict[str, Any] | None = Field(
        default=None, description="Restoring-force check on this window (every 10 s)."
    )


class LogChange(BaseModel):
    """A change of beta between two layers."""

    model_config = ConfigDict(populate_by_name=True)

    t_s: float
    sd_s: float = Field(description="Uncertainty of the change time (profile likelihood).")
    from_: str = Field(alias="from")
    to: str
    from_beta: float | None
    to_beta: float | None


class LogResult(BaseModel):
    """The stiffness log of a record (``stiffnet log --json``, ``POST /log``)."""

    source: str
    duration_s: float
    fs_hz: float
    natural_frequency_hz: float
    natural_frequency_source: str | None = None
    window_s: float
    hop_s: float
    model: ModelInfo
    n_points: int
    layers: list[LogLayer]
    changes: list[LogChange]
    points: list[LogPoint]
    sensor: dict[str, Any] | None = Field(
        default=None,
        description="The accelerometer chain identified on the record's first 24 natural "
        "periods, or the data sheet's (the restoring-force check's sensor; null: none).",
    )
    chain_undone: dict[str, Any] | None = Field(
        default=None,
        description="The stages divided out of every window the model read, with their source "
        "(data sheet or fitted); null: the record as recorded.",
    )
    chain_readings: list[str] | None = Field(
        default=None,
        description="Behind a fitted chain, the other chains the model also read each window "
        "through; every interval spans those readings (null: none).",
    )
    warnings: list[str]


class PredictRequest(BaseModel):
    """JSON body of ``POST /predict``.

    Strict: numbers are JSON numbers (``true`` is not 1, ``"1000"`` is not 1000) and finite.
    """

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)

    samples: list[float] = Field(description="Acceleration samples (any unit, either sign).")
    fs_hz: float = Field(description="Sampling rate in Hz.")
    natural_frequency_hz: float | None = Field(
        default=None,
        description="Natural frequency of the rig (Hz). Required: without it the request is "
        "refused (the training data's value is never assumed).",
    )
    sensor: dict[str, float] | None = Field(
        default=None,
        description="The accelerometer chain's data sheet (resonance_hz, resonance_damping, "
        "lowpass_hz, lowpass_order, highpass_hz; a stage left out is none): undone as given "
        "instead of fitted from the impacts (POST /log: out of every window).",
    )


class ErrorBody(BaseModel):
    """Every error response: one line."""

    error: str


class HealthResponse(BaseModel):
    """``GET /health``: liveness and load."""

    status: Literal["ok"] = Field(description="Always 'ok' when the server answers.")
    model: str = Field(description="Name of the served model (file stem).")
    sha256: str = Field(description="SHA-256 of the served ONNX file.")
    in_flight: int = Field(ge=0, description="Small predictions running or queued now.")
    large_in_flight: int = Field(
        ge=0, description="Large requests admitted now (reading, waiting or running)."
    )
    served: int = Field(ge=0, description="Predictions answered since start.")


class ServerLimits(BaseModel):
    """The server's limits (``stiffnet serve`` options)."""

    max_upload_mb: float = Field(description="Largest request body in MB (413 beyond).")
    timeout_s: float = Field(description="Per-request time limit in s (504 beyond).")
    max_concurrency: int = Field(description="Predictions running at once.")
    max_queue: int = Field(description="Requests waiting beyond which 429 is returned.")


class ModelResponse(BaseModel):
    """``GET /model``: the served model, the predictor's settings and the server limits."""

    # fields the predictor adds later still reach clients (documented once added here)
    model_config = ConfigDict(extra="allow")

    name: str = Field(description="File stem of the model (cnn, gbm).")
    sha256: str = Field(description="SHA-256 of the ONNX file (verified against its card).")
    kind: str = Field(description="Model family: cnn or gbm.")
    class_names: list[str] = Field(description="Output classes, in the model's column order.")
    window_periods: float = Field(description="Natural periods per model window.")
    min_samples_per_natural_period: float = Field(
        description="Lowest accepted fs / f_n (the sampling-rate floor)."
    )
    training_natural_frequency_hz: float | None = Field(
        description="f_n of the training data (information only: never assumed for a request)."
    )
    segment_windows: int = Field(description="Windows aggregated per reported segment.")
    geometric_windows: int = Field(description="Windows the geometric cross-check analyses.")
    ood_reference: bool = Field(description="An OOD reference is loaded (ood_score is set).")
    ood_threshold: float | None = Field(description="OOD alarm threshold; null without one.")
    metadata: dict[str, Any] = Field(description="The ONNX file's metadata_props, decoded.")
    limits: ServerLimits

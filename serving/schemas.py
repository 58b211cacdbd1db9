"""Pydantic models of the predictor's output and of the HTTP request (the OpenAPI schema)."""

from __future__ import annotations

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


class Segment(BaseModel):
    """Aggregate over consecutive windows: a change of formation shows as a change here."""

    model_config = ConfigDict(populate_by_name=True)

    index: int
    start_s: float
    end_s: float
    n_windows: int
    class_: str = Field(alias="class")
    probabilities: dict[str, float]
    beta: float | None


class PredictionResult(BaseModel):
    """Prediction for one recording (``stiffnet predict``, ``POST /predict``)."""

    model_config = ConfigDict(populate_by_name=True)

    source: str = Field(description="Where the samples came from.")
    class_: str = Field(alias="class", description="Predicted stiffness class.")
    probabilities: dict[str, float] = Field(description="Mean of the per-window probabilities.")
    beta: float | None = Field(description="exp(mean per-window log beta); null for no_contact.")
    beta_interval: list[float] | None = Field(
        description="[lo, hi]: split-conformal interval of the model card around beta."
    )
    beta_interval_coverage: float | None = Field(
        description="Nominal per-window coverage of beta_interval."
    )
    geometric: GeometricCheck
    agreement: bool = Field(description="Model class == geometric class.")
    contact_detected: bool = Field(description="The model's class is not no_contact.")
    ood_score: float | None = Field(
        description="Median over the scored windows of the smallest class-conditional "
        "Mahalanobis distance of the inclination features to the training data."
    )
    ood_threshold: float | None
    ood_flag: bool = Field(description="ood_score > ood_threshold: unlike the training data.")
    n_windows: int = Field(description="Windows the model predicted (and aggregated).")
    window_s: float
    hop_s: float
    duration_s: float
    fs_hz: float
    segments: list[Segment]
    model: ModelInfo
    natural_frequency_hz: float
    natural_frequency_source: str = Field(
        description="option / argument / request / sidecar:<path> / training_data"
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
        default=None, description="Natural frequency of the rig; default: the training data's."
    )


class ErrorBody(BaseModel):
    """Every error response: one line."""

    error: str

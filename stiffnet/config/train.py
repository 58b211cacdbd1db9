"""Configuration of model training (``configs/train/*.yaml``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from stiffnet.config.window import CANONICAL_RATE, DELAY_FRACTION, WINDOW_PERIODS


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class GBMConfig(_Strict):
    """Hyper-parameters shared by the HistGradientBoosting classifier and regressor."""

    learning_rate: float = Field(0.05, gt=0.0, le=1.0)
    max_iter: int = Field(
        500, ge=1, le=10_000, description="upper bound; early stopping ends sooner"
    )
    max_leaf_nodes: int = Field(31, ge=2, le=1024)
    max_depth: int | None = Field(None, ge=1, le=64)
    min_samples_leaf: int = Field(20, ge=1, le=10_000)
    l2_regularization: float = Field(0.0, ge=0.0, le=1000.0)
    max_bins: int = Field(255, ge=2, le=255)
    early_stopping: bool = True
    validation_fraction: float = Field(
        0.15, gt=0.0, lt=0.5, description="training trajectories held out for early stopping"
    )
    n_iter_no_change: int = Field(20, ge=1, le=1000)
    class_weight: Literal["balanced"] | None = Field(
        "balanced", description="classifier class weights"
    )


class CNNConfig(_Strict):
    """The 1-D CNN on canonical windows (``training/cnn.py``, ``stiffnet.features.windows``)."""

    rate: int = Field(
        CANONICAL_RATE, ge=8, le=256, description="canonical samples per natural period"
    )
    periods: int = Field(
        WINDOW_PERIODS, ge=2, le=128, description="natural periods per canonical window"
    )
    n_channels: int = Field(
        3, ge=1, le=8, description="delay-embedded input channels (delays 0, d, 2d, ...)"
    )
    delay_fraction: float = Field(
        DELAY_FRACTION, gt=0.0, le=1.0, description="embedding delay d in natural periods"
    )
    width: int = Field(48, ge=4, le=256, description="convolution channels")
    n_blocks: int = Field(
        4, ge=1, le=8, description="Conv1d-BN-ReLU blocks (all but the first halve L)"
    )
    kernel_size: int = Field(7, ge=3, le=31)
    dropout: float = Field(0.1, ge=0.0, lt=1.0)
    learning_rate: float = Field(1e-3, gt=0.0, le=1.0)
    weight_decay: float = Field(1e-4, ge=0.0, le=1.0)
    batch_size: int = Field(64, ge=1, le=4096)
    max_epochs: int = Field(40, ge=1, le=10_000)
    patience: int = Field(10, ge=1, le=1000, description="epochs without improvement")
    beta_loss_weight: float = Field(
        1.0, ge=0.0, le=100.0, description="weight of the standardised log-beta MSE"
    )
    validation_fraction: float = Field(
        0.15, gt=0.0, lt=0.5, description="training trajectories held out for early stopping"
    )
    class_weight: Literal["balanced"] | None = Field(
        "balanced", description="cross-entropy class weights"
    )
    max_train_seconds: float | None = Field(
        None,
        gt=0.0,
        description="optional wall-clock limit (best epoch kept); results then depend on speed",
    )


class TrainConfig(_Strict):
    """What ``training/train.py`` trains and how it splits and tracks."""

    model: Literal["gbm", "cnn"] = "gbm"
    seed: int = Field(0, ge=0)
    test_fraction: float = Field(0.2, gt=0.0, lt=0.9, description="trajectories held out for test")
    calibration_fraction: float = Field(
        0.2, gt=0.0, lt=0.9, description="trajectories held out for conformal calibration"
    )
    coverage: float = Field(0.9, gt=0.0, lt=1.0, description="target beta interval coverage")
    alarm_checks: list[Literal["embedding", "ambiguity", "beta_uncertainty", "class_edge"]] = Field(
        ["embedding", "ambiguity"],
        min_length=1,
        description="the alarm's checks (stiffnet.uncertainty.alarm); those the model "
        "cannot compute (embedding for the GBM) are left out. Each check spends part of "
        "the false-alarm budget: on the shipped CNN's test trajectories these two kept "
        "4.5 % in-distribution flags, all four 6.2 % (docs/model_benchmark.md)",
    )
    alarm_false_alarm: float = Field(
        0.04,
        gt=0.0,
        lt=0.5,
        description="fraction of in-distribution (calibration) recordings the alarm may flag",
    )
    use_natural_frequency: bool = Field(
        True, description="feature period_natural needs f_n at prediction time"
    )
    noise_bins: list[float] = Field(
        [0.0, 0.02, 0.05, 0.09],
        min_length=1,
        description="noise levels: exactly the first, then (prev, edge] bins, then > last",
    )
    n_jobs: int = Field(1, ge=-1, le=256, description="feature-extraction processes (-1: all)")
    gbm: GBMConfig = Field(default_factory=GBMConfig)
    cnn: CNNConfig = Field(default_factory=CNNConfig)
    tracking: bool = Field(True, description="log the run to MLflow")
    tracking_uri: str = Field("sqlite:///mlflow.db", min_length=1)
    experiment: str = Field("stiffnet-gbm", min_length=1)

    @model_validator(mode="after")
    def _check(self) -> TrainConfig:
        if self.test_fraction + self.calibration_fraction >= 0.9:
            raise ValueError("test_fraction + calibration_fraction must be < 0.9")
        if any(b <= a for a, b in zip(self.noise_bins, self.noise_bins[1:], strict=False)):
            raise ValueError("noise_bins must be increasing")
        if self.n_jobs == 0:
            raise ValueError("n_jobs must be -1 or >= 1")
        return self

"""The 1-D CNN family's section of the training config (``cnn:`` in YAML)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from stiffnet.config.window import CANONICAL_RATE, DELAY_FRACTION, WINDOW_PERIODS


class CNNConfig(BaseModel):
    """The 1-D CNN on canonical windows (``network.py`` here, ``stiffnet.features.windows``)."""

    model_config = ConfigDict(extra="forbid")

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

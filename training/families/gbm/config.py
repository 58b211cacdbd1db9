"""The gradient-boosting family's section of the training config (``gbm:`` in YAML)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field


class GBMConfig(BaseModel):
    """Hyper-parameters shared by the HistGradientBoosting classifier and regressor."""

    model_config = ConfigDict(extra="forbid")

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

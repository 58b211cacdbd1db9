"""Configuration of model training (``configs/train/FAMILY.yaml``).

:class:`TrainConfig` holds what every family shares (splits, interval coverage, the
alarm, noise bins, tracking) and names the family (``model:``, or ``family:``). Each
registered family (:mod:`training.families`) owns its own section, a pydantic model
under its name (``gbm:``, ...): the config validates every section it is given
against its family's model and fills in the defaults of the others, so a new family
adds a section without editing this module.
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import AliasChoices, BaseModel, ConfigDict, Field, ValidationError, model_validator

from stiffnet.config import validation_message


class TrainConfig(BaseModel):
    """What :func:`training.train.train` trains and how it splits and tracks.

    Besides the fields below, one attribute per registered family holds its
    section (``config.gbm``, ...; :attr:`section` is the trained family's).
    """

    # the family sections are the only extra fields (checked in _sections)
    model_config = ConfigDict(extra="allow")

    model: str | None = Field(
        None,
        validation_alias=AliasChoices("model", "family"),
        description="the model family to train (training.families); default: the one "
        "whose section alone is given, else the registry's default for `train`",
    )
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
    undo_chain: str | None = Field(
        None,
        description="which identified sensor chain the predictor divides out of a record "
        "before this model reads it (one of serving.chain_undo.UNDO_MODES; written to the "
        "card); none: the predictor's default. A model trained behind a campaign's own fitted "
        "chain (the loop's) reads it as recorded: 'outside_priors'",
    )
    tracking: bool = Field(True, description="log the run to MLflow")
    tracking_uri: str = Field("sqlite:///mlflow.db", min_length=1)
    experiment: str | None = Field(
        None, min_length=1, description="MLflow experiment (default: stiffnet-FAMILY)"
    )
    registered_model: str | None = Field(
        None,
        max_length=200,
        description="MLflow Model Registry name the trained model is registered under "
        "(default: stiffnet-FAMILY; an empty string registers nothing)",
    )

    @model_validator(mode="before")
    @classmethod
    def _sections(cls, data: Any) -> Any:
        """Validate the family sections given, fill in the others, name the family."""
        from training.families import default_family, families

        if not isinstance(data, dict):
            return data
        known = families()
        data = dict(data)
        for key in set(data) - set(cls.model_fields) - {"family"} - set(known):
            raise ValueError(
                f"unknown field {key!r} (a family section must name one of {sorted(known)})"
            )
        given = [name for name in known if name in data]
        if data.get("model") and data.get("family") and data["model"] != data["family"]:
            raise ValueError(f"model: {data['model']} and family: {data['family']} disagree")
        name = data.get("model") or data.get("family")
        if name is None:
            name = given[0] if len(given) == 1 else default_family("train").name
            data["model"] = name
        if name not in known:
            raise ValueError(f"model family {name!r} is not available: use {' or '.join(known)}")
        for key, family in known.items():
            section = data.get(key) or {}
            if isinstance(section, BaseModel):
                section = section.model_dump()
            try:
                data[key] = family.config.model_validate(section)
            except ValidationError as exc:
                raise ValueError(f"{key}.{validation_message(exc)}") from None
        return data

    @model_validator(mode="after")
    def _check(self) -> TrainConfig:
        if self.test_fraction + self.calibration_fraction >= 0.9:
            raise ValueError("test_fraction + calibration_fraction must be < 0.9")
        if any(b <= a for a, b in zip(self.noise_bins, self.noise_bins[1:], strict=False)):
            raise ValueError("noise_bins must be increasing")
        if self.n_jobs == 0:
            raise ValueError("n_jobs must be -1 or >= 1")
        if self.undo_chain is not None:
            from serving.chain_undo import UNDO_MODES

            if self.undo_chain not in UNDO_MODES:
                raise ValueError(f"undo_chain must be one of {', '.join(UNDO_MODES)}")
        if self.experiment is None:
            self.experiment = f"stiffnet-{self.model}"
        if self.registered_model is None:
            self.registered_model = f"stiffnet-{self.model}"
        return self

    @property
    def family(self) -> Any:
        """The trained family (:class:`training.families.base.TrainingFamily`)."""
        from training.families import get_family

        return get_family(str(self.model))

    @property
    def section(self) -> BaseModel:
        """The trained family's section of the config."""
        return getattr(self, str(self.model))

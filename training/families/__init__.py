"""The registry of model families (pysindy style: :mod:`.base` plus one package per family).

Every package in this folder whose ``__init__`` defines a
:class:`~training.families.base.TrainingFamily` subclass is a family, found by
name; adding a family is adding a package (with its serving module in
``serving/families/`` and its ``configs/train/NAME.yaml``), nothing else.
A family defined elsewhere joins with :func:`register_family`. The training
command, the measurement loop and recalibration list families from here.
"""

from __future__ import annotations

from serving.families import register as register_serving
from stiffnet.errors import StiffnetError
from stiffnet.plugins import discover, once
from training.families.base import TrainedModel, TrainingFamily

_FAMILIES: dict[str, type[TrainingFamily]] = {}


def register_family(cls: type[TrainingFamily]) -> type[TrainingFamily]:
    """Add a family (and its serving half) to the registry; usable as a class decorator."""
    cls.check()
    known = _FAMILIES.get(cls.name)
    if known is not None and known is not cls:
        raise ValueError(f"model family {cls.name!r} is already registered ({known.__module__})")
    _FAMILIES[cls.name] = cls
    register_serving(cls.serving)
    return cls


@once
def _discover() -> None:
    for cls in discover(__name__, TrainingFamily, packages_only=True):  # a family is a folder
        register_family(cls)


def families() -> dict[str, type[TrainingFamily]]:
    """Every registered family by name (the packages here first, then plugins)."""
    _discover()
    return dict(_FAMILIES)


def get_family(name: str) -> TrainingFamily:
    """The family ``name`` (an instance); a one-line error naming those available."""
    known = families()
    if name not in known:
        raise StiffnetError(f"model family {name!r} is not available: use {' or '.join(known)}")
    return known[name]()


def family_for_model(model_kind: object) -> TrainingFamily:
    """The family whose models carry the ONNX metadata ``model_kind``."""
    for cls in families().values():
        if cls.serving.model_kind == model_kind:
            return cls()
    raise StiffnetError(f"model_kind {model_kind!r} is not a registered model family's")


def default_family(command: str) -> TrainingFamily:
    """The family ``command`` (``train``, ``loop``) trains when none is named."""
    found = [cls for cls in families().values() if command in cls.defaults]
    if len(found) != 1:
        raise StiffnetError(
            f"{len(found)} model families are the default of {command!r}: name one with --family"
        )
    return found[0]()


__all__ = [
    "TrainedModel",
    "TrainingFamily",
    "default_family",
    "families",
    "family_for_model",
    "get_family",
    "register_family",
]

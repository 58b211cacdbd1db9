"""Model families the predictor serves (pysindy style: :mod:`.base` plus one module per family).

Every :class:`~serving.families.base.ModelFamily` subclass defined in a module of
this package is registered by its ``model_kind`` metadata; a family defined
elsewhere (a plugin, a test; :func:`training.families.register_family` does it
for a family's serving half) joins with :func:`register`. The predictor finds a
model's family here and holds no branch per family.
"""

from __future__ import annotations

from serving.families.base import ModelFamily
from stiffnet.plugins import discover, once

_FAMILIES: dict[str, type[ModelFamily]] = {}


def register(cls: type[ModelFamily]) -> type[ModelFamily]:
    """Serve models whose ``model_kind`` metadata is ``cls.model_kind`` with `cls`."""
    known = _FAMILIES.get(cls.model_kind)
    if known is not None and known is not cls:
        raise ValueError(f"model_kind {cls.model_kind!r} is already served by {known.__name__}")
    _FAMILIES[cls.model_kind] = cls
    return cls


@once
def _discover() -> None:
    for cls in discover(__name__, ModelFamily):
        if "model_kind" in vars(cls):  # a family names its own kind (a helper subclass may not)
            register(cls)


def families() -> dict[str, type[ModelFamily]]:
    """Every served family by its ``model_kind``."""
    _discover()
    return dict(_FAMILIES)


def family_for(model_kind: object) -> type[ModelFamily] | None:
    """The family serving models with this ``model_kind`` (None if none does)."""
    return families().get(str(model_kind))


__all__ = ["ModelFamily", "families", "family_for", "register"]

"""Find effects by canonical name or by ``"package.module:ClassName"``."""

from __future__ import annotations

import importlib
from collections.abc import Iterable, Mapping
from typing import Any

from stiffnet.effects.base import Effect
from stiffnet.errors import ConfigError

#: Canonical names of the shipped effects and where they live.
CANONICAL: dict[str, str] = {
    "contact_damping": "stiffnet.effects.contact_damping:ContactDamping",
    "hertz_contact": "stiffnet.effects.hertz_contact:HertzContact",
    "restraint_mass": "stiffnet.effects.restraint_mass:RestraintMass",
    "learned_contact": "stiffnet.effects.learned_contact:LearnedContact",
    "forcing_harmonics": "stiffnet.effects.forcing_harmonics:ForcingHarmonics",
    "gap_drift": "stiffnet.effects.gap_drift:GapDrift",
    "dry_friction": "stiffnet.effects.dry_friction:DryFriction",
    "sensor_dynamics": "stiffnet.effects.sensor_dynamics:SensorDynamics",
    "colored_noise": "stiffnet.effects.colored_noise:ColoredNoise",
    "adc": "stiffnet.effects.adc:ADC",
}


def effect_class(name: str) -> type[Effect]:
    """The effect class for a canonical name or a ``module.path:ClassName`` string."""
    target = CANONICAL.get(name, name)
    if ":" not in target:
        known = ", ".join(CANONICAL)
        raise ConfigError(f"unknown effect {name!r}: use one of {known} or 'module.path:ClassName'")
    module_name, _, cls_name = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(
            f"effect {name!r}: cannot import module {module_name!r} ({exc})"
        ) from None
    cls = getattr(module, cls_name, None)
    if not (isinstance(cls, type) and issubclass(cls, Effect)) or cls.kind not in (
        "dynamics",
        "measurement",
    ):
        raise ConfigError(
            f"effect {name!r}: {cls_name!r} in {module_name!r} is not a DynamicsEffect or "
            "MeasurementEffect subclass"
        )
    return cls


def build_effect(name: str, params: Mapping[str, Any] | None = None) -> Effect:
    """Instantiate an effect, validating its parameters."""
    return effect_class(name)(**dict(params or {}))


def parse_effect_option(text: str) -> tuple[str, dict[str, Any]]:
    """Parse the CLI form ``NAME[:k=v,k=v]`` (a value ``lo..hi`` is a range).

    A user class path contains a colon too: ``pkg.mod:Class:k=v``.
    """
    head, _, tail = text.rpartition(":")
    if "=" not in tail:  # no parameters: the whole text names the effect
        head, tail = text, ""
    params: dict[str, Any] = {}
    for item in filter(None, tail.split(",")):
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"effect option {text!r}: expected NAME[:key=value,...]")
        try:
            if ".." in value:
                lo, hi = value.split("..", 1)
                params[key.strip()] = [float(lo), float(hi)]
            else:
                params[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"effect option {text!r}: {key}={value!r} is not a number") from None
    return head, params


def available_effects() -> Iterable[type[Effect]]:
    """The shipped effect classes, in canonical order."""
    return [effect_class(name) for name in CANONICAL]

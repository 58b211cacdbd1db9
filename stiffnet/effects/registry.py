"""Find effects by canonical name, by entry point, or by ``module:ClassName`` of a plugin.

A name resolves only to

* a shipped effect (:data:`CANONICAL`),
* an effect an installed package declares in the entry-point group
  :data:`ENTRY_POINT_GROUP` (by its entry-point name or its ``module:Class`` value), or
* a ``module:ClassName`` of a plugin file given explicitly (``stiffnet --plugin FILE``,
  :func:`register_plugin`, or the :data:`PLUGINS_ENV` list, which worker processes
  inherit).

Nothing else is imported: not a module of the working directory (``python -m stiffnet``
puts it on the import path), not an arbitrary installed module (``this:X``). The
name is known to be a stiffnet effect before anything of it runs.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import os
import sys
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

from stiffnet.effects.base import Effect
from stiffnet.errors import ConfigError
from stiffnet.plugins import defined_subclasses

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

#: Entry-point group in which installed packages declare their effects
#: (``[project.entry-points."stiffnet.effects"] my_law = "my_pkg.laws:MyLaw"``).
ENTRY_POINT_GROUP = "stiffnet.effects"
#: Environment variable: plugin files (``PATH`` or ``MODULE=PATH``), separated by ``os.pathsep``.
PLUGINS_ENV = "STIFFNET_PLUGINS"

#: Plugin modules loaded from explicit files: module name -> resolved file.
_PLUGINS: dict[str, Path] = {}


def register_plugin(path: str | os.PathLike[str], module: str | None = None) -> str:
    """Load the effects file ``path`` as module ``module`` (default: the file's stem).

    The file runs now (the user named it); its classes are then known as
    ``module:ClassName``. Returns the module name.
    """
    p = Path(path)
    name = module or p.stem
    if p.suffix != ".py" or not p.is_file():
        raise ConfigError(f"plugin {p}: not a Python file (.py)")
    if not all(part.isidentifier() for part in name.split(".")):
        raise ConfigError(f"plugin {p}: {name!r} is not a module name")
    real = p.resolve()
    if _PLUGINS.get(name) == real:
        return name
    loaded = sys.modules.get(name)
    if loaded is not None:
        if Path(getattr(loaded, "__file__", "") or "").resolve() != real:
            raise ConfigError(f"plugin {p}: module name {name!r} is taken by another module")
    else:
        spec = importlib.util.spec_from_file_location(name, real)
        if spec is None or spec.loader is None:
            raise ConfigError(f"plugin {p}: cannot load it")
        loaded = importlib.util.module_from_spec(spec)
        sys.modules[name] = loaded
        try:
            spec.loader.exec_module(loaded)
        except Exception as exc:  # noqa: BLE001 - the user's code: one line, not a traceback
            del sys.modules[name]
            raise ConfigError(f"plugin {p} failed to load: {type(exc).__name__}: {exc}") from None
    _by_value(loaded)
    _PLUGINS[name] = real
    return name


def plugin_files() -> dict[str, Path]:
    """The plugin files loaded so far: module name -> resolved file (what a page that
    records its provenance must name, since their code shaped the result)."""
    return dict(_PLUGINS)


def _by_value(module: Any) -> None:
    """Dask workers get the plugin's classes by value (they cannot import the file's name)."""
    try:
        import cloudpickle
    except ImportError:  # pragma: no cover - Dask (and cloudpickle) are optional
        return
    try:
        cloudpickle.register_pickle_by_value(module)
    except ValueError:  # pragma: no cover - already registered
        pass


def _environment_plugins() -> None:
    for item in filter(None, os.environ.get(PLUGINS_ENV, "").split(os.pathsep)):
        module, sep, path = item.rpartition("=")
        register_plugin(path, module if sep else None)


@lru_cache(maxsize=1)
def _entry_points() -> dict[str, str]:
    """Installed packages' declared effects: entry-point name -> ``module:Class``."""
    from importlib.metadata import entry_points

    return {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}


def _target(name: str) -> str:
    """``module:Class`` of a known effect name; nothing is imported here."""
    if not isinstance(name, str) or not name or "\x00" in name or len(name) > 200:
        raise ConfigError(f"effect name {str(name)[:60]!r} is not a name")
    if name in CANONICAL:
        return CANONICAL[name]
    declared = _entry_points()
    if name in declared:
        return declared[name]
    if ":" not in name:
        known = ", ".join([*CANONICAL, *declared])
        raise ConfigError(f"unknown effect {name!r}: use one of {known} or a plugin's "
                          "'module:ClassName'")  # fmt: skip
    if name in CANONICAL.values() or name in declared.values():
        return name
    _environment_plugins()
    if name.partition(":")[0] in _PLUGINS:
        return name
    raise ConfigError(
        f"effect {name!r} is not a registered stiffnet effect: load its file with "
        f"'stiffnet --plugin FILE.py' (or ${PLUGINS_ENV}), or install it in the "
        f"'{ENTRY_POINT_GROUP}' entry-point group; nothing was imported"
    )


def effect_class(name: str) -> type[Effect]:
    """The effect class for a canonical name, an entry point or a plugin's ``module:Class``."""
    module_name, _, cls_name = _target(name).partition(":")
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

    A plugin's class path contains a colon too: ``mod:Class:k=v``. Values are finite
    numbers (``nan`` and ``inf`` are refused here, before any work).
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
            numbers = [float(v) for v in value.split("..", 1)]
        except ValueError:
            raise ConfigError(f"effect option {text!r}: {key}={value!r} is not a number") from None
        if not all(map(math.isfinite, numbers)):
            raise ConfigError(f"effect option {text!r}: {key}={value!r} is not a finite number")
        params[key.strip()] = numbers if len(numbers) == 2 else numbers[0]
    return head, params


def check_effect_option(text: str, flag: str = "--effect") -> None:
    """A ``NAME[:k=v,...]`` option names a stiffnet effect and valid values (one line if not)."""
    try:
        name, params = parse_effect_option(text)
        cls = effect_class(name)
        if params:
            cls(**params)
    except ConfigError as exc:
        raise ConfigError(f"{flag}: {exc}") from None


def available_effects() -> Iterable[type[Effect]]:
    """The shipped effect classes, in canonical order."""
    return [effect_class(name) for name in CANONICAL]


def user_effects() -> list[tuple[str, type[Effect]]]:
    """``(name to type, class)`` of the effects beyond the shipped ones.

    The installed packages' entry points, then the classes the loaded plugin files
    define (``module:Class``).
    """
    _environment_plugins()
    found = [(name, effect_class(name)) for name in _entry_points()]
    for module_name in _PLUGINS:
        module = sys.modules.get(module_name)
        for obj in defined_subclasses(module, Effect) if module else ():
            if getattr(obj, "kind", None) in ("dynamics", "measurement"):
                found.append((f"{module_name}:{obj.__name__}", obj))
    return found

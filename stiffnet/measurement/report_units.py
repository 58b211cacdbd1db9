"""Diagnose's fitted values in the campaign's physical units, beside the model's.

The simulator works in the nondimensional units of the paper's eqs (11)-(12):
model time is ``tau = 2 pi f_n t`` (one model time unit is ``1 / (2 pi f_n)`` s),
lengths share one free unit, which a manifest in physical units fixes at 1 mm
(:data:`stiffnet.campaign.manifest.MODEL_LENGTH_MM`; docs/campaign.md, "Physical
units and tolerances"). Each effect declares the unit of each parameter
(:func:`stiffnet.effects.base.param`); a nuisance's unit is its manifest column's.

:func:`physical_reading` is the one conversion the terminal table, the JSON and
the HTML report use: a value in a model unit becomes ``value * factor * T**t * L**l``
with ``T`` the model time unit in s and ``L`` the length unit in mm (exponents per
unit in :data:`MODEL_UNITS`). What needs ``f_n`` stays in model units, said so,
when the manifest does not give ``natural_frequency_hz`` (the simulator then
assumed the paper's 9.48 Hz); what needs a length stays in the model's length
unit when no manifest column is in mm or g. Hz (sensor corners, measured against
the sampling rate), radians, bits and ratios need no scale.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from stiffnet.campaign.manifest import MODEL_LENGTH_MM

#: Manifest columns that fix the model's length unit at 1 mm (an amplitude or gap in mm,
#: or a base acceleration converted through it).
LENGTH_COLUMNS = ("gap_mm", "base_displacement_mm", "base_acceleration_ms2", "base_acceleration_g")

#: Model unit -> (physical unit, exponent of the model time unit, exponent of the length
#: unit, factor). ``""`` is a ratio (dimensionless).
MODEL_UNITS: dict[str, tuple[str, int, int, float]] = {
    "": ("dimensionless", 0, 0, 1.0),
    "Hz": ("Hz", 0, 0, 1.0),
    "rad": ("rad", 0, 0, 1.0),
    "bit": ("bit", 0, 0, 1.0),
    "model length": ("mm", 0, 1, 1.0),
    "model time": ("s", 1, 0, 1.0),
    "natural periods": ("s", 1, 0, 2 * math.pi),
    "f/f_n": ("Hz", -1, 0, 1 / (2 * math.pi)),
    "model time / length": ("s/mm", 1, -1, 1.0),
    "model acceleration": ("m/s²", -2, 1, 1e-3),  # mm/s² -> m/s²
}

#: The unit of each nuisance diagnose profiles (its manifest column's, docs/campaign.md).
NUISANCE_UNITS = {
    "gap": "model length",
    "amplitude": "model length",
    "frequency_ratio": "f/f_n",
    "damping_ratio": "",
    "beta": "",
}


@dataclass(frozen=True)
class Scale:
    """What a campaign's manifest says about the model's units.

    Attributes
    ----------
    natural_frequency_hz : float or None
        ``f_n`` given by the manifest (the same on every row); None: not given, or the
        rows differ (a campaign-wide model value has no single physical value then).
    length_mm : bool
        The manifest fixes the model's length unit at 1 mm (:data:`LENGTH_COLUMNS`).
    frequency_note, length_note : str
        Why a scale is missing (empty when it is known).
    """

    natural_frequency_hz: float | None = None
    length_mm: bool = False
    frequency_note: str = "the manifest gives no natural_frequency_hz"
    length_note: str = "no manifest column is in mm or g"
    frequency_from: str = "the manifest"

    @classmethod
    def of(cls, rows: Sequence[Any]) -> Scale:
        """The scale shared by the manifest rows (one row: that recording's)."""
        given = [r.natural_frequency_hz for r in rows]
        f_n, f_note = None, cls.frequency_note
        if given and all(v is not None for v in given):
            lo, hi = min(given), max(given)
            if math.isclose(lo, hi, rel_tol=1e-9):
                f_n, f_note = float(lo), ""
            else:
                f_note = f"natural_frequency_hz differs between recordings ({lo:g}-{hi:g} Hz)"
        elif any(v is not None for v in given):
            f_note = "natural_frequency_hz is missing on some rows"
        has = [any(getattr(r, c, None) is not None for c in LENGTH_COLUMNS) for r in rows]
        mm = bool(has) and all(has)
        l_note = "" if mm else cls.length_note
        if any(has) and not mm:
            l_note = "only some rows give a length in mm or g"
        return cls(f_n, mm, f_note, l_note, _frequency_from(rows))

    def model_time_s(self) -> float | None:
        """One model time unit in seconds, ``1 / (2 pi f_n)`` (None without ``f_n``)."""
        f_n = self.natural_frequency_hz
        return None if f_n is None else 1.0 / (2 * math.pi * f_n)

    def said(self) -> str:
        """The scale in words (the line under the terminal table, the report's note)."""
        freq = (f"f_n = {self.natural_frequency_hz:g} Hz from {self.frequency_from}: times in s, "
                "frequencies in Hz" if self.natural_frequency_hz is not None else
                f"model units for times and frequencies ({self.frequency_note}; the simulator "
                "assumed the paper's 9.48 Hz)")  # fmt: skip
        length = ("lengths in mm (the manifest's unit)" if self.length_mm
                  else f"model units for lengths ({self.length_note})")  # fmt: skip
        return f"units: {freq}; {length}; ratios dimensionless"

    def as_json(self) -> dict[str, Any]:
        return {
            "natural_frequency_hz": self.natural_frequency_hz,
            "length_unit": "mm" if self.length_mm else "model length",
            "said": self.said(),
        }


def _frequency_from(rows: Sequence[Any]) -> str:
    """Where the rows' f_n was read: the manifest's column, the recordings' sidecars (the
    manifest gave none), or both."""
    sidecar = [bool(getattr(r, "natural_frequency_from_sidecar", False)) for r in rows]
    if sidecar and all(sidecar):
        return "the recordings' sidecars"
    return "the manifest and the recordings' sidecars" if any(sidecar) else "the manifest"


@dataclass(frozen=True)
class Reading:
    """One value in its physical unit (``physical``) or, failing a scale, in its model unit."""

    value: float
    unit: str
    model_value: float
    model_unit: str
    physical: bool

    def text(self) -> str:
        """``237 Hz``, ``0.4 mm``, ``0.25 (dimensionless)``, ``1.2 s (model 94.2 natural
        periods)``, ``12 natural periods (model units)``."""
        v = f"{self.value:.3g}"
        if not self.physical:
            return f"{v} {self.unit} (model units)".replace("  ", " ")
        if self.unit == "dimensionless":
            return f"{v} (dimensionless)"
        said = f"{v} {self.unit}"
        if self.model_unit not in ("", self.unit) and f"{self.model_value:.3g}" != v:
            said += f" (model {self.model_value:.3g} {self.model_unit})"
        return said

    def as_json(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "unit": self.unit,
            "model_value": self.model_value,
            "model_unit": self.model_unit or "dimensionless",
            "in_physical_unit": self.physical,
        }


def physical_reading(value: float, model_unit: str, scale: Scale) -> Reading:
    """A value in the unit it was fitted in, converted to the campaign's physical unit.

    Parameters
    ----------
    value : float
        The model value (the unit of eqs 11-12 the effect or manifest column declares).
    model_unit : str
        Its unit, a key of :data:`MODEL_UNITS`; another unit (a user effect's own) is
        returned as declared, not physical.
    scale : Scale
        The campaign's (or recording's) ``f_n`` and length unit.

    Returns
    -------
    Reading
        ``value * factor * T**t * L**l`` (``T = 1 / (2 pi f_n)`` s, ``L`` = 1 mm) in the
        physical unit, or the model value, ``physical=False``, when a needed scale is missing.
    """
    v = float(value)
    if model_unit not in MODEL_UNITS:
        return Reading(v, model_unit or "dimensionless", v, model_unit, False)
    unit, t, length, factor = MODEL_UNITS[model_unit]
    tau = scale.model_time_s()
    if (t and tau is None) or (length and not scale.length_mm):
        return Reading(v, model_unit, v, model_unit, False)
    phys = v * factor * (tau or 1.0) ** t * MODEL_LENGTH_MM**length
    return Reading(phys, unit, v, model_unit, True)


def parameter_unit(effect: str, name: str) -> str | None:
    """The unit an effect declares for a parameter (None: effect or parameter unknown)."""
    from stiffnet.effects.registry import effect_class
    from stiffnet.errors import StiffnetError

    try:
        field = effect_class(effect).Params.model_fields.get(name)
    except (StiffnetError, ImportError, AttributeError, KeyError, ValueError):
        return None  # a result read back may name an effect this install lacks
    return None if field is None else str((field.json_schema_extra or {}).get("unit", ""))


def fitted_readings(
    effect: str, params: Mapping[str, Any], fitted: Sequence[str] | None, scale: Scale
) -> dict[str, Reading]:
    """The readings of a ranking entry's parameters (those ``fitted``, all when None)."""
    names = [k for k in (params if fitted is None else fitted) if k in params]
    out = {}
    for k in names:
        v = params[k]
        if not isinstance(v, int | float) or isinstance(v, bool):
            continue
        unit = parameter_unit(effect, k)
        out[k] = (
            physical_reading(v, unit, scale)
            if unit is not None
            else Reading(float(v), "unit not declared", float(v), "", False)
        )
    return out


def nuisance_readings(nuisances: Mapping[str, Any], rows: Sequence[Any]) -> dict[str, list]:
    """Each profiled nuisance per recording as readings, each with its own row's scale."""
    out: dict[str, list] = {}
    for name, unit in NUISANCE_UNITS.items():
        values = nuisances.get(name)
        if not isinstance(values, list) or len(values) != len(rows):
            continue
        out[name] = [
            physical_reading(v, unit, Scale.of([r])) if isinstance(v, int | float) else None
            for v, r in zip(values, rows, strict=True)
        ]
    return out


def with_physical_units(diagnosis: dict[str, Any], rows: Sequence[Any]) -> dict[str, Any]:
    """The diagnosis with its values in the campaign's units beside the model's.

    Adds ``units`` (the scale, :meth:`Scale.as_json`), ``params_physical`` to each
    ranking entry (its fitted parameters, :meth:`Reading.as_json`) and
    ``nuisances_physical`` / ``nuisances_effect_free_physical`` (per recording).
    ``rows`` are the campaign's manifest rows (put in the order of the diagnosis'
    ``recordings`` where it lists them).
    """
    by_name = {r.recording: r for r in rows}
    names = diagnosis.get("recordings")
    if isinstance(names, list) and names and all(n in by_name for n in names):
        rows = [by_name[n] for n in names]  # the nuisances are listed in this order
    scale = Scale.of(rows)
    res = dict(diagnosis)
    res["units"] = scale.as_json()
    ranking = []
    for entry in diagnosis.get("ranking") or []:
        if isinstance(entry, dict) and isinstance(entry.get("params"), dict):
            said = fitted_readings(str(entry.get("effect")), entry["params"],
                                   entry.get("fitted"), scale)  # fmt: skip
            entry = {**entry, "params_physical": {k: r.as_json() for k, r in said.items()}}
        ranking.append(entry)
    res["ranking"] = ranking
    for key in ("nuisances", "nuisances_effect_free"):
        nuis = diagnosis.get(key)
        if isinstance(nuis, dict):
            res[f"{key}_physical"] = {
                k: [None if r is None else r.as_json() for r in v]
                for k, v in nuisance_readings(nuis, rows).items()
            }
    return res


def _reading(entry: Any) -> Reading | None:
    """A JSON reading (:meth:`Reading.as_json`) back as a :class:`Reading` (None: malformed)."""
    try:
        model_unit = str(entry.get("model_unit", ""))
        return Reading(float(entry["value"]), str(entry["unit"]), float(entry["model_value"]),
                       "" if model_unit == "dimensionless" else model_unit,
                       bool(entry.get("in_physical_unit")))  # fmt: skip
    except (AttributeError, KeyError, TypeError, ValueError):
        return None


def reading_of(entry: Any) -> str:
    """A JSON reading as text (:meth:`Reading.text`), for a result read back from a file."""
    r = _reading(entry)
    return "–" if r is None else r.text()


def span_of(entries: Sequence[Any]) -> str:
    """Per-recording readings as one span: ``1.1-2.9 mm``, ``12.2-13.8 Hz (model 0.98-1.1
    f/f_n)``, ``0.02 (dimensionless)``."""
    said = [r for r in map(_reading, entries) if r is not None]
    if not said:
        return "–"
    units = {(r.unit, r.model_unit, r.physical) for r in said}
    lo, hi = min(said, key=lambda r: r.value), max(said, key=lambda r: r.value)
    if len(units) > 1 or lo.text() == hi.text():
        return lo.text() if lo.text() == hi.text() else f"{lo.text()} to {hi.text()}"

    def span(a: float, b: float) -> str:
        return f"{a:.3g}" if f"{a:.3g}" == f"{b:.3g}" else f"{a:.3g}-{b:.3g}"

    values = span(lo.value, hi.value)
    if not lo.physical:
        return f"{values} {lo.unit} (model units)"
    if lo.unit == "dimensionless":
        return f"{values} (dimensionless)"
    model = span(lo.model_value, hi.model_value)
    beside = f" (model {model} {lo.model_unit})" if model != values and lo.model_unit else ""
    return f"{values} {lo.unit}{beside}"


def nuisance_lines(diagnosis: Mapping[str, Any]) -> list[str]:
    """The profiled nuisances in words, over the recordings (the final model's and, when an
    effect was selected, the baseline's), from :func:`with_physical_units`'
    ``nuisances_physical``."""
    lines = []
    final = (diagnosis.get("nuisances") or {}).get("profiled_with")
    selected = ", ".join(map(str, final)) if isinstance(final, list) and final else ""
    said = {
        "nuisances": f"with {selected} (the final model)" if selected else "with no effect",
        "nuisances_effect_free": "with no effect (the baseline)",
    }
    for key, with_ in said.items():
        readings = diagnosis.get(f"{key}_physical")
        if not isinstance(readings, dict) or not readings:
            continue
        if key == "nuisances_effect_free" and not selected:
            continue  # nothing selected: the same profile as the line above
        spans = "; ".join(f"{k} {span_of(v)}" for k, v in readings.items() if isinstance(v, list))
        lines.append(f"nuisances profiled {with_}, over the recordings: {spans}")
    return lines

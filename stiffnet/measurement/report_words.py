"""What the report says in words: provenance, alarm checks, units, the two discrepancies.

Each function turns a piece of a command's JSON into text a person reads
(plain strings; :mod:`stiffnet.measurement.report` escapes them):

* :func:`provenance`: when, by which stiffnet and which command line the page was
  made, from which campaign (its manifest's SHA-256), config, model and diagnosis;
* :func:`check_sentences`: each alarm check of one recording as a sentence (what it
  measured, its score against its threshold, fired or passed);
* :class:`Units`: a physical-unit manifest's operating points in mm and Hz, and the
  evaluation's slices relabelled in them;
* :func:`discrepancy_note`: why ``compare``'s campaign discrepancy and ``diagnose``'s
  baseline differ on the same campaign, and by how much.
"""

from __future__ import annotations

import math
import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from stiffnet.uncertainty.alarm_verdict import ALARM_WORDS

# ----------------------------------------------------------------------------- provenance


def file_identity(path: str | Path | None) -> dict[str, Any] | None:
    """A file's absolute path and SHA-256 (None when no file was given)."""
    from stiffnet.io_utils import sha256_file

    if path is None:
        return None
    p = Path(path).resolve()
    try:
        digest = sha256_file(p) if p.is_file() else None
    except OSError:  # unreadable: the page says so rather than failing after the work
        digest = None
    return {"path": str(p), "sha256": digest}


def command_line(command: str, arguments: Sequence[Any], plugins: Sequence[Any] = ()) -> str:
    """``stiffnet [--plugin FILE ...] COMMAND ARG ...`` quoted so that it can be pasted into a
    shell (the plugin files come first: they are options of ``stiffnet`` itself)."""
    loaded = [part for path in plugins for part in ("--plugin", str(path))]
    return shlex.join(["stiffnet", *loaded, command, *(str(a) for a in arguments)])


def provenance(
    campaign: Any,
    command: str,
    config: str | Path | None = None,
    diagnosis: str | Path | None = None,
    diagnosis_how: str = "",
    loop: str | Path | None = None,
    now: datetime | None = None,
    model: str | Path | None = None,
) -> dict[str, Any]:
    """What made the page: date (UTC), stiffnet version, command line and input files.

    Parameters
    ----------
    campaign : Campaign
        The campaign reported (its folder and manifest are hashed).
    command : str
        The command line (:func:`command_line`).
    config, diagnosis, loop : path, optional
        The simulator config, the ``diagnose --json`` and ``loop --json`` files used.
    model : path, optional
        The ONNX model file evaluated (its card ``NAME.card.json`` is hashed beside it).
    diagnosis_how : str
        Where the diagnosis came from when no file was given ("run by this report",
        "not run").
    """
    from stiffnet import __version__
    from stiffnet.effects.registry import plugin_files

    when = (now or datetime.now(UTC)).astimezone(UTC)
    return {
        "created_utc": when.strftime("%Y-%m-%d %H:%M:%S UTC"),
        "stiffnet_version": __version__,
        "command": command,
        "campaign": str(Path(campaign.folder).resolve()),
        "manifest": file_identity(campaign.manifest_path),
        "config": file_identity(config),
        "diagnosis": file_identity(diagnosis),
        "diagnosis_how": diagnosis_how,
        "loop": file_identity(loop),
        "model_file": file_identity(model),
        "model_card": file_identity(Path(model).with_suffix(".card.json")) if model else None,
        "interval_coverage": card_coverage(model),
        "plugins": [file_identity(path) for path in plugin_files().values()],
    }


def card_coverage(model: str | Path | None) -> float | None:
    """The nominal coverage of the model's beta interval (its card's ``conformal_coverage``),
    None when the card cannot be read or does not say."""
    import json

    if model is None:
        return None
    try:
        card = json.loads(Path(model).with_suffix(".card.json").read_text())
        value = (card.get("metadata") or {}).get("conformal_coverage")
    except (OSError, ValueError, AttributeError, RecursionError):
        return None
    return float(value) if _number(value) and 0 < value < 1 else None


def provenance_rows(prov: dict[str, Any], model: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The provenance as (label, value) lines; the model identity from ``evaluate``'s JSON."""

    def ident(f: dict[str, Any] | None, none: str) -> str:
        if not f:
            return none
        return f"{f['path']} (SHA-256 {f.get('sha256') or 'unreadable'})"

    rows = [
        ("made", prov.get("created_utc", "–")),
        ("stiffnet version", str(prov.get("stiffnet_version", "–"))),
        ("command", prov.get("command") or "–"),
        ("campaign", prov.get("campaign") or "–"),
        ("manifest", ident(prov.get("manifest"), "–")),
    ]
    if model:
        rows.append(("model", f"{model.get('name')} ({model.get('kind')}, SHA-256 "
                              f"{model.get('sha256')})"))  # fmt: skip
    else:
        rows.append(("model", "no evaluation: no model read"))
    if prov.get("model_file"):
        rows.append(("model file", ident(prov["model_file"], "–")))
        rows.append(("model card", ident(prov.get("model_card"), "–")))
    rows.append(("simulator config", ident(prov.get("config"), "the default config")))
    rows.append(("diagnosis", ident(prov.get("diagnosis"), prov.get("diagnosis_how") or "none")))
    rows.append(("loop result", ident(prov.get("loop"), "none")))
    for plugin in prov.get("plugins") or []:
        rows.append(("plugin file", ident(plugin, "–")))
    return rows


# ----------------------------------------------------------------------------- alarm checks

#: What each alarm check measures (its score), for the sentence of a check.
CHECK_MEASURES = {
    "embedding": "distance of the windows to the training data in the model's embedding",
    "ambiguity": "1 minus the largest mean class probability",
    "beta_uncertainty": "scale of the log-beta error (model's own plus window spread)",
    "class_edge": "closeness of beta to a class edge, in units of its error",
    "class_beta": "log-gap between the beta interval and the answered class's beta range",
    "features": "inclination-feature distance to the training data",
    "restoring_force": "log-gap between the model's and the restoring-force beta intervals",
    "sensor": "identified sensor chain against the chains in the training data",
    "contact_law": "restoring-force contact law against the laws in the training data",
    "layers": "change of beta along the record",
}


def check_sentences(alarm: dict[str, Any] | None, fired: Sequence[str] = ()) -> list[str]:
    """Each alarm check of one recording as a short sentence.

    ``alarm`` is the predictor's ``alarm`` object (``scores``, ``thresholds``,
    ``fired``); ``fired`` adds checks known only by name (``ood_checks``).
    Example: "embedding (distance of the windows to the training data in the
    model's embedding): 2.3 above its threshold 1.8: FIRED: the recording does not
    look like the training data to the model."
    """
    alarm = alarm if isinstance(alarm, dict) else {}
    scores = alarm.get("scores") if isinstance(alarm.get("scores"), dict) else {}
    thresholds = alarm.get("thresholds") if isinstance(alarm.get("thresholds"), dict) else {}
    went = [str(f) for f in (*(alarm.get("fired") or []), *fired)]
    names = list(dict.fromkeys([*thresholds, *scores, *went]))
    out = []
    for name in names:
        what = CHECK_MEASURES.get(name, "check")
        score, limit = scores.get(name), thresholds.get(name)
        on = name in went
        if _number(score) and _number(limit):
            side = "above" if score > limit else "within"
            measured = f"{score:.3g} {side} its threshold {limit:.3g}"
        else:
            measured = "no score recorded"
        verdict = f"FIRED: {ALARM_WORDS.get(name, name)}" if on else "passed"
        out.append(f"{name} ({what}): {measured}: {verdict}.")
    return out


def _number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


# ----------------------------------------------------------------------------- units

#: Manifest columns given in physical units (docs/campaign.md, "Physical units").
PHYSICAL_COLUMNS = (
    "forcing_frequency_hz",
    "base_acceleration_ms2",
    "base_acceleration_g",
    "base_displacement_mm",
    "gap_mm",
)


@dataclass
class Units:
    """How the report writes a campaign's operating points (gap, forcing, amplitude).

    A physical-unit manifest (any of :data:`PHYSICAL_COLUMNS`) reads in mm and Hz where it
    gives the scale: lengths in mm when every row has a length in mm or g (the model's
    length unit is then 1 mm, :data:`stiffnet.campaign.manifest.MODEL_LENGTH_MM`), the
    forcing frequency ``frequency_ratio * f_n`` in Hz when every row gives
    ``natural_frequency_hz`` or ``forcing_frequency_hz``. Otherwise the model's own units
    (paper eqs 11-12): lengths in the model's length unit, frequency as ``f/f_n``. The
    values go through :func:`stiffnet.measurement.report_units.physical_reading`.
    """

    physical: bool = False
    #: f_n (Hz) per recording name, for the rows whose forcing is known in Hz.
    natural_frequency_hz: dict[str, float] = field(default_factory=dict)
    #: Lengths in mm (None: as ``physical``, for callers that give only that).
    length_mm: bool | None = None
    #: Every row's forcing is known in Hz (None: as ``physical``).
    forcing_hz: bool | None = None

    @classmethod
    def of(cls, rows: Sequence[Any]) -> Units:
        """From a campaign's manifest rows."""
        from stiffnet.campaign.simulate import natural_frequency
        from stiffnet.measurement.report_units import Scale

        physical = any(getattr(r, c, None) is not None for r in rows for c in PHYSICAL_COLUMNS)
        # a forcing given in Hz became its ratio to f_n (the paper's 9.48 Hz when the manifest
        # gives none): back in Hz it is exact; a ratio without f_n has no Hz
        given = ("natural_frequency_hz", "forcing_frequency_hz")
        known = {
            r.recording: natural_frequency(r)
            for r in rows
            if any(getattr(r, c, None) is not None for c in given)
        }
        hz = physical and bool(rows) and len(known) == len(rows)
        return cls(physical, known, physical and Scale.of(rows).length_mm, hz)

    @property
    def lengths_mm(self) -> bool:
        return self.physical if self.length_mm is None else self.length_mm

    @property
    def hz(self) -> bool:
        return self.physical if self.forcing_hz is None else self.forcing_hz

    @property
    def length(self) -> str:
        return "mm" if self.lengths_mm else "model length"

    def headers(self) -> dict[str, str]:
        """Column headers of the operating point, with their units."""
        return {"gap": f"gap [{self.length}]",
                "forcing": "forcing frequency [Hz]" if self.hz else "forcing f/f_n",
                "amplitude": "base displacement amplitude [mm]" if self.lengths_mm
                else "base amplitude [model length]"}  # fmt: skip

    def operating_point(self, row: dict[str, Any]) -> dict[str, Any]:
        """One evaluated recording's gap, forcing and amplitude under :meth:`headers`."""
        from stiffnet.measurement.report_units import Scale, physical_reading

        h = self.headers()
        ratio, f_n = row.get("frequency_ratio"), self.natural_frequency_hz.get(row["recording"])
        scale = Scale(f_n if self.hz else None, self.lengths_mm)

        def read(v: Any, unit: str) -> float | None:
            return None if v is None else physical_reading(v, unit, scale).value

        forcing = None if self.hz and f_n is None else read(ratio, "f/f_n")
        return {
            h["gap"]: read(row.get("gap"), "model length"),
            h["forcing"]: forcing,
            h["amplitude"]: read(row.get("amplitude"), "model length"),
        }

    def slice_label(self, name: str, group: str, members: Sequence[dict[str, Any]]) -> str:
        """A slice's label with its unit (``members``: the evaluated rows in the group)."""
        if name in ("gap", "amplitude"):
            what = self.headers()[name]
            return f"{what} in {group}"
        if name == "frequency_ratio":
            if not self.hz:
                return f"forcing f/f_n in {group}"
            hz = [
                r["frequency_ratio"] * self.natural_frequency_hz[r["recording"]]
                for r in members
                if r.get("frequency_ratio") is not None
                and r["recording"] in self.natural_frequency_hz
            ]
            lo, hi = (f"{min(hz):.3g}", f"{max(hz):.3g}") if hz else ("unknown", "unknown")
            span = f"{lo} Hz" if lo == hi else f"{lo}-{hi} Hz"
            return f"forcing frequency [Hz] {span} (f/f_n in {group})"
        return f"{name.replace('_', ' ')} {group}"


# ----------------------------------------------------------------------------- discrepancies


def profiled_nuisances(diagnosis: dict[str, Any] | None) -> list[str]:
    """The row parameters a diagnosis profiled (its JSON ``nuisances``: one number per
    recording), not counting the initial state (``start``) or the orbits it reached."""
    nuis = (diagnosis or {}).get("nuisances")
    if not isinstance(nuis, dict):
        return []
    return [
        str(k)
        for k, v in nuis.items()
        if k != "start" and isinstance(v, list) and v and all(_number(x) for x in v)
    ]


def discrepancy_note(comparison: dict[str, Any], diagnosis: dict[str, Any]) -> str:
    """One paragraph: what compare's discrepancy and diagnose's baseline each are.

    Both are the same statistic (mean over recordings of the mean squared
    normalised difference of :mod:`stiffnet.measurement.discrepancy`) of the same
    model; they differ by what is simulated. ``compare`` simulates each recording
    once, from the manifest's parameters (missing ones estimated), from the first
    initial state, over the recording's length with the config's solver settings.
    ``diagnose`` first profiles the nuisances (the initial state among
    ``N_STARTS`` draws, and the uncertain gap, damping, forcing and beta within
    their tolerances) to the recordings and simulates the fitting loop's records
    (``FIT_SETTINGS``: 40 natural periods); picking the best match lowers it
    where the manifest's settings or first start miss a recording's orbit.
    """
    from stiffnet.campaign.simulate import FIT_SETTINGS
    from stiffnet.measurement.nuisance import N_STARTS

    c, b = comparison.get("discrepancy"), diagnosis.get("baseline_discrepancy")
    if not _number(c) or not _number(b):
        return ""
    profiled = profiled_nuisances(diagnosis)
    others = (f"the {', '.join(profiled)} within their tolerances or ranges" if profiled
              else "no other nuisance: the manifest gives them")  # fmt: skip
    names = [r.get("recording") for r in comparison.get("recordings") or []]
    same = diagnosis.get("recordings")
    scope = ""
    if isinstance(same, list) and sorted(map(str, same)) != sorted(map(str, names)):
        scope = " The diagnosis read other recordings than this comparison: it is not comparable."
    return (
        f"Two discrepancies of the same model, the same statistic (mean over recordings of "
        f"the mean squared normalised difference): compare's {c:.3g} simulates each "
        f"recording once with the manifest's parameters (missing ones estimated), from the "
        f"first initial state, over "
        f"the recording's length; diagnose's baseline {b:.3g} is taken after diagnose fitted "
        f"the nuisances to the recordings (the initial state, best of {N_STARTS} per "
        f"recording; {others}) on records of {FIT_SETTINGS.periods:g} natural periods, so "
        f"it is the simulator's best match before any effect is added: lower where the "
        f"manifest's settings or first start miss a recording's orbit, while the shorter "
        f"record alone moves it either way (difference {c - b:+.3g}).{scope}"
    )

"""Metrics of a campaign's evaluation: accuracy, macro-F1, beta MAPE, interval coverage and
alarm rates per method, and their slices by beta class, gap, frequency ratio, amplitude and
impact regime.

Shared by :mod:`stiffnet.measurement.evaluate` (the learned model and both cross-checks),
:mod:`stiffnet.measurement.simulation_reading` (beta by simulation and the loop's reading) and
the report's slices, so each reads the recordings' rows the same way. A refusal counts as a
wrong class; beta MAPE is over recordings with contact, a known beta and an estimate.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from stiffnet.geometry.calibration import NO_CONTACT, beta_class

#: Slices of the metrics: manifest column and its bin edges (None: the column is categorical).
SLICE_EDGES: dict[str, list[float]] = {
    "gap": [-np.inf, 0.5, 1.5, 2.5, np.inf],
    "frequency_ratio": [0.0, 0.95, 1.05, np.inf],
    "amplitude": [0.0, 1.0, 1.5, np.inf],
}


def true_class(beta: float | None, contact: bool) -> str | None:
    """The label a recording should get: its beta class, or no_contact."""
    if beta is None:
        return None
    return str(beta_class(beta)) if contact else NO_CONTACT


def macro_f1(truth: Sequence[str], pred: Sequence[str]) -> float:
    """Macro-averaged F1 over the classes present in either list."""
    labels = sorted(set(truth) | set(pred))
    if not labels:
        return float("nan")
    f1 = []
    for c in labels:
        tp = sum(t == c and p == c for t, p in zip(truth, pred, strict=True))
        fp = sum(t != c and p == c for t, p in zip(truth, pred, strict=True))
        fn = sum(t == c and p != c for t, p in zip(truth, pred, strict=True))
        f1.append(2 * tp / (2 * tp + fp + fn) if tp + fp + fn else 0.0)
    return float(np.mean(f1))


def method_metrics(rows: Sequence[dict[str, Any]], cls_key: str, beta_key: str) -> dict[str, Any]:
    """Accuracy, macro-F1 and beta MAPE of one method over recordings with a known class."""
    known = [r for r in rows if r["true_class"] is not None]
    truth = [r["true_class"] for r in known]
    pred = [str(r[cls_key]) for r in known]
    ape = [
        abs(r[beta_key] - r["beta"]) / r["beta"]
        for r in known
        if r[beta_key] is not None and r["beta"] and r["true_class"] != NO_CONTACT
    ]
    return {
        "n": len(known),
        "accuracy": float(np.mean([t == p for t, p in zip(truth, pred, strict=True)]))
        if known
        else None,
        "macro_f1": macro_f1(truth, pred) if known else None,
        "beta_mape": float(np.mean(ape)) if ape else None,
    }


def alarm_metrics(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """How often the alarm fired, on the wrongly classified recordings too, and how often
    the beta interval held the manifest's beta (recordings with contact and a known beta)."""
    known = [r for r in rows if r["true_class"] is not None]
    return {
        "alarm_rate": flag_share(r.get("ood") for r in rows),
        "alarm_rate_wrong": flag_share(
            r.get("ood") for r in known if r["class"] != r["true_class"]
        ),
        "interval_coverage": interval_coverage(rows, "beta_interval"),
    }


def interval_coverage(rows: Sequence[dict[str, Any]], key: str) -> float | None:
    """Fraction of the recordings with a known beta and an interval whose interval holds it."""
    hits = [
        r[key][0] <= r["beta"] <= r[key][1]
        for r in rows
        if r.get(key) and r["beta"] and r["true_class"] not in (None, NO_CONTACT)
    ]
    return float(np.mean(hits)) if hits else None


def flag_share(flags: Iterable[Any]) -> float | None:
    """Fraction of True among the flags that are not None."""
    known = [bool(f) for f in flags if f is not None]
    return float(np.mean(known)) if known else None


def bin_label(value: float | None, edges: list[float]) -> str:
    """The slice ``[lo, hi)`` of ``edges`` that holds ``value`` (the end slices are open)."""
    if value is None:
        return "unknown"
    k = int(np.searchsorted(edges, value, side="right")) - 1
    k = min(max(k, 0), len(edges) - 2)
    return f"[{edges[k]:g}, {edges[k + 1]:g})"


#: Each method's class and beta keys in a recording's row; ``simulation`` and ``reading``
#: are there once :mod:`stiffnet.measurement.simulation_reading` has run.
METHOD_KEYS: dict[str, tuple[str, str]] = {
    "learned": ("class", "beta_estimate"),
    "geometric": ("geometric_class", "geometric_beta"),
    "restoring_force": ("restoring_force_class", "restoring_force_beta"),
    "simulation": ("simulation_class", "simulation_beta"),
    "reading": ("reading_class", "reading_beta"),
}


def _method_rows(rows: Sequence[dict[str, Any]], method: str) -> list[dict[str, Any]]:
    """The rows a method is scored on: all of them (a refusal is a wrong class), but for the
    simulation only the recordings it read (as its campaign metrics)."""
    if method == "simulation":
        return [r for r in rows if r.get("simulation_class") is not None]
    return list(rows)


def sliced_metrics(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Every method's metrics (those whose keys the rows carry) by beta class, gap,
    frequency ratio, amplitude and impact regime."""
    keys: dict[str, Any] = {
        "beta_class": lambda r: r["true_class"] or "unknown",
        "impact_regime": lambda r: r["impact_regime"],
    }
    for col, edges in SLICE_EDGES.items():
        keys[col] = lambda r, col=col, edges=edges: bin_label(r.get(col), edges)
    methods = {m: k for m, k in METHOD_KEYS.items() if any(k[0] in r for r in rows)}
    out: dict[str, dict[str, Any]] = {}
    for name, key in keys.items():
        groups: dict[str, list[dict[str, Any]]] = {}
        for r in rows:
            groups.setdefault(key(r), []).append(r)
        out[name] = {
            g: {m: method_metrics(_method_rows(rs, m), *k) for m, k in methods.items()}
            for g, rs in sorted(groups.items())
        }
    return out

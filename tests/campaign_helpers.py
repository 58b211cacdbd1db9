"""Shared by the measurement tests: the example manifest shortened for fast campaigns."""

from __future__ import annotations

import csv
from pathlib import Path

MANIFEST = Path(__file__).resolve().parents[1] / "examples" / "hidden_effect_manifest.csv"


def short_manifest(tmp: Path, n: int | None = None, duration_s: str = "3") -> Path:
    """The first ``n`` rows (all by default) of the example manifest, ``duration_s`` long."""
    with open(MANIFEST, encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))[:n]
    out = tmp / f"manifest{n or ''}.csv"
    with open(out, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({**r, "duration_s": duration_s})
    return out


def without_beta(campaign: Path, out: Path) -> Path:
    """A field-campaign copy of ``campaign`` (its recordings, the manifest less ``beta``)."""
    import shutil

    shutil.copytree(campaign / "recordings", out / "recordings")
    with open(campaign / "manifest.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    with open(out / "manifest.csv", "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(
            fh, fieldnames=[c for c in rows[0] if c != "beta"], extrasaction="ignore"
        )
        w.writeheader()
        w.writerows(rows)
    return out

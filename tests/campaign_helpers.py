"""Shared by the measurement tests: the example manifest shortened for fast campaigns, and one
lab rig's operating point as a manifest row."""

from __future__ import annotations

import csv
from pathlib import Path

from stiffnet.campaign import ManifestRow

MANIFEST = Path(__file__).resolve().parents[1] / "examples" / "hidden_effect_manifest.csv"
#: The lab rig of the paper's Table 1 forced at its natural frequency, 1.2 mm gap, beta 30, 2 %
#: noise: the row the measurement tests vary with ``model_copy(update=...)``.
LAB_ROW = ManifestRow(
    recording="r.csv",
    fs_hz=1250,
    natural_frequency_hz=9.48,
    frequency_ratio=1.0,
    amplitude=1.2,
    gap=1.2,
    damping_ratio=0.02,
    beta=30,
    noise=0.02,
)


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


def ms_campaign(recording: Path, folder: Path) -> Path:
    """A one-recording campaign in `folder` whose file is `recording` rewritten as a lab's
    export (``time_ms,acc_ms2``: milliseconds, m/s^2), its manifest row saying so; returns
    the folder."""
    import numpy as np

    from stiffnet.recordings import read_recording

    a = read_recording(recording)
    folder.mkdir(parents=True, exist_ok=True)
    t_ms = 1000 * np.arange(a.accel.size) / a.fs_hz
    lines = (f"{float(t)!r},{float(v)!r}\n" for t, v in zip(t_ms, a.accel, strict=True))
    (folder / "run.csv").write_text("time_ms,acc_ms2\n" + "".join(lines))
    (folder / "manifest.csv").write_text(
        "recording,fs_hz,natural_frequency_hz,columns,time_unit\n"
        f"run.csv,{a.fs_hz:g},9.48,time_ms;acc_ms2,ms\n"
    )
    return folder

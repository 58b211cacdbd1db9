"""The stiffness log as a picture a geologist reads at a glance (PNG, matplotlib Agg).

Beta on a log axis along the record: each point with its interval as a band, the
layers as thick steps with their pooled interval shaded, the change times as
vertical lines with their uncertainty, points where the alarm fired as red
crosses, the restoring-force cross-checks as diamonds, the class edges as dashed
lines labelled with the classes.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.io_utils import write_bytes_atomic


def log_figure(
    log: dict[str, Any], path: str | Path, class_edges: list[float] | None = None
) -> Path:
    """Draw the log (:func:`serving.log.stiffness_log`'s document) into a PNG at `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from stiffnet.geometry.calibration import DEFAULT_CLASSES

    pts = [p for p in log["points"] if p["beta"] is not None]
    fig, ax = plt.subplots(figsize=(11, 4.8))
    if pts:
        t = np.array([p["t_s"] for p in pts])
        b = np.array([p["beta"] for p in pts])
        iv = np.array([p["beta_interval"] or [p["beta"], p["beta"]] for p in pts])
        ax.fill_between(t, iv[:, 0], iv[:, 1], color="tab:blue", alpha=0.15, lw=0,
                        label="point interval")  # fmt: skip
        ax.plot(t, b, ".", ms=2.5, color="tab:blue", label="beta per window")
        al = np.array([p["alarm"] for p in pts])
        if al.any():
            ax.plot(t[al], b[al], "x", color="red", ms=5, label="alarm")
    ph = [p for p in log["points"] if p.get("restoring_force", {}).get("beta") is not None]
    if ph:
        ax.plot([p["t_s"] for p in ph], [p["restoring_force"]["beta"] for p in ph], "D", ms=4,
                color="tab:green", label="restoring force")  # fmt: skip
    for la in log["layers"]:
        if la["beta"] is None:
            ax.axvspan(la["start_s"], la["end_s"], color="0.85", alpha=0.5)
            continue
        lo, hi = la["beta_interval"] or (la["beta"], la["beta"])
        ax.fill_between([la["start_s"], la["end_s"]], lo, hi, color="tab:orange", alpha=0.25,
                        lw=0)  # fmt: skip
        ax.plot([la["start_s"], la["end_s"]], [la["beta"]] * 2, color="tab:orange", lw=3)
        ax.text(0.5 * (la["start_s"] + la["end_s"]), hi * 1.05,
                f"{la['class']} {la['beta']:.3g}" + (" (alarm)" if la["alarm"] else ""),
                ha="center", va="bottom", fontsize=8)  # fmt: skip
    for c in log["changes"]:
        ax.axvline(c["t_s"], color="k", lw=1)
        ax.axvspan(c["t_s"] - c["sd_s"], c["t_s"] + c["sd_s"], color="k", alpha=0.12, lw=0)
    edges = class_edges or [c[1] for c in DEFAULT_CLASSES] + [DEFAULT_CLASSES[-1][2]]
    for e in edges[1:-1]:
        ax.axhline(e, color="0.5", ls="--", lw=0.8)
    ax.set_yscale("log")
    ax.set_xlim(0, log["duration_s"])
    ax.set_xlabel("time along the record (s)")
    ax.set_ylabel("beta (contact / primary stiffness)")
    ax.set_title(f"stiffness log: {log['source'] or 'record'} "
                 f"({len(log['layers'])} layer(s), model {log['model']['name']})")  # fmt: skip
    ax.legend(loc="upper left", fontsize=8, ncol=4)
    ax.grid(alpha=0.3, which="both")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())
    return Path(path)

"""Figures of the measurement loop (matplotlib, Agg; imported only by the commands)."""

from __future__ import annotations

import io
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from stiffnet.inputs import mpl_text
from stiffnet.io_utils import write_bytes_atomic
from stiffnet.measurement.statistics import SignalStatistics


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: str | Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    _plt().close(fig)
    write_bytes_atomic(path, buf.getvalue())
    return Path(path)


def panel_grid(n: int, max_cols: int = 4) -> tuple[int, int]:
    """Rows and columns for `n` panels: the fewest rows of at most `max_cols`, balanced."""
    rows = int(np.ceil(n / max_cols))
    return rows, int(np.ceil(n / rows))


def _recording_panels(
    names: Sequence[str],
    measured: Sequence[SignalStatistics],
    simulated: Sequence[SignalStatistics | None],
    draw: Callable[[Any, SignalStatistics, SignalStatistics | None], None],
    xlabel: str,
    ylabel: str,
    path: str | Path,
    max_panels: int,
) -> Path:
    """One panel per recording (at most ``max_panels``) drawn by ``draw``.

    The grid is sized to the panel count (:func:`panel_grid`): 5 panels are 2 x 3,
    not a 4-wide row with three empty cells below.
    """
    plt = _plt()
    n = max(1, min(len(names), max_panels))
    rows, cols = panel_grid(n)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for k, ax in enumerate(axes.flat):
        if k >= n:
            ax.axis("off")
            continue
        draw(ax, measured[k], simulated[k])
        ax.set_title(mpl_text(names[k]), fontsize=8)
        ax.tick_params(labelsize=7)
        if k == 0:
            ax.legend(fontsize=6)
    fig.supxlabel(xlabel, fontsize=8)
    fig.supylabel(ylabel, fontsize=8)
    # fixed margins in inches: tight_layout measured every tick label of every panel and
    # took half the time of a 24-panel page
    w, h = fig.get_size_inches()
    fig.subplots_adjust(left=0.75 / w, right=1 - 0.15 / w, bottom=0.6 / h, top=1 - 0.3 / h,
                        wspace=0.3, hspace=0.45)  # fmt: skip
    return _save(fig, path)


def _draw_waveform(ax: Any, m: SignalStatistics, s: SignalStatistics | None) -> None:
    if m.waveform.size:
        ax.plot(m.waveform_t, m.waveform, color="k", lw=1.2, label="measured")
    if s is not None and s.waveform.size:
        ax.plot(s.waveform_t, s.waveform, color="tab:orange", lw=1, label="simulated")
        if m.waveform.size:
            ax.plot(m.waveform_t, s.waveform - m.waveform, color="tab:red", lw=0.8, ls=":",
                    label="residual")  # fmt: skip


def _draw_spectrum(ax: Any, m: SignalStatistics, s: SignalStatistics | None) -> None:
    ax.semilogx(m.psd_f, m.log_psd, color="k", lw=1.2, label="measured")
    if s is not None:
        ax.semilogx(s.psd_f, s.log_psd, color="tab:orange", lw=1, label="simulated")
        # the residual, offset below the curves so it does not cross them
        ax.semilogx(m.psd_f, s.log_psd - m.log_psd + m.log_psd.min() - 1, color="tab:red",
                    lw=0.8, ls=":", label="residual (offset)")  # fmt: skip


def waveform_figure(
    names: Sequence[str],
    measured: Sequence[SignalStatistics],
    simulated: Sequence[SignalStatistics | None],
    path: str | Path,
    max_panels: int = 8,
) -> Path:
    """Measured vs simulated impact-aligned mean waveform per recording, with the residual."""
    return _recording_panels(names, measured, simulated, _draw_waveform,
                             "time from spike extremum (natural periods)",
                             "accel (robust units, spikes up)", path, max_panels)  # fmt: skip


def spectrum_figure(
    names: Sequence[str],
    measured: Sequence[SignalStatistics],
    simulated: Sequence[SignalStatistics | None],
    path: str | Path,
    max_panels: int = 8,
) -> Path:
    """Measured vs simulated band-averaged log PSD per recording, with the residual."""
    ylabel = "log10 PSD [log10 (robust units² / Hz)]"
    return _recording_panels(names, measured, simulated, _draw_spectrum, "f / f_n", ylabel,
                             path, max_panels)  # fmt: skip


def components_figure(result: dict[str, Any], path: str | Path) -> Path:
    """Normalised differences per recording and component (a heat map): where it fails."""
    plt = _plt()
    recs = [r for r in result["recordings"] if r.get("components")]
    comps = list(recs[0]["components"]) if recs else []
    mat = np.array(
        [
            [np.nan if r["components"][c] is None else r["components"][c] for c in comps]
            for r in recs
        ]
    )
    fig, ax = plt.subplots(figsize=(1 + 0.6 * len(comps), 1 + 0.35 * len(recs)))
    if recs:
        lim = max(1.0, float(np.nanmax(np.abs(mat))) if np.isfinite(mat).any() else 1.0)
        im = ax.imshow(mat, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
        ax.set_xticks(range(len(comps)), comps, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(recs)), [mpl_text(r["recording"]) for r in recs], fontsize=7)
        fig.colorbar(im, ax=ax, label="(sim - meas) / tolerance")
    ax.set_title(f"discrepancy {result['discrepancy']:.3g}", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


#: Lowest relative reduction drawn; worse effects are clipped there, hatched and labelled.
RANKING_FLOOR = -0.2


def ranking_figure(diagnosis: dict[str, Any], path: str | Path) -> Path:
    """Discrepancy removed by each fitted effect (significant ones filled)."""
    plt = _plt()
    rk = diagnosis["ranking"]
    fig, ax = plt.subplots(figsize=(6, 0.4 * len(rk) + 1.2))
    y = np.arange(len(rk))[::-1]
    rel = np.array([r["relative_reduction"] for r in rk], dtype=float)
    red = np.maximum(rel, RANKING_FLOOR)
    colors = ["tab:green" if r["significant"] else "lightgray" for r in rk]
    bars = ax.barh(y, 100 * red, color=colors, edgecolor="k")
    for bar, value in zip(bars, rel, strict=True):
        if value < RANKING_FLOOR:  # clipped: hatch it and print the true value
            bar.set_hatch("//")
            ax.annotate(f"◀ {100 * value:.0f} % (clipped)", (100 * RANKING_FLOOR, bar.get_y()
                        + bar.get_height() / 2), xytext=(3, 0), textcoords="offset points",
                        va="center", ha="left", fontsize=7)  # fmt: skip
    ax.set_yticks(y, [mpl_text(r["effect"]) for r in rk], fontsize=8)
    ax.axvline(0, color="k", lw=0.5)
    ax.set_xlim(left=min(100 * RANKING_FLOOR * 1.05, ax.get_xlim()[0]))
    ax.set_xlabel("discrepancy removed [% of baseline]")
    ax.set_title(f"baseline discrepancy {diagnosis['baseline_discrepancy']:.3g} (mean d²); "
                 "green: significant, hatched: clipped", fontsize=8)  # fmt: skip
    fig.tight_layout()
    return _save(fig, path)


def loop_figure(iterations: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Error and discrepancy against loop iteration (0 = the starting config, 1, 2, ...).

    Left: ``1 - accuracy`` (learned, geometric, by simulation), β MAPE (learned, by
    simulation) and ``1 - agreement`` of the
    learned model with the restoring-force cross-check (the one error a field campaign
    without β has); right: the simulator-measurement discrepancy (log scale).
    """
    plt = _plt()

    def series(key: str, one_minus: bool = False) -> list[float]:
        v = [it.get(key) for it in iterations]
        return [np.nan if a is None else (1 - a if one_minus else a) for a in v]

    x = np.arange(len(iterations))
    labels = [it.get("label", str(i)) for i, it in enumerate(iterations)]
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
    for key, label, one_minus, style in (
        ("accuracy", "1 - learned accuracy", True, "o-"),
        ("beta_mape", "learned beta MAPE", False, "s-"),
        ("geometric_accuracy", "1 - geometric accuracy", True, "^--"),
        ("simulation_accuracy", "1 - accuracy by simulation", True, "v-"),
        ("simulation_beta_mape", "beta MAPE by simulation", False, "x-"),
        ("restoring_force_agreement", "1 - agreement with restoring force", True, "d:"),
    ):
        y = series(key, one_minus)
        if not all(np.isnan(y)):
            ax[0].plot(x, y, style, label=label)
    ax[0].set_xticks(x, labels, rotation=15, ha="right", fontsize=7)
    ax[0].set_ylabel("error [fraction]")
    ax[0].set_xlabel("loop iteration")
    if ax[0].get_legend_handles_labels()[0]:
        ax[0].legend(fontsize=7)
    ax[1].semilogy(x, series("discrepancy"), "o-", color="k")
    ax[1].set_xticks(x, labels, rotation=15, ha="right", fontsize=7)
    ax[1].set_ylabel("discrepancy [mean d²]")
    ax[1].set_xlabel("loop iteration")
    fig.tight_layout()
    return _save(fig, path)

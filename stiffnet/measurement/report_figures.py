"""The report's comparison figures: every recording in pages of panels, bounded, with alt texts.

A campaign's recordings are drawn :data:`PANELS_PER_PAGE` to a figure (waveform
and spectrum, :mod:`stiffnet.measurement.plots`), at most :data:`MAX_PANEL_RECORDINGS`
of them: a larger campaign shows the recordings with the largest discrepancy
and says so (every recording stays in the comparison table and in the
heat map of the components, itself bounded at :data:`MAX_HEATMAP_RECORDINGS`
rows). Each figure carries an alt text that says what it shows and for which
recordings.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Panels per figure (a 6 x 4 grid).
PANELS_PER_PAGE = 24
#: Most recordings drawn as panels (two pages per kind); the rest are in the table.
MAX_PANEL_RECORDINGS = 48
#: Most rows of the components heat map.
MAX_HEATMAP_RECORDINGS = 120


@dataclass
class Figure:
    """A rendered figure and its alt text."""

    path: Path
    alt: str


def drawn_recordings(result: dict[str, Any], bound: int) -> list[int]:
    """Indices of the recordings to draw: all when at most ``bound``, else the ``bound``
    with the largest discrepancy (a failed simulation counts as the largest), in order."""
    recs = result["recordings"]
    if len(recs) <= bound:
        return list(range(len(recs)))

    def key(i: int) -> float:
        d = recs[i].get("discrepancy")
        return float("inf") if d is None else float(d)

    return sorted(sorted(range(len(recs)), key=key, reverse=True)[:bound])


def shown_sentence(n_drawn: int, n_all: int, bound: int, what: str) -> str:
    """What a figure kind shows of the campaign, and where the rest is."""
    if n_drawn == n_all:
        return (f"{what}: all {n_all} recordings (at most {bound} are drawn; a larger campaign "
                f"shows the {bound} with the largest discrepancy).")  # fmt: skip
    return (
        f"{what}: the {n_drawn} recordings with the largest discrepancy of {n_all} (at most "
        f"{bound} are drawn); every recording is in the comparison table above."
    )


def _names(names: Sequence[str], limit: int = 6) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def comparison_figures(
    comparison: Any, folder: Path, prefix: str = ""
) -> tuple[list[Figure], list[str]]:
    """The waveform and spectrum pages and the components heat map of a comparison.

    Files are ``PREFIXwaveform.png``, ``PREFIXwaveform_2.png`` (the second page), ...,
    ``PREFIXcomponents.png`` in ``folder``. Returns the figures (in page order) and the
    sentences saying what they show.
    """
    from stiffnet.measurement import plots

    res = comparison.result
    names = [str(r["recording"]) for r in res["recordings"]]
    idx = drawn_recordings(res, MAX_PANEL_RECORDINGS)
    pages = [idx[k : k + PANELS_PER_PAGE] for k in range(0, len(idx), PANELS_PER_PAGE)]
    kinds: list[tuple[str, Callable[..., Path], str]] = [
        ("waveform", plots.waveform_figure,
         "impact-aligned mean waveform, measured (black) against simulated (orange) with the "
         "residual (red, dotted); x: time from the spike's extremum in natural periods, y: "
         "acceleration in robust units"),
        ("spectrum", plots.spectrum_figure,
         "band-averaged log power spectrum, measured (black) against simulated (orange) with "
         "the residual offset below (red, dotted); x: f/f_n (log), y: log10 PSD"),
    ]  # fmt: skip
    figures = []
    for kind, draw, what in kinds:
        for p, page in enumerate(pages):
            sel = [names[i] for i in page]
            path = draw(sel, [comparison.measured[i] for i in page],
                        [comparison.simulated[i] for i in page],
                        folder / f"{prefix}{kind}{f'_{p + 1}' if p else ''}.png",
                        max_panels=len(page))  # fmt: skip
            alt = (f"{kind.capitalize()} figure, page {p + 1} of {len(pages)}: one panel per "
                   f"recording ({len(sel)}: {_names(sel)}); {what}.")  # fmt: skip
            figures.append(Figure(path, alt))
    heat = drawn_recordings(res, MAX_HEATMAP_RECORDINGS)
    sub = {**res, "recordings": [res["recordings"][i] for i in heat]}
    worst = res.get("failure") or {}
    figures.append(Figure(
        plots.components_figure(sub, folder / f"{prefix}components.png"),
        f"Heat map of the normalised differences (simulated minus measured over the "
        f"tolerance; red: simulation above, blue: below), one row per recording "
        f"({len(heat)} of {len(names)}) and one column per statistic; campaign discrepancy "
        f"{res['discrepancy']:.3g}, worst statistic {worst.get('component')}, worst "
        f"recording {worst.get('recording')}.",
    ))  # fmt: skip
    said = [
        shown_sentence(len(idx), len(names), MAX_PANEL_RECORDINGS,
                       f"Waveform and spectrum figures ({len(pages)} page(s) each, "
                       f"{PANELS_PER_PAGE} panels a page)"),
        shown_sentence(len(heat), len(names), MAX_HEATMAP_RECORDINGS, "Heat map"),
    ]  # fmt: skip
    return figures, said


def ranking_alt(diagnosis: dict[str, Any]) -> str:
    """Alt text of the diagnosis's ranking chart: the effects and what each removed."""
    bars = ", ".join(
        f"{r.get('effect')} {100 * r['relative_reduction']:.0f} %"
        + (" (significant)" if r.get("significant") else "")
        for r in diagnosis.get("ranking") or []
        if isinstance(r.get("relative_reduction"), int | float)
    )
    return (
        f"Bar chart of the discrepancy each candidate effect removed, in % of the baseline "
        f"discrepancy {diagnosis.get('baseline_discrepancy', float('nan')):.3g}; significant "
        f"effects in green, worse than -20 % clipped and hatched: {bars or 'no candidates'}."
    )


def loop_alt(loop: dict[str, Any]) -> str:
    """Alt text of the loop chart: errors and discrepancy per iteration."""
    its = [it for it in loop.get("iterations") or [] if isinstance(it, dict)]

    def num(v: Any) -> str:
        return f"{v:.3g}" if isinstance(v, int | float) and not isinstance(v, bool) else "–"

    steps = "; ".join(
        f"{it.get('index')} ({it.get('label')}): discrepancy "
        f"{num((it.get('metrics') or {}).get('discrepancy'))}"
        for it in its
    )
    return (
        "Loop chart: left, the learned model's error (1 - accuracy, beta MAPE, 1 - agreement "
        "with the restoring force) against loop iteration; right, the simulator-measurement "
        f"discrepancy (log scale) against iteration. {steps or 'No iterations listed.'}"
    )

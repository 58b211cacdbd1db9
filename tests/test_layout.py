"""Output that fits: terminal tables at 80 columns and --wide, the HTML report's layout
rules (1280 px page), labelled figures, clipped bars marked, panel grids sized to the count."""

from __future__ import annotations

import io
import re

import numpy as np
import pytest
from rich.table import Table
from typer.testing import CliRunner

from stiffnet.cli import app
from stiffnet.console import _Out
from stiffnet.measurement import plots
from stiffnet.measurement.report import _CSS, _table

runner = CliRunner()


def _render(table: Table, width: int) -> str:
    buf = io.StringIO()
    _Out(file=buf, width=width, color_system=None).print(table)
    return buf.getvalue()


def _diagnosis_table() -> Table:
    t = Table(title="diagnosis")
    for col in ("effect", "reduction (abs.)", "reduction (rel.)", "fitted params",
                "recordings improved", "significant"):  # fmt: skip
        t.add_column(col)
    t.add_row("contact_damping_with_a_long_name", "0.123456", "45%",
              "damping_ratio=0.314, restitution_exponent=1.57", "100%", "yes")  # fmt: skip
    return t


def test_tables_keep_names_and_numbers_whole_at_80_columns():
    """Too wide for its words side by side: the table turns vertical, nothing is cut."""
    text = _render(_diagnosis_table(), 80)
    assert "…" not in text and max(len(line) for line in text.splitlines()) <= 80
    for token in (
        "0.123456",
        "45%",
        "100%",
        "contact_damping_with_a_long_name",
        "damping_ratio=0.314,",
        "restitution_exponent=1.57",
        "reduction (abs.)",
    ):
        assert token in text, token  # numbers and names never cut
    wide = _render(_diagnosis_table(), 400)
    assert "contact_damping_with_a_long_name" in wide and "restitution_exponent=1.57" in wide


def test_effects_command_fits_80_columns_and_wide_keeps_lines_whole():
    res = runner.invoke(app, ["effects"], env={"COLUMNS": "80"})
    assert res.exit_code == 0 and "…" not in res.output
    assert max(len(line) for line in res.output.splitlines()) <= 80
    wide = runner.invoke(app, ["--wide", "effects"])
    assert wide.exit_code == 0
    assert max(len(line) for line in wide.output.splitlines()) > 100  # natural width
    again = runner.invoke(app, ["effects"], env={"COLUMNS": "80"})  # --wide does not stick
    assert max(len(line) for line in again.output.splitlines()) <= 80


def test_report_layout_rules_fit_a_1280px_page():
    css = _CSS.replace(" ", "")
    assert "table{" in css and "width:100%" in css and "table-layout:auto" in css
    assert "overflow-wrap:break-word" in css  # long cells wrap instead of widening the page
    assert ".wrap{max-width:100%;overflow-x:auto}" in css  # a table never leaves the page
    assert "img{max-width:100%;height:auto}" in css
    body = re.search(r"body\{[^}]*max-width:(\d+)px", css)
    assert body and int(body.group(1)) <= 1280
    # no fixed widths anywhere else (px widths only as the page's max-width)
    assert re.findall(r"(?<!max-)width:\d+px", css) == []
    html = _table([{"effect": "x", "leave_one_out_relative_reduction": 0.5}],
                  ["effect", "leave_one_out_relative_reduction"])  # fmt: skip
    assert html.startswith("<div class='wrap'><table>")
    assert "leave-one-out relative reduction" in html  # headers wrap at spaces, say what
    assert "_" not in re.sub(r"<td>.*?</td>", "", html)


@pytest.mark.parametrize(("n", "grid"), [(1, (1, 1)), (3, (1, 3)), (4, (1, 4)), (5, (2, 3)),
                                          (6, (2, 3)), (7, (2, 4)), (8, (2, 4))])  # fmt: skip
def test_panel_grid_is_sized_to_the_panel_count(n, grid):
    rows, cols = plots.panel_grid(n)
    assert (rows, cols) == grid and rows * cols - n < cols  # no empty row


def _figure_of(monkeypatch, fn, *args):
    figs = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figs.append(fig) or path)
    fn(*args)
    return figs[0]


def test_ranking_chart_marks_clipped_bars(monkeypatch, tmp_path):
    diag = {
        "baseline_discrepancy": 3.0,
        "ranking": [
            {"effect": "contact_damping", "relative_reduction": 0.6, "significant": True},
            {"effect": "adc", "relative_reduction": -0.45, "significant": False},
        ],
    }
    fig = _figure_of(monkeypatch, plots.ranking_figure, diag, tmp_path / "r.png")
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert any("-45 %" in t and "clipped" in t for t in texts)
    hatched = [p.get_hatch() for p in ax.patches]
    assert hatched.count("//") == 1
    assert "%" in ax.get_xlabel() and "clipped" in ax.get_title()
    assert ax.get_xlim()[0] < 100 * plots.RANKING_FLOOR  # the clipped bar is inside


def test_analysis_figures_are_labelled_and_the_attractor_names_its_delay(monkeypatch, tmp_path):
    import stiffnet.plots as sp
    from stiffnet.analyze import analyze_signal
    from stiffnet.simulator.batch import OscillatorBatch
    from stiffnet.simulator.simulator import Simulator

    batch = OscillatorBatch.single(31.0, 2.8, 1.9, 1.05, 0.02)
    x = Simulator().simulate(batch, 100.0, 8000, noise=0.01, rng=3).accel[0]
    a = analyze_signal(x, 948.0)
    figs = []
    monkeypatch.setattr(sp, "_save", lambda fig, path: figs.append(fig) or path)
    sp.analysis_plots(a, x, tmp_path)
    axes = {p.axes[0].get_title().split(" ")[0]: p.axes[0] for p in figs}
    g = a.geometric
    attractor = axes["Attractor,"]
    assert f"{2 * g.delay} samples" in attractor.get_ylabel()
    assert f"tau = {g.delay} samples" in attractor.get_title()
    assert f"AMI embedding delay {a.delay}" in attractor.get_title()
    assert a.summary()["geometric_delay"] == g.delay
    assert axes["Embedding"].get_ylabel()  # the dimension plot has a y label
    for ax in axes.values():
        assert ax.get_xlabel() and ax.get_ylabel()
    assert np.isfinite(a.delay)

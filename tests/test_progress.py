"""Progress reporting: silent by default, bars with ETA on a terminal, per-step updates."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console
from typer.testing import CliRunner

from stiffnet import progress

MANIFEST = """recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s
a.csv,500,1.05,1.9,2.8,0.02,12,0.4
b.csv,500,0.95,1.0,0.5,0.02,40,0.4
c.csv,500,1.0,1.2,1.2,0.02,90,0.4
"""


class Recorder:
    """A display that records what it is told (stands in for rich's Progress)."""

    def __init__(self) -> None:
        self.events: list[tuple] = []
        self.tasks: dict[int, dict] = {}

    def add_task(self, description, total=None, **fields):
        tid = len(self.tasks)
        self.tasks[tid] = {"description": description, "total": total, "completed": 0, **fields}
        self.events.append(("add", description, total))
        return tid

    def update(self, task_id, advance=None, **kwargs):
        t = self.tasks[task_id]
        if advance is not None:
            t["completed"] += advance
        t.update(kwargs)
        self.events.append(("update", t["description"], t["completed"], t.get("note")))

    def remove_task(self, task_id):
        self.events.append(("remove", self.tasks[task_id]["description"]))


def test_tasks_are_silent_without_a_display():
    assert not progress.active()
    with progress.task("work", 3) as bar:
        bar.advance()
        bar.update(2, 5, note="x")  # no display: nothing to fail


def test_tasks_report_to_the_installed_display_only_inside_the_block():
    rec = Recorder()
    with progress.reporting(rec):
        assert progress.active()
        with progress.task("epochs", 2) as bar:
            bar.advance(note="loss 1")
            bar.advance(note="loss 0.5")
    assert not progress.active()
    with progress.task("after", 1) as bar:
        bar.advance()
    assert rec.events == [
        ("add", "epochs", 2),
        ("update", "epochs", 1, "loss 1"),
        ("update", "epochs", 2, "loss 0.5"),
        ("remove", "epochs"),
    ]


def test_simulate_campaign_reports_each_recording(tmp_path):
    from stiffnet.campaign import simulate_campaign

    (tmp_path / "plan.csv").write_text(MANIFEST)
    rec = Recorder()
    with progress.reporting(rec):
        simulate_campaign(tmp_path / "plan.csv", tmp_path / "out")
    done = [e[2] for e in rec.events if e[:2] == ("update", "simulating recordings")]
    assert done == [1, 2, 3] and rec.tasks[0]["total"] == 3


def _cli(monkeypatch, terminal: bool, *args: str) -> tuple[int, str]:
    import stiffnet.cli as cli
    import stiffnet.cli.console as shared

    buf = io.StringIO()
    console = Console(file=buf, force_terminal=terminal, width=120)
    monkeypatch.setattr(shared, "console", console)
    res = CliRunner().invoke(cli.app, list(args))
    return res.exit_code, buf.getvalue()


@pytest.mark.parametrize("terminal", [True, False])
def test_cli_draws_bars_with_eta_only_on_a_terminal(tmp_path, monkeypatch, terminal):
    (tmp_path / "plan.csv").write_text(MANIFEST)
    out = tmp_path / f"out{terminal}"
    code, err = _cli(monkeypatch, terminal, "simulate-campaign", str(tmp_path / "plan.csv"),
                     "--out", str(out))  # fmt: skip
    assert code == 0 and Path(out, "a.csv").is_file()
    if terminal:
        assert "simulating recordings" in err and "eta" in err and "/3" in err
    else:
        assert err == ""  # piped, redirected, scripted: silent


def test_diagnose_plans_its_steps_and_names_the_stage(tmp_path):
    """The total is known when the bar appears and never changes; the count only grows and
    reaches it; the note names the stage and the effect being fitted."""
    from stiffnet.campaign import ManifestRow, load_campaign, simulate_campaign, write_manifest
    from stiffnet.measurement.diagnose import diagnose_campaign, planned_steps

    rows = [
        ManifestRow(recording=f"r{b}.csv", fs_hz=1000, natural_frequency_hz=9.48,
                    frequency_ratio=w, amplitude=1.9, gap=e, damping_ratio=0.02, beta=b,
                    duration_s=2.0, noise=0.02)
        for b, w, e in ((10, 1.05, 2.8), (25, 1.1, 2.0), (45, 1.08, 2.4))
    ]  # fmt: skip
    write_manifest(tmp_path / "plan.csv", rows)
    camp = simulate_campaign(
        tmp_path / "plan.csv", tmp_path / "c", ["contact_damping:damping_ratio=0.3"]
    )
    rec = Recorder()
    calls = []
    with progress.reporting(rec):
        diagnose_campaign(
            load_campaign(camp), effects=["contact_damping", "colored_noise"],
            inclination=False, progress=lambda d, t: calls.append((d, t)),
        )  # fmt: skip
    (tid,) = [i for i, t in rec.tasks.items() if t["description"] == "diagnosis"]
    total = planned_steps(2)[-1]
    assert ("add", "diagnosis", total) in rec.events  # known from the start
    assert {t for _, t in calls} == {total}
    done = [d for d, _ in calls]
    assert done == sorted(done) and done[-1] == total
    notes = [e[3] for e in rec.events if e[0] == "update" and e[1] == "diagnosis"]
    assert any(n and "fitting contact_damping" in n for n in notes)
    assert any(n and "joint refit of contact_damping" in n for n in notes)

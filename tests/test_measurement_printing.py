"""Every candidate effect through the diagnosis' printing and JSON paths.

A rejected fit reports "effect off"; its parameters must still name every parameter the
effect fits (a harmonic's phase at zero amplitude), the terminal table must print any
ranking entry, and the JSON is written before anything is printed.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from campaign_helpers import without_beta
from rich.console import Console
from typer.testing import CliRunner

from stiffnet.campaign import ManifestRow, simulate_campaign, write_manifest
from stiffnet.cli import app
from stiffnet.cli import measurement as commands
from stiffnet.effects.registry import CANONICAL, effect_class
from stiffnet.measurement.diagnose import PROPOSED_ONLY
from stiffnet.measurement.fitting import effect_space, off_params

runner = CliRunner()


class _Row:
    fs_hz = 1000.0


def _entry(name: str, params: dict, selected: bool) -> dict:
    space = effect_space(name, [_Row()])
    return {
        "effect": name,
        "selected": selected,
        "significant": selected,
        "reasons": [] if selected else ["too small: it removes 1.0% of the discrepancy"],
        "params": params,
        "fitted": space.fitted,
        "discrepancy_reduction": 0.1,
        "excess_reduction": 0.05,
    }


def _printed(res: dict) -> str:
    console = Console(width=200, record=True, file=None)
    with console.capture() as cap:
        console.print(commands.diagnosis_table(res, "diagnosis"))
        console.print(commands.recording_table(res["per_recording"]))
        for line in commands.diagnosis_lines(res):
            console.print(line)
    return cap.get()


@pytest.mark.parametrize("name", list(CANONICAL))
def test_rejected_and_fitted_entries_print_for_every_candidate(name):
    """Rejected ("effect off") and fitted entries of every library effect: every fitted
    name has a value, and the table prints them (the harmonics' phases included)."""
    space = effect_space(name, [_Row()])
    off = off_params(name, space)
    fitted_point = space.params(np.full(len(space.free), 0.3))
    rows = [_entry(name, fitted_point, True)]
    if off is not None:
        assert set(space.fitted) <= set(off[0]), name
        effect_class(name)(**off[0])  # a valid parameter set of the effect
        rows.append(_entry(name, off[0], False))
    rows.append(_entry(name, {}, False))  # names without values must print, not raise
    res = {
        "baseline_discrepancy": 2.0,
        "noise_floor": 0.1,
        "ranking": rows,
        "verdict": "explained",
        "residual_discrepancy": 0.1,
        "explained_fraction": 0.95,
        "summary": "s",
        "restoring_force": {"summary": "evidence"},
        "per_recording": [
            {"recording": "a.csv", "floor": 0.1, "residual": 0.3, "ratio": 3.0,
             "above_floor": True, "non_repeatable": False, "measured_orbit": "no impacts",
             "simulated_orbit": "no impacts", "starts_on_measured_orbit": None,
             "distinct_orbits": 1, "note": ""},
            {"recording": "b.csv", "floor": 5.0, "residual": 0.3, "ratio": 0.06,
             "above_floor": False, "non_repeatable": True, "note": "non-repeatable: ..."},
        ],
    }  # fmt: skip
    text = _printed(res)
    assert "3 above" in text and "non-repeatable" in text
    assert name in text and "verdict: explained" in text
    for k in space.fitted:
        assert f"{k}=" in text


def test_json_is_written_before_printing_even_when_printing_fails(tmp_path, monkeypatch):
    """A display error cannot lose the diagnosis: the JSON is already on disk."""
    fake = {"baseline_discrepancy": 1.0, "noise_floor": 0.1, "ranking": [], "verdict": "x"}
    monkeypatch.setattr(
        "stiffnet.measurement.diagnose.diagnose_campaign", lambda *a, **k: dict(fake)
    )

    def broken(*_a, **_k):
        raise RuntimeError("display broke")

    monkeypatch.setattr(commands, "diagnosis_table", broken)
    camp = _campaign(tmp_path, 1.0)
    out = tmp_path / "d.json"
    res = runner.invoke(app, ["diagnose", str(camp), "--json", str(out)])
    assert res.exit_code != 0
    assert json.loads(out.read_text())["verdict"] == "x"


def _campaign(tmp, duration_s: float):
    rows = [
        ManifestRow(recording=f"recordings/r{b:03d}.csv", fs_hz=fs, natural_frequency_hz=9.48,
                    frequency_ratio=w, amplitude=a, gap=e, damping_ratio=0.02, beta=b,
                    duration_s=duration_s, noise=0.02)
        for b, fs, w, a, e in ((10, 1000, 1.05, 1.9, 2.8), (25, 1250, 1.1, 1.9, 2.0),
                               (45, 1500, 1.08, 1.7, 2.4))
    ]  # fmt: skip
    write_manifest(tmp / "plan.csv", rows)
    return simulate_campaign(tmp / "plan.csv", tmp / "camp", ["contact_damping:damping_ratio=0.3"])


@pytest.mark.slow
@pytest.mark.parametrize("field", [False, True], ids=["with_beta", "field_no_beta"])
def test_diagnose_cli_every_candidate(tmp_path, field):
    """The whole library as candidates (small budgets) on a tiny campaign with and without β:
    exit 0, the JSON holds every candidate with a value for each parameter it fits."""
    camp = _campaign(tmp_path, 2.0)
    if field:
        camp = without_beta(camp, tmp_path / "field")
    out = tmp_path / "d.json"
    args = ["diagnose", str(camp), "--budget", "3", "--budget-numerical", "2",
            "--no-inclination", "--json", str(out)]  # fmt: skip
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    diag = json.loads(out.read_text())
    assert {r["effect"] for r in diag["ranking"]} == set(CANONICAL) - set(PROPOSED_ONLY)
    for r in diag["ranking"]:
        assert set(r["fitted"]) <= set(r["params"]), r["effect"]
    assert "verdict:" in res.output


def test_a_mean_one_recording_carries_names_it_and_the_median():
    """An ideal campaign's one wandering orbit (1,140 against 0.008) made the headline mean
    48.1: the headline names the recording and the median beside the mean; a campaign whose
    recordings share the mean prints the mean alone."""
    names = [f"rec/r{i}.csv" for i in range(24)]
    values = [0.008] * 24
    values[5] = 1140.0
    note = commands.carried_note(values, names)
    assert "rec/r5.csv" in note and "100%" in note and "median 0.008" in note
    res = {
        "verdict": "nothing_missing",
        "residual_discrepancy": float(np.mean(values)),
        "explained_fraction": 0.0,
        "summary": "the base model is at the recordings' own noise floors",
        "residual_per_recording": values,
        "recordings": names,
    }
    assert "% of it from rec/r5.csv, median 0.008," in commands.diagnosis_lines(res)[0]
    shared = [0.5 + 0.01 * i for i in range(24)]
    assert commands.carried_note(shared, names) == ""
    assert commands.carried_note([1.0, float("nan")], names[:2]) == ""  # too few to say

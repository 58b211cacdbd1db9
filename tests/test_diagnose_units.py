"""Diagnose's output in the campaign's physical units, its nuisances named, the two-stage law.

The conversion is checked against the scales by hand: one model time unit is
``1 / (2 pi f_n)`` s, a natural period ``1 / f_n`` s, the length unit 1 mm when the
manifest gives a length in mm or g. The terminal, the JSON and the report say the same
values; a manifest without ``natural_frequency_hz`` says "model units".
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from stiffnet.campaign import ManifestRow
from stiffnet.cli import app
from stiffnet.effects.registry import effect_class
from stiffnet.measurement.report import diagnose_section
from stiffnet.measurement.report_units import (
    MODEL_UNITS,
    Scale,
    physical_reading,
    with_physical_units,
)

F_N = 12.5
TAU = 1 / (2 * math.pi * F_N)  # one model time unit, s
LAB = Scale(F_N, True, "", "")


@pytest.mark.parametrize(
    ("value", "unit", "expected", "physical_unit"),
    [
        (0.6, "model length", 0.6, "mm"),
        (12.0, "natural periods", 12.0 / F_N, "s"),
        (3.0, "model time", 3.0 * TAU, "s"),
        (1.05, "f/f_n", 1.05 * F_N, "Hz"),
        (2.0, "model time / length", 2.0 * TAU, "s/mm"),
        (0.1, "model acceleration", 0.1 * 1e-3 / TAU**2, "m/s²"),
        (237.0, "Hz", 237.0, "Hz"),
        (0.5, "rad", 0.5, "rad"),
        (0.25, "", 0.25, "dimensionless"),
    ],
)
def test_each_model_unit_is_its_value_times_the_scale(value, unit, expected, physical_unit):
    r = physical_reading(value, unit, LAB)
    assert r.physical and r.unit == physical_unit
    assert r.value == pytest.approx(expected, rel=1e-12) and r.model_value == value
    bare = physical_reading(value, unit, Scale())  # neither f_n nor a length unit given
    _, t, length, _ = MODEL_UNITS[unit]
    assert bare.physical == (t == 0 and length == 0)
    if not bare.physical:
        assert bare.value == value and bare.unit == unit and "(model units)" in bare.text()


def test_scale_of_a_manifest_says_what_it_lacks():
    lab = [ManifestRow(recording=f"{i}.csv", fs_hz=1000, natural_frequency_hz=F_N,
                       forcing_frequency_hz=13.0, base_acceleration_g=0.5, gap_mm=2.0)
           for i in range(2)]  # fmt: skip
    assert Scale.of(lab) == LAB
    plain = [ManifestRow(recording="a.csv", fs_hz=1000, frequency_ratio=1.0, gap=2.0)]
    s = Scale.of(plain)
    assert s.natural_frequency_hz is None and not s.length_mm
    assert "no natural_frequency_hz" in s.said() and "model units for lengths" in s.said()
    mixed = [lab[0], lab[1].model_copy(update={"natural_frequency_hz": 20.0})]
    assert "differs between recordings (12.5-20 Hz)" in Scale.of(mixed).said()
    # a user effect's own unit is kept, never converted
    assert not physical_reading(0.2, "furlongs", LAB).physical


def _diagnosis(names: list[str]) -> dict:
    """A diagnosis as diagnose returns it: gap_drift and sensor_dynamics fitted, the gap
    profiled with the selected effect and without."""
    n = len(names)
    return {
        "baseline_discrepancy": 3.0,
        "noise_floor": 0.1,
        "recordings": names,
        "ranking": [
            {"effect": "gap_drift", "selected": True, "significant": True, "reasons": [],
             "params": {"amplitude": 0.6, "period": 12.0, "phase": 0.5},
             "fitted": ["amplitude", "period", "phase"], "discrepancy_reduction": 2.0,
             "relative_reduction": 0.66,
             "excess_reduction": 0.9},
            {"effect": "sensor_dynamics", "selected": False, "significant": False,
             "reasons": ["too small"], "params": {"resonance_hz": 237.0,
                                                  "resonance_damping": 0.03},
             "fitted": ["resonance_hz", "resonance_damping"], "discrepancy_reduction": 0.1,
             "relative_reduction": 0.03,
             "excess_reduction": 0.01},
        ],
        "missing_effect": "gap_drift",
        "missing_effects": ["gap_drift"],
        "verdict": "explained",
        "residual_discrepancy": 0.1,
        "explained_fraction": 0.97,
        "summary": "s",
        "per_recording": [],
        "nuisances": {"start": [0] * n, "gap": [1.5 + 0.5 * i for i in range(n)],
                      "frequency_ratio": [1.04, 1.1][:n], "profiled_with": ["gap_drift"]},
        "nuisances_effect_free": {"start": [0] * n, "gap": [1.2, 1.9][:n],
                                  "profiled_with": []},
    }  # fmt: skip


def _campaign(tmp_path, physical: bool):
    """Two short recordings (noise: diagnose itself is replaced) and their manifest, in mm and
    Hz with f_n, or in model units without it."""
    folder = tmp_path / ("lab" if physical else "plain")
    (folder / "recordings").mkdir(parents=True)
    rng = np.random.default_rng(0)
    names = ["recordings/a.csv", "recordings/b.csv"]
    for name in names:
        t = np.arange(1000) / 1000
        np.savetxt(folder / name, np.c_[t, rng.normal(size=t.size)], delimiter=",",
                   header="t,accel", comments="")  # fmt: skip
    with open(folder / "manifest.csv", "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        if physical:
            w.writerow(["recording", "fs_hz", "natural_frequency_hz", "forcing_frequency_hz",
                        "base_displacement_mm", "gap_mm", "beta"])  # fmt: skip
            w.writerows([[n, 1000, F_N, 13.0, 1.5, 2.0, 20] for n in names])
        else:
            w.writerow(["recording", "fs_hz", "frequency_ratio", "amplitude", "gap", "beta"])
            w.writerows([[n, 1000, 1.04, 1.5, 2.0, 20] for n in names])
    return folder, names


def _run_diagnose(tmp_path, monkeypatch, physical: bool) -> tuple[dict, str]:
    folder, names = _campaign(tmp_path, physical)
    monkeypatch.setattr("stiffnet.measurement.diagnose.diagnose_campaign",
                        lambda *a, **k: _diagnosis(names))  # fmt: skip
    out = tmp_path / f"d{physical}.json"
    res = CliRunner().invoke(app, ["diagnose", str(folder), "--json", str(out)],
                             env={"COLUMNS": "200"})  # fmt: skip
    assert res.exit_code == 0, res.output
    return json.loads(out.read_text()), " ".join(res.output.split())


def test_diagnose_in_hz_and_mm_when_the_manifest_gives_them(tmp_path, monkeypatch):
    d, text = _run_diagnose(tmp_path, monkeypatch, physical=True)
    assert d["units"]["natural_frequency_hz"] == F_N and d["units"]["length_unit"] == "mm"
    drift = d["ranking"][0]["params_physical"]
    assert drift["period"]["unit"] == "s" and drift["period"]["model_value"] == 12.0
    assert drift["period"]["value"] == pytest.approx(12.0 / F_N)  # 12 natural periods
    assert drift["amplitude"] == {"value": 0.6, "unit": "mm", "model_value": 0.6,
                                  "model_unit": "model length",
                                  "in_physical_unit": True}  # fmt: skip
    assert d["ranking"][1]["params_physical"]["resonance_hz"]["unit"] == "Hz"
    freq = d["nuisances_physical"]["frequency_ratio"]
    assert [f["value"] for f in freq] == pytest.approx([1.04 * F_N, 1.1 * F_N])
    assert [g["unit"] for g in d["nuisances_effect_free_physical"]["gap"]] == ["mm", "mm"]
    # the terminal says the same numbers with their units
    assert "period=0.96 s (model 12 natural periods)" in text and "amplitude=0.6 mm" in text
    assert "resonance_hz=237 Hz" in text and "resonance_damping=0.03 (dimensionless)" in text
    assert "f_n = 12.5 Hz from the manifest" in text
    assert "nuisances profiled with gap_drift (the final model)" in text
    assert "frequency_ratio 13-13.8 Hz (model 1.04-1.1 f/f_n)" in text
    assert "nuisances profiled with no effect (the baseline), over the recordings: gap " \
           "1.2-1.9 mm" in text  # fmt: skip


def test_diagnose_says_model_units_without_a_natural_frequency(tmp_path, monkeypatch):
    d, text = _run_diagnose(tmp_path, monkeypatch, physical=False)
    assert d["units"]["natural_frequency_hz"] is None
    assert d["units"]["length_unit"] == "model length"
    period = d["ranking"][0]["params_physical"]["period"]
    assert period == {"value": 12.0, "unit": "natural periods", "model_value": 12.0,
                      "model_unit": "natural periods", "in_physical_unit": False}  # fmt: skip
    assert "period=12 natural periods (model units)" in text
    assert "amplitude=0.6 model length (model units)" in text
    assert "resonance_hz=237 Hz" in text  # measured against the sampling rate: always Hz
    assert "model units for times and frequencies (the manifest gives no " \
           "natural_frequency_hz" in text  # fmt: skip
    assert "frequency_ratio 1.04-1.1 f/f_n (model units)" in text


def test_the_report_says_the_same_values(tmp_path):
    names = ["a.csv", "b.csv"]
    rows = [ManifestRow(recording=n, fs_hz=1000, natural_frequency_hz=F_N,
                        forcing_frequency_hz=13.0, base_displacement_mm=1.5, gap_mm=2.0)
            for n in names]  # fmt: skip
    diag = with_physical_units(_diagnosis(names), rows)
    diag["per_recording"] = []
    page = "".join(diagnose_section(diag, tmp_path))
    assert "period=0.96 s (model 12 natural periods)" in page
    assert "f_n = 12.5 Hz from the manifest" in page
    assert "Nuisances: what diagnose fitted besides the effects" in page
    assert "<td>13 Hz (model 1.04 f/f_n)</td>" in page and "<td>no effect</td>" in page


def test_stiffening_contact_is_the_two_stage_law():
    """The test effect reuses the library's two-stage shape: beta d below the knee, then
    ``ratio`` times stiffer, as written by hand."""

    class Batch:
        beta = np.array([20.0, 20.0, 20.0, 20.0])

    delta = np.array([0.0, 0.01, 0.02, 0.05])
    effect = effect_class("user_effects:StiffeningContact")(knee=0.02, ratio=6.0)
    p = effect.batch_params(4, np.random.default_rng(0))
    force = effect.elastic_contact(delta, p, Batch())
    expected = 20.0 * (delta + 5.0 * np.maximum(delta - 0.02, 0.0))
    assert force == pytest.approx(expected, abs=1e-12)
    assert force[-1] == pytest.approx(20.0 * (0.05 + 5 * 0.03))


@pytest.mark.slow  # a real diagnosis: 5 recordings x 3 s, one candidate (~10 s of CPU)
def test_a_real_diagnosis_in_mm_and_hz_with_both_nuisance_profiles(tmp_path):
    """Contact damping hidden in a campaign written in mm and Hz with tolerances: the JSON's
    nuisances say what they were profiled with, and every value reads in the manifest's
    units as the model value times its scale."""
    from stiffnet.campaign import simulate_campaign, write_manifest

    plan = [ManifestRow(recording=f"recordings/r{i}.csv", fs_hz=1000, natural_frequency_hz=F_N,
                        frequency_ratio=w, amplitude=a, gap=e, damping_ratio=0.02, beta=b,
                        duration_s=3, noise=0.02)
            for i, (w, a, e, b) in enumerate([(1.05, 1.9, 2.8, 8), (1.0, 1.2, 1.2, 14),
                                               (1.1, 1.9, 2.0, 22), (0.98, 1.5, 1.6, 30),
                                               (1.02, 1.5, 1.0, 45)])]  # fmt: skip
    write_manifest(tmp_path / "plan.csv", plan)
    model = simulate_campaign(tmp_path / "plan.csv", tmp_path / "model",
                              ["contact_damping:damping_ratio=0.25"], seed=0)  # fmt: skip
    lab = tmp_path / "lab"
    (lab / "recordings").mkdir(parents=True)
    for r in plan:
        (lab / r.recording).write_bytes((model / r.recording).read_bytes())
    write_manifest(lab / "manifest.csv", [
        ManifestRow(recording=r.recording, fs_hz=1000, natural_frequency_hz=F_N,
                    forcing_frequency_hz=r.frequency_ratio * F_N, forcing_frequency_hz_tol=0.3,
                    base_displacement_mm=r.amplitude, gap_mm=r.gap, gap_mm_tol=0.1 * r.gap,
                    damping_ratio=0.02, beta=r.beta)
        for r in plan
    ])  # fmt: skip
    out = tmp_path / "d.json"
    res = CliRunner().invoke(app, ["diagnose", str(lab), "--only", "contact_damping",
                                   "--no-inclination", "--json", str(out)],
                             env={"COLUMNS": "200"})  # fmt: skip
    assert res.exit_code == 0, res.output
    d = json.loads(out.read_text())
    assert d["missing_effects"] == ["contact_damping"]
    assert d["nuisances"]["profiled_with"] == ["contact_damping"]
    assert d["nuisances_effect_free"]["profiled_with"] == []
    assert d["units"]["natural_frequency_hz"] == F_N and d["units"]["length_unit"] == "mm"
    for key in ("nuisances", "nuisances_effect_free"):
        gaps, said = d[key]["gap"], d[f"{key}_physical"]["gap"]
        assert [g["unit"] for g in said] == ["mm"] * 5
        assert [g["value"] for g in said] == pytest.approx(gaps)  # the model's unit is 1 mm
        assert all(abs(g - r.gap) <= 0.1 * r.gap + 1e-9 for g, r in zip(gaps, plan, strict=True))
    freq = d["nuisances_physical"]["frequency_ratio"]
    ratios = d["nuisances"]["frequency_ratio"]
    assert [f["value"] for f in freq] == pytest.approx([w * F_N for w in ratios])
    assert [f["value"] for f in freq] == pytest.approx([r.frequency_ratio * F_N for r in plan],
                                                       abs=0.3)  # fmt: skip
    damping = d["ranking"][0]["params_physical"]["damping_ratio"]
    assert damping["unit"] == "dimensionless"
    assert damping["value"] == d["fitted_params"]["contact_damping"]["damping_ratio"]
    text = " ".join(res.output.split())
    assert "nuisances profiled with contact_damping (the final model)" in text
    assert "Hz (model" in text and " mm" in text


def test_operating_points_in_hz_and_mm_only_where_the_manifest_gives_the_scale():
    """The report's operating points: a ratio without f_n stays a ratio (never times the
    paper's 9.48 Hz in silence), a forcing given in Hz reads back exactly, lengths are in mm
    only when the manifest gives one in mm or g."""
    from stiffnet.measurement.report_words import Units

    row = {"recording": "a.csv", "frequency_ratio": 1.05, "gap": 2.0, "amplitude": 1.5}
    ratio_mm = [ManifestRow(recording="a.csv", fs_hz=1000, frequency_ratio=1.05,
                            base_displacement_mm=1.5, gap_mm=2.0)]  # fmt: skip
    u = Units.of(ratio_mm)
    assert u.operating_point(row) == {"gap [mm]": 2.0, "forcing f/f_n": 1.05,
                                      "base displacement amplitude [mm]": 1.5}  # fmt: skip
    hz_model = [ManifestRow(recording="a.csv", fs_hz=1000, forcing_frequency_hz=9.954,
                            amplitude=1.5, gap=2.0)]  # fmt: skip
    u = Units.of(hz_model)
    ratio = hz_model[0].frequency_ratio  # 9.954 / 9.48, as the manifest reader made it
    point = u.operating_point({**row, "frequency_ratio": ratio})
    assert point["forcing frequency [Hz]"] == pytest.approx(9.954, rel=1e-12)
    assert point["gap [model length]"] == 2.0 and "base amplitude [model length]" in point


def test_the_field_report_says_which_model_its_diagnose_beta_was_profiled_with():
    from stiffnet.measurement.report import field_section

    ev = {"model": {"name": "m"}, "recordings": [{"recording": "a.csv", "beta": None}]}
    nuis = {"beta": [46.0], "profiled_with": ["contact_damping"]}
    page = "".join(field_section(ev, {"nuisances": nuis}))
    assert "profiled with the base model with contact_damping" in page
    page = "".join(field_section(ev, {"nuisances": {**nuis, "profiled_with": []}}))
    assert "profiled with the base model (the diagnosis' final model)" in page


def test_every_library_parameter_declares_a_unit_the_conversion_knows():
    """A new effect parameter in a unit the conversion lacks would print without one."""
    from stiffnet.effects.registry import CANONICAL

    for name in CANONICAL:
        for row in effect_class(name).parameter_table():
            assert row["unit"] in MODEL_UNITS, (name, row["name"], row["unit"])

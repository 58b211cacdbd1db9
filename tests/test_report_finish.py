"""The report's finish: every recording in its figures (bounded), provenance, beta intervals,
the manifest's units, alarm checks in words, alt texts, the two discrepancies explained."""

from __future__ import annotations

import ast
import csv
import hashlib
import inspect
import json
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from stiffnet import __version__
from stiffnet.campaign import ManifestRow, load_campaign, simulate_campaign
from stiffnet.cli import app
from stiffnet.measurement import plots, report, report_figures
from stiffnet.measurement.compare import Comparison, compare_campaign
from stiffnet.measurement.metrics import sliced_metrics
from stiffnet.measurement.report import render_report
from stiffnet.measurement.report_words import (
    Units,
    check_sentences,
    discrepancy_note,
    provenance,
    provenance_rows,
)

ODD = "a$^}<b>1.csv"  # mathtext and HTML in one recording name
PLAN_HEAD = ("recording,fs_hz,natural_frequency_hz,frequency_ratio,amplitude,gap,damping_ratio,"
             "beta,duration_s,noise\n")  # fmt: skip
LINES = [
    "1000,9.48,1.05,1.9,2.8,0.02,10,2.5,0.02",
    "1000,9.48,1.1,1.9,2.0,0.02,25,2.5,0.02",
    "1000,9.48,1.08,1.7,2.4,0.02,45,2.5,0.02",
    "1000,9.48,1.05,1.9,2.8,0.02,80,2.5,0.02",
    "1000,9.48,1.0,1.2,1.2,0.02,14,2.5,0.02",
    "1000,9.48,0.95,1.0,0.5,0.02,30,2.5,0.02",
    "1000,9.48,1.05,1.9,2.8,0.02,60,2.5,0.02",
    "1000,9.48,1.1,1.9,2.0,0.02,20,2.5,0.02",
    "1000,9.48,1.08,1.7,2.4,0.02,12,2.5,0.02",
]


def _campaign(root: Path, n: int, physical: bool) -> Path:
    """``n`` short recordings (the first named :data:`ODD`); ``physical``: the manifest is
    rewritten in mm and Hz, as a lab writes it."""
    names = [ODD, *(f"r{k:02d}.csv" for k in range(1, n))]
    (root / "plan.csv").write_text(
        PLAN_HEAD + "".join(f"{nm},{ln}\n" for nm, ln in zip(names, LINES[:n], strict=True))
    )
    camp = simulate_campaign(root / "plan.csv", root / "camp", ["contact_damping"], seed=3)
    if physical:
        rows = list(csv.DictReader((camp / "manifest.csv").open()))
        cols = ["recording", "fs_hz", "natural_frequency_hz", "forcing_frequency_hz",
                "base_displacement_mm", "gap_mm", "damping_ratio", "beta"]  # fmt: skip
        with (camp / "manifest.csv").open("w", newline="") as fh:
            w = csv.DictWriter(fh, cols)
            w.writeheader()
            for r in rows:
                w.writerow({**{k: r[k] for k in cols if k in r},
                            "forcing_frequency_hz": float(r["frequency_ratio"]) * 9.48,
                            "base_displacement_mm": r["amplitude"],
                            "gap_mm": r["gap"]})  # fmt: skip
    return camp


@pytest.fixture(scope="module")
def nine(tmp_path_factory):
    """Nine recordings compared with the simulator (more than the 8 panels drawn before)."""
    camp = _campaign(tmp_path_factory.mktemp("nine"), 9, physical=False)
    return compare_campaign(load_campaign(camp))


def _diagnosis(names, baseline=5.0):
    return {"baseline_discrepancy": baseline, "noise_floor": 0.5, "verdict": "explained",
            "summary": "s", "missing_effect": "contact_damping",
            "missing_effects": ["contact_damping"], "recordings": list(names),
            "nuisances": {"start": [0] * len(names), "gap": [1.0] * len(names)},
            "ranking": [{"effect": "contact_damping", "selected": True, "significant": True,
                         "relative_reduction": 0.8, "params": {"damping_ratio": 0.3},
                         "fitted": ["damping_ratio"], "discrepancy_reduction": 4.0,
                         "reasons": []}]}  # fmt: skip


def _alts(page: str) -> list[str]:
    return re.findall(r'<img alt="([^"]*)"', page)


# ------------------------------------------------------------------- 1 and 6: the figures


def test_every_recording_is_drawn_and_each_figure_says_what_it_shows(nine, monkeypatch):
    drawn = []
    for name in ("waveform_figure", "spectrum_figure"):
        real = getattr(plots, name)

        def spy(names, *a, _real=real, _name=name, max_panels=8, **kw):
            drawn.append((_name, list(names)[:max_panels]))
            return _real(names, *a, max_panels=max_panels, **kw)

        monkeypatch.setattr(plots, name, spy)
    names = [r["recording"] for r in nine.result["recordings"]]
    page = render_report("t", None, nine, _diagnosis(names, baseline=1.25))
    for kind in ("waveform_figure", "spectrum_figure"):
        shown = [n for k, ns in drawn if k == kind for n in ns]
        assert sorted(shown) == sorted(names), kind  # all nine, not the first eight
    assert "all 9 recordings" in page
    alts = _alts(page)
    assert len(alts) == page.count("data:image/png;base64,") == 4  # 2 pages, heat map, ranking
    assert all(len(a) > 80 for a in alts), alts  # words, not "w" or "s"
    assert any("Waveform figure" in a and "9:" in a for a in alts)
    assert any("Heat map" in a for a in alts) and any("contact_damping 80 %" in a for a in alts)
    assert "<b>1.csv" not in page and "a$^}&lt;b&gt;1.csv" in page  # escaped, drawn
    # compare's discrepancy and diagnose's baseline, both printed and explained
    assert f"compare&#x27;s {nine.result['discrepancy']:.3g}" in page
    assert "diagnose&#x27;s baseline 1.25" in page


def test_compare_plots_draw_every_recording_too(nine, tmp_path):
    figs = tmp_path / "figs"
    res = CliRunner().invoke(app, ["compare", nine.result["campaign"], "--plots", str(figs),
                                   "--json", str(tmp_path / "c.json")])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "all 9 recordings" in " ".join(res.output.split())
    written = json.loads((tmp_path / "c.json").read_text())["plots"]
    assert [Path(p).name for p in written] == [
        "compare_waveform.png", "compare_spectrum.png", "compare_components.png"
    ]  # fmt: skip
    assert all(Path(p).stat().st_size > 5000 for p in written)


def _fake_comparison(n):
    rng = np.random.default_rng(1)
    recs = [{"recording": f"r{k:03d}.csv", "beta": 20.0, "discrepancy": float(d),
             "components": {"waveform": 1.0}, "groups": {"contact": 1.0}}
            for k, d in enumerate(rng.uniform(0, 10, n))]  # fmt: skip
    res = {"discrepancy": 5.0, "recordings": recs, "by_group": {"contact": 1.0},
           "failure": {"group": "contact", "component": "waveform", "beta_class": "medium",
                       "recording": "r000.csv"}}  # fmt: skip
    return Comparison([None] * n, [None] * n, res)


def test_a_large_campaign_is_drawn_within_its_stated_bound(monkeypatch, tmp_path):
    calls = []

    def stub(kind):
        def draw(*args, max_panels=None, **kw):
            path = Path(args[-1] if kind == "components" else args[3])
            calls.append((kind, args[0] if kind != "components" else args[0]["recordings"]))
            path.write_bytes(report.PNG_SIGNATURE)
            return path

        return draw

    monkeypatch.setattr(plots, "waveform_figure", stub("waveform"))
    monkeypatch.setattr(plots, "spectrum_figure", stub("spectrum"))
    monkeypatch.setattr(plots, "components_figure", stub("components"))
    cmp = _fake_comparison(500)
    page = render_report("t", None, cmp, None)
    bound = report_figures.MAX_PANEL_RECORDINGS
    pages = [names for kind, names in calls if kind == "waveform"]
    assert [len(p) for p in pages] == [report_figures.PANELS_PER_PAGE] * (
        bound // report_figures.PANELS_PER_PAGE
    )
    worst = sorted(cmp.result["recordings"], key=lambda r: -r["discrepancy"])[:bound]
    assert sorted(n for p in pages for n in p) == sorted(r["recording"] for r in worst)
    heat = [rows for kind, rows in calls if kind == "components"][0]
    assert len(heat) == report_figures.MAX_HEATMAP_RECORDINGS
    assert f"the {bound} recordings with the largest discrepancy of 500" in page
    assert f"at most {bound} are drawn" in page
    assert page.count("<tr>") >= 500  # every recording stays in the table


def test_loop_and_learned_law_figures_have_alt_texts(tmp_path):
    from stiffnet.measurement.learned_law import learned_law_html

    loop = {"iterations": [{"index": 0, "label": "start", "metrics": {"discrepancy": 7.123456}},
                           {"index": 1, "label": "+contact_damping",
                            "metrics": {"discrepancy": 0.5}}]}  # fmt: skip
    alt = report_figures.loop_alt(loop)
    assert "0 (start): discrepancy 7.12; 1 (+contact_damping): discrepancy 0.5" in alt
    d = [0.0, 0.1, 0.2]
    proposal = {"ran": True, "summary": "a law", "law": {"path": [], "equation": "F = k d"},
                "map": [{"recording": ODD, "penetration": d, "force": d, "library": d,
                         "learned": d, "beta": 20.0}]}  # fmt: skip
    page = "".join(learned_law_html(proposal, tmp_path / "law.png"))  # "$^}" drawn as text
    (law_alt,) = _alts(page)
    assert "a$^}&lt;b&gt;1.csv" in law_alt and "learned law F = k d" in law_alt


# ------------------------------------------------------------------- 3, 4 and 5: evaluate


def _evaluated(name, ratio=1.05, fired=()):
    r = {"recording": name, "beta": 20.0, "class": "medium", "true_class": "medium",
         "beta_estimate": 21.0, "beta_interval": [17.5, 24.25], "geometric_class": "hard",
         "geometric_beta": 40.0, "restoring_force_class": "medium",
         "restoring_force_beta": 19.0, "restoring_force_beta_interval": [16.125, 22.5],
         "impact_regime": "impacting",
         "gap": 2.0, "frequency_ratio": ratio, "amplitude": 1.5, "ood": bool(fired),
         "ood_checks": list(fired), "error": 0.05,
         "alarm": {"flag": bool(fired), "fired": list(fired),
                   "scores": {"embedding": 5.0 if fired else 1.0, "ambiguity": 0.1},
                   "thresholds": {"embedding": 3.0, "ambiguity": 0.5}}}  # fmt: skip
    return r


def _evaluation(rows):
    return {"model": {"name": "cnn", "sha256": "ab" * 32, "kind": "cnn"}, "recordings": rows,
            "metrics": {"learned": {"n": len(rows)}}, "slices": sliced_metrics(rows)}  # fmt: skip


def test_evaluate_table_and_slices_carry_beta_by_simulation_and_the_reading():
    read = _evaluated("read.csv")
    read.update({"simulation_class": "medium", "simulation_beta": 20.5,
                 "simulation_beta_interval": [19.25, 21.75], "simulation_reproduced": True,
                 "reading_class": "medium", "reading_beta": 20.5,
                 "reading_method": "simulation"})  # fmt: skip
    lost = _evaluated("lost.csv", ratio=0.9)
    lost.update({"class": "hard", "simulation_class": None, "simulation_beta": None,
                 "simulation_beta_interval": None, "simulation_reproduced": None,
                 "reading_class": "hard", "reading_beta": 21.0,
                 "reading_method": "learned"})  # fmt: skip
    slices = sliced_metrics([read, lost])
    medium = slices["beta_class"]["medium"]
    # the simulation is scored on what it read, the reading on every recording
    assert medium["simulation"]["n"] == 1 and medium["simulation"]["accuracy"] == 1.0
    assert medium["reading"]["n"] == 2 and medium["reading"]["accuracy"] == 0.5
    assert medium["learned"]["accuracy"] == 0.5
    page = render_report("t", _evaluation([read, lost]), None, None)
    assert "beta (simulation)" in page and "[19.2, 21.8]" in page
    assert "medium (simulation)" in page and "hard (learned)" in page
    assert "reading accuracy" in page and "simulation beta MAPE" in page
    # without the simulation the table and the slices stay as they were
    plain = _evaluation([_evaluated("a.csv")])
    assert "simulation" not in plain["slices"]["beta_class"]["medium"]
    assert "beta (simulation)" not in render_report("t", plain, None, None)


def test_evaluate_table_has_both_beta_intervals_and_alarm_checks_in_words():
    rows = [_evaluated("quiet.csv"), _evaluated("loud.csv", fired=["embedding"])]
    renamed = _evaluated("renamed.csv")
    renamed["restoring_force_beta_interval"] = [30.5, 41.0]
    ev = _evaluation(rows)
    ev["recordings"] = [*rows, renamed]
    page = render_report("t", ev, None, None)
    assert "[30.5, 41]" in page
    assert "learned interval" in page and "[17.5, 24.2]" in page  # coverage unknown here
    assert "restoring-force interval" in page and "[16.1, 22.5]" in page
    assert "[&#x27;" not in page and "['" not in page  # no Python lists
    said = check_sentences(rows[1]["alarm"])
    assert said[0] == (
        "embedding (distance of the windows to the training data in the model's embedding): "
        "5 above its threshold 3: FIRED: the recording does not look like the training data "
        "to the model."
    )
    assert said[1].startswith("ambiguity (") and said[1].endswith("0.1 within its threshold "
                                                                  "0.5: passed.")  # fmt: skip
    assert "5 above its threshold 3: FIRED" in page and "loud.csv: alarm fired" in page
    assert check_sentences(None, ["layers"]) == [
        "layers (change of beta along the record): no score recorded: FIRED: layers."
    ]


def test_a_physical_manifest_reads_in_mm_and_hz():
    plain = [ManifestRow(recording="a.csv", fs_hz=1000, natural_frequency_hz=9.48,
                         frequency_ratio=1.05, amplitude=1.5, gap=2.0)]  # fmt: skip
    lab = [ManifestRow(recording="a.csv", fs_hz=1000, natural_frequency_hz=8.0,
                       forcing_frequency_hz=8.4, base_displacement_mm=1.5, gap_mm=2.0)]  # fmt: skip
    assert not Units.of(plain).physical and Units.of(lab).physical
    ev = _evaluation([_evaluated("a.csv", ratio=1.05)])
    page = render_report("t", ev, None, None, units=Units.of(lab))
    assert "gap [mm]" in page and "forcing frequency [Hz]" in page
    assert "<td>8.4</td>" in page  # 1.05 f_n with f_n = 8 Hz, not the ratio
    assert "forcing frequency [Hz] 8.4 Hz (f/f_n in [1.05, inf))" in page
    assert "gap [mm] in [1.5, 2.5)" in page
    model = render_report("t", ev, None, None, units=Units.of(plain))
    assert "forcing f/f_n" in model and "gap [model length]" in model and "[Hz]" not in model


# ------------------------------------------------------------------- 2: provenance


def test_provenance_names_date_version_command_and_hashes(tmp_path):
    camp = _campaign(tmp_path, 1, physical=False)
    c = load_campaign(camp)
    diag = tmp_path / "d.json"
    diag.write_text("{}")
    when = datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC)
    prov = provenance(c, "stiffnet report X --diagnosis d.json", diagnosis=diag, now=when)
    model = {"name": "cnn", "kind": "cnn", "sha256": "cd" * 32}
    page = render_report("t", None, None, None, provenance=prov)
    assert "2026-01-02 03:04:05 UTC" in page and __version__ in page
    assert "stiffnet report X --diagnosis d.json" in page
    manifest_hash = hashlib.sha256((camp / "manifest.csv").read_bytes()).hexdigest()
    assert manifest_hash in page and str(camp.resolve()) in page
    assert hashlib.sha256(b"{}").hexdigest() in page
    assert "cd" * 32 in render_report("t", _evaluation([_evaluated("a")]) | {"model": model},
                                      None, None, provenance=prov)  # fmt: skip


def test_provenance_names_the_plugin_files_and_puts_them_in_the_command(tmp_path, monkeypatch):
    """A plugin's code shaped the result: its file and hash are on the page, and the pasted
    command loads it again (``--plugin`` before the command, as ``stiffnet`` wants it)."""
    from stiffnet.effects import registry
    from stiffnet.measurement.report_words import command_line

    monkeypatch.setattr(registry, "_PLUGINS", dict(registry._PLUGINS))  # undone after the test
    plugin = tmp_path / "provenance_probe_effects.py"
    plugin.write_text("X = 1\n")
    registry.register_plugin(plugin)
    c = load_campaign(_campaign(tmp_path, 1, physical=False))
    prov = provenance(c, command_line("report", ["C"], plugins=[plugin.resolve()]))
    assert {"path": str(plugin.resolve()),
            "sha256": hashlib.sha256(b"X = 1\n").hexdigest()} in prov["plugins"]  # fmt: skip
    assert prov["command"] == f"stiffnet --plugin {plugin.resolve()} report C"
    assert ("plugin file", f"{plugin.resolve()} (SHA-256 {prov['plugins'][-1]['sha256']})") in (
        provenance_rows(prov, None)
    )


def test_an_unreadable_input_is_named_not_fatal(tmp_path, monkeypatch):
    from stiffnet import io_utils
    from stiffnet.measurement.report_words import file_identity

    def refuse(path):
        raise PermissionError(path)

    monkeypatch.setattr(io_utils, "sha256_file", refuse)
    (tmp_path / "d.json").write_text("{}")
    assert file_identity(tmp_path / "d.json") == {"path": str(tmp_path / "d.json"),
                                                  "sha256": None}  # fmt: skip
    rows = dict(provenance_rows({"diagnosis": file_identity(tmp_path / "d.json")}, None))
    assert rows["diagnosis"].endswith("(SHA-256 unreadable)")


def test_the_interval_header_says_the_models_own_coverage(tmp_path):
    from stiffnet.measurement.report_words import card_coverage

    (tmp_path / "m.card.json").write_text('{"metadata": {"conformal_coverage": 0.8}}')
    (tmp_path / "bad.card.json").write_text('{"metadata": [1]}')
    assert card_coverage(tmp_path / "m.onnx") == 0.8
    assert card_coverage(tmp_path / "bad.onnx") is None
    assert card_coverage(tmp_path / "none.onnx") is None
    ev = _evaluation([_evaluated("a.csv")])
    page = render_report("t", ev, None, None, provenance={"interval_coverage": 0.8})
    assert "learned 80 % interval" in page


# ------------------------------------------------------------------- 7: two discrepancies


def test_compare_and_diagnose_discrepancies_are_both_printed_and_explained(nine):
    names = [r["recording"] for r in nine.result["recordings"]]
    note = discrepancy_note(nine.result, _diagnosis(names, baseline=1.25))
    c = nine.result["discrepancy"]
    assert f"compare's {c:.3g}" in note and "diagnose's baseline 1.25" in note
    assert "same statistic" in note and "best of 8" in note and "the gap within" in note
    assert f"(difference {c - 1.25:+.3g})" in note
    with_orbits = _diagnosis(names, baseline=1.25)
    with_orbits["nuisances"]["orbits"] = [{"measured_orbit": "1 impact"}] * len(names)
    assert "orbits" not in discrepancy_note(nine.result, with_orbits)  # not a row parameter
    other = discrepancy_note(nine.result, _diagnosis(["x.csv"]))
    assert "other recordings" in other


@pytest.mark.slow
def test_diagnose_baseline_is_compare_after_the_nuisances_are_profiled(tmp_path):
    """What the note says, reproduced: the same per-recording statistic, compare's from the
    manifest and the first start, diagnose's after its starts and nuisances are profiled."""
    from stiffnet.campaign import LoadedCampaign
    from stiffnet.campaign.simulate import DEFAULT_SEED, FIT_SETTINGS, CampaignSolverSettings
    from stiffnet.measurement.diagnose import diagnose_campaign
    from stiffnet.measurement.noise_floor import noise_floor
    from stiffnet.measurement.nuisance import profile_nuisances, resolve_rows
    from stiffnet.measurement.target import CampaignTarget, measured_statistics

    camp = LoadedCampaign.of(load_campaign(_campaign(tmp_path, 3, physical=False)))
    cmp = compare_campaign(camp)
    diag = diagnose_campaign(camp, effects=["adc"], budget=2)
    rows, info = resolve_rows(camp)
    measured, lengths, signals = measured_statistics(camp, rows, True)
    target = CampaignTarget(rows, measured, lengths, [], DEFAULT_SEED, True)
    first = target.per_recording([], CampaignSolverSettings())
    assert np.allclose(first, [r["discrepancy"] for r in cmp.result["recordings"]])
    target.weights = noise_floor(signals, rows, FIT_SETTINGS.periods, True)["floors"].weights()
    target.weights = target.weights.tolist()
    profile_nuisances(target, [], FIT_SETTINGS, info)
    best = target.per_recording([], FIT_SETTINGS)
    assert np.allclose(best, diag["baseline_per_recording"])
    note = discrepancy_note(cmp.result, diag)
    assert f"{cmp.result['discrepancy']:.3g}" in note
    assert f"{diag['baseline_discrepancy']:.3g}" in note


# ------------------------------------------------------------------- 8: one job per function


def test_report_functions_each_decide_one_part():
    tree = ast.parse(inspect.getsource(report))
    long = {f.name: f.end_lineno - f.lineno + 1 for f in ast.walk(tree)
            if isinstance(f, ast.FunctionDef) and f.end_lineno - f.lineno + 1 > 60}  # fmt: skip
    assert not long, long
    for section in ("provenance_section", "evaluate_section", "compare_section",
                    "diagnose_section", "loop_section"):  # fmt: skip
        assert callable(getattr(report, section))


# ------------------------------------------------------------------- the command, end to end


def test_report_command_writes_the_finished_page(tmp_path):
    camp = _campaign(tmp_path, 3, physical=True)
    names = [r["recording"] for r in csv.DictReader((camp / "manifest.csv").open())]
    dj = tmp_path / "diag.json"
    dj.write_text(json.dumps(_diagnosis(names)))
    out = tmp_path / "r.html"
    res = CliRunner().invoke(app, ["report", str(camp), "--diagnosis", str(dj), "--out",
                                   str(out), "--json", str(tmp_path / "r.json")])  # fmt: skip
    assert res.exit_code == 0, res.output
    prov = json.loads((tmp_path / "r.json").read_text())["provenance"]
    assert prov["diagnosis"]["sha256"] == hashlib.sha256(dj.read_bytes()).hexdigest()
    page = out.read_text()
    today = datetime.now(UTC).strftime("%Y-%m-%d")
    assert f"<th>made</th><td>{today}" in page and f"<td>{__version__}</td>" in page
    # after `stiffnet` come the plugin files the suite loaded, then the command
    assert f" report {camp.resolve()} --out {out.resolve()} --diagnosis" in page
    assert f"--json {(tmp_path / 'r.json').resolve()}" in page
    assert hashlib.sha256(dj.read_bytes()).hexdigest() in page
    from serving.model import default_model_path

    card = default_model_path().with_suffix(".card.json")
    assert f"<th>model card</th><td>{card.resolve()} (SHA-256 " in page
    assert hashlib.sha256(card.read_bytes()).hexdigest() in page
    assert hashlib.sha256((camp / "manifest.csv").read_bytes()).hexdigest() in page
    assert "gap [mm]" in page and "forcing frequency [Hz]" in page
    assert "learned 90 % interval" in page and "restoring-force interval" in page
    assert "all 3 recordings" in page and "diagnose&#x27;s baseline 5" in page
    assert all(len(a) > 80 for a in _alts(page)) and "<b>1.csv" not in page

"""A recording's f_n is one value whatever reads it: the manifest's row and its sidecar
agree or the manifest is refused; ``predict`` on one recording of a campaign reads its row
as ``predict-batch`` does; a campaign's rows without f_n are said, not read silently at
the paper's 9.48 Hz."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from stiffnet.campaign import load_campaign, read_manifest
from stiffnet.campaign.manifest import campaign_row_of
from stiffnet.cli import app
from stiffnet.cli.measurement import assumed_natural_frequency
from stiffnet.errors import StiffnetError

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "recordings" / "impact_beta45.csv"
runner = CliRunner()


def _campaign(tmp_path: Path, header: str, row: str, sidecar_hz: float | None) -> Path:
    folder = tmp_path / "camp"
    (folder / "rec").mkdir(parents=True)
    shutil.copy(EXAMPLE, folder / "rec" / "run.csv")
    (folder / "manifest.csv").write_text(f"{header}\n{row}\n")
    if sidecar_hz is not None:
        (folder / "rec" / "run.csv.json").write_text(
            json.dumps({"natural_frequency_hz": sidecar_hz})
        )
    return folder


def test_a_sidecar_disagreeing_with_the_manifest_is_refused(tmp_path):
    camp = _campaign(
        tmp_path, "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,9.48", 12.0
    )
    said = r"line 2, column natural_frequency_hz: 9\.48 Hz disagrees with the recording's sidecar"
    with pytest.raises(StiffnetError, match=said + r" run\.csv\.json \(12 Hz\)"):
        load_campaign(camp)
    res = runner.invoke(app, ["predict", str(camp / "rec" / "run.csv")])
    assert res.exit_code == 2 and "disagrees with the recording's sidecar" in res.output


def test_a_sidecar_with_a_unit_on_its_f_n_is_told_to_write_the_number_alone(tmp_path):
    """'"natural_frequency_hz": "9.48 Hz"' was refused as 'must be a number' only."""
    camp = _campaign(tmp_path, "recording,fs_hz", "rec/run.csv,1000", None)
    (camp / "rec" / "run.csv.json").write_text(json.dumps({"natural_frequency_hz": "9.48 Hz"}))
    said = r"natural_frequency_hz must be a number, got '9\.48 Hz' \(the number alone: the name"
    with pytest.raises(StiffnetError, match=said):
        load_campaign(camp)
    res = runner.invoke(app, ["predict", str(camp / "rec" / "run.csv")])
    assert res.exit_code == 2 and "the number alone" in res.output


def test_a_sidecar_agreeing_within_its_rounding_is_read(tmp_path):
    # 0.05 % apart (the tolerance of a file's own rate): a value rounded in one file
    camp = _campaign(
        tmp_path, "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,9.48", 9.4847
    )
    assert load_campaign(camp).rows[0].natural_frequency_hz == 9.48


def test_the_sidecar_fills_a_row_without_f_n_before_its_units_convert(tmp_path):
    header = "recording,fs_hz,forcing_frequency_hz,base_acceleration_g,gap_mm,beta"
    camp = _campaign(tmp_path, header, "rec/run.csv,1000,14.9,1.7,2.8,45", 14.2)
    (row,) = read_manifest(camp / "manifest.csv")
    assert row.natural_frequency_hz == 14.2
    assert row.frequency_ratio == pytest.approx(14.9 / 14.2)  # not 14.9 / 9.48
    assert assumed_natural_frequency(load_campaign(camp)) is None


def test_diagnoses_units_say_the_f_n_came_from_the_sidecars(tmp_path):
    """A diagnosis's scale names where f_n was read: a campaign whose f_n is only in its
    recordings' sidecars said "from the manifest", a column the manifest lacks."""
    from stiffnet.measurement.report_units import Scale

    header = "recording,fs_hz,forcing_frequency_hz,base_acceleration_g,gap_mm,beta"
    camp = _campaign(tmp_path, header, "rec/run.csv,1000,14.9,1.7,2.8,45", 14.2)
    rows = read_manifest(camp / "manifest.csv")
    said = Scale.of(rows).said()
    assert "f_n = 14.2 Hz from the recordings' sidecars: times" in said
    given = _campaign(
        tmp_path / "b", "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,9.48", None
    )
    assert (
        "f_n = 9.48 Hz from the manifest:" in Scale.of(read_manifest(given / "manifest.csv")).said()
    )


def test_rows_without_f_n_are_said(tmp_path):
    camp = _campaign(tmp_path, "recording,fs_hz,beta", "rec/run.csv,1000,45", None)
    said = assumed_natural_frequency(load_campaign(camp))
    assert said is not None and "1 of 1 recordings (rec/run.csv)" in said and "9.48 Hz" in said


def test_predict_reads_the_row_of_the_campaign_its_recording_sits_in(tmp_path):
    camp = _campaign(
        tmp_path, "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,9.48", None
    )
    recording = camp / "rec" / "run.csv"
    manifest, row = campaign_row_of(recording)
    assert manifest == camp / "manifest.csv" and row.recording == "rec/run.csv"
    res = runner.invoke(app, ["predict", str(recording), "--json", str(tmp_path / "r.json")])
    assert res.exit_code == 0, res.output
    r = json.loads((tmp_path / "r.json").read_text())
    assert r["natural_frequency_source"].startswith(f"manifest:{manifest}: line 2")
    assert r["natural_frequency_hz"] == 9.48 and "manifest.csv line 2" in res.output
    # --fn still wins; a recording the manifest does not list is not read through it
    assert campaign_row_of(camp / "rec" / "other.csv") is None
    shutil.copy(EXAMPLE, tmp_path / "alone.csv")
    assert campaign_row_of(tmp_path / "alone.csv") is None


def test_a_broken_manifest_above_a_recording_says_why_predict_reads_it(tmp_path):
    """``predict rec/run.csv --fn 9.48`` in a folder whose manifest has a broken row was
    refused by the manifest's own message alone, which never said why a manifest was read
    for one recording given its f_n: it says so, and how to read the file alone."""
    camp = _campaign(tmp_path, "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,abc", None)
    res = runner.invoke(app, ["predict", str(camp / "rec" / "run.csv"), "--fn", "9.48"])
    assert res.exit_code == 2, res.output
    line = " ".join(res.output.split())
    assert "column natural_frequency_hz: not a number (got 'abc') (the manifest of the " in line
    assert "campaign run.csv sits in, read for its row: fix it, or copy the recording out" in line


@pytest.mark.parametrize("output", ["manifest.csv", "rec/run.csv.json"])
def test_an_output_never_lands_on_what_predict_reads_beside_its_recording(tmp_path, output):
    """``predict rec --json manifest.csv`` replaced the campaign's manifest (and a sidecar
    named as the output was replaced too): both are read with the recording."""
    camp = _campaign(
        tmp_path, "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,9.48", 9.48
    )
    before = (camp / output).read_bytes()
    res = runner.invoke(
        app, ["predict", str(camp / "rec" / "run.csv"), "--json", str(camp / output)]
    )
    assert res.exit_code == 2 and "is the input recording's" in res.output, res.output
    assert (camp / output).read_bytes() == before


def test_reading_a_campaigns_row_does_not_load_the_simulator():
    """``predict`` on a campaign's recording reads its manifest row (f_n): the predictor's
    path stays free of the simulator and numba (a subprocess: this one has both loaded)."""
    import subprocess
    import sys

    code = (
        "import sys; from stiffnet.campaign.manifest import campaign_row_of; "
        "import stiffnet.campaign as c; "
        "print('numba' in sys.modules, 'stiffnet.simulator.simulator' in sys.modules); "
        "c.simulate_rows; print('numba' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "True"], out.stderr


def test_predict_with_fn_still_reads_the_rows_layout_and_the_manifest_once(tmp_path, monkeypatch):
    """``--fn`` replaces the row's f_n only: its columns and time unit still read the file
    (it was refused for a wrong header); the manifest is parsed once (it was twice)."""
    from campaign_helpers import ms_campaign

    import stiffnet.campaign.manifest as manifest_module

    folder = ms_campaign(EXAMPLE, tmp_path / "camp")
    calls = []
    real = manifest_module.read_manifest
    monkeypatch.setattr(
        manifest_module, "read_manifest", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    out = tmp_path / "r.json"
    res = runner.invoke(app, ["predict", str(folder / "run.csv"), "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert len(calls) == 1 and json.loads(out.read_text())["natural_frequency_hz"] == 9.48
    res = runner.invoke(
        app, ["predict", str(folder / "run.csv"), "--fn", "9.5", "--json", str(out)]
    )
    assert res.exit_code == 0, res.output
    r = json.loads(out.read_text())
    assert r["natural_frequency_hz"] == 9.5 and r["natural_frequency_source"] == "option --fn"


def test_predict_channel_replaces_the_rows_columns(tmp_path):
    """``--channel`` on a recording whose campaign row names ``columns``: the option says
    which column to read (it was "give either 'columns' or 'channel'", as if the user had
    given both)."""
    import numpy as np

    from stiffnet.recordings import read_recording

    a = read_recording(EXAMPLE)
    folder = tmp_path / "camp"
    folder.mkdir()
    t = np.arange(a.accel.size) / a.fs_hz
    rows = (f"{float(x)!r},0.0,{float(v)!r}\n" for x, v in zip(t, a.accel, strict=True))
    (folder / "run.csv").write_text("t,force,accel\n" + "".join(rows))
    (folder / "manifest.csv").write_text(
        f"recording,fs_hz,natural_frequency_hz,columns\nrun.csv,{a.fs_hz:g},9.48,t;force\n"
    )
    out = tmp_path / "r.json"
    res = runner.invoke(
        app, ["predict", str(folder / "run.csv"), "--channel", "accel", "--json", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert json.loads(out.read_text())["class"] == "hard"  # the example's beta 45


def test_predict_batch_says_a_rows_f_n_came_from_its_sidecar(tmp_path):
    """A manifest without natural_frequency_hz whose recordings' sidecars give it: the
    folder and a glob say ``sidecar:<path>`` (they said ``manifest: line 2``, a column the
    manifest does not have); a row giving it still says its line."""
    from serving.batch_prediction import campaign_inputs, listed_settings

    camp = _campaign(tmp_path, "recording,fs_hz", "rec/run.csv,1000", 12.0)
    sidecar = f"sidecar:{camp / 'rec' / 'run.csv.json'}"
    _, settings, _, sources, _ = campaign_inputs(camp)
    assert settings[0][1] == 12.0 and sources == [sidecar]
    _, _, sources, _ = listed_settings([str(camp / "rec" / "run.csv")], (None,) * 5)
    assert sources == [sidecar]
    row = _campaign(
        tmp_path / "b", "recording,fs_hz,natural_frequency_hz", "rec/run.csv,1000,12", None
    )
    assert campaign_inputs(row)[3][0].startswith(f"manifest:{row / 'manifest.csv'}: line 2")

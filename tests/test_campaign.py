"""Campaigns: manifest validation, loading, and simulated campaigns (round trip, atomicity)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from stiffnet.campaign import (
    CARD_NAME,
    MANIFEST_NAME,
    Campaign,
    ManifestRow,
    load_campaign,
    read_manifest,
    sensor_gain,
    simulate_campaign,
    write_manifest,
)
from stiffnet.effects.gap_drift import GapDrift
from stiffnet.errors import StiffnetError
from stiffnet.recordings import write_recording_csv
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.simulator import Simulator

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "campaign_manifest.csv"

HEADER = "recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s"
SMALL = f"""{HEADER}
a.csv,500,1.05,1.9,2.8,0.02,12,0.4
sub/b.csv,800,0.95,1.0,0.5,0.02,40,0.3
c.npy,600,1.0,1.2,1.2,0.02,90,0.2
"""


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def manifest_error(tmp_path: Path, text: str, match: str) -> str:
    path = write(tmp_path / MANIFEST_NAME, text)
    with pytest.raises(StiffnetError, match=match) as info:
        read_manifest(path)
    msg = str(info.value)
    assert "\n" not in msg and MANIFEST_NAME in msg
    return msg


def snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("sim")
    manifest = write(root / "in" / "plan.csv", SMALL)
    effect = GapDrift(amplitude=[0.1, 0.3])
    out = simulate_campaign(manifest, root / "out", [effect], seed=7)
    return manifest, out


# ----------------------------------------------------------------- simulated campaigns


def test_round_trip(simulated):
    manifest, out = simulated
    assert sorted(os.listdir(out)) == sorted([CARD_NAME, "a.csv", "c.npy", MANIFEST_NAME, "sub"])
    camp = load_campaign(out)
    assert isinstance(camp, Campaign) and len(camp) == 3 and camp.is_calibration
    np.testing.assert_array_equal(camp.betas, [12, 40, 90])
    for row, rec in camp.recordings():
        assert rec.fs_hz == pytest.approx(row.fs_hz)
        assert len(rec) == round(row.duration_s * row.fs_hz)
        assert np.all(np.isfinite(rec.accel))
    # the output manifest carries the input's columns and values
    assert (out / MANIFEST_NAME).read_text().splitlines()[0] == HEADER
    assert read_manifest(out / MANIFEST_NAME) == read_manifest(manifest)


def test_card_lists_the_hidden_effect(simulated):
    _, out = simulated
    card = json.loads((out / CARD_NAME).read_text())
    assert card["seed"] == 7 and card["stiffnet_version"]
    (eff,) = card["effects"]
    assert eff["name"] == "gap_drift" and eff["params"]["amplitude"] == [0.1, 0.3]
    assert eff["class"] == "stiffnet.effects.gap_drift:GapDrift"
    drawn = [r["effects"]["gap_drift"]["amplitude"] for r in card["recordings"]]
    assert all(0.1 <= d <= 0.3 for d in drawn) and len(set(drawn)) == 3
    assert [r["recording"] for r in card["recordings"]] == ["a.csv", "sub/b.csv", "c.npy"]
    assert all(r["n_impacts"] > 0 for r in card["recordings"])


def test_card_reproduces_the_recording(simulated):
    """The card holds all it takes to re-simulate a recording (gain included)."""
    _, out = simulated
    card = json.loads((out / CARD_NAME).read_text())
    entry = card["recordings"][0]
    row = load_campaign(out).row("a.csv")
    batch = OscillatorBatch.single(
        row.beta, row.gap, row.amplitude, row.frequency_ratio, row.damping_ratio
    )
    res = Simulator([GapDrift(amplitude=[0.1, 0.3])]).simulate(
        batch,
        entry["fs_ratio"],
        entry["n_samples"],
        noise=entry["noise"],
        rng=np.random.default_rng(entry["seed_entropy"]),
    )
    rec = load_campaign(out).recording("a.csv")
    assert entry["sensor_gain"] == pytest.approx(sensor_gain(9.48))
    np.testing.assert_allclose(rec.accel, res.accel[0] * entry["sensor_gain"], rtol=1e-12)


def test_same_seed_same_files_whatever_the_row_order(simulated, tmp_path):
    manifest, out = simulated
    lines = SMALL.strip().splitlines()
    reordered = write(tmp_path / "rev.csv", "\n".join([lines[0], *lines[:0:-1]]) + "\n")
    again = simulate_campaign(reordered, tmp_path / "again", [GapDrift(amplitude=[0.1, 0.3])], 7)
    a, b = snapshot(out), snapshot(again)
    for name in ("a.csv", "sub/b.csv", "c.npy"):
        assert a[name] == b[name]
    other = simulate_campaign(manifest, tmp_path / "other", ["gap_drift:amplitude=0.1..0.3"], 8)
    assert snapshot(other)["a.csv"] != a["a.csv"]


def test_identical_output_for_identical_input(simulated, tmp_path):
    manifest, out = simulated
    again = simulate_campaign(manifest, tmp_path / "again", [GapDrift(amplitude=[0.1, 0.3])], 7)
    assert snapshot(again) == snapshot(out)


def test_existing_folder_is_left_untouched(simulated, tmp_path):
    manifest, _ = simulated
    out = tmp_path / "taken"
    write(out / "keep.txt", "precious")
    before = snapshot(out)
    with pytest.raises(StiffnetError, match="exists and is not empty"):
        simulate_campaign(manifest, out, [])
    assert snapshot(out) == before
    assert sorted(os.listdir(tmp_path)) == ["taken"]  # no temporary sibling left


def test_overwrite_replaces_the_folder(tmp_path):
    manifest = write(tmp_path / "m.csv", "\n".join(SMALL.splitlines()[:2]) + "\n")
    out = tmp_path / "out"
    write(out / "stale.txt", "old")
    write(out / CARD_NAME, "{}")  # a card without stiffnet's marker: not trusted
    with pytest.raises(StiffnetError, match="did not write"):
        simulate_campaign(manifest, out, [], overwrite=True)
    assert (out / "stale.txt").read_text() == "old"
    from stiffnet.io_utils import new_marker

    write(out / CARD_NAME, json.dumps(new_marker("stiffnet-campaign")))  # an earlier campaign
    simulate_campaign(manifest, out, [], overwrite=True)
    assert sorted(os.listdir(out)) == sorted([CARD_NAME, "a.csv", MANIFEST_NAME])
    assert sorted(os.listdir(tmp_path)) == ["m.csv", "out"]


def test_refuses_to_overwrite_the_input_folder(tmp_path):
    manifest = write(tmp_path / "camp" / MANIFEST_NAME, SMALL)
    with pytest.raises(StiffnetError, match="folder holding the input manifest"):
        simulate_campaign(manifest, tmp_path / "camp", [], overwrite=True)
    assert manifest.read_text() == SMALL


def test_failed_run_leaves_nothing(tmp_path):
    # the second row's rate is below 4 f_n: the simulator refuses it after row one
    text = f"{HEADER}\na.csv,500,1.05,1.9,2.8,0.02,12,0.2\nb.csv,20,1.05,1.9,2.8,0.02,12,0.2\n"
    manifest = write(tmp_path / "m.csv", text)
    with pytest.raises(StiffnetError, match=r"line 3 \(b\.csv\): fs_ratio"):
        simulate_campaign(manifest, tmp_path / "out", [])
    assert sorted(os.listdir(tmp_path)) == ["m.csv"]


def test_simulation_needs_model_columns(tmp_path):
    text = "recording,fs_hz,beta,gap,amplitude\nx.csv,500,10,1,1.5\n"
    manifest = write(tmp_path / "m.csv", text)
    with pytest.raises(
        StiffnetError, match=r"line 2 \(x\.csv\): column frequency_ratio, damping_ratio is required"
    ):
        simulate_campaign(manifest, tmp_path / "out", [])
    assert not (tmp_path / "out").exists()


def test_simulation_refuses_other_formats(tmp_path):
    text = SMALL.replace("c.npy", "c.wav")
    with pytest.raises(StiffnetError, match=r"\(c\.wav\): simulated recordings are .csv or .npy"):
        simulate_campaign(write(tmp_path / "m.csv", text), tmp_path / "out", [])


def test_example_manifest_is_a_simulation_input():
    rows = read_manifest(EXAMPLE)
    assert len(rows) == 8 and all(r.beta is not None for r in rows)
    for r in rows:
        assert None not in (r.gap, r.amplitude, r.frequency_ratio, r.damping_ratio)
        assert r.natural_frequency_hz == 9.48 and 1000 <= r.fs_hz <= 2000


# ----------------------------------------------------------------------- manifests


def test_manifest_round_trip(tmp_path):
    rows = read_manifest(write(tmp_path / "a" / MANIFEST_NAME, SMALL))
    path = write_manifest(tmp_path / "b" / MANIFEST_NAME, rows)
    assert read_manifest(path) == rows
    assert path.read_text().splitlines()[1] == "a.csv,500,1.05,1.9,2.8,0.02,12,0.4"
    assert os.listdir(path.parent) == [MANIFEST_NAME]  # no temp file left


def test_manifest_optional_cells_and_windows_paths(tmp_path):
    text = "recording,fs_hz,beta,channel\nday1\\run1.tdms,1000,,mass\nrun2.csv,2000,31,\n\n"
    rows = read_manifest(write(tmp_path / MANIFEST_NAME, text))
    assert rows[0].recording == "day1/run1.tdms" and rows[0].beta is None
    assert rows[0].channel == "mass" and rows[1].beta == 31 and rows[1].channel is None


def test_manifest_not_found(tmp_path):
    with pytest.raises(StiffnetError, match="manifest not found"):
        read_manifest(tmp_path / MANIFEST_NAME)


def test_manifest_empty(tmp_path):
    manifest_error(tmp_path, "", "manifest is empty")


def test_manifest_header_only(tmp_path):
    manifest_error(tmp_path, "recording,fs_hz\n", "lists no recordings")


def test_a_comment_above_the_manifest_header_is_said_so(tmp_path):
    """A lab's export notes on line 1 were 'unknown column 1 (name not shown)' beside the
    list of every allowed column."""
    manifest_error(
        tmp_path,
        "# exported by LabVIEW 2021, operator: K. Meier\nrecording,fs_hz\na.csv,1000\n",
        r"line 1 is a comment \(it starts with '#'\), not the header: a manifest's first line",
    )


def test_a_comment_line_among_the_rows_is_said_so(tmp_path):
    """A note between the rows was 'line 3 has 1 cells, expected 2'."""
    msg = manifest_error(
        tmp_path,
        "recording,fs_hz\na.csv,1000\n# b repeated: bolt loose\nb.csv,1000\n",
        r"line 3 is a comment \(it starts with '#'\): a manifest has no comment lines",
    )
    assert "cells" not in msg


@pytest.mark.parametrize("sep", [";", "\t"])
def test_a_manifest_separated_otherwise_is_said_so(tmp_path, sep):
    """A spreadsheet's export with ';' (decimal commas) was 'unknown column 1 (name not
    shown)' beside the list of every allowed column."""
    manifest_error(
        tmp_path,
        sep.join(["recording", "fs_hz", "beta"]) + "\n" + sep.join(["a.csv", "1000", "12,5"]),
        "the header's columns are separated by .*, not commas \\(recording, fs_hz, beta, ...\\)",
    )


def test_manifest_unknown_column(tmp_path):
    manifest_error(tmp_path, "recording,fs_hz,stiffness\na.csv,1,2\n", "unknown column 'stiffness'")


@pytest.mark.parametrize(
    ("header", "match"),
    [
        ("gap_mm [mm]", r"column 3 'gap_mm \[mm\]': a unit beside .* write 'gap_mm'$"),
        ("fs (Hz)", r"column 3 'fs \(Hz\)': .* write 'fs_hz'$"),  # as written, not 'fs (hz)'
        ("gap [mm]", r"write 'gap_mm'$"),  # not the model's 'gap'
        ("base_acceleration [m/s^2]", r"write 'base_acceleration_ms2'$"),
        ("fs_hz [kHz]", r"write 'fs_hz', in Hz \('kHz' is not its unit\)$"),
        # a stiffness in N/m is not the ratio the column holds; '-' is the ratio's own unit
        (
            "Beta [N/m]",
            r"'Beta \[N/m\]': .* write 'beta', a ratio without a unit \(the "
            r"restraint's stiffness over the primary spring's\) \('N/m' is not its unit\)$",
        ),
        ("damping_ratio (-)", r"write 'damping_ratio'$"),
    ],
)
def test_manifest_unit_beside_a_column_name_names_the_column_to_write(tmp_path, header, match):
    """A lab sheet's header with units beside the names is refused naming the cell and the
    column that carries the unit (was: 'unknown column 3 (name not shown)')."""
    manifest_error(tmp_path, f"recording,beta,{header}\na.csv,3,2\n", match)


@pytest.mark.parametrize(("cell", "hinted"), [("1000 Hz", True), ("2.8mm", True), ("x", False)])
def test_manifest_cell_with_its_unit_says_to_write_the_number_alone(tmp_path, cell, hinted):
    """A lab sheet's cells written with their unit ('1000 Hz' in fs_hz) were 'not a number'
    with nothing said of why; a sidecar's '9.48 Hz' already got the hint."""
    msg = manifest_error(tmp_path, f"recording,fs_hz\na.csv,{cell}\n", "column fs_hz: not a number")
    assert msg.endswith("(the number alone: the name carries the unit)") == hinted, msg


def test_manifest_cell_with_a_decimal_comma_says_to_write_a_point(tmp_path):
    """A lab sheet's '9,48' (a German locale's decimal comma, quoted so the comma-separated
    file keeps it one cell) was 'not a number' with nothing said of why."""
    msg = manifest_error(
        tmp_path, 'recording,fs_hz\na.csv,"1000,0"\n', "column fs_hz: not a number"
    )
    assert msg.endswith("(a comma in a number: write the decimal point '.' and no thousands "
                        "separator)"), msg  # fmt: skip


def test_manifest_with_absolute_windows_paths_names_the_tail_to_write(tmp_path):
    """A manifest written on the lab's Windows machine (``C:\\Users\\...\\rec\\r1.csv``) was
    refused on every row with no word of what to write; the tail that names a file of the
    folder is now said. A path whose tail names nothing here gets no suggestion."""
    write(tmp_path / "rec" / "r1.csv", "t,accel\n0,1\n")
    text = (
        "recording,fs_hz\n"
        "C:\\Users\\lab\\camp\\rec\\r1.csv,1000\n"
        "C:\\Users\\lab\\camp\\rec\\gone.csv,1000\n"
    )
    msg = manifest_error(tmp_path, text, r"^2 problems: ")
    assert (
        "line 2, column recording: must be a path relative to the campaign folder (an absolute "
        "path: write its tail 'rec/r1.csv', a file of this folder); also line 3, column "
        "recording: must be a path relative to the campaign folder" in msg
    ), msg
    assert msg.endswith("must be a path relative to the campaign folder"), msg


def test_a_folder_whose_manifest_sits_in_a_subfolder_is_told_where_it_must_sit(tmp_path):
    """``meta/manifest.csv`` naming ``../rec/r1.csv``: the folder was 'not a campaign folder
    (no manifest.csv)', and the manifest itself refused every '..' path."""
    write(tmp_path / "rec" / "r1.csv", "t,accel\n0,1\n")
    write(tmp_path / "meta" / MANIFEST_NAME, "recording,fs_hz\n../rec/r1.csv,1000\n")
    with pytest.raises(StiffnetError) as info:
        load_campaign(tmp_path)
    assert str(info.value) == (
        f"{tmp_path}: not a campaign folder (no manifest.csv) (meta/manifest.csv is one, but a "
        "campaign is the folder its manifest sits in, its recordings' paths starting there "
        "without '..': move it here and write its paths from here)"
    )
    (tmp_path / "meta" / MANIFEST_NAME).unlink()
    with pytest.raises(StiffnetError, match=r"not a campaign folder \(no manifest.csv\)$"):
        load_campaign(tmp_path)


@pytest.mark.parametrize(
    ("encoding", "said"),
    [
        ("utf-16", ": it is UTF-16 text, as Windows saves 'Unicode' text; save it as UTF-8"),
        ("latin-1", ": line 2 holds a byte that is not UTF-8 (Latin-1 or Windows-1252 text, "),
    ],
)
def test_manifest_not_utf8_says_which_encoding_or_line(tmp_path, encoding, said):
    """A manifest saved by a spreadsheet as UTF-16 or Latin-1 (a file name with an accent)
    was 'manifest is not a UTF-8 text file' alone."""
    path = tmp_path / MANIFEST_NAME
    path.write_text("recording,fs_hz\nmesuré.csv,1000\n", encoding=encoding)
    with pytest.raises(StiffnetError) as info:
        read_manifest(path)
    assert str(info.value).startswith(f"{path}: manifest is not a UTF-8 text file{said}")


def test_manifest_header_cell_with_odd_symbols_beside_a_name_is_not_quoted(tmp_path):
    msg = manifest_error(tmp_path, "recording,fs_hz,beta [k=\x01!]\na.csv,3,2\n", "unknown")
    assert "(name not shown)" in msg and "k=" not in msg


def test_manifest_names_every_bad_row_in_one_line(tmp_path):
    """A lab sheet with a bad cell, a repeated recording and a bad number: all three in one
    message, in file order, so that one run shows what to mend (was: the first alone)."""
    text = ("recording,fs_hz,damping_ratio\na.csv,1000,0.02\nb.csv,1000,2\nc.csv,x,0.02\n"
            "a.csv,1000,0.02\nd.csv,1000,0.02\n")  # fmt: skip
    msg = manifest_error(tmp_path, text, r"^3 problems: ")
    lines = [msg.index(f"line {n}") for n in (3, 4, 5)]
    assert lines == sorted(lines), msg
    assert "must be < 1" in msg and "fs_hz" in msg and "listed twice (also on line 2)" in msg
    assert msg.count(str(tmp_path)) == 1  # the manifest named once


def test_manifest_counts_the_problems_it_does_not_spell_out(tmp_path):
    text = "recording,fs_hz\n" + "".join(f"r{i}.csv,-1\n" for i in range(8))
    msg = manifest_error(tmp_path, text, r"^8 problems: ")
    assert msg.endswith("; and 3 more"), msg


def test_load_campaign_names_every_missing_file(tmp_path):
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\na.csv,1000\nb.csv,1000\nc.csv,1000\n")
    write(tmp_path / "b.csv", "t,accel\n0,1\n")
    with pytest.raises(
        StiffnetError,
        match=r"^2 problems: .*line 2 \(a\.csv\): recording file "
        r"not found.*; also line 4 \(c\.csv\): recording file not found",
    ):
        load_campaign(tmp_path)


def test_manifest_missing_required_column(tmp_path):
    manifest_error(tmp_path, "recording,beta\na.csv,3\n", "missing required column fs_hz")


def test_manifest_duplicate_column(tmp_path):
    manifest_error(tmp_path, "recording,fs_hz,fs_hz\na.csv,1,2\n", "'fs_hz' appears twice")


def test_manifest_wrong_number_of_cells(tmp_path):
    manifest_error(tmp_path, "recording,fs_hz\na.csv,1\nb.csv\n", "line 3 has 1 cells, expected 2")


def test_manifest_missing_value(tmp_path):
    manifest_error(
        tmp_path, "recording,fs_hz\na.csv,\n", "line 2, column fs_hz: a value is required"
    )


def test_manifest_not_a_number(tmp_path):
    manifest_error(
        tmp_path, "recording,fs_hz\na.csv,1000\nb.csv,fast\n", "line 3, column fs_hz: not a number"
    )


@pytest.mark.parametrize(
    ("column", "value", "match"),
    [
        ("fs_hz", "0", "must be > 0"),
        ("fs_hz", "-100", "must be > 0"),
        ("beta", "-1", "must be >= 0"),
        ("damping_ratio", "1", "must be < 1"),
        ("damping_ratio", "0", "must be > 0"),
        ("frequency_ratio", "0", "must be > 0"),
        ("amplitude", "-0.5", "must be > 0"),
        ("natural_frequency_hz", "0", "must be > 0"),
        ("duration_s", "0", "must be > 0"),
        ("noise", "-0.1", "must be >= 0"),
        ("gap", "nan", "must be a finite number"),
        ("beta", "inf", "must be a finite number"),
    ],
)
def test_manifest_out_of_range(tmp_path, column, value, match):
    text = f"recording,fs_hz,{column}\na.csv,1000,{value}\n"
    if column == "fs_hz":
        text = f"recording,fs_hz\na.csv,{value}\n"
    msg = manifest_error(tmp_path, text, f"line 2, column {column}: {match}")
    assert repr(value) in msg


def test_manifest_duplicate_recording(tmp_path):
    text = "recording,fs_hz\na.csv,1\nb.csv,1\n./a.csv,2\n"
    manifest_error(tmp_path, text, r"line 4: recording 'a.csv' is listed twice \(also on line 2\)")


@pytest.mark.parametrize("path", ["../x.csv", "a/../../x.csv", "/etc/x.csv", "C:/data/x.csv"])
def test_manifest_refuses_paths_outside(tmp_path, path):
    manifest_error(tmp_path, f"recording,fs_hz\n{path},1\n", "line 2, column recording")


def test_manifest_row_in_code():
    row = ManifestRow(recording="r.csv", fs_hz=100)
    assert row.beta is None and row.where() == "manifest.csv: (r.csv)"
    with pytest.raises(ValueError, match="Extra inputs"):
        ManifestRow(recording="r.csv", fs_hz=100, bogus=1)


def test_write_manifest_keeps_values(tmp_path):
    rows = [ManifestRow(recording="r.csv", fs_hz=100, beta=12.5)]
    with pytest.raises(StiffnetError, match="column 'beta' has a value"):
        write_manifest(tmp_path / MANIFEST_NAME, rows, columns=["recording", "fs_hz"])


# ------------------------------------------------------------------------ loading


def test_load_campaign_reads_lazily_with_manifest_fs(tmp_path):
    x = np.sin(np.arange(300) / 7.0)
    write_recording_csv(tmp_path / "r1.csv", x, 1000)
    np.save(tmp_path / "r2.npy", 2 * x)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nr1.csv,1000\nr2.npy,500\n")
    camp = load_campaign(tmp_path)
    assert not camp.is_calibration and np.isnan(camp.betas).all()
    rec = camp.recording("r2.npy")
    assert rec.fs_hz == 500 and np.array_equal(rec.accel, 2 * x)
    assert camp.path(0) == (tmp_path / "r1.csv").resolve()
    # the manifest file itself works too
    assert len(load_campaign(tmp_path / MANIFEST_NAME)) == 2


def test_load_campaign_fs_mismatch_is_reported_on_read(tmp_path):
    write_recording_csv(tmp_path / "r1.csv", np.zeros(10), 1000)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nr1.csv,2000\n")
    camp = load_campaign(tmp_path)
    with pytest.raises(StiffnetError, match="r1.csv: column t gives fs = 1000 Hz"):
        camp.recording(0)


def test_fs_mismatch_names_the_manifest_line_that_gave_the_rate(tmp_path):
    write_recording_csv(tmp_path / "r0.csv", np.zeros(10), 1000)
    write_recording_csv(tmp_path / "r1.csv", np.zeros(10), 1000)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nr0.csv,1000\nr1.csv,1200\n")
    camp = load_campaign(tmp_path)
    said = r"manifest.csv: line 3 \(r1.csv\), column fs_hz: .*r1.csv: column t gives fs = 1000 Hz"
    with pytest.raises(StiffnetError, match=said):
        camp.recording(1)


def test_manifest_ignores_the_unnamed_empty_columns_a_spreadsheet_leaves(tmp_path):
    write_recording_csv(tmp_path / "r1.csv", np.zeros(10), 1000)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz,beta,,\r\nr1.csv,1000,12,,\r\n")
    camp = load_campaign(tmp_path)
    assert camp.rows[0].beta == 12 and camp.rows[0].fs_hz == 1000
    # a value under an unnamed column is still a problem, and so is an unnamed column between
    manifest_error(tmp_path, "recording,fs_hz,,\nr1.csv,1000,7,\n", "line 2 has 4 cells")
    manifest_error(
        tmp_path, "recording,,fs_hz\nr1.csv,,1000\n", "column 2 of the header has no name"
    )


def test_missing_recording_names_its_twin_in_another_case(tmp_path):
    write_recording_csv(tmp_path / "rec" / "Run01.csv", np.zeros(10), 1000)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nrec/run01.csv,1000\n")
    with pytest.raises(StiffnetError, match=r"not found: .* \(the folder holds 'Run01.csv', which"):
        load_campaign(tmp_path)


def test_missing_recording_names_its_folders_twin_in_another_case(tmp_path):
    """A manifest typed on Windows ('REC/R00_B12.CSV' for rec/r00_b12.csv) was 'recording
    file not found' with nothing said: the hint looked for the file in a folder missing too."""
    write_recording_csv(tmp_path / "rec" / "r00.csv", np.zeros(10), 1000)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nREC/R00.CSV,1000\n")
    with pytest.raises(StiffnetError, match=r"not found: .* \(the folder holds 'rec' \(where "
                       r"'REC' was written\), which differs only in letter case"):  # fmt: skip
        load_campaign(tmp_path)


def test_load_campaign_missing_recording(tmp_path):
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nmissing.csv,1000\n")
    with pytest.raises(StiffnetError, match=r"line 2 \(missing.csv\): recording file not found"):
        load_campaign(tmp_path)


def test_load_campaign_without_manifest(tmp_path):
    with pytest.raises(StiffnetError, match="not a campaign folder"):
        load_campaign(tmp_path)
    with pytest.raises(StiffnetError, match="campaign folder not found"):
        load_campaign(tmp_path / "nope")


def test_load_campaign_refuses_symlinks_out(tmp_path):
    outside = write_recording_csv(tmp_path / "secret.csv", np.zeros(10), 1000)
    camp = tmp_path / "camp"
    camp.mkdir()
    (camp / "link.csv").symlink_to(outside)
    write(camp / MANIFEST_NAME, "recording,fs_hz\nlink.csv,1000\n")
    with pytest.raises(StiffnetError, match="recording path leaves the campaign folder"):
        load_campaign(camp)


def test_manifest_columns_and_time_unit_read_lab_files(tmp_path):
    """Each row may name its CSV columns and time unit (a quoted cell or ';' between them)."""
    x = np.sin(np.arange(400) / 7.0)
    lines = "\n".join(f"{k * 2},{float(v)!r}" for k, v in enumerate(x))  # 2 ms steps
    write(tmp_path / "lab.csv", "time_ms,acc_g\n" + lines + "\n")
    text = 'recording,fs_hz,columns,time_unit\nlab.csv,500,"time_ms,acc_g",ms\n'
    write(tmp_path / MANIFEST_NAME, text)
    rec = load_campaign(tmp_path).recording(0)
    assert rec.fs_hz == 500 and np.array_equal(rec.accel, x)
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz,columns,time_unit\nlab.csv,500,0;1,ms\n")
    assert np.array_equal(load_campaign(tmp_path).recording(0).accel, x)
    # a wrong unit is a manifest error naming the line and column
    manifest_error(tmp_path, "recording,fs_hz,time_unit\nlab.csv,500,min\n",
                   "line 2, column time_unit")  # fmt: skip
    # without the columns the header error says how to map it
    write(tmp_path / MANIFEST_NAME, "recording,fs_hz\nlab.csv,500\n")
    with pytest.raises(StiffnetError, match="--columns time_ms,acc_g --time-unit ms"):
        load_campaign(tmp_path).recording(0)


def test_simulated_manifest_drops_read_options(tmp_path):
    text = SMALL.replace(HEADER, HEADER + ",time_unit").replace("0.4\n", "0.4,ms\n", 1)
    text = text.replace("0.3\n", "0.3,\n").replace("0.2\n", "0.2,\n")
    out = simulate_campaign(write(tmp_path / "plan.csv", text), tmp_path / "out")
    assert "time_unit" not in (out / MANIFEST_NAME).read_text()  # written in seconds
    assert load_campaign(out).recording(0).fs_hz == pytest.approx(500)


def test_unlisted_recordings_are_the_folders_recording_files_without_a_row(tmp_path):
    """Only files of a recording format count: not the manifest, a sidecar, notes, hidden
    files or folders; listed ones by any spelling of their path."""
    from stiffnet.campaign.manifest import unlisted_recordings, unlisted_words

    for name in ("a.csv", "sub/b.tdms", "sub/c.npy", "a.csv.json", "notes.txt", ".hidden.csv",
                 ".git/x.csv", "d.WAV"):  # fmt: skip
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("x")
    manifest = write(tmp_path / MANIFEST_NAME, "recording,fs_hz\na.csv,1000\n")
    found = unlisted_recordings(manifest, ["a.csv", "sub/./c.npy"])
    assert found == ["d.WAV", "sub/b.tdms"]
    assert unlisted_words(found).startswith(
        "2 recording file(s) in the campaign folder are not in its manifest (d.WAV, sub/b.tdms)"
    )
    assert unlisted_words([]) is None

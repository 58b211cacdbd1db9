"""The finish a lab user expects: tables that never split a word or a number at 60, 80
or 100 columns, hints that can be pasted, ``--version``, ``--json -``, completion."""

from __future__ import annotations

import re
import shlex
import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_contract import EXAMPLE, ROOT, runner

from stiffnet import __version__
from stiffnet.cli import app

MODEL = ROOT / "models" / "gbm.onnx"
_NOT_TOKEN = r"\s│┃┆║|─━═┏┓┗┛┡┩┢┪╇╈┯┷┳┻╋┼┌┐└┘├┤┬┴╭╮╰╯"
TOKEN = re.compile(f"[^{_NOT_TOKEN}]+")


def _tokens(text: str) -> set[str]:
    return set(TOKEN.findall(text))


def _render(args: list[str], width: int | str) -> str:
    res = runner.invoke(app, args, env={"COLUMNS": str(width)})
    assert res.exit_code == 0, res.output
    return res.stdout


def assert_no_token_split(args: list[str], width: int) -> None:
    """Every word of the natural-width tables is whole on some line at ``width`` columns."""
    wide = _render(["--wide", *args], 400)
    narrow = _render(args, width)
    lines = narrow.splitlines()
    assert max(map(len, lines)) <= width, max(lines, key=len)
    found = set().union(*(set(TOKEN.findall(line)) for line in lines))
    missing = sorted(t for t in _tokens(wide) if len(t) < width - 8 and t not in found)
    assert not missing, (width, missing[:10], narrow[:2000])


@pytest.mark.parametrize("width", [60, 80, 100])
def test_effects_tables_never_split_a_name_or_a_number(width):
    assert_no_token_split(["effects"], width)
    names = [
        "resonance_damping",
        "stiffness_ratio",
        "reference_penetration",
    ]  # names a user must type, e.g. --effect sensor_dynamics:resonance_damping=0.01
    text = _render(["effects"], width)
    for name in names:
        assert name in _tokens(text), name


@pytest.mark.parametrize("width", [60, 80, 100])
def test_predict_and_analyze_tables_never_split_a_token(width, tmp_path):
    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    assert_no_token_split(["predict", str(rec), "--model", str(MODEL), "--fn", "9.48"], width)
    assert_no_token_split(["analyze", str(rec), "--fn", "9.48"], width)


def _lab_recording(path):
    from stiffnet.recordings import read_recording

    rec = read_recording(EXAMPLE)
    rows = "".join(f"{1e3 * i / rec.fs_hz:.6f},{a:.9g}\n" for i, a in enumerate(rec.accel))
    path.write_text("Time [ms],Acceleration [g]\n" + rows)
    return path


def test_wrong_header_hint_can_be_pasted(tmp_path):
    rec = _lab_recording(tmp_path / "lab.csv")
    res = runner.invoke(app, ["predict", str(rec), "--model", str(MODEL), "--fn", "9.48"])
    assert res.exit_code == 2
    line = res.stderr.strip()
    assert "wrong header 'Time [ms],Acceleration [g]'" in line  # the header it then names
    hint = line.split("name its columns: ", 1)[1]
    assert hint == '--columns "Time [ms],Acceleration [g]" --time-unit ms'
    pasted = runner.invoke(
        app, ["predict", str(rec), "--model", str(MODEL), "--fn", "9.48", *shlex.split(hint)]
    )
    assert pasted.exit_code == 0, pasted.output


def test_evaluate_hint_names_the_manifest_not_an_option(tmp_path):
    camp = tmp_path / "camp"
    camp.mkdir()
    _lab_recording(camp / "lab.csv")
    (camp / "manifest.csv").write_text("recording,fs_hz,beta\nlab.csv,1000,12\n")
    res = runner.invoke(app, ["evaluate", str(camp), "--model", str(MODEL)])
    assert res.exit_code == 2
    assert "--columns" not in res.stderr  # evaluate has no such option
    assert 'in the manifest: columns "Time [ms],Acceleration [g]" and time_unit ms' in res.stderr


def test_plugin_after_the_command_says_where_it_goes():
    res = runner.invoke(app, ["simulate", "--plugin", "x.py"])
    assert res.exit_code == 2 and "stiffnet --plugin FILE.py COMMAND" in res.stderr


def test_version_and_completion(monkeypatch):
    # Typer asks the parent process which shell it is unless told not to; pytest run
    # detached from any shell (a background job, some CI runners) has none to find.
    monkeypatch.setenv("_TYPER_COMPLETE_TEST_DISABLE_SHELL_DETECTION", "1")
    res = runner.invoke(app, ["--version"])
    assert res.exit_code == 0 and res.stdout.strip() == f"stiffnet {__version__}"
    res = runner.invoke(app, ["--show-completion", "bash"], prog_name="stiffnet")
    assert res.exit_code == 0 and "_STIFFNET_COMPLETE=complete_bash" in res.stdout


def test_json_dash_keeps_stdout_pure_json(tmp_path):
    import json

    res = runner.invoke(app, ["effects", "--json", "-"])
    assert res.exit_code == 0, res.output
    effects = json.loads(res.stdout)
    assert {e["name"] for e in effects} >= {"contact_damping", "sensor_dynamics"}
    assert "contact_damping (dynamics)" in res.stderr  # the tables, out of the way


def test_effects_lists_the_loaded_plugins_by_the_name_to_type(tmp_path):
    import json

    plugin = tmp_path / "lab_laws.py"
    plugin.write_text(
        "from stiffnet.effects.base import EffectParams, MeasurementEffect, ParamValue, param\n"
        "class Tilt(MeasurementEffect):\n"
        '    """A gain."""\n'
        '    name = "tilt"\n'
        "    class Params(EffectParams):\n"
        '        gain: ParamValue = param(1.0, 0.1, 10.0, "gain")\n'
        "    def apply(self, signal, fs_hz, p, rng):\n"
        '        return signal * p["gain"][:, None]\n'
    )
    res = runner.invoke(app, ["--plugin", str(plugin), "effects", "--json", "-"])
    assert res.exit_code == 0, res.output
    listed = {e["name"]: e for e in json.loads(res.stdout)}
    assert listed["lab_laws:Tilt"]["kind"] == "measurement" and "contact_damping" in listed


WORD = st.text(alphabet="abcdefghij_=.0123456789[],%", min_size=1, max_size=18)
CELL = st.lists(WORD, min_size=1, max_size=6).map(" ".join)


@settings(max_examples=60, deadline=None)
@given(
    heads=st.lists(st.text(alphabet="abcdefgh ", min_size=1, max_size=14).filter(str.strip),
                   min_size=1, max_size=7),
    data=st.data(),
    width=st.sampled_from([60, 80, 100]),
)  # fmt: skip
def test_any_table_keeps_its_words_whole(heads, data, width):
    """Generated tables at 60/80/100 columns: every word and number is whole on a line."""
    import io

    from rich.table import Table
    from rich.text import Text

    from stiffnet.cli.console import _Out

    rows = data.draw(st.lists(st.lists(CELL, min_size=len(heads), max_size=len(heads)),
                              min_size=1, max_size=4))  # fmt: skip
    table = Table(title="t")
    for h in heads:
        table.add_column(h)
    for row in rows:
        table.add_row(*map(Text, row))  # text, not rich markup ("[a]" would be a tag)
    buf = io.StringIO()
    _Out(file=buf, width=width, color_system=None).print(table)
    lines = buf.getvalue().splitlines()
    assert max(map(len, lines)) <= width
    found = set().union(*(set(TOKEN.findall(line)) for line in lines))
    words = {t for row in rows for cell in row for t in TOKEN.findall(cell)}
    words |= {t for h in heads for t in TOKEN.findall(h)}
    assert words <= found, sorted(words - found)[:5]


def test_predict_table_stays_side_by_side_at_80_columns_with_a_sidecar(tmp_path):
    """The sidecar f_n came from is named by its file name (it sits beside the recording):
    a long path is one unbreakable token that would turn the table vertical."""
    deep = tmp_path / ("a-long-folder-name-" * 3) / "recordings"
    deep.mkdir(parents=True)
    rec = deep / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    (deep / "rec.csv.json").write_text('{"natural_frequency_hz": 9.48}')
    text = _render(["predict", str(rec)], 80)
    assert "#1" not in text  # no record-by-record (vertical) layout
    assert any("model cnn" in line and "geometric" in line for line in text.splitlines()) or any(
        "model cnn" in line and line.count("┃") == 4 for line in text.splitlines()
    )  # the header row: the model's and the geometric method's columns side by side
    assert "rec.csv.json)" in _tokens(text) and str(deep) not in text


@pytest.mark.parametrize("width", [60, 80])
def test_a_long_path_in_a_title_stays_whole(width):
    """A narrow table's title (``stiffness log of PATH``) wrapped at the table's width cut
    the recording's path in two (``d_drill3/d`` / ``rill.csv``)."""
    import io

    from rich.console import Console
    from rich.table import Table

    from stiffnet.cli.console import fit_table

    path = "/work/scratch/s38/fresh/rigs/d_drill3/drill.csv"
    t = Table(title=f"stiffness log of {path}: 3 layer(s), 87 points every 0.5 s")
    for col in ("layer", "beta"):
        t.add_column(col)
    t.add_row("0", "11.6 [9.92, 13.8]")
    console = Console(width=width, record=True, file=io.StringIO())
    console.print(fit_table(t, width))
    assert path in console.export_text()

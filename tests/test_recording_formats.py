"""The reader registry: formats found by discovery, a plugin format end to end, no lists.

Adding a format is one module in ``stiffnet/recordings/`` (discovered) or one
``register_reader`` call from elsewhere (``tests/toy_format``: one value per line,
``.txt``); the command line, the HTTP schema, ``predict-batch`` and
``read_recording`` all ask the registry, and no other module lists the formats
(checked here on the source, as tests/test_import_rules.py does for families).
"""

from __future__ import annotations

import ast
import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from test_import_rules import docstring_ids
from toy_format import TextColumnReader, write_text_recording

from stiffnet.errors import StiffnetError
from stiffnet.recordings import SUPPORTED_EXTENSIONS, read_recording, registry

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "impact_beta45.csv"
#: Modules that may name several formats, and why.
MAY_LIST_FORMATS = {
    # it writes recordings (which formats it can write is its own question)
    "stiffnet/campaign/synthetic.py",
}


@pytest.fixture
def toy():
    reader = registry.register_reader(TextColumnReader())
    yield reader
    registry.unregister_reader(reader)
    assert ".txt" not in registry.supported_extensions()


def test_the_shipped_formats_are_found_by_discovery():
    found = {type(r).__name__: r for r in registry.discover_readers()}
    assert set(found) == {"CsvReader", "NpyReader", "WavReader", "TdmsReader"}
    assert set(SUPPORTED_EXTENSIONS) == {".csv", ".npy", ".wav", ".tdms"}
    assert registry.supported_extensions()[0] == ".csv"  # the common one first in help texts
    for reader in registry.readers():
        assert reader.description and "\n" not in reader.description
        assert registry.reader_for(f"x{reader.extensions[0].upper()}") is reader  # case-insensitive
    assert [r.extensions for r in registry.readers() if not r.rate_in_file] == [(".npy",)]
    with pytest.raises(StiffnetError, match=r"unknown recording extension '\.txt' \(use one of"):
        registry.reader_for("run.txt")


def test_a_new_module_in_the_package_is_a_new_format(tmp_path, monkeypatch):
    """One file dropped into stiffnet/recordings/ is a format; a module merely importing one
    is not, and ``_private`` modules are never imported."""
    import stiffnet.recordings as package

    (tmp_path / "dat.py").write_text(
        "from toy_format import TextColumnReader\n"
        "class DatReader(TextColumnReader):\n"
        "    extensions = ('.dat',)\n"
    )
    (tmp_path / "helpers.py").write_text(
        "from stiffnet.recordings.dat import DatReader  # re-exported\n"
    )
    (tmp_path / "_private.py").write_text("raise RuntimeError('never imported')\n")
    # the folder joins the package's search path: as if the files were in it
    monkeypatch.setattr(package, "__path__", [*package.__path__, str(tmp_path)])
    try:
        found = [type(r).__name__ for r in registry.discover_readers()]
    finally:
        for name in ("stiffnet.recordings.dat", "stiffnet.recordings.helpers"):
            sys.modules.pop(name, None)
    assert found == ["CsvReader", "DatReader", "NpyReader", "TdmsReader", "WavReader"]


def test_a_clash_of_extensions_is_refused(toy):
    class OtherCsv(TextColumnReader):
        extensions = (".csv",)

    with pytest.raises(ValueError, match=r"\.csv is already read by CsvReader"):
        registry.register_reader(OtherCsv())
    with pytest.raises(ValueError, match="lower case"):

        class Upper(TextColumnReader):
            extensions = (".TXT2",)

        registry.register_reader(Upper())
    with pytest.raises(TypeError):
        registry.register_reader(TextColumnReader)  # the class, not an instance


def test_channels_of_the_shipped_formats(tmp_path):
    from nptdms import ChannelObject, TdmsWriter
    from scipy.io import wavfile

    x = np.sin(np.arange(100) * 0.3)
    csv = tmp_path / "lab.csv"
    csv.write_text("time_ms,acc_g,temp\n" + "".join(f"{i},{v},20\n" for i, v in enumerate(x)))
    np.save(tmp_path / "two.npy", np.c_[x, x])
    wavfile.write(tmp_path / "one.wav", 1000, x.astype(np.float32))
    with TdmsWriter(tmp_path / "r.tdms") as w:
        w.write_segment([ChannelObject("g", "force", x), ChannelObject("g", "mass", x),
                         ChannelObject("g", "empty", np.empty(0))])  # fmt: skip
    assert registry.reader_for(csv).channels(csv) == ["time_ms", "acc_g", "temp"]
    assert registry.reader_for("x.npy").channels(tmp_path / "two.npy") == ["0", "1"]
    assert registry.reader_for("x.wav").channels(tmp_path / "one.wav") == ["0"]
    assert registry.reader_for("x.tdms").channels(tmp_path / "r.tdms") == ["g/force", "g/mass"]


def test_a_toy_format_from_the_tests_folder_reads_and_predicts(toy, tmp_path):
    """Registered from outside the package: read, refused like the others, predicted by the CLI."""
    from typer.testing import CliRunner

    from serving.batch_prediction import find_recordings
    from stiffnet.cli import app

    rec = read_recording(EXAMPLE)
    txt = write_text_recording(tmp_path / "impact.txt", rec.accel, rec.fs_hz)
    (tmp_path / "impact.txt.json").write_text((ROOT / f"{EXAMPLE}.json").read_text())
    got = read_recording(txt)
    assert np.array_equal(got.accel, rec.accel) and got.fs_hz == rec.fs_hz
    assert find_recordings(tmp_path) == [txt]
    # what every format shares: the rate check, CSV-only options, the early refusal
    bare = write_text_recording(tmp_path / "bare.txt", rec.accel[:50], None)
    with pytest.raises(StiffnetError, match="sampling rate missing"):
        read_recording(bare)
    with pytest.raises(StiffnetError, match="sampling rate must be > 0"):
        read_recording(bare, fs_hz=-5)
    with pytest.raises(StiffnetError, match=r"'columns' applies to CSV recordings only, not \.txt"):
        read_recording(txt, columns="0")
    with pytest.raises(StiffnetError, match=r"line 1 says .* Hz, not 10.0 Hz"):
        read_recording(txt, fs_hz=10.0)
    registry.require_rate(bare, None)  # the file may carry its rate: no early refusal
    assert read_recording(bare, fs_hz=rec.fs_hz).accel.size == 50

    runner = CliRunner()
    outs = {}
    for path in (EXAMPLE, txt):
        out = tmp_path / f"{path.stem}.json"
        res = runner.invoke(app, ["predict", str(path), "--json", str(out)])
        assert res.exit_code == 0, res.output
        outs[path.suffix] = json.loads(out.read_text())
    csv_result, txt_result = outs[".csv"], outs[".txt"]
    assert txt_result["natural_frequency_source"] == f"sidecar:{txt}.json"
    assert txt_result["source"] == str(txt)
    for key in ("source", "natural_frequency_source"):  # the file's name, nothing else
        del csv_result[key], txt_result[key]
    assert txt_result == csv_result  # the same samples and rate: the same prediction


def test_the_http_schema_lists_the_registered_formats(toy):
    from serving.app import _predict_body

    upload = _predict_body()["requestBody"]["content"]["multipart/form-data"]["schema"]
    props = upload["properties"]
    assert props["file"]["x-extensions"] == list(registry.supported_extensions())
    assert ".txt" in props["file"]["x-extensions"]
    assert ".txt: one value per line" in props["file"]["description"]
    assert "needed for .npy" in props["fs_hz"]["description"]
    assert ".tdms: a channel name" in props["channel"]["description"]


def test_the_command_line_help_lists_the_formats():
    from stiffnet.cli.options import RECORDING_HELP

    for reader in registry.readers():
        assert f"{reader.extensions[0]}: {reader.description}" in RECORDING_HELP


def format_lists(source: str, names: dict[str, str]) -> list[str]:
    """String constants (docstrings aside) or literal collections naming 2+ formats.

    `names` maps a word (``csv``, ``.csv``) to its format; a word counts when it
    stands alone (``manifest.csv`` names CSV once, ``runs/*.csv`` too).
    """
    tree = ast.parse(source)
    docstrings = docstring_ids(tree)
    word = re.compile(r"(?<![\w])\.?(" + "|".join(n.lstrip(".") for n in names) + r")\b", re.I)

    def formats(text: str) -> set[str]:
        return {names[m.group(1).lower()] for m in word.finditer(text)}

    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            if id(node) not in docstrings and len(formats(node.value)) > 1:
                found.append(f"line {node.lineno}: {node.value[:60]!r}")
        elif isinstance(node, ast.Tuple | ast.List | ast.Set):
            texts = [e.value for e in node.elts if isinstance(e, ast.Constant)]
            if len(set().union(*map(formats, [t for t in texts if isinstance(t, str)]))) > 1:
                found.append(f"line {node.lineno}: {ast.unparse(node)[:60]}")
    return found


def _format_words() -> dict[str, str]:
    words = {}
    for reader in registry.readers():
        for ext in reader.extensions:
            words[ext.lstrip(".")] = reader.name
        words[reader.name.lower()] = reader.name
    return words


def test_the_checker_finds_a_hard_coded_list():
    words = _format_words()
    old = 'def f(r: str = typer.Argument(help="Recording: CSV t,accel, .npy, WAV, TDMS.")): ...'
    assert len(format_lists(old, words)) == 1
    assert format_lists('EXT = (".csv", ".tdms")', words)
    assert format_lists('ok = "manifest.csv"; rows = (".csv", ".parquet")', words) == []
    assert format_lists('def f():\n    """Reads .csv, .npy and .wav."""\n', words) == []


def test_no_module_outside_the_readers_lists_the_formats():
    words = _format_words()
    bad = []
    for pkg in ("stiffnet", "serving", "training"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel.startswith("stiffnet/recordings/") or rel in MAY_LIST_FORMATS:
                continue
            bad += [f"{rel} {hit}" for hit in format_lists(path.read_text(), words)]
    assert not bad, "formats listed outside stiffnet/recordings/ (ask the registry):\n" + "\n".join(
        bad
    )
    for rel in MAY_LIST_FORMATS:  # an exception that no longer lists them goes
        assert format_lists((ROOT / rel).read_text(), words), f"{rel}: drop it from the list"

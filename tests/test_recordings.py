"""Reading and writing recordings: CSV, NPY, WAV, TDMS, and every user error."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.io import wavfile

from stiffnet.errors import StiffnetError
from stiffnet.recordings import Recording, read_recording, write_recording_csv

FS = 1000.0


def signal(n: int = 200, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.sin(2 * np.pi * 10 * np.arange(n) / FS) + 0.1 * rng.standard_normal(n)


def write_text(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def assert_error(match: str, path: Path, **kwargs) -> None:
    with pytest.raises(StiffnetError, match=match) as info:
        read_recording(path, **kwargs)
    msg = str(info.value)
    assert "\n" not in msg
    assert path.name in msg  # every message names the file


# --------------------------------------------------------------------------- CSV


def test_csv_round_trip_is_exact_and_infers_fs(tmp_path):
    x = signal()
    path = write_recording_csv(tmp_path / "sub" / "rec.csv", x, FS)
    assert path.read_text().startswith("t,accel\n0,")
    rec = read_recording(path)
    assert isinstance(rec, Recording)
    assert rec.fs_hz == pytest.approx(FS, rel=1e-12)
    assert rec.accel.dtype == np.float64
    np.testing.assert_array_equal(rec.accel, x)  # shortest round-trip floats
    assert rec.source == str(path)
    assert len(rec) == x.size and rec.duration_s == pytest.approx(x.size / FS)
    assert [p.name for p in path.parent.iterdir()] == ["rec.csv"]  # no temp file left


def test_csv_gain_does_not_matter_to_the_format(tmp_path):
    x = signal()
    a = read_recording(write_recording_csv(tmp_path / "a.csv", x, FS))
    b = read_recording(write_recording_csv(tmp_path / "b.csv", 1000 * x, FS))
    np.testing.assert_array_equal(b.accel, 1000 * a.accel)
    assert a.fs_hz == b.fs_hz


def test_csv_write_replaces_an_existing_file(tmp_path):
    path = write_recording_csv(tmp_path / "r.csv", signal(50), FS)
    write_recording_csv(path, signal(80), 2 * FS)
    rec = read_recording(path)
    assert len(rec) == 80 and rec.fs_hz == pytest.approx(2 * FS)


def test_csv_tolerates_rounded_times_crlf_bom_and_spaces(tmp_path):
    lines = [f"{n / 3000:.5f} , {np.sin(n / 10):.6f}" for n in range(300)]
    path = tmp_path / "lab.csv"
    path.write_bytes(("\ufeffT, Accel\r\n" + "\r\n".join(lines) + "\r\n").encode("utf-8"))
    rec = read_recording(path, fs_hz=3000)
    assert len(rec) == 300 and rec.fs_hz == 3000


def test_csv_given_fs_must_agree_with_t(tmp_path):
    path = write_recording_csv(tmp_path / "r.csv", signal(), FS)
    assert read_recording(path, fs_hz=FS).fs_hz == FS
    assert_error(r"column t gives fs = 1000 Hz but fs_hz = 2000 Hz", path, fs_hz=2000)


def test_csv_missing_header(tmp_path):
    assert_error("missing header", write_text(tmp_path / "e.csv", "\n0,1\n"))


def test_csv_empty_file_is_said_empty(tmp_path):
    """A 0-byte file (a failed copy) was said to miss its header."""
    assert_error(r"the file is empty \(0 bytes", write_text(tmp_path / "e.csv", ""))


def test_csv_wrong_header(tmp_path):
    assert_error("wrong header 'time,acc'", write_text(tmp_path / "h.csv", "time,acc\n0,1\n"))
    assert_error("wrong header '0,1'", write_text(tmp_path / "n.csv", "0,1\n0.001,2\n"))


def test_csv_binary_content(tmp_path):
    path = tmp_path / "b.csv"
    path.write_bytes(b"\x80\x81 not text")
    assert_error("not a UTF-8 text file", path)
    path.write_bytes(b"t,accel\n0,1\n0.001,\xff\n")
    assert_error("not a UTF-8 text file", path)


def test_csv_semicolon_separated(tmp_path):
    path = write_text(tmp_path / "s.csv", "t;accel\n0;1\n")
    assert_error("comma-separated", path)


def test_csv_tab_separated_is_said_so(tmp_path):
    path = write_text(tmp_path / "s.csv", "t\taccel\n0\t1\n0.001\t2\n")
    assert_error(r"its columns are separated by tabs, not commas: t, accel", path)


@pytest.mark.parametrize("sep, what", [(";", "';'"), ("\t", "tabs")])
@pytest.mark.parametrize("columns", ["time_ms,acc_g", "time_ms;acc_g"])
def test_columns_named_in_a_file_separated_otherwise_are_said_so(tmp_path, sep, what, columns):
    """A spreadsheet's export with decimal commas read with the columns it names was 'no
    column 'time_ms' in the header (time_ms;acc_g)', or with the manifest's ';' form
    'line 2 has 3 cells, expected 1': the columns are there, joined by another separator."""
    text = sep.join(["time_ms", "acc_g"]) + "\n" + sep.join(["0,0", "1,5"]) + "\n"
    path = write_text(tmp_path / "s.csv", text)
    assert_error(
        f"line 1: its columns are separated by {what}, not commas: time_ms, acc_g; save it",
        path,
        columns=columns,
        time_unit="ms" if "," in columns else None,  # one name: no time column
    )


def test_a_comment_above_the_header_is_read_past(tmp_path):
    """A logger's note above the table was read as the header: 'no column 'time_ms' in
    the header (# labview export,kanal 1)'. It is skipped: the columns named read, and the
    header not 't,accel' is said to be on line 2."""
    path = write_text(
        tmp_path / "c.csv", "# LabVIEW export, Kanal 1\ntime_ms,acc_g\n0,1\n1,2\n2,3\n"
    )
    rec = read_recording(path, columns="time_ms,acc_g", time_unit="ms")
    assert rec.fs_hz == pytest.approx(1000.0) and list(rec.accel) == [1.0, 2.0, 3.0]
    assert_error(r"wrong header 'time_ms,acc_g', expected 't,accel' on line 2", path)


def test_csv_a_file_of_zeros_is_refused_without_reading_it_whole(tmp_path):
    path = tmp_path / "z.csv"
    with open(path, "wb") as fh:  # sparse: a logger's file allocated and never written
        fh.truncate(64 * 2**20)
    assert_error("line 1 holds NUL bytes", path)
    path.write_text("a" * 100_000 + "\n1,2\n")
    assert_error("line 1 is longer than 65536 characters", path)


def test_csv_trailing_unnamed_empty_columns_read_as_t_accel(tmp_path):
    x = signal()
    write_recording_csv(tmp_path / "plain.csv", x, 1000)
    lines = (tmp_path / "plain.csv").read_text().splitlines()
    path = write_text(tmp_path / "sheet.csv", "\r\n".join(line + ",," for line in lines) + "\r\n")
    rec = read_recording(path)
    assert rec.fs_hz == pytest.approx(1000) and np.array_equal(
        rec.accel, read_recording(tmp_path / "plain.csv").accel
    )


def test_csv_non_numeric_cell_names_the_line(tmp_path):
    path = write_text(tmp_path / "x.csv", "t,accel\n0,1\n0.001,abc\n0.002,3\n")
    assert_error(r"line 3, column accel: 'abc' is not a number", path)


def test_csv_empty_cell_names_the_line(tmp_path):
    path = write_text(tmp_path / "x.csv", "t,accel\n0,1\n0.001,2\n,3\n")
    assert_error(r"line 4, column t: '' is not a number", path)


def test_csv_wrong_number_of_cells(tmp_path):
    path = write_text(tmp_path / "x.csv", "t,accel\n0,1\n0.001,2,7\n")
    assert_error(r"line 3 has 3 cells, expected 2", path)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf", "NaN"])
def test_csv_nan_or_inf(tmp_path, bad):
    path = write_text(tmp_path / "x.csv", f"t,accel\n0,1\n0.001,2\n0.002,{bad}\n")
    assert_error(rf"line 4, column accel: {bad} is not a finite number", path)


def test_csv_empty_recording(tmp_path):
    assert_error("recording is empty", write_text(tmp_path / "x.csv", "t,accel\n"))


def test_csv_one_sample(tmp_path):
    assert_error("only one sample", write_text(tmp_path / "x.csv", "t,accel\n0,1\n"))


def test_csv_t_not_increasing(tmp_path):
    path = write_text(tmp_path / "x.csv", "t,accel\n0,1\n0.001,2\n0.001,3\n0.003,4\n")
    assert_error(r"not strictly increasing \(line 4", path)


def test_csv_t_not_uniform(tmp_path):
    t = np.delete(np.arange(100) / FS, 50)  # one dropped sample
    text = "t,accel\n" + "".join(f"{float(v)!r},1\n" for v in t)
    assert_error("has a gap.*about 1 sample", write_text(tmp_path / "x.csv", text))
    jittered = np.arange(100) / FS + np.tile([0.0, 0.3 / FS], 50)  # a third of a period
    text = "t,accel\n" + "".join(f"{float(v)!r},1\n" for v in jittered)
    assert_error("not uniformly sampled", write_text(tmp_path / "y.csv", text))


def test_csv_gap_in_time_says_how_many_samples_are_missing(tmp_path):
    """0.5 s of rows missing from a 1 kHz record: it said 'line 22001 is 2.7e+02 sample
    periods off the uniform grid' (the mean step stretched by the gap), not 500 missing."""
    t = np.delete(np.arange(4000) / FS, np.arange(2000, 2500))
    text = "t,accel\n" + "".join(f"{float(v)!r},1\n" for v in t)
    assert_error(
        r"column t has a gap: t jumps from 1\.999 to 2\.5 \(line 2002\), 0\.501 s where the "
        r"other steps are 0\.001 s: about 500 sample\(s\) missing",
        write_text(tmp_path / "x.csv", text),
    )


def test_csv_a_loggers_comment_preamble_is_skipped(tmp_path):
    """Lines of ``#`` comments before the header (operator, rig, settings) were read as the
    header: 'wrong header (2 cell(s), not shown)'. They are skipped; line numbers in the
    messages still count them."""
    x = signal()
    clean = read_recording(write_recording_csv(tmp_path / "clean.csv", x, FS))
    body = (tmp_path / "clean.csv").read_text()
    preamble = "# rig 3, run 1\n# operator: A. N. Other, gain 10 mV/g\n"
    rec = read_recording(write_text(tmp_path / "pre.csv", preamble + body))
    assert rec.fs_hz == clean.fs_hz and np.array_equal(rec.accel, clean.accel)
    lines = (preamble + body).splitlines()
    lines[10] = "0.0085,abc"  # file line 11
    assert_error(r"line 11, column accel: 'abc' is not a number",
                 write_text(tmp_path / "bad.csv", "\n".join(lines) + "\n"))  # fmt: skip
    t = np.delete(np.arange(100) / FS, 50)
    text = preamble + "t,accel\n" + "".join(f"{float(v)!r},1\n" for v in t)
    assert_error(r"\(line 54\)", write_text(tmp_path / "gap.csv", text))  # data from line 4
    assert_error(r"2 comment line\(s\) \('#'\) and no data after them",
                 write_text(tmp_path / "only.csv", preamble))  # fmt: skip
    named = write_text(tmp_path / "named.csv", preamble + "time,acc\n0,1\n0.001,2\n")
    assert_error(r"wrong header 'time,acc', expected 't,accel' on line 3", named)


def test_csv_written_by_numpy_savetxt_reads_its_commented_header(tmp_path):
    """``np.savetxt(path, data, delimiter=",", header="t,accel")`` writes ``# t,accel``:
    that comment is the header; a commented header naming other columns is one where
    ``columns`` names them, and none otherwise."""
    x = signal()
    data = np.column_stack([np.arange(x.size) / FS, x])
    np.savetxt(tmp_path / "np.csv", data, delimiter=",", header="t,accel")
    rec = read_recording(tmp_path / "np.csv")
    assert rec.fs_hz == pytest.approx(FS) and np.allclose(rec.accel, x, rtol=1e-15, atol=0)
    np.savetxt(tmp_path / "named.csv", data, delimiter=",", header="Time,Acc")
    rec = read_recording(tmp_path / "named.csv", columns="Time,Acc")
    assert np.allclose(rec.accel, x, rtol=1e-15, atol=0)
    assert_error(r"wrong header .* on line 2; no header", tmp_path / "named.csv")


def test_csv_clock_times_are_quoted_and_said_not_seconds(tmp_path):
    """A logger's ISO time stamps in column t read 'the cell is not a number' (a stamp is not
    quoted as a word): the stamp is quoted, said a clock time, and the way out given; the
    acceleration alone with the rate reads the file."""
    stamps = [f"2026-12-02T10:00:00.{i:03d}" for i in range(200)]
    x = signal()
    text = "t,accel\n" + "".join(f"{s},{float(v)!r}\n" for s, v in zip(stamps, x, strict=True))
    path = write_text(tmp_path / "iso.csv", text)
    assert_error(
        r"line 2, column t: '2026-12-02T10:00:00\.000' is a clock time, not a time in seconds; "
        r"name its columns: --columns accel and give the rate",
        path,
    )
    rec = read_recording(path, columns="accel", fs_hz=FS)
    assert np.array_equal(rec.accel, x)
    word = write_text(tmp_path / "w.csv", "t,accel\n0,1\nabc,2\n")
    assert_error(r"line 3, column t: 'abc' is not a number$", word)


def test_csv_not_utf8_says_which_encoding_or_line(tmp_path):
    """A recording saved as UTF-16 (Windows' 'Unicode' text) or with a Latin-1 degree sign
    was 'not a UTF-8 text file' alone: it now says which, or on which line."""
    text = "t,accel\n0,1\n0.001,2\n"
    utf16 = tmp_path / "u.csv"
    utf16.write_text(text, encoding="utf-16")
    assert_error(
        r"not a UTF-8 text file \(expected a CSV 't,accel'\): it is UTF-16 text, as Windows "
        r"saves 'Unicode' text; save it as UTF-8$",
        utf16,
    )
    latin1 = tmp_path / "l.csv"
    latin1.write_bytes(text.encode() + "0.002,3 # 20 °C\n".encode("latin-1"))
    assert_error(r"line 4 holds a byte that is not UTF-8 \(Latin-1 or Windows-1252", latin1)


def test_csv_large_file_reads(tmp_path):
    x = signal(200_000)
    path = write_recording_csv(tmp_path / "big.csv", x, 20_000.0)
    rec = read_recording(path)
    assert rec.fs_hz == pytest.approx(20_000.0)
    np.testing.assert_array_equal(rec.accel, x)


# ------------------------------------------------------------- generic errors


def test_missing_file(tmp_path):
    assert_error("recording file not found", tmp_path / "nope.csv")


def test_unknown_extension(tmp_path):
    assert_error(r"unknown recording extension '\.txt'", write_text(tmp_path / "r.txt", "1\n"))


def test_a_compressed_recording_is_said_compressed(tmp_path):
    """``run.csv.gz`` was only 'unknown recording extension .gz': it says what it is."""
    import gzip

    gz = tmp_path / "run.csv.gz"
    gz.write_bytes(gzip.compress(b"t,accel\n0,1\n0.001,2\n"))
    assert_error(r"'\.gz' \(use one of .*\); it is a compressed \.csv file: decompress it first$",
                 gz)  # fmt: skip
    plain = write_text(tmp_path / "notes.gz", "x")
    with pytest.raises(StiffnetError) as info:
        read_recording(plain)
    assert "a compressed" not in str(info.value)


@pytest.mark.parametrize("fs", [0, -5.0, float("nan")])
def test_fs_must_be_positive(tmp_path, fs):
    path = tmp_path / "r.npy"
    np.save(path, signal())
    assert_error("sampling rate must be > 0", path, fs_hz=fs)


def test_csv_channel_names_the_acceleration_column(tmp_path):
    path = tmp_path / "r.csv"
    x = signal()
    t = np.arange(x.size) / FS
    lines = (f"{float(a)!r},{-float(b)!r},{float(b)!r}\n" for a, b in zip(t, x, strict=True))
    path.write_text("t,force,accel\n" + "".join(lines))
    np.testing.assert_array_equal(read_recording(path, channel="accel").accel, x)
    np.testing.assert_array_equal(read_recording(path, channel=1).accel, -x)
    assert_error("no column 'bogus'", path, channel="bogus")
    assert_error("either 'columns' or 'channel'", path, channel="accel", columns="t,accel")
    # without a choice: refused, naming its columns
    assert_error(r"its 3 columns: t, force, accel \(--channel NAME", path)


def test_csv_hint_names_the_acceleration_column_never_the_first_two_of_several(tmp_path):
    """A logger's sample counter and a force channel before the accelerometer: the hint
    read them as time and acceleration (``--columns sample,force_N``)."""
    path = tmp_path / "r.csv"
    path.write_text("sample,force_N,accel_g\n0,1.5,0.1\n1,1.6,0.2\n")
    assert_error(r"no time column \('sample' counts samples: it is not a time\): name its "
                 r"columns: --columns accel_g and give the rate \(--fs HZ\)", path)  # fmt: skip
    path.write_text("time_s,force,acc_z\n0,1,2\n0.001,1,2\n")
    assert_error(r"name its columns: --columns time_s,acc_z; its 3 columns", path)
    path.write_text("t,accel,accel_y\n0,1,2\n0.001,1,2\n")  # the default name among axes
    assert_error(r"name its columns: --columns t,accel; its 3 columns", path)
    path.write_text("t,ax,ay\n0,1,2\n0.001,1,2\n")  # two axes: the user picks
    assert_error(r"name its columns: --columns TIME,ACCEL; its 3 columns", path)
    # a channel named without a time column 't': how to read it with no time column
    path.write_text("sample,force_N,accel_g\n0,1.5,0.1\n1,1.6,0.2\n")
    said = r"no time column 't' in the header \(sample,force_N,accel_g\); .* without a time"
    assert_error(said + " column --columns accel_g and give the rate", path, channel="accel_g")
    rec = read_recording(path, columns="accel_g", fs_hz=2000.0)
    assert rec.fs_hz == 2000.0 and rec.accel.tolist() == [0.1, 0.2]


# --------------------------------------------------------------------------- NPY


def test_npy_reads_with_given_fs(tmp_path):
    path = tmp_path / "r.npy"
    np.save(path, (1000 * signal()).astype(np.float32))
    rec = read_recording(path, fs_hz=FS)
    assert rec.accel.dtype == np.float64 and rec.fs_hz == FS and len(rec) == 200


def test_npy_int_array_is_converted(tmp_path):
    path = tmp_path / "r.npy"
    np.save(path, np.arange(10, dtype=np.int16))
    np.testing.assert_array_equal(read_recording(path, fs_hz=FS).accel, np.arange(10.0))


def test_npy_needs_fs(tmp_path):
    path = tmp_path / "r.npy"
    np.save(path, signal())
    assert_error("sampling rate missing", path)


def test_npy_must_be_1d(tmp_path):
    path = tmp_path / "r.npy"
    np.save(path, np.zeros((10, 2, 2)))
    assert_error(r"expected a 1-D array, got shape \(10, 2, 2\)", path, fs_hz=FS)


def test_npy_nan(tmp_path):
    path = tmp_path / "r.npy"
    x = signal()
    x[17] = np.nan
    np.save(path, x)
    assert_error("1 NaN/inf samples \\(first at sample 17\\)", path, fs_hz=FS)


def test_npy_empty_and_one_sample(tmp_path):
    np.save(tmp_path / "e.npy", np.zeros(0))
    np.save(tmp_path / "o.npy", np.zeros(1))
    assert_error("recording is empty", tmp_path / "e.npy", fs_hz=FS)
    assert_error("only one sample", tmp_path / "o.npy", fs_hz=FS)


def test_npy_garbage(tmp_path):
    assert_error("not a readable .npy", write_text(tmp_path / "g.npy", "hello"), fs_hz=FS)


def test_npy_corrupt_header(tmp_path):
    path = tmp_path / "c.npy"
    np.save(path, np.arange(3.0))
    raw = bytearray(path.read_bytes())
    raw[raw.index(b"{") + 1 : raw.index(b"}")] = b"(" * (raw.index(b"}") - raw.index(b"{") - 1)
    path.write_bytes(bytes(raw))  # an unterminated Python literal: tokenize.TokenError
    assert_error("not a readable .npy", path, fs_hz=FS)


# --------------------------------------------------------------------------- WAV


def test_wav_int16_is_scaled(tmp_path):
    data = np.array([0, 16384, -32768, 32767, -16384], dtype=np.int16)
    wavfile.write(tmp_path / "r.wav", 8000, data)
    rec = read_recording(tmp_path / "r.wav")
    assert rec.fs_hz == 8000
    np.testing.assert_array_equal(rec.accel, data / 32768.0)


def test_wav_float_and_channel(tmp_path):
    data = np.stack([signal(), 5 * signal(seed=1)], axis=1).astype(np.float32)
    path = tmp_path / "r.wav"
    wavfile.write(path, 1000, data)
    assert_error(r"2 channels \(0..1\); choose one with --channel INDEX", path)
    np.testing.assert_array_equal(read_recording(path, channel=0).accel, data[:, 0])
    rec = read_recording(path, channel=1)
    np.testing.assert_array_equal(rec.accel, data[:, 1])
    assert "channel 1" in rec.source
    assert_error("channel 2 requested but the file has 2 channels", path, channel=2)


def test_wav_fs_must_agree(tmp_path):
    wavfile.write(tmp_path / "r.wav", 1000, signal().astype(np.float32))
    assert_error("the file says fs = 1000 Hz but fs_hz = 500 Hz", tmp_path / "r.wav", fs_hz=500)


def test_wav_garbage(tmp_path):
    assert_error("not a readable WAV", write_text(tmp_path / "g.wav", "RIFFnope"))


@pytest.mark.parametrize(("fmt", "channels", "bits"), [(1, 0, 16), (3, 1, 8), (1, 0, 8)])
def test_wav_corrupt_header(tmp_path, fmt, channels, bits):
    """Headers scipy chokes on with ZeroDivisionError / TypeError give one-line errors."""
    import struct

    data = bytes(range(40))
    fmt_chunk = struct.pack("<IHHIIHH", 16, fmt, channels, 1000, 2000, 2, bits)
    body = b"WAVEfmt " + fmt_chunk + b"data" + struct.pack("<I", len(data)) + data
    path = tmp_path / "c.wav"
    path.write_bytes(b"RIFF" + struct.pack("<I", len(body)) + body)
    assert_error("not a readable WAV", path)


# -------------------------------------------------------------------------- TDMS


def write_tdms(path: Path, increment: float | None = 1 / FS) -> None:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    props = {} if increment is None else {"wf_increment": increment}
    with TdmsWriter(path) as writer:
        writer.write_segment(
            [
                RootObject(),
                GroupObject("rig"),
                ChannelObject("rig", "empty", np.zeros(0)),
                ChannelObject("rig", "mass", signal(), properties=props),
                ChannelObject("rig", "base", 3 * signal(seed=2), properties=props),
            ]
        )


def test_tdms_several_channels_need_a_choice(tmp_path):
    path = tmp_path / "r.tdms"
    write_tdms(path)
    assert_error(r"2 channels hold data \(rig/mass, rig/base\); choose one with --channel", path)
    rec = read_recording(path, channel="mass")
    np.testing.assert_array_equal(rec.accel, signal())
    assert rec.fs_hz == pytest.approx(FS)
    assert "rig/mass" in rec.source
    np.testing.assert_array_equal(read_recording(path, channel="1").accel, 3 * signal(seed=2))


def test_npy_columns_are_channels(tmp_path):
    path = tmp_path / "r.npy"
    np.save(path, np.stack([signal(), 2 * signal()], axis=1))
    assert_error(r"2 channels \(columns 0..1 of shape", path, fs_hz=FS)
    np.testing.assert_array_equal(read_recording(path, fs_hz=FS, channel=1).accel, 2 * signal())


def test_tdms_named_channel(tmp_path):
    path = tmp_path / "r.tdms"
    write_tdms(path)
    for name in ("base", "rig/base"):
        np.testing.assert_array_equal(read_recording(path, channel=name).accel, 3 * signal(seed=2))
    assert_error(r"no TDMS channel 'bogus' \(channels: rig/empty, rig/mass", path, channel="bogus")


def test_tdms_without_increment_needs_fs(tmp_path):
    path = tmp_path / "r.tdms"
    write_tdms(path, increment=None)
    assert_error("sampling rate missing", path, channel="mass")
    assert read_recording(path, fs_hz=250.0, channel="mass").fs_hz == 250.0


def test_tdms_fs_must_agree(tmp_path):
    path = tmp_path / "r.tdms"
    write_tdms(path)
    assert_error("wf_increment gives fs = 1000 Hz but fs_hz = 999 Hz", path, fs_hz=999,
                 channel="mass")  # fmt: skip


def test_tdms_garbage(tmp_path):
    assert_error("not a readable TDMS", write_text(tmp_path / "g.tdms", "not tdms"))


def test_tdms_corrupt_after_lead_in_is_quiet(tmp_path, capfd):
    path = tmp_path / "c.tdms"
    path.write_bytes(b"TDSm" + bytes(range(7, 90)))
    with pytest.raises(StiffnetError) as exc:
        read_recording(path, fs_hz=FS)
    assert "\n" not in str(exc.value)
    assert capfd.readouterr().err == ""  # npTDMS's warnings are silenced


# ------------------------------------------------------- user layouts (columns, time unit)


def lab_csv(path: Path, header: str, scale: float, n: int = 300, fs: float = FS) -> Path:
    """A lab export: time in 1/scale seconds, acceleration in column 2 of 3."""
    x = signal(n)
    rows = [f"{k / fs * scale:.9g},{0.5 * k},{float(v)!r}" for k, v in enumerate(x)]
    return write_text(path, header + "\n" + "\n".join(rows) + "\n")


def test_columns_by_name_and_time_unit(tmp_path):
    path = lab_csv(tmp_path / "lab.csv", "time_ms,temp_C,acc_g", 1e3)
    rec = read_recording(path, columns="time_ms,acc_g", time_unit="ms")
    assert rec.fs_hz == pytest.approx(FS, rel=1e-9)
    np.testing.assert_array_equal(rec.accel, signal(300))
    # names are case-insensitive; a (time, accel) pair works like the string
    same = read_recording(path, columns=("TIME_MS", "Acc_G"), time_unit="ms")
    np.testing.assert_array_equal(same.accel, rec.accel)
    # microseconds
    us = lab_csv(tmp_path / "us.csv", "t_us,x,a", 1e6)
    assert read_recording(us, columns="0,2", time_unit="us").fs_hz == pytest.approx(FS)


def test_columns_by_index_reads_headerless_files(tmp_path):
    path = lab_csv(tmp_path / "raw.csv", "", 1.0)
    path.write_text(path.read_text().lstrip("\n"))  # no header line at all
    rec = read_recording(path, columns="0,2")
    assert len(rec) == 300 and rec.fs_hz == pytest.approx(FS)
    np.testing.assert_array_equal(rec.accel, signal(300))
    # with a header, indices skip it
    named = lab_csv(tmp_path / "named.csv", "t,x,a", 1.0)
    assert len(read_recording(named, columns="0,2")) == 300


def test_accel_only_column_needs_the_rate(tmp_path):
    path = lab_csv(tmp_path / "lab.csv", "time,x,acc", 1.0)
    rec = read_recording(path, columns="acc", fs_hz=2 * FS)  # no time column: the given rate
    assert rec.fs_hz == 2 * FS and len(rec) == 300
    assert_error("sampling rate missing \\(no time column", path, columns="acc")
    assert_error("time_unit given but columns names no time column", path, columns="acc",
                 time_unit="ms")  # fmt: skip


def test_wrong_header_says_how_to_map_it(tmp_path):
    path = lab_csv(tmp_path / "lab.csv", "time_ms,acc_g,temp", 1e3)
    with pytest.raises(StiffnetError) as info:
        read_recording(path)
    msg = str(info.value)
    assert "wrong header" in msg and "--columns time_ms,acc_g --time-unit ms" in msg
    assert "\n" not in msg
    from stiffnet.inputs import HINT_CONTEXT

    token = HINT_CONTEXT.set("manifest")  # a campaign's recording: the manifest's columns
    try:
        with pytest.raises(StiffnetError, match="in the manifest: columns time_ms,acc_g and "
                                                "time_unit ms"):  # fmt: skip
            read_recording(path)
    finally:
        HINT_CONTEXT.reset(token)
    numeric = write_text(tmp_path / "n.csv", "0,1\n0.001,2\n")
    assert_error("no header: name its columns: --columns 0,1", numeric)


@pytest.mark.parametrize(
    ("where", "said"),
    [("cli", "give its campaign folder to predict-batch"), ("http", "post each of its recordings")],
)
def test_a_manifest_read_as_a_recording_is_said_to_be_one(tmp_path, where, said):
    """A campaign's manifest given as a recording (posted, or named to predict) was read for
    its columns: 'wrong header (8 cell(s), not shown)' then listed them, with the hint
    '--columns recording,fs_hz' (even over HTTP); a wide header of names is not 'not shown'."""
    from stiffnet.inputs import HINT_CONTEXT

    manifest = write_text(
        tmp_path / "manifest.csv",
        "recording,fs_hz,natural_frequency_hz,forcing_frequency_hz,base_acceleration_g,gap_mm,"
        "damping_ratio,beta\nrec/a.csv,1000,9.48,9.95,0.75,2.8,0.02,13\n",
    )
    wide = write_text(tmp_path / "w.csv", "time,acc_x,acc_y,acc_z,force,temp\n0,1,2,3,4,5\n")
    token = HINT_CONTEXT.set(where)
    try:
        manifest_said = r"a campaign manifest \(columns recording, fs_hz, .*\), not a recording"
        assert_error(f"{manifest_said}: {said}", manifest)
        with pytest.raises(StiffnetError) as info:
            read_recording(manifest)
        assert "--" not in str(info.value) or where == "cli"
        assert_error("wrong header of 6 named columns, expected 't,accel'", wide)
    finally:
        HINT_CONTEXT.reset(token)


def test_layout_errors_are_one_line(tmp_path):
    path = lab_csv(tmp_path / "lab.csv", "time,x,acc", 1.0)
    assert_error(r"no column 'accel' in the header \(time,x,acc\)", path, columns="time,accel")
    assert_error("column index 5 out of range \\(the file has 3 columns\\)", path, columns="0,5")
    assert_error("unknown time unit 'min'", path, columns="time,acc", time_unit="min")
    assert_error("columns must be 'TIME,ACCEL'", path, columns="a,b,c")
    assert_error("names the same column twice", path, columns="acc,acc")
    bad = write_text(tmp_path / "b.csv", "time,x,acc\n0,1,2\n0.001,1,oops\n")
    assert_error("line 3, column acc: 'oops' is not a number", bad, columns="time,acc")
    short = write_text(tmp_path / "s.csv", "time,x,acc\n0,1,2\n0.001,1\n")
    assert_error(r"line 3 has 2 cells, expected 3 \(time,x,acc\)", short, columns="time,acc")
    np.save(tmp_path / "r.npy", signal())
    assert_error("applies to CSV recordings only", tmp_path / "r.npy", fs_hz=FS, columns="0")
    assert_error("applies to CSV recordings only", tmp_path / "r.npy", fs_hz=FS, time_unit="ms")


def test_a_rate_off_by_a_unit_factor_says_so(tmp_path):
    from stiffnet.recordings import unit_mistake_hint

    path = lab_csv(tmp_path / "lab.csv", "time,x,acc", 1e3)  # times in ms
    assert_error(r"gives fs = 1 Hz but fs_hz = 1000 Hz was given \(is the time in milliseconds",
                 path, columns="time,acc", fs_hz=FS)  # fmt: skip
    # the rule itself: a rate 1000x (or 1e6x) too low for the expected band
    assert "--time-unit ms" in unit_mistake_hint(5.0, 474.0, 5000.0 * 4)
    assert "--time-unit us" in unit_mistake_hint(0.005, 474.0, 20000.0)
    assert unit_mistake_hint(300.0, 474.0, 20000.0) == ""  # just too low: no unit story


def test_a_missing_recording_names_its_twin_in_another_case(tmp_path):
    """predict on 'Run01.CSV' beside 'run01.csv' was 'recording file not found' alone."""
    write_recording_csv(tmp_path / "data" / "run01.csv", np.zeros(10), 1000)
    assert_error(r"not found \(the folder holds 'run01.csv', which differs only in letter case",
                 tmp_path / "data" / "Run01.csv")  # fmt: skip
    assert_error(r"\(the folder holds 'data' \(where 'Data' was written\)",
                 tmp_path / "Data" / "run01.csv")  # fmt: skip


@pytest.mark.parametrize(
    ("where", "said"),
    [("cli", "--fs HZ"), ("manifest", "the manifest's column fs_hz"), ("http", "the field fs_hz")],
)
def test_a_missing_rate_names_what_to_give_where_the_user_is(tmp_path, where, said):
    """A TDMS without wf_increment, or a CSV without a time column, said 'give fs_hz' on the
    command line too, where the option is --fs."""
    from stiffnet.inputs import HINT_CONTEXT

    write_tdms(tmp_path / "r.tdms", increment=None)
    write_text(tmp_path / "a.csv", "acc\n1\n2\n3\n")
    token = HINT_CONTEXT.set(where)
    try:
        assert_error(f"no wf_increment; give {said}\\)$", tmp_path / "r.tdms", channel="mass")
        assert_error(f"no time column; give {said}\\)$", tmp_path / "a.csv", columns="acc")
    finally:
        HINT_CONTEXT.reset(token)

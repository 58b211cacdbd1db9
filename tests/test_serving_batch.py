"""Batch prediction (``predict-batch``) in-process and on a real LocalCluster (2 processes).

A bad recording becomes a row with its error; a worker killed mid-part loses nothing;
an interrupted run resumes without predicting its finished parts again.
"""

from __future__ import annotations

import functools
from pathlib import Path

import pyarrow.parquet as pq
import pytest

pytest.importorskip("distributed")
pytest.importorskip("onnxruntime")

from fault_injection import run_killing_one_task  # noqa: E402

from serving.batch_prediction import find_recordings, predict_batch  # noqa: E402
from serving.predictor import Predictor, predict_recording  # noqa: E402
from stiffnet.campaign import simulate_campaign  # noqa: E402
from stiffnet.distributed.cluster import local_cluster  # noqa: E402
from stiffnet.errors import StiffnetError  # noqa: E402

MODEL = Path(__file__).resolve().parents[1] / "models" / "cnn.onnx"
#: The simulated rig's natural frequency (the campaign simulator's default).
FN = 9.48
if not MODEL.is_file():  # pragma: no cover
    pytest.skip("no shipped model", allow_module_level=True)

HEADER = "recording,fs_hz,frequency_ratio,amplitude,gap,damping_ratio,beta,duration_s"
ROWS = [
    "r0.csv,800,1.05,1.9,2.8,0.02,8,2.2",
    "r1.csv,800,0.95,1.0,0.5,0.02,30,2.2",
    "sub/r2.csv,1000,1.0,1.2,1.2,0.02,90,2.2",
    "sub/r3.csv,800,1.0,1.2,1.2,0.02,50,2.2",
    "sub/deeper/r4.csv,800,1.05,1.9,2.8,0.02,12,2.2",
]


@pytest.fixture(scope="module")
def cluster():
    with local_cluster(2) as c:
        yield c


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> Path:
    """Five simulated recordings, a file that is not a recording, one too short."""
    root = tmp_path_factory.mktemp("batch")
    manifest = root / "plan.csv"
    manifest.write_text("\n".join([HEADER, *ROWS]) + "\n")
    camp = simulate_campaign(manifest, root / "camp", [], seed=3)
    (camp / "manifest.csv").unlink()  # a plain folder of recordings, not a campaign
    (camp / "sub" / "broken.csv").write_text("not,a\nrecording,at all\n")
    (camp / "short.csv").write_text("t,accel\n0,0.1\n0.001,0.2\n0.002,0.1\n")
    (camp / "notes.txt").write_text("ignored: not a recording extension")
    return camp


@pytest.fixture(scope="module")
def reference(recordings, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "res.parquet"
    predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN, part_size=2)
    return out


def _crash_on(victim: int, part: int) -> None:
    if part == victim:
        raise KeyboardInterrupt  # as if the run were interrupted here


def test_every_recording_gets_a_row_and_bad_ones_an_error(recordings, reference):
    found = [p.relative_to(recordings).as_posix() for p in find_recordings(recordings)]
    assert found == ["r0.csv", "r1.csv", "short.csv", "sub/broken.csv", "sub/deeper/r4.csv",
                     "sub/r2.csv", "sub/r3.csv"]  # fmt: skip
    table = pq.read_table(reference).to_pandas().set_index("path")
    assert len(table) == 7
    bad = table[table["error"].notna()]
    assert sorted(Path(p).name for p in bad.index) == ["broken.csv", "short.csv"]
    good = table[table["error"].isna()]
    assert good["class"].notna().all() and (good["n_windows"] >= 1).all()
    probs = good[[c for c in good.columns if c.startswith("p_")]]
    assert ((probs.sum(axis=1) - 1).abs() < 1e-5).all()
    contact = good[good["class"] != "no_contact"]
    assert (contact["beta_low"] <= contact["beta"]).all()
    assert (contact["beta"] <= contact["beta_high"]).all()
    for col in ("geometric_class", "agreement", "ood_score"):
        assert col in good.columns
    meta = pq.read_schema(reference).metadata
    assert meta[b"stiffnet.model"] == b"cnn"
    assert not reference.with_name("res.parquet.parts").exists()  # parts cleaned up


def test_rows_carry_both_cross_checks_of_the_predictor(recordings, reference):
    table = pq.read_table(reference).to_pandas().set_index("path")
    good = table[table["error"].isna()]
    predictor = Predictor.load(MODEL)
    for path, row in good.iterrows():
        result = predict_recording(path, predictor=predictor, natural_frequency_hz=FN)
        assert row["class"] == result["class"]
        assert row["geometric_class"] == result["geometric"]["class"]
        # the restoring-force cross-check, as the single-recording answer gives it
        assert (row["restoring_force_class"] or None) == result["restoring_force_class"], path
        if result["restoring_force_class"] is None:  # that method refused: nulls, no verdict
            assert row[["restoring_force_beta", "restoring_force_agreement"]].isna().all(), path
            continue
        assert row["restoring_force_beta"] == pytest.approx(result["restoring_force_beta"])
        lo, hi = result["restoring_force_beta_interval"]
        assert (row["restoring_force_beta_low"], row["restoring_force_beta_high"]) == pytest.approx(
            (lo, hi)
        )
        assert (
            row["restoring_force_beta_low"]
            <= row["restoring_force_beta"]
            <= row["restoring_force_beta_high"]
        )
        assert row["restoring_force_agreement"] == (row["restoring_force_class"] == row["class"])
    # the simulated recordings are impacting: the restoring force answers for most of them
    assert good["restoring_force_class"].notna().sum() >= 3
    bad = table[table["error"].notna()]
    assert (
        bad[["restoring_force_class", "restoring_force_beta", "restoring_force_agreement"]]
        .isna()
        .all()
        .all()
    )


def test_glob_and_no_match(recordings, tmp_path):
    assert len(find_recordings(f"{recordings}/**/r*.csv")) == 5
    with pytest.raises(StiffnetError, match="no recordings found"):
        predict_batch(tmp_path / "nothing", tmp_path / "x.parquet", model_path=MODEL)


def test_cluster_gives_the_same_table(cluster, recordings, reference, tmp_path):
    out = tmp_path / "res.parquet"
    summary = predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN, part_size=2,
                            scheduler=cluster.scheduler_address)  # fmt: skip
    assert summary["backend"].startswith("tcp://") and summary["errors"] == 2
    assert pq.read_table(out).equals(pq.read_table(reference))
    assert out.read_bytes() == reference.read_bytes()


def test_killed_worker_loses_nothing(cluster, recordings, reference, tmp_path):
    out = tmp_path / "res.parquet"
    summary = run_killing_one_task(
        lambda hook: predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN,
                                   part_size=2, scheduler=cluster.scheduler_address,
                                   before_part=hook),
        tmp_path / "victim.pid", 2,
    )  # fmt: skip
    assert "part-00002" in summary["rerun"]
    assert pq.read_table(out).equals(pq.read_table(reference))
    cluster.wait_for_workers(2, timeout=30)


def test_interrupted_run_resumes_without_redoing_parts(recordings, reference, tmp_path):
    out = tmp_path / "res.parquet"
    with pytest.raises(KeyboardInterrupt):
        predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN, part_size=2,
                      before_part=functools.partial(_crash_on, 2))  # fmt: skip
    parts = tmp_path / "res.parquet.parts"
    done = {p.name: p.stat().st_mtime_ns for p in parts.glob("*.parquet")}
    assert sorted(done) == ["part-00000.parquet", "part-00001.parquet"] and not out.exists()
    seen = []
    summary = predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN, part_size=2,
                            progress=lambda d, t: seen.append((d, t)),
                            before_part=functools.partial(_check_not_in, (0, 1)))  # fmt: skip
    assert summary["parts_kept"] == 2 and seen[0] == (2, 4) and seen[-1] == (4, 4)
    assert out.read_bytes() == reference.read_bytes()
    with pytest.raises(StiffnetError, match="exists .use --overwrite"):
        predict_batch(recordings, out, model_path=MODEL, natural_frequency_hz=FN)


def _check_not_in(finished: tuple[int, ...], part: int) -> None:
    assert part not in finished, f"part {part} was predicted again"


def test_cli_predict_batch(recordings, reference, tmp_path):
    import json

    from typer.testing import CliRunner

    from stiffnet.cli import app

    out = tmp_path / "res.parquet"
    args = ["predict-batch", str(recordings), "--out", str(out), "--model", str(MODEL),
            "--part-size", "2", "--fn", str(FN), "--json", str(tmp_path / "s.json")]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 1, res.output  # two recordings failed: named, exit 1
    assert "failed: " in res.output and "broken.csv" in res.output and "short.csv" in res.output
    for line in (ln for ln in res.output.splitlines() if ln.startswith("failed: ")):
        assert line.count(str(recordings)) == 1, line  # the reader names the file already
    assert "2 of 7 recording(s) failed" in res.output
    assert f"7 recordings -> {out}\n" in res.output  # the path whole, not wrapped in a title
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["recordings"] == 7 and summary["errors"] == 2
    assert sorted(Path(f["path"]).name for f in summary["failed"]) == ["broken.csv", "short.csv"]
    assert out.read_bytes() == reference.read_bytes()
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2 and "use --overwrite" in res.output
    res = CliRunner().invoke(app, ["predict-batch", str(tmp_path / "none"), "--out", "x.parquet"])
    assert res.exit_code == 2 and "no recordings found" in res.output


def test_campaign_folder_is_read_through_its_manifest(recordings, tmp_path):
    """Columns, time unit, fs, f_n and channel per recording from manifest.csv; failures named."""
    import numpy as np
    import pandas as pd
    from typer.testing import CliRunner

    from stiffnet.cli import app
    from stiffnet.recordings import read_recording, write_recording_csv

    a = read_recording(recordings / "r1.csv")  # 800 Hz, beta 30
    camp = tmp_path / "field"
    camp.mkdir()
    t_ms = 1000 * np.arange(a.accel.size) / a.fs_hz
    lines = (f"{float(t)!r},0.5,{float(v)!r}\n" for t, v in zip(t_ms, a.accel, strict=True))
    (camp / "lab.csv").write_text("time_ms,force_n,acc_g\n" + "".join(lines))
    np.save(camp / "two.npy", np.stack([np.zeros(a.accel.size), a.accel], axis=1))
    write_recording_csv(camp / "nofn.csv", a.accel, a.fs_hz)
    (camp / "manifest.csv").write_text(
        "recording,fs_hz,natural_frequency_hz,columns,time_unit,channel\n"
        "lab.csv,800,9.48,time_ms;acc_g,ms,\n"
        "two.npy,800,9.48,,,1\n"
        "nofn.csv,800,,,,\n"
        "gone.csv,800,9.48,,,\n"
    )
    ref = predict_recording(recordings / "r1.csv", natural_frequency_hz=FN, model_path=MODEL)
    summary = predict_batch(camp, tmp_path / "f.parquet", model_path=MODEL)
    assert summary["manifest"] == str(camp / "manifest.csv")
    table = pq.read_table(tmp_path / "f.parquet").to_pandas().set_index("path")
    for name in ("lab.csv", "two.npy"):
        row = table.loc[str(camp / name)]
        assert pd.isna(row["error"]) and row["class"] == ref["class"], row["error"]
        assert row["beta"] == pytest.approx(ref["beta"], rel=1e-6)
    assert table.loc[str(camp / "two.npy"), "channel"] == "1"
    # f_n said from where it came: the row that gave it, not an "argument"
    source = table.loc[str(camp / "lab.csv"), "natural_frequency_source"]
    assert source.startswith(f"manifest:{camp / 'manifest.csv'}: line 2"), source
    failed = {Path(f["path"]).name: f["error"] for f in summary["failed"]}
    assert set(failed) == {"nofn.csv", "gone.csv"}
    assert "natural frequency unknown" in failed["nofn.csv"]
    assert "not found" in failed["gone.csv"]
    res = CliRunner().invoke(app, ["predict-batch", str(camp), "--out",
                                   str(tmp_path / "g.parquet"), "--model", str(MODEL)])  # fmt: skip
    assert res.exit_code == 1 and "nofn.csv" in res.output and "gone.csv" in res.output


def test_campaign_manifest_sensor_sheet_reaches_the_predictor(tmp_path):
    """A manifest's ``sensor`` cell is undone as given, exactly as ``sensor=`` (the CLI's
    ``--sensor``) would; a row without one is not read with another row's sheet."""
    import shutil

    chain = "sensor_dynamics:resonance_hz=50000,highpass_hz=0,lowpass_hz=160,lowpass_order=4"
    plan = tmp_path / "plan.csv"
    plan.write_text(HEADER + "\nr.csv,1600,1.05,1.9,2.8,0.02,30,4\n")
    camp = simulate_campaign(plan, tmp_path / "sim", [chain], seed=3)
    field = tmp_path / "field"
    field.mkdir()
    shutil.copy(camp / "r.csv", field / "sheet.csv")
    shutil.copy(camp / "r.csv", field / "bare.csv")
    (field / "manifest.csv").write_text(
        "recording,fs_hz,natural_frequency_hz,sensor\n"
        'sheet.csv,1600,9.48,"lowpass_hz=160,lowpass_order=4"\n'
        "bare.csv,1600,9.48,\n"
    )
    summary = predict_batch(field, tmp_path / "s.parquet", model_path=MODEL)
    assert not summary["failed"], summary["failed"]
    table = pq.read_table(tmp_path / "s.parquet").to_pandas().set_index("path")
    row = table.loc[str(field / "sheet.csv")]
    sheet = {"lowpass_hz": 160.0, "lowpass_order": 4.0}
    ref = predict_recording(field / "sheet.csv", natural_frequency_hz=FN, model_path=MODEL,
                            sensor=sheet)  # fmt: skip
    assert row["sensor_source"] == "data sheet" == ref["restoring_force"]["sensor"]["source"]
    assert row.isna()["chain_readings"]  # a data sheet is read once: no spread
    assert row["restoring_force_beta"] == pytest.approx(ref["restoring_force_beta"], rel=1e-9)
    assert row["restoring_force_beta"] == pytest.approx(30.0, rel=0.1)
    bare = table.loc[str(field / "bare.csv")]
    assert bare["sensor_source"] != "data sheet"
    assert bare["restoring_force_beta"] != pytest.approx(row["restoring_force_beta"], rel=1e-3)


def test_a_glob_of_a_campaigns_files_reads_each_through_its_row(recordings, tmp_path):
    """A glob (not the folder) over a campaign's recordings reads each with its manifest
    row (columns, time unit, f_n) and that manifest's sidecar check, and judges them as the
    campaign, as the folder would: it read them alike with the options, a sidecar
    disagreeing with its row won, and the campaign's contact-law alarm was left out (on a
    restraint-mass campaign, 6 of 24 wrong and silent by a glob, none by the folder)."""
    import json

    from campaign_helpers import ms_campaign

    camp = ms_campaign(recordings / "r1.csv", tmp_path / "lab")
    ref = predict_recording(recordings / "r1.csv", natural_frequency_hz=FN, model_path=MODEL)
    summary = predict_batch(f"{camp}/*.csv", tmp_path / "g.parquet", model_path=MODEL)
    assert summary["failed"] == [], summary["failed"]
    # judged as that campaign (its chain pooled, its contact law counted), as the folder is
    assert Path(summary["manifest"]).resolve() == (camp / "manifest.csv").resolve()
    (row,) = pq.read_table(tmp_path / "g.parquet").to_pylist()
    assert row["beta"] == pytest.approx(ref["beta"], rel=1e-6)
    assert row["natural_frequency_source"].startswith(f"manifest:{camp / 'manifest.csv'}: line 2")
    (camp / "run.csv.json").write_text(json.dumps({"natural_frequency_hz": 12.0}))
    with pytest.raises(StiffnetError, match="disagrees with the recording's sidecar"):
        predict_batch(f"{camp}/*.csv", tmp_path / "h.parquet", model_path=MODEL)


def test_a_rows_rate_contradicting_its_file_names_the_manifest_line(recordings, tmp_path):
    """A row's ``fs_hz`` that contradicts its file's time column fails that recording with
    the manifest's line and column first, as ``evaluate`` says it, by the folder and by a glob
    over its files: it named only the file, leaving the user to find the row."""
    import shutil

    camp = tmp_path / "lab"
    camp.mkdir()
    shutil.copy(recordings / "r0.csv", camp / "good.csv")  # 800 Hz
    shutil.copy(recordings / "r1.csv", camp / "bad.csv")  # 800 Hz, its row says 1200
    (camp / "manifest.csv").write_text(
        "recording,fs_hz,natural_frequency_hz\ngood.csv,800,9.48\nbad.csv,1200,9.48\n"
    )
    for spec, out in ((camp, "f.parquet"), (f"{camp}/*.csv", "g.parquet")):
        summary = predict_batch(spec, tmp_path / out, model_path=MODEL)
        (failed,) = summary["failed"]
        assert Path(failed["path"]).name == "bad.csv"
        assert failed["error"].startswith(
            f"{camp / 'manifest.csv'}: line 3 (bad.csv), column fs_hz: "
        )
        assert "gives fs = 800 Hz but fs_hz = 1200 Hz" in failed["error"]


def test_a_campaign_folders_unlisted_recording_is_said(recordings, tmp_path):
    """A row missing from the manifest made its recording vanish from the table in silence
    (3 files, 2 rows: '2 recordings', nothing said); a glob of some files says nothing."""
    from typer.testing import CliRunner

    from stiffnet.cli import app

    camp = tmp_path / "camp"
    camp.mkdir()
    for name in ("r0.csv", "r1.csv", "sub/r3.csv"):
        (camp / Path(name).name).write_bytes((recordings / name).read_bytes())
    (camp / "manifest.csv").write_text("recording,fs_hz,natural_frequency_hz\n"
                                       "r0.csv,800,9.48\nr1.csv,800,9.48\n")  # fmt: skip
    summary = predict_batch(camp, tmp_path / "a.parquet", model_path=MODEL)
    assert summary["unlisted"] == ["r3.csv"] and summary["recordings"] == 2
    res = CliRunner().invoke(app, ["--wide", "predict-batch", str(camp), "--out",
                                   str(tmp_path / "b.parquet"), "--model", str(MODEL)])  # fmt: skip
    assert res.exit_code == 0, res.output
    assert ("warning: 1 recording file(s) in the campaign folder are not in its manifest "
            "(r3.csv): not read") in res.output  # fmt: skip
    glob = predict_batch(f"{camp}/r*.csv", tmp_path / "c.parquet", model_path=MODEL)
    assert glob["unlisted"] == []

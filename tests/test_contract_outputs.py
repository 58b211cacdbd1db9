"""Outputs never land on inputs, never replace or delete a user's files, never mix runs.

Each case is a red-team finding: a user's folder with generic marker names, a parts
folder of the user's, two writers of one table, an output that is an input.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from test_contract import CAMPAIGN, EXAMPLE, ROOT, one_line_error, runner

from stiffnet.cli import app
from stiffnet.errors import StiffnetError

MODEL = ROOT / "models" / "gbm.onnx"


def _user_folder(folder: Path, **extra: str) -> dict[str, str]:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "thesis.tex").write_text("years of work")
    for name, text in extra.items():
        (folder / name.replace("__", ".")).write_text(text)
    return _snapshot(folder)


def _snapshot(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): p.read_text() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture
def recordings(tmp_path):
    folder = tmp_path / "recs"
    folder.mkdir()
    for i in range(3):
        shutil.copy(EXAMPLE, folder / f"r{i}.csv")
    return folder


# ------------------------------------------------------------------ markers with a run id


@pytest.mark.parametrize("marker", ["job.json", "card.json", "campaign_card.json",
                                    "stiffnet-run.json"])  # fmt: skip
def test_generic_marker_names_are_not_trusted(tmp_path, marker):
    """A user's folder holding a `job.json` (or a stiffnet name without a run id) is not ours."""
    other = tmp_path / "F"
    before = _user_folder(other, **{marker.replace(".", "__"): '{"kind": "stiffnet-x"}'})
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text("n_trajectories: 4\nshard_size: 2\n")
    one_line_error(["simulate", "--config", cfg, "--out", other, "--overwrite"], "did not write")
    one_line_error(["simulate-campaign", ROOT / "examples" / "campaign_manifest.csv", "--out",
                    other, "--overwrite"], "did not write")  # fmt: skip
    assert _snapshot(other) == before


def test_train_out_refuses_a_foreign_folder_and_the_working_directory(tmp_path, monkeypatch):
    foreign = tmp_path / "thesis"
    before = _user_folder(foreign, summary__json='{"mine": 1}')
    data = tmp_path / "no-data-needed"  # refused before the dataset is even opened
    one_line_error(["train", "--data", data, "--out", foreign], "not an earlier stiffnet-train")
    assert _snapshot(foreign) == before
    monkeypatch.chdir(foreign)
    one_line_error(["train", "--data", data, "--out", "."], "working directory")
    assert _snapshot(foreign) == before


def test_shipped_models_folder_is_a_train_output():
    from stiffnet.io_utils import RUN_MARKER, read_marker

    marker = read_marker(ROOT / "models" / RUN_MARKER)  # `train --out models` replaces its files
    assert marker is not None and marker["kind"] == "stiffnet-train"


# ------------------------------------------------------------------------ outputs vs inputs


def test_outputs_never_land_on_inputs(tmp_path):
    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    data = rec.read_bytes()
    one_line_error(["predict", rec, "--json", rec], "is the input recording")
    one_line_error(["analyze", rec, "--json", rec], "is the input recording")
    assert rec.read_bytes() == data
    camp = tmp_path / "C"
    shutil.copytree(CAMPAIGN, camp)
    manifest = (camp / "manifest.csv").read_bytes()
    one_line_error(["report", camp, "--out", camp / "manifest.csv"], "input campaign")
    one_line_error(["compare", camp, "--json", camp / "manifest.csv"], "input campaign")
    one_line_error(["compare", camp, "--plots", camp], "--plots")
    assert (camp / "manifest.csv").read_bytes() == manifest
    one_line_error(["analyze", rec, "--json", tmp_path / "a.json", "--plots", tmp_path / "a.json"],
                   "is also --json")  # fmt: skip


@pytest.mark.parametrize("flag", ["--rows", "--json", "--plot"])
def test_log_outputs_never_land_on_its_recording(tmp_path, flag):
    """`log`'s recording is text (it may be `-`): it still counts as the input, and --rows
    and --plot are checked with the other outputs (they replaced the record before)."""
    rec = tmp_path / "drill.csv"
    shutil.copy(EXAMPLE, rec)
    data = rec.read_bytes()
    one_line_error(["log", rec, "--fn", "9.48", flag, rec], "is the input recording")
    assert rec.read_bytes() == data


def test_log_rows_and_plot_are_two_outputs(tmp_path):
    rec = tmp_path / "drill.csv"
    shutil.copy(EXAMPLE, rec)
    out = tmp_path / "log.png"
    one_line_error(["log", rec, "--fn", "9.48", "--rows", out, "--plot", out], "is also --rows")


def test_plots_never_replace_a_users_figures(tmp_path):
    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    figs = tmp_path / "C"
    figs.mkdir()
    (figs / "force_displacement.png").write_bytes(b"the user's figure")
    one_line_error(["analyze", rec, "--plots", figs], "stiffnet did not write")
    assert (figs / "force_displacement.png").read_bytes() == b"the user's figure"


@pytest.mark.slow
def test_plots_folder_is_marked_and_reused(tmp_path):
    """A figure folder stiffnet wrote carries its marker; a second run replaces its figures."""
    from stiffnet.io_utils import RUN_MARKER, read_marker

    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    for _ in range(2):
        res = runner.invoke(app, ["analyze", str(rec), "--plots", str(tmp_path / "figs")])
        assert res.exit_code == 0, res.output
    assert read_marker(tmp_path / "figs" / RUN_MARKER)["kind"] == "stiffnet-figures"


# ------------------------------------------------------------------------ predict-batch


def test_predict_batch_never_deletes_a_users_parts_folder(tmp_path, recordings):
    out = tmp_path / "r.parquet"
    users = tmp_path / "r.parquet.parts"
    before = _user_folder(users)
    one_line_error(["predict-batch", recordings, "--out", out, "--model", MODEL],
                   "stiffnet did not write")  # fmt: skip
    assert _snapshot(users) == before and not out.exists()


def test_predict_batch_out_named_other_than_parquet_is_refused(tmp_path, recordings):
    """--out results.csv wrote Parquet bytes under a .csv name, exit 0."""
    out = tmp_path / "results.csv"
    said = "results.csv: give a .parquet file name (the result table is Parquet)"
    one_line_error(["predict-batch", recordings, "--out", out, "--model", MODEL], said)
    assert not out.exists()


def test_predict_batch_writers_are_refused_not_mixed(tmp_path, recordings):
    from stiffnet.io_utils import output_lock

    out = tmp_path / "r.parquet"
    with output_lock(out):  # another predict-batch is writing this table
        one_line_error(["predict-batch", recordings, "--out", out, "--model", MODEL],
                       "another stiffnet run")  # fmt: skip
    assert not out.exists()


def test_predict_batch_parts_of_another_run_are_replaced_wholly(tmp_path, recordings):
    """An interrupted run's parts (other inputs) are removed, not concatenated with ours."""
    import pyarrow.parquet as pq

    from serving.batch_prediction import predict_batch
    from stiffnet.io_utils import RUN_MARKER

    out = tmp_path / "r.parquet"

    def crash(part: int) -> None:
        if part == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        predict_batch(recordings, out, model_path=MODEL, part_size=1, before_part=crash)
    parts = tmp_path / "r.parquet.parts"
    assert (parts / "part-00000.parquet").is_file() and (parts / RUN_MARKER).is_file()
    (parts / "notes.txt").write_text("the user's")  # a file stiffnet did not write
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(EXAMPLE, other / "z.csv")
    summary = predict_batch(other, out, model_path=MODEL, part_size=1)
    assert summary["recordings"] == 1 and summary["parts_kept"] == 0
    assert pq.read_table(out).column("path").to_pylist() == [str(other / "z.csv")]
    assert sorted(p.name for p in parts.iterdir()) == ["notes.txt"]  # ours gone, theirs kept


def test_report_holds_its_outputs_lock(tmp_path):
    from stiffnet.io_utils import output_lock

    page = tmp_path / "r.html"
    with output_lock(page):
        one_line_error(["report", CAMPAIGN, "--out", page], "another stiffnet run")
    assert not page.exists()


def test_json_dash_writes_to_stdout(tmp_path):
    rec = tmp_path / "rec.csv"
    shutil.copy(EXAMPLE, rec)
    res = runner.invoke(
        app, ["predict", str(rec), "--model", str(MODEL), "--fn", "9.48", "--json", "-"]
    )
    assert res.exit_code == 0, res.output
    result = json.loads(res.stdout)  # stdout holds the JSON alone (the tables go to stderr)
    assert result["class"] in result["probabilities"]
    assert not Path("-").exists()


def test_a_result_inside_a_campaign_folder_can_be_written_again(tmp_path):
    """Replacing an earlier result in an input folder is fine; replacing its data is not."""
    camp = tmp_path / "C"
    shutil.copytree(CAMPAIGN, camp)
    (camp / "compare.json").write_text("{}")  # an earlier `compare --json C/compare.json`
    from stiffnet.cli.console import check_arguments

    check_arguments({"campaign": camp, "json_path": camp / "compare.json"})
    rec = next(camp.rglob("*.csv"))
    with pytest.raises(StiffnetError, match="would replace a file of the input campaign"):
        check_arguments({"campaign": camp, "json_path": rec})

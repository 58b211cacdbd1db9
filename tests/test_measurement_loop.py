"""The iterating measurement loop on campaigns from ``simulate_campaign``.

The campaigns hide two effects at realistic levels (a damped contact 0.25 and a 237 Hz
accelerometer resonance, 5 recordings of 3 s, 2 % noise). The fast tests train GBMs on
tiny datasets (60 trajectories) with the effects given by the user, so no diagnosis
runs; the slow one lets the diagnosis find both effects and trains the default family
(CNN). A field campaign (no β column) is looped too.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pytest
from campaign_helpers import short_manifest, without_beta
from typer.testing import CliRunner

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.config import load_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.errors import StiffnetError
from stiffnet.measurement import loop as loop_mod
from stiffnet.shipped import default_config

DAMPED = "contact_damping:damping_ratio=0.25"
SENSOR = "sensor_dynamics:resonance_hz=237,resonance_damping=0.03,lowpass_hz=0"
SENSOR_PARAMS = {"resonance_hz": 237.0, "resonance_damping": 0.03, "lowpass_hz": 0.0}
TINY = 60  # trajectories per dataset: every class in training and test, seconds per GBM


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    return tmp_path_factory.mktemp("loop")


@pytest.fixture(scope="module")
def two_effects(tmp):
    return simulate_campaign(short_manifest(tmp, 5), tmp / "two_effects", [DAMPED, SENSOR], seed=0)


def _ideal() -> SimulationConfig:
    return load_config(SimulationConfig, default_config("sim/ideal.yaml"))


def _mlflow(uri: str, experiment: str):
    import mlflow

    client = mlflow.MlflowClient(uri)
    exp = client.get_experiment_by_name(experiment)
    return client, client.search_runs([exp.experiment_id])


@pytest.fixture(scope="module")
def looped(two_effects, tmp):
    """Two runs of the loop on one state folder: iteration 0 and 1, then (resumed) 2."""
    uri = f"sqlite:///{tmp / 'mlflow.db'}"
    state = tmp / "state"
    charts: list[int] = []
    original = loop_mod._chart

    def counting_chart(folder, st):
        charts.append(len(st["iterations"]))
        return original(folder, st)

    camp = load_campaign(two_effects)
    kw = dict(family="gbm", n_trajectories=TINY, tracking_uri=uri)
    fits = []  # each run's kept restoring-force fits
    keep = loop_mod.fits_kept

    @contextlib.contextmanager
    def kept_fits(path):
        with keep(path) as kept:
            fits.append(kept)
            yield kept

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(loop_mod, "_chart", counting_chart)
        mp.setattr(loop_mod, "fits_kept", kept_fits)
        first = loop_mod.run_loop(
            camp,
            _ideal(),
            state,
            iterations=1,
            add_effects=[("sensor_dynamics", SENSOR_PARAMS)],
            **kw,
        )
        second = loop_mod.run_loop(
            camp,
            _ideal(),
            state,
            iterations=1,
            add_effects=[("contact_damping", {"damping_ratio": 0.25})],
            tracking_uri=uri,  # family and dataset size: the state's
        )
    return {"first": first, "second": second, "uri": uri, "state": state, "charts": charts,
            "fits": fits}  # fmt: skip


def test_the_resumed_loop_reads_the_fits_the_first_run_kept(looped):
    # the recordings behind the 237 Hz mount are read by every iteration's model: their chain
    # and corner fits run in the first run (iterations 0 and 1), and the resumed run (a new
    # process in use) reads them back from the state folder instead of fitting them again
    first, second = looped["fits"]
    assert (looped["state"] / loop_mod.KEPT_FITS_FILE).is_file()
    assert first.fitted > 0 and first.reused > 0  # iteration 1 reused iteration 0's
    assert second.reused > 0 and second.fitted < first.fitted


def test_two_iterations_with_resume(looped):
    first, second, state = looped["first"], looped["second"], looped["state"]
    assert [it["index"] for it in first["iterations"]] == [0, 1]
    assert [it["index"] for it in second["iterations"]] == [0, 1, 2]  # resumed, not restarted
    assert second["iterations"][:2] == first["iterations"]
    assert second["family"] == "gbm" and second["n_trajectories"] == TINY
    saved = json.loads((state / "state.json").read_text())
    assert [it["label"] for it in saved["iterations"]] == [
        "start",
        "+sensor_dynamics",
        "+contact_damping",
    ]
    assert json.loads((state / "stiffnet-run.json").read_text())["status"] == "complete"
    for k in range(3):
        folder = state / f"iter-{k:03d}"
        assert (folder / "config.yaml").is_file() and (folder / "evaluation.json").is_file()
        assert (folder / "model" / "gbm.onnx").is_file() and (folder / "data_card.json").is_file()
        assert not (folder / "data").exists()  # datasets are not kept by default
    # true values given here: the resonance alone explains little (11.6 -> 8.7 when
    # written: each effect changes what the other does to the statistics), both together
    # bring the simulator to the noise floor (0.0025)
    d = [it["metrics"]["discrepancy"] for it in second["iterations"]]
    assert d[1] < d[0] and d[2] < 0.01 * d[0], d
    assert all(it["metrics"]["accuracy"] is not None for it in second["iterations"])
    # beta by simulation beside the model in every iteration, and the reading per recording
    for it in second["iterations"]:
        assert {"simulation_accuracy", "simulation_beta_mape", "reading_accuracy"} <= set(
            it["metrics"]
        )
        assert {r["reading_method"] for r in it["recordings"]} <= {"simulation", "learned"}
    # without the campaign's effects no beta reproduces its recordings; with both at their
    # true values every one is reproduced and read within a few per cent
    sim = [it["metrics"] for it in second["iterations"]]
    assert sim[0]["simulation_reproduced_share"] < 0.5
    assert sim[2]["simulation_reproduced_share"] == 1.0 and sim[2]["simulation_beta_mape"] < 0.05
    assert second["before"]["discrepancy"] == d[0] and second["after"]["discrepancy"] == d[2]
    for it in second["iterations"]:  # each phase's CPU seconds, inside the iteration's
        cpu = it["cpu_seconds"]
        assert set(cpu) == {"dataset", "train", "evaluation", "total"} and min(cpu.values()) > 0
        assert cpu["dataset"] + cpu["train"] + cpu["evaluation"] <= cpu["total"] + 0.03, cpu


def test_a_model_trained_behind_the_fitted_chain_reads_through_it(looped):
    # from +sensor_dynamics on, the world holds the campaign's fitted chain: those models
    # read the record with the stages inside their priors left in; iteration 0's world has
    # no fitted chain and keeps the predictor's default (every identified stage undone)
    from serving.predictor import UNDO_CHAIN, Predictor

    state = looped["state"]
    modes = [
        Predictor.load(state / f"iter-{k:03d}" / "model" / "gbm.onnx").undo_chain for k in range(3)
    ]
    assert modes == [UNDO_CHAIN, loop_mod.FITTED_CHAIN_UNDO, loop_mod.FITTED_CHAIN_UNDO]
    assert loop_mod.FITTED_CHAIN_UNDO == "outside_priors" != UNDO_CHAIN
    # the user's own setting wins
    state_user = {"train_overrides": {"undo_chain": "off"}}
    fitted = [{"name": "sensor_dynamics"}]
    assert loop_mod.iteration_train_overrides(state_user, fitted) == {"undo_chain": "off"}


def test_config_yaml_per_iteration_is_a_valid_simulator_config(looped):
    state = looped["state"]
    cfgs = [
        load_config(SimulationConfig, state / f"iter-{k:03d}" / "config.yaml") for k in range(3)
    ]
    assert [e.name for e in cfgs[0].effects] == []
    assert [e.name for e in cfgs[1].effects] == ["sensor_dynamics"]
    assert [e.name for e in cfgs[2].effects] == ["sensor_dynamics", "contact_damping"]
    assert all(c.n_trajectories == TINY for c in cfgs)
    # a prior centred on the value: +-25 % (given values are not fitted: kept fixed)
    assert cfgs[2].effects[1].params == {"damping_ratio": 0.25}
    assert cfgs[2].effects[0].params["resonance_hz"] == 237.0
    text = (state / "iter-002" / "config.yaml").read_text()
    assert text.startswith("# stiffnet loop on two_effects, iteration 2: added contact_damping")


def test_spread_is_a_prior_centred_on_the_fit():
    p = loop_mod.spread_params("contact_damping", {"damping_ratio": 0.2}, ["damping_ratio"], 0.25)
    assert p["damping_ratio"] == pytest.approx([0.15, 0.25])
    # clipped to the declared range (damping_ratio <= 1... here at the lower end 0)
    p = loop_mod.spread_params(
        "sensor_dynamics", {"resonance_hz": 240.0, "resonance_damping": 0.03}, ["resonance_hz"], 0.5
    )
    assert p["resonance_hz"] == pytest.approx([120.0, 360.0]) and p["resonance_damping"] == 0.03


def test_a_learned_laws_prior_is_no_wider_than_its_discovered_interval():
    law = {"exponent": 1.0, "knee": 0.2, "knee_ratio": 2.8}
    diag = {"learned_law": {"law": {"intervals": {"knee": [0.19, 0.22], "knee_ratio": [2.0, 2.7]}}}}
    added = [{"name": "learned_contact", "params": law, "fitted": ["knee", "knee_ratio"],
              "source": "diagnosis"},
             {"name": "contact_damping", "params": {"damping_ratio": 0.2},
              "fitted": ["damping_ratio"], "source": "diagnosis"}]  # fmt: skip
    out, same = loop_mod.with_law_intervals(added, diag)
    assert same is diag and "intervals" not in out[1]
    ivs = out[0]["intervals"]
    p = loop_mod.spread_params("learned_contact", law, ["knee", "knee_ratio"], 0.25, ivs)
    assert p["knee"] == pytest.approx([0.19, 0.22])  # inside +-25 %: the interval
    # an interval that misses the value (a refit moved it) still holds it
    assert p["knee_ratio"] == pytest.approx([2.1, 2.8])  # and never wider than the spread
    assert p["exponent"] == 1.0
    given = [{**added[0], "source": "given"}]
    given[0].pop("intervals")
    assert "intervals" not in loop_mod.with_law_intervals(given, diag)[0][0]


def _two_stage_diagnosis(**evidence) -> dict:
    """A diagnosis as ``diagnose --json`` writes it for a two-stage contact behind a 240 Hz
    mount (the independent rig's held-out campaign): the simulation fit bent the mount to
    181 Hz through the library's linear contact, the evidence read 238 Hz on the maps."""
    fit = {"lowpass_order": 1.0, "resonance_hz": 180.8, "resonance_damping": 0.0655,
           "highpass_hz": 0.668, "lowpass_hz": 247.6}  # fmt: skip
    law = {"exponent": 1.0, "knee_ratio": 1.988, "reference_penetration": 0.54, "knee": 0.2974}
    chain = {"n": 24, "resonance_hz": 238.1, "resonance_damping": 0.040, "lowpass_hz": 258.1,
             "lowpass_order": 1.0, "highpass_hz": 0.244}  # fmt: skip
    return {
        "missing_effects": ["sensor_dynamics"],
        "fitted_params": {"sensor_dynamics": fit},
        "ranking": [{"effect": "sensor_dynamics", "params": fit,
                     "fitted": ["resonance_hz", "resonance_damping", "highpass_hz", "lowpass_hz"]}],
        "learned_law": {"proposed": True, "effect": {"name": "learned_contact", "params": law},
                        "replaces": [], "law": {"terms": ["hinge"], "intervals": {}}},
        "restoring_force": {"sensor": chain, "chain_fitted_on": ["a.csv", "b.csv", "c.csv"],
                            **evidence},
    }  # fmt: skip


def _rig_discrepancy(campaign, start_cfg, effects, seed):
    """The campaign's discrepancy as the rig's (a 240 Hz mount and nothing else) answers it:
    the further the world's resonance from 240 Hz and the more stages it adds, the larger."""
    sensor = next(e["params"] for e in effects if e["name"] == "sensor_dynamics")
    extra = sum(1.0 for k in ("lowpass_hz", "highpass_hz") if sensor.get(k))
    return abs(sensor["resonance_hz"] - 240.0) + 10.0 * extra


def _next_from(diagnosis: dict, monkeypatch) -> dict:
    monkeypatch.setattr(loop_mod, "chain_discrepancy", _rig_discrepancy)
    state = {"iterations": [{"effects": [], "model": ""}], "seed": 0}
    added, _ = loop_mod._next_effects(None, state, _ideal(), (diagnosis, []), None, False)
    return {a["name"]: a for a in added}


def test_a_chain_fitted_through_a_replaced_contact_is_the_evidences(monkeypatch):
    added = _next_from(_two_stage_diagnosis(), monkeypatch)
    sensor = added["sensor_dynamics"]
    # the world's chain is the one the maps read, not the fit made through a linear contact,
    # less the stages the campaign's discrepancy does not want
    assert sensor["params"]["resonance_hz"] == pytest.approx(238.1)
    assert sensor["params"]["resonance_damping"] == pytest.approx(0.040)
    assert sensor["params"]["lowpass_hz"] == 0.0 and sensor["params"]["highpass_hz"] == 0.0
    assert sensor["simulation_fit"]["resonance_hz"] == pytest.approx(180.8)
    assert sensor["origin"] == "restoring-force chain"
    choice = {c["chain"]: c["discrepancy"] for c in sensor["chain_choice"]}
    assert choice["simulation fit"] == pytest.approx(59.2 + 20.0)
    assert choice["evidence"] == pytest.approx(1.9 + 20.0)
    assert min(choice, key=choice.get) == "evidence less highpass_hz and lowpass_hz"
    # the prior is centred on it: the rig's 240 Hz inside, the fit's 181 Hz outside
    cfg = loop_mod._prior_config(_ideal(), list(added.values()), 0.1)
    res = next(e for e in cfg.effects if e.name == "sensor_dynamics").params["resonance_hz"]
    assert res[0] < 240.0 < res[1] and res[0] > 181.0
    assert added["learned_contact"]["params"]["knee_ratio"] == pytest.approx(1.988)


@pytest.mark.parametrize(
    "change",
    ["refuted", "no_law", "no_resonance", "unconfirmed"],
)
def test_the_simulation_fit_stays_where_the_evidence_cannot_replace_it(change, monkeypatch):
    diag = _two_stage_diagnosis()
    rf = diag["restoring_force"]
    if change == "refuted":  # the recordings read better as recorded: no sensor's chain
        rf["chain_refuted"] = {"fitted_on": ["a.csv"]}
        rf.pop("chain_fitted_on")
    elif change == "no_law":  # the fit's contact is the model's: nothing conditions it
        diag["learned_law"]["proposed"] = False
    elif change == "no_resonance":  # a low-pass alone is not the stage a contact bends
        rf["sensor"] = {**rf["sensor"], "resonance_hz": None}
    else:  # every recording kept its own chain: none shared
        rf.pop("chain_fitted_on")
    sensor = _next_from(diag, monkeypatch)["sensor_dynamics"]
    assert sensor["params"]["resonance_hz"] == pytest.approx(180.8)
    assert "simulation_fit" not in sensor


def test_the_simulation_fit_stays_where_the_campaign_prefers_it(monkeypatch):
    """Where the simulation fit's chain reproduces the campaign best, it is kept."""
    diag = _two_stage_diagnosis()
    diag["fitted_params"]["sensor_dynamics"]["resonance_hz"] = 240.0
    diag["fitted_params"]["sensor_dynamics"]["lowpass_hz"] = 0.0
    diag["fitted_params"]["sensor_dynamics"]["highpass_hz"] = 0.0
    sensor = _next_from(diag, monkeypatch)["sensor_dynamics"]
    assert sensor["params"]["resonance_hz"] == 240.0 and sensor["origin"] == "simulation fit"
    assert sensor["simulation_fit"]["resonance_hz"] == 240.0


def test_mlflow_runs_nested_and_models_registered(looped):
    import mlflow

    second = looped["second"]
    client, runs = _mlflow(looped["uri"], second["experiment"])
    parent = second["parent_run_id"]
    assert looped["first"]["parent_run_id"] == parent  # the resumed run reuses the parent
    children = [r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent]
    assert sorted(int(r.data.params["iteration"]) for r in children) == [0, 1, 2]
    assert {r.info.run_id for r in children} == {it["run_id"] for it in second["iterations"]}
    for r in children:
        assert "discrepancy" in r.data.metrics and "accuracy" in r.data.metrics
    # the parent holds the metrics against the iteration (one point per iteration)
    history = client.get_metric_history(parent, "discrepancy")
    assert sorted(m.step for m in history) == [0, 1, 2]
    versions = client.search_model_versions(f"name='{second['registered_model']}'")
    assert sorted(int(v.version) for v in versions) == [1, 2, 3]
    assert [it["model_version"] for it in second["iterations"]] == [1, 2, 3]
    # the registered model is the ONNX file with its card
    model = mlflow.onnx.load_model(f"models:/{second['registered_model']}/3")
    assert model.graph.input
    info = mlflow.models.get_model_info(second["iterations"][2]["model_uri"])
    assert info.metadata["onnx_file"] == "gbm.onnx" and info.metadata["stiffnet_card"]


def test_chart_covers_all_iterations(looped):
    # the chart is drawn after each iteration from the whole state: 1, 2, then (resumed) 3
    assert looped["charts"][-1] == 3 and looped["charts"][:2] == [1, 2]
    chart = Path(looped["second"]["chart"])
    assert chart.read_bytes().startswith(b"\x89PNG") and chart.stat().st_size > 5000


def test_predict_takes_the_produced_model(looped, two_effects):
    from stiffnet.cli import app

    model = looped["second"]["iterations"][-1]["model"]
    rec = next((two_effects / "recordings").iterdir())
    res = CliRunner().invoke(app, ["predict", str(rec), "--model", model, "--fn", "9.48"])
    assert res.exit_code == 0, res.output
    assert "beta" in res.output.lower()


def test_state_is_checked_on_resume(looped, two_effects, tmp):
    camp = load_campaign(two_effects)
    with pytest.raises(StiffnetError, match="started with family 'gbm'"):
        loop_mod.run_loop(camp, _ideal(), looped["state"], family="cnn", tracking_uri=None)
    foreign = tmp / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(StiffnetError, match="not a loop state folder"):
        loop_mod.run_loop(camp, _ideal(), foreign, family="gbm", tracking_uri=None)
    assert (foreign / "notes.txt").read_text() == "mine"


def test_default_state_folder_is_never_inside_shipped_files(tmp):
    checkout = Path(loop_mod.__file__).resolve().parents[2]
    assert loop_mod.default_state_dir(checkout / "examples" / "x") == Path("runs/loop-x")
    assert loop_mod.default_state_dir(tmp / "camp") == (tmp / "camp-loop").resolve()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--iterations", "-1"], "--iterations must be"),
        (["--family", "svm"], "model family 'svm'"),
        (["--spread", "1.5"], "--spread must be"),
        (["--add-effect", "contact_damping:damping_ratio=abc"], "is not a number"),
        (["--envelope", "--operating-points"], "give one of --envelope and --operating-points"),
        (["--sweep", "--operating-points"], "give one of --sweep and --operating-points"),
    ],
)
def test_bad_loop_options_are_one_line(two_effects, tmp, args, needle):
    from stiffnet.cli import app

    state = tmp / f"bad{args[0]}"
    res = CliRunner().invoke(app, ["loop", str(two_effects), "--state", str(state), *args])
    assert res.exit_code == 2, res.output
    assert needle in res.output and "Traceback" not in res.output
    assert not state.exists()


def test_keep_data_reaches_the_loop(two_effects, tmp, monkeypatch):
    from stiffnet.cli import app

    seen = {}

    def stop(*_args, **kwargs):
        seen.update(kwargs)
        raise StiffnetError("stopped before any work")

    monkeypatch.setattr(loop_mod, "run_loop", stop)
    args = ["loop", str(two_effects), "--state", str(tmp / "kept"), "--no-tracking"]
    res = CliRunner().invoke(app, [*args, "--keep-data"])
    assert res.exit_code == 2 and "stopped before any work" in res.output, res.output
    assert seen["keep_data"] is True
    CliRunner().invoke(app, args)
    assert seen["keep_data"] is False


def test_field_campaign_without_beta(two_effects, tmp):
    """No β: the error is the discrepancy and the agreement with the restoring force."""
    field = without_beta(two_effects, tmp / "field")
    res = loop_mod.run_loop(
        load_campaign(field),
        _ideal(),
        tmp / "field-state",
        iterations=1,
        add_effects=[
            ("contact_damping", {"damping_ratio": 0.25}),
            ("sensor_dynamics", SENSOR_PARAMS),
        ],
        family="gbm",
        n_trajectories=TINY,
        tracking_uri=None,
    )
    m0, m1 = (it["metrics"] for it in res["iterations"])
    assert m0["accuracy"] is None and m0["beta_mape"] is None  # nothing to score against
    assert m1["discrepancy"] < 0.5 * m0["discrepancy"]
    assert {"restoring_force_agreement", "geometric_agreement"} <= set(m1)
    assert res["iterations"][1]["label"] == "+contact_damping+sensor_dynamics"
    assert Path(res["chart"]).is_file()


def test_loop_trains_at_the_campaigns_operating_points(two_effects, tmp):
    """``world="operating_points"``: every dataset is drawn at the manifest's rows, the
    state keeps it, and a resume in another world is refused."""
    state = tmp / "ops-state"
    kw = dict(family="gbm", n_trajectories=TINY, tracking_uri=None)
    res = loop_mod.run_loop(load_campaign(two_effects), _ideal(), state, iterations=0,
                            world="operating_points", **kw)  # fmt: skip
    assert res["world"] == "operating_points"
    card = json.loads((state / "iter-000" / "data_card.json").read_text())
    points = card["operating_points"]["points"]
    rows = load_campaign(two_effects).rows
    assert [p["gap"] for p in points] == [r.gap for r in rows] and len(points) == 5
    assert card["n_trajectories"] == TINY and len(card["shards"]) == 5
    assert res["after"]["accuracy"] is not None
    with pytest.raises(StiffnetError, match="world 'operating_points'"):
        loop_mod.run_loop(load_campaign(two_effects), _ideal(), state, iterations=1,
                          world="sweep", **kw)  # fmt: skip
    with pytest.raises(StiffnetError, match="training world must be one of"):
        loop_mod.run_loop(load_campaign(two_effects), _ideal(), tmp / "x", world="grid", **kw)


@pytest.mark.slow
def test_diagnosed_loop_with_the_shipped_family(two_effects, tmp):
    """Default family (CNN, tiny here); the diagnosis adds both effects at once with their
    joint fits, then finds nothing more and the loop stops."""
    camp = load_campaign(two_effects)
    candidates = ["contact_damping", "forcing_harmonics", "sensor_dynamics", "colored_noise"]
    kw = dict(
        n_trajectories=120,
        train_overrides={"cnn": {"max_epochs": 3}},
        candidates=candidates,
        tracking_uri=f"sqlite:///{tmp / 'cnn.db'}",
    )
    res = loop_mod.run_loop(camp, _ideal(), tmp / "cnn-state", iterations=1, **kw)
    assert res["family"] == "cnn"
    start, it = res["iterations"]
    assert sorted(a["name"] for a in it["added"]) == ["contact_damping", "sensor_dynamics"]
    fit = {a["name"]: a["params"] for a in it["added"]}
    assert fit["contact_damping"]["damping_ratio"] == pytest.approx(0.25, rel=0.2)
    assert fit["sensor_dynamics"]["resonance_hz"] == pytest.approx(237, rel=0.05)
    assert it["metrics"]["discrepancy"] < 0.5 * start["metrics"]["discrepancy"]
    assert Path(it["model"]).name == "cnn.onnx" and it["model_version"] == 2
    cfg = load_config(SimulationConfig, it["config"])
    damping = next(e for e in cfg.effects if e.name == "contact_damping")
    assert isinstance(damping.params["damping_ratio"], list)  # the prior around the fit
    again = loop_mod.run_loop(camp, _ideal(), tmp / "cnn-state", iterations=1, **kw)
    assert len(again["iterations"]) == 2 and "adds no effect" in again["stopped"]


def test_loop_uses_only_the_public_tracking_api():
    """The loop logs through ``training.tracking``'s public functions."""
    import ast

    tree = ast.parse(Path(loop_mod.__file__).read_text())
    imported = [
        (node.module, alias.name)
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("training")
        for alias in node.names
    ]
    assert ("training.tracking", "log_child_run") in imported
    assert not [name for _, name in imported if name.startswith("_")]


def test_given_diagnosis_and_an_interrupted_iteration(two_effects, tmp):
    """``--diagnosis``: its selected effects with their joint fits; a half-written iteration
    folder (a killed run) is redone, not mixed in."""
    state = tmp / "given-diagnosis"
    camp = load_campaign(two_effects)
    kw = dict(family="gbm", n_trajectories=TINY, tracking_uri=None)
    start = loop_mod.run_loop(camp, _ideal(), state, iterations=0, **kw)
    assert [it["index"] for it in start["iterations"]] == [0]
    (state / "iter-001").mkdir()
    (state / "iter-001" / "leftover.npy").write_bytes(b"partial")
    diagnosis = {
        "missing_effects": ["contact_damping", "sensor_dynamics"],
        "fitted_params": {"contact_damping": {"damping_ratio": 0.25},
                          "sensor_dynamics": SENSOR_PARAMS},
        "ranking": [{"effect": "contact_damping", "fitted": ["damping_ratio"]},
                    {"effect": "sensor_dynamics", "fitted": ["resonance_hz"]}],
        "verdict": "explained",
    }  # fmt: skip
    res = loop_mod.run_loop(camp, _ideal(), state, diagnosis=diagnosis, **kw)
    assert not (state / "iter-001" / "leftover.npy").exists()
    it = res["iterations"][1]
    assert it["diagnosis"]["verdict"] == "explained"
    cfg = load_config(SimulationConfig, it["config"])
    damping, sensor = cfg.effects
    assert damping.params["damping_ratio"] == pytest.approx([0.1875, 0.3125])
    assert sensor.params["resonance_hz"] == pytest.approx([177.75, 296.25])
    assert sensor.params["resonance_damping"] == 0.03  # not fitted: fixed
    assert it["metrics"]["discrepancy"] < 0.01 * res["before"]["discrepancy"]


@pytest.mark.parametrize(
    ("effects", "world"),
    [
        ([], "sweep"),
        (
            [("contact_damping", {"damping_ratio": 0.25}), ("sensor_dynamics", SENSOR_PARAMS)],
            "sweep",
        ),  # fmt: skip
        ([("learned_contact", {"face_mass": 0.1, "face_stiffness": 10.0})], "sweep"),
        ([("learned_contact", {"knee": 0.2, "knee_ratio": [2.7, 3.0]})], "operating_points"),
        ([("learned_contact", {"hunt_crossley": 0.4})], "operating_points"),
        ([("hertz_contact", {})], "operating_points"),
        ([("restraint_mass", {})], "sweep"),
    ],
)
def test_auto_world_follows_the_contact_law(effects, world):
    """``auto``: the operating points once a contact law is not a linear spring and
    dashpot (a knee, a power, Hunt-Crossley, a user's law with its own elastic force); a
    face with its own mass, a damped contact and a sensor keep the sweep."""
    from stiffnet.effects.registry import build_effect

    given = [build_effect(n, p) for n, p in effects]
    chosen, why = loop_mod.dataset_world("auto", given)
    assert chosen == world
    if world == "operating_points":
        assert effects[0][0] in why and "not a linear spring" in why
    # a world the user gave is kept whatever the law
    assert loop_mod.dataset_world("sweep", given)[0] == "sweep"
    assert loop_mod.dataset_world("operating_points", [])[0] == "operating_points"


def test_a_user_law_with_its_own_elastic_force_is_nonlinear():
    """The default rule reads the hooks a user's law overrides: its own elastic or
    dissipative force is nonlinear, a face with its own mass (a linear restraint) is not."""
    import unknown_contact_laws as laws

    assert laws.TwoStageContact(knee=0.2, ratio=3.0).nonlinear_contact
    assert laws.HuntCrossleyContact().nonlinear_contact
    assert not laws.SprungFaceContact().nonlinear_contact
    assert not laws.BeamTipContact().nonlinear_contact


@pytest.mark.slow
def test_auto_world_moves_to_the_operating_points_with_a_nonlinear_law(tmp):
    """A new loop without a world trains iteration 0 over the sweep and, once a Hertz
    contact is added, iteration 1 at the manifest's rows (the data card lists them), with
    the reason in the iteration and the table."""
    state = tmp / "auto-state"
    # two recordings of 2 s: the numerical engine's shards cost their steps, one per row
    (tmp / "auto").mkdir()
    small = simulate_campaign(short_manifest(tmp / "auto", 2, "2"), tmp / "auto" / "c",
                              [DAMPED], seed=0)  # fmt: skip
    res = loop_mod.run_loop(load_campaign(small), _ideal(), state, iterations=1,
                            add_effects=[("hertz_contact", {})], family="gbm",
                            n_trajectories=TINY, tracking_uri=None)  # fmt: skip
    assert res["world"] == "auto"
    first, second = res["iterations"]
    assert (first["world"], second["world"]) == ("sweep", "operating_points")
    assert "hertz_contact" in second["world_reason"] and second["n_trajectories"] == TINY
    card0 = json.loads((state / "iter-000" / "data_card.json").read_text())
    card1 = json.loads((state / "iter-001" / "data_card.json").read_text())
    assert "operating_points" not in card0 or not card0["operating_points"]
    assert len(card1["operating_points"]["points"]) == len(load_campaign(small).rows) == 2
    from stiffnet.cli.measurement import loop_table

    rendered = [c._cells for c in loop_table(res, "c").columns if c.header == "trained on"]
    assert rendered == [[f"sweep x{TINY}", f"points x{TINY}"]]


def test_auto_world_reads_the_starting_configs_own_law():
    """A starting config that already carries a nonlinear law trains iteration 0 at the
    operating points too (the loop's world is read from every effect of the config)."""
    from stiffnet.config.sim import EffectSpec
    from stiffnet.measurement.compare import config_effects

    cfg = _ideal()
    cfg = cfg.model_copy(update={"effects": [*cfg.effects, EffectSpec(name="hertz_contact")]})
    every = config_effects(loop_mod.config_with_effects(cfg, []))
    assert loop_mod.dataset_world("auto", every)[0] == "operating_points"


def test_chain_discrepancy_prefers_the_campaigns_own_chain(two_effects):
    """The campaign's discrepancy, the judge of the chain candidates, is least at the chain the
    recordings were made through (237 Hz), not at a mount bent to 181 Hz."""
    damped = {"name": "contact_damping", "params": {"damping_ratio": 0.25}}
    own = [damped, {"name": "sensor_dynamics", "params": SENSOR_PARAMS}]
    bent = [damped, {"name": "sensor_dynamics",
                     "params": {**SENSOR_PARAMS, "resonance_hz": 181.0}}]  # fmt: skip
    campaign = load_campaign(two_effects)
    d_own = loop_mod.chain_discrepancy(campaign, _ideal(), own, 0)
    d_bent = loop_mod.chain_discrepancy(campaign, _ideal(), bent, 0)
    assert d_own < 0.5 * d_bent


def _chain_entry(lowpass_hz: float, source: str = "diagnosis") -> dict:
    """A diagnosed sensor chain's loop entry: a 240 Hz mount and a first-order low-pass."""
    params = {"resonance_hz": 240.0, "resonance_damping": 0.04, "highpass_hz": 0.0,
              "lowpass_hz": lowpass_hz, "lowpass_order": 1.0}  # fmt: skip
    return {"name": "sensor_dynamics", "params": params, "source": source,
            "fitted": ["resonance_hz", "resonance_damping", "lowpass_hz"]}  # fmt: skip


def test_a_lowpass_fitted_at_the_top_of_its_search_is_none():
    """The two-stage rig's chain refit ended at 439 Hz, its search's top 450 Hz (0.45 of the
    campaign's lowest rate, 1 kHz): the loop's world gets no low-pass, the fit kept aside."""
    law = {"name": "learned_contact", "params": {"knee": 0.3}, "fitted": ["knee"],
           "source": "diagnosis"}  # fmt: skip
    out = loop_mod.without_lowpass_at_top([_chain_entry(439.25), law], 1000.0)
    assert out[0]["params"]["lowpass_hz"] == 0.0 and out[0]["lowpass_at_top"] == 439.25
    assert "lowpass_hz" not in out[0]["fitted"] and out[0]["params"]["resonance_hz"] == 240.0
    assert out[1] == law
    # no prior around the fit's corner: the world's records are not low-passed
    cfg = loop_mod._prior_config(_ideal(), out, 0.25)
    assert next(e for e in cfg.effects if e.name == "sensor_dynamics").params["lowpass_hz"] == 0


@pytest.mark.parametrize(
    ("lowpass_hz", "fs_min", "source"),
    [(234.0, 1000.0, "diagnosis"),  # power_lp's real 250 Hz low-pass
     (439.25, 2000.0, "diagnosis"),  # far below a 2 kHz campaign's top (900 Hz)
     (439.25, 1000.0, "given"),  # the user's chain
     (0.0, 1000.0, "diagnosis")],  # none to begin with
)  # fmt: skip
def test_a_lowpass_inside_its_search_or_given_stays(lowpass_hz, fs_min, source):
    entry = _chain_entry(lowpass_hz, source)
    assert loop_mod.without_lowpass_at_top([entry], fs_min) == [entry]


def test_a_world_behind_an_analog_chain_is_simulated_as_the_diagnosis_fitted_it():
    """The diagnosis fits a chain on the motion filtered at 8x the logger's rate, then sampled
    (campaign.simulate.oversampling): switched on, the loop's world with that chain is
    oversampled alike; a world with no chain, or the setting off, stays at the logger's rate."""
    chained = loop_mod._prior_config(_ideal(), [_chain_entry(0.0)], 0.25)
    assert loop_mod.with_analog_chain(chained, on=True).solver.oversampled == 8
    assert loop_mod.with_analog_chain(chained, on=False) == chained
    assert loop_mod.with_analog_chain(_ideal(), on=True) == _ideal()
    # off as shipped: it cost the rig's two-stage campaign two recordings at both seeds
    assert not loop_mod.loop_chain_settings().analog_world
    assert loop_mod.with_analog_chain(chained) == chained


def _hp_chain_entry(source: str = "diagnosis") -> dict:
    """The Hunt-Crossley rig's chain refitted with the learned law (260 Hz mount, no
    high-pass on the rig): 257.2 Hz, zeta 0.054, a 0.306 Hz high-pass."""
    params = {"resonance_hz": 257.2, "resonance_damping": 0.054, "highpass_hz": 0.306,
              "lowpass_hz": 0.0, "lowpass_order": 1.0}  # fmt: skip
    return {"name": "sensor_dynamics", "params": params, "source": source,
            "fitted": ["resonance_hz", "resonance_damping", "highpass_hz"]}  # fmt: skip


def _pooled(highpass_hz: float | None) -> dict:
    """A diagnosis whose restoring-force evidence pooled the mount and, or not, a high-pass."""
    return {"restoring_force": {"sensor": {"n": 24, "resonance_hz": 258.8,
                                           "resonance_damping": 0.054,
                                           "highpass_hz": highpass_hz}}}  # fmt: skip


def test_a_highpass_no_recordings_map_reads_is_none():
    """The fit's 0.306 Hz high-pass, read on none of the 24 maps: switched on, the world has
    none (it made the loop's GBM read beta 7 % low), the fit kept aside; the mount and the law
    stay."""
    law = {"name": "learned_contact", "params": {"hunt_crossley": 0.49},
           "fitted": ["hunt_crossley"], "source": "diagnosis"}  # fmt: skip
    out = loop_mod.without_unread_highpass([_hp_chain_entry(), law], _pooled(None), on=True)
    assert out[0]["params"]["highpass_hz"] == 0.0 and out[0]["highpass_unread"] == 0.306
    assert "highpass_hz" not in out[0]["fitted"] and out[0]["params"]["resonance_hz"] == 257.2
    assert out[1] == law
    cfg = loop_mod._prior_config(_ideal(), out, 0.25)
    assert next(e for e in cfg.effects if e.name == "sensor_dynamics").params["highpass_hz"] == 0


@pytest.mark.parametrize(
    ("entry", "diag", "on"),
    [(_hp_chain_entry(), _pooled(0.31), True),  # the maps read it: it stays
     (_hp_chain_entry(), {"restoring_force": {"sensor": None}}, True),  # no evidence
     (_hp_chain_entry(), None, True),
     (_hp_chain_entry("given"), _pooled(None), True),  # the user's chain
     (_hp_chain_entry(), _pooled(None), False),  # the setting off
     (_hp_chain_entry(), _pooled(None), None)],  # off as shipped (it cost power_lp 2 of 24)
)  # fmt: skip
def test_a_highpass_the_evidence_reads_or_given_stays(entry, diag, on):
    assert loop_mod.without_unread_highpass([entry], diag, on) == [entry]


def test_the_loops_chain_settings_are_the_shipped_config():
    shipped = load_config(loop_mod.LoopChainSettings, default_config("loop_chain.yaml"))
    assert shipped == loop_mod.loop_chain_settings()
    assert 0.5 < shipped.lowpass_top_fraction < 1.0
    with pytest.raises(ValueError):
        loop_mod.LoopChainSettings(lowpass_top_fraction=1.5)


def _evidence_per_recording() -> list[dict]:
    """The restoring-force evidence's recordings on the two-stage rig (240 Hz ζ 0.04 mount):
    two read the mount with intervals, one a low-pass alone, one nothing."""
    return [
        {"sensor": {"intervals": {"resonance_hz": [239.00, 239.68],
                                  "resonance_damping": [0.0199, 0.0306],
                                  "lowpass_hz": [179.2, 201.4]}}},
        {"sensor": {"intervals": {"lowpass_hz": [168.3, 195.7]}}},
        {"sensor": {"intervals": {"resonance_hz": [238.96, 239.33],
                                  "resonance_damping": [0.0392, 0.0411]}}},
        {"sensor": None},
    ]  # fmt: skip


def test_a_chains_prior_is_no_wider_than_the_evidence_reads_its_mount(monkeypatch):
    diag = _two_stage_diagnosis(per_recording=_evidence_per_recording())
    monkeypatch.setattr(loop_mod, "chain_discrepancy", _rig_discrepancy)
    state = {"iterations": [{"effects": [], "model": ""}], "seed": 0}
    added, _ = loop_mod._next_effects(None, state, _ideal(), (diag, []), None, False)
    sensor = next(a for a in added if a["name"] == "sensor_dynamics")
    # the union of the recordings' intervals, the mount only (not the low-pass they bend)
    assert sensor["intervals"] == {"resonance_hz": [238.96, 239.68],
                                   "resonance_damping": [0.0199, 0.0411]}  # fmt: skip
    cfg = loop_mod._prior_config(_ideal(), loop_mod.carried_effects([], added), 0.25)
    chain = next(e for e in cfg.effects if e.name == "sensor_dynamics").params
    # the world's chain is the evidence's (238.1 Hz, zeta 0.040, with_evidence_chain); +-25 %
    # would be 179-298 Hz: the prior keeps that chain and the recordings' span
    assert chain["resonance_hz"] == pytest.approx([238.1, 239.68])
    assert chain["resonance_damping"] == pytest.approx([0.040 * 0.75, 0.0411])


def test_a_chains_prior_stays_blanket_without_the_evidences_intervals():
    entry = _chain_entry(0.0)
    diag = {
        "restoring_force": {"per_recording": [{"sensor": {"intervals": {"lowpass_hz": [1, 2]}}}]}
    }
    added, _ = loop_mod.with_chain_intervals([dict(entry)], diag)
    assert "intervals" not in added[0]
    given = _chain_entry(0.0, source="given")
    added, _ = loop_mod.with_chain_intervals(
        [given], {"restoring_force": {"per_recording": _evidence_per_recording()}}
    )
    assert "intervals" not in added[0]

"""Evidence for the measurement loop on synthetic campaigns with a hidden effect.

The diagnosis tests here are slow (six campaigns with the inclination statistics); the
fast evidence for the diagnosis is ``test_measurement_diagnosis.py``. Campaigns are
simulated once per module from ``examples/hidden_effect_manifest.csv``
(8 recordings, 2 % white noise) shortened to 3 s, with an effect the default
config lacks; a clean twin (same manifest and seed, no effect) is the control.
The diagnosis fits the closed-form and measurement effects of the library and
a user effect (``tests/user_effects.py``); the numerical-engine effects cost
seconds per evaluation, their fit is exercised in ``test_measurement_units.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from campaign_helpers import short_manifest

from stiffnet.campaign import load_campaign, simulate_campaign
from stiffnet.measurement.diagnose import diagnose_campaign

#: The library's effects that keep the closed-form engine, plus the measurement chain.
FAST_EFFECTS = [
    "contact_damping",
    "forcing_harmonics",
    "gap_drift",
    "sensor_dynamics",
    "colored_noise",
    "adc",
]

HIDDEN = {
    "contact_damping_0.12": "contact_damping:damping_ratio=0.12",
    "contact_damping_0.3": "contact_damping:damping_ratio=0.3",
    "forcing_harmonics": "forcing_harmonics:second=0.45,third=0.25",
    "sensor_dynamics": "sensor_dynamics:resonance_hz=240,resonance_damping=0.04",
    "user_preload": "user_effects:ConstantPreload:force=0.4",
}
USER_EFFECT = "user_effects:ConstantPreload"


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("measurement")
    manifest = short_manifest(tmp)
    out = {"clean": simulate_campaign(manifest, tmp / "clean", [], seed=0)}
    for key, eff in HIDDEN.items():
        out[key] = simulate_campaign(manifest, tmp / key, [eff], seed=0)
    return {k: load_campaign(v) for k, v in out.items()}


@pytest.fixture(scope="module")
def diagnoses(campaigns):
    # the geometric inclination statistics cost a third of each evaluation: on for the
    # control (where a false alarm would show), off for the hidden-effect campaigns
    return {
        k: diagnose_campaign(
            c,
            effects=FAST_EFFECTS,
            user_effects=[USER_EFFECT],
            inclination=k == "clean",
        )
        for k, c in campaigns.items()
    }


@pytest.mark.slow
def test_control_campaign_nothing_missing(diagnoses):
    d = diagnoses["clean"]
    assert d["missing_effect"] is None and d["verdict"] == "nothing_missing"
    assert not any(r["significant"] for r in d["ranking"])
    assert d["baseline_discrepancy"] < 0.5  # the noise floor of the statistics


@pytest.mark.slow
@pytest.mark.parametrize("key", list(HIDDEN))
def test_diagnose_ranks_hidden_effect_first(diagnoses, key):
    d = diagnoses[key]
    hidden = USER_EFFECT if key == "user_preload" else HIDDEN[key].split(":")[0]
    # a constant force towards the restraint is a static gap change: the gap drift (now
    # fitted with its phase) may name it, a physically equivalent diagnosis
    allowed = {hidden, "gap_drift"} if key == "user_preload" else {hidden}
    top = d["ranking"][0]
    assert top["effect"] in allowed, [(r["effect"], r["bic_delta"]) for r in d["ranking"]]
    assert top["significant"]
    assert d["missing_effect"] in allowed
    assert top["relative_reduction"] > 0.8
    assert d["verdict"] == "explained", d["summary"]
    assert d["baseline_discrepancy"] > 10 * diagnoses["clean"]["baseline_discrepancy"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("key", "param", "expected", "tol"),
    [
        ("contact_damping_0.12", "damping_ratio", 0.12, 0.03),
        ("contact_damping_0.3", "damping_ratio", 0.3, 0.03),
        ("sensor_dynamics", "resonance_hz", 240.0, 12.0),
        ("user_preload", "force", 0.4, 0.1),
    ],
)
def test_fitted_parameters_recover_the_hidden_values(diagnoses, key, param, expected, tol):
    name = USER_EFFECT if key == "user_preload" else HIDDEN[key].split(":")[0]
    entry = next(r for r in diagnoses[key]["ranking"] if r["effect"] == name)
    assert entry["params"][param] == pytest.approx(expected, abs=tol)


@pytest.mark.slow
def test_diagnose_json_contract(diagnoses):
    d = diagnoses["contact_damping_0.3"]
    keys = {"baseline_discrepancy", "ranking", "missing_effect", "noise_floor", "verdict",
            "residual_discrepancy", "explained_fraction", "unexplained_where"}  # fmt: skip
    assert keys <= set(d)
    for r in d["ranking"]:
        assert {"effect", "discrepancy_reduction", "params", "significant", "reasons"} <= set(r)
    assert {r["effect"] for r in d["ranking"]} == {*FAST_EFFECTS, USER_EFFECT}


def test_shipped_model_holds_on_a_damped_contact(campaigns):
    """The shipped CNN trains on rigs with dissipative contacts (docs/priors.md): a damped
    campaign costs it little, and its per-recording interval still holds the truth (a
    model trained on the ideal world lost 0.4 in beta MAPE here)."""
    from stiffnet.measurement.evaluate import evaluate_campaign

    clean = evaluate_campaign(campaigns["clean"])["metrics"]["learned"]
    hidden = evaluate_campaign(campaigns["contact_damping_0.3"])["metrics"]["learned"]
    assert hidden["beta_mape"] < clean["beta_mape"] + 0.1
    assert hidden["interval_coverage"] >= 0.75 and clean["interval_coverage"] >= 0.75
    assert hidden["alarm_rate"] is not None


def test_compare_says_where_it_fails(campaigns):
    from stiffnet.measurement.compare import compare_campaign

    clean = compare_campaign(campaigns["clean"]).result
    hidden = compare_campaign(campaigns["contact_damping_0.3"]).result
    assert hidden["discrepancy"] > 10 * clean["discrepancy"]
    # a damped contact lowers the spikes and reshapes the impact: the spike statistics move
    # (the free flight's harmonics move too: they span the whole orbit, which it changes)
    assert hidden["by_component"]["spike_height"] > 1.0
    assert hidden["by_component"]["waveform"] > 1.0
    assert clean["by_component"]["spike_height"] < 0.1
    assert clean["failure"]["recording"] in {r["recording"] for r in clean["recordings"]}


@pytest.mark.slow
def test_loop_closes_the_gap(campaigns, tmp_path):
    from stiffnet.config.sim import SimulationConfig
    from stiffnet.measurement.loop import run_loop

    res = run_loop(
        campaigns["contact_damping_0.3"],
        SimulationConfig(),
        tmp_path / "state",
        family="gbm",
        n_trajectories=64,
        candidates=["contact_damping", "forcing_harmonics", "sensor_dynamics", "colored_noise"],
        tracking_uri=f"sqlite:///{tmp_path / 'mlflow.db'}",
    )
    before, after = res["before"], res["after"]
    assert after["discrepancy"] <= 0.5 * before["discrepancy"]
    assert after["beta_mape"] < before["beta_mape"] - 0.1  # 0.33 -> 0.15
    # 8 recordings and models trained on 64 trajectories: accuracy moves in steps of 1/8
    # with the random stream; the error that matters is beta's, above
    assert after["accuracy"] >= before["accuracy"]
    assert before["run_id"] and after["run_id"] and before["run_id"] != after["run_id"]
    assert Path(res["chart"]).stat().st_size > 1000
    added = res["iterations"][1]["added"]
    assert [a["name"] for a in added] == ["contact_damping"]
    assert added[0]["params"]["damping_ratio"] == pytest.approx(0.3, abs=0.05)

"""Simulation config: defaults, YAML loading and one-line validation errors."""

from pathlib import Path

import pytest
import yaml

from stiffnet.config import load_config, validate_config
from stiffnet.config.sim import SimulationConfig, randomised_effects
from stiffnet.errors import ConfigError
from stiffnet.geometry.calibration import DEFAULT_CLASSES, NO_CONTACT, beta_class
from stiffnet.measurement.compare import beta_class_name
from stiffnet.measurement.metrics import true_class

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_configs_validate_and_default_matches_model():
    ideal = load_config(SimulationConfig, ROOT / "configs/sim/ideal.yaml")
    assert ideal == SimulationConfig()  # the YAML restates the model's defaults
    default = load_config(SimulationConfig, ROOT / "configs/sim/default.yaml")
    # the randomised world: the same domain plus every effect's own prior, restated
    assert default.effects == randomised_effects()
    assert default.ideal_fraction == 0.2
    same = {"effects": [], "solver": ideal.solver, "ideal_fraction": 0.0}
    assert default.model_copy(update=same) == ideal
    assert {e.name for e in default.effects} >= {
        "contact_damping", "hertz_contact", "forcing_harmonics", "gap_drift",
        "sensor_dynamics", "colored_noise", "adc",
    }  # fmt: skip
    assert default.class_names() == ["no_contact", "soft", "medium", "hard", "very_hard"]
    quick = load_config(SimulationConfig, ROOT / "configs/sim/quick.yaml")
    assert quick.n_trajectories < default.n_trajectories


def test_class_edges_have_one_source():
    # the shipped YAMLs leave the classes to the model, whose default is the geometry's table
    for name in ("ideal", "default", "quick"):
        assert "classes" not in yaml.safe_load((ROOT / f"configs/sim/{name}.yaml").read_text())
    cfg = SimulationConfig()
    assert [(c.name, *c.beta) for c in cfg.classes] == list(DEFAULT_CLASSES)
    assert cfg.no_contact_class == NO_CONTACT
    # the measurement reports label a known beta by the same nearest-class rule
    for beta in (1.0, 5.0, 14.99, 15.0, 35.0, 59.9, 60.0, 100.0, 250.0):
        assert beta_class_name(beta) == true_class(beta, True) == beta_class(beta)
    assert (beta_class_name(14.99), beta_class_name(15.0)) == ("soft", "medium")
    assert (beta_class_name(None), true_class(None, True), true_class(20.0, False)) == (
        "unknown", None, NO_CONTACT,
    )  # fmt: skip


def test_priors_cover_the_issue_ranges():
    """Contact dissipation at least 0-0.5 (restitution down to ~0.4), harmonics with any
    phase, the sensor resonance relative to f_n and the anti-alias corner relative to fs."""
    priors = {e.name: e for e in randomised_effects()}
    assert priors["contact_damping"].params["damping_ratio"] == [0.0, 0.5]
    fh = priors["forcing_harmonics"].params
    assert fh["phase_second"][0] < -3.14 and fh["phase_second"][1] > 3.14
    rel = priors["sensor_dynamics"].relative
    assert rel["resonance_hz"].per == "natural_frequency"
    assert rel["lowpass_hz"].per == "sampling_rate"
    assert all(0.0 < e.probability < 1.0 for e in priors.values())


@pytest.mark.parametrize(
    ("effect", "needle"),
    [
        ({"name": "contact_damping", "probability": 1.5}, "probability"),
        (
            {"name": "contact_damping", "relative": {"damping_ratio": {"per": "sampling_rate",
                                                                       "range": [0.1, 0.2]}}},
            "'damping_ratio' is not a frequency in Hz",
        ),
        (
            {"name": "sensor_dynamics", "relative": {"nope_hz": {"per": "sampling_rate",
                                                                 "range": [0.1, 0.2]}}},
            "'nope_hz' is not one of its parameters",
        ),
        (
            {"name": "sensor_dynamics", "relative": {"resonance_hz": {
                "per": "natural_frequency", "range": [1, 10000]}}},
            "resonance_hz relative to the natural frequency [1.0, 10000.0] gives",
        ),
        (
            {"name": "sensor_dynamics", "relative": {"lowpass_hz": {"per": "sampling_rate",
                                                                    "range": [0.3, 0.1]}}},
            "range must be [low, high]",
        ),
        (
            {"name": "sensor_dynamics", "params": {"lowpass_hz": 100.0},
             "relative": {"lowpass_hz": {"per": "sampling_rate", "range": [0.1, 0.2]}}},
            "given both in params and relative",
        ),
    ],
)  # fmt: skip
def test_bad_priors_give_one_line_errors(effect, needle):
    with pytest.raises(ConfigError) as info:
        validate_config(SimulationConfig, {"effects": [effect]}, "priors.yaml")
    msg = str(info.value)
    assert needle in msg and msg.startswith("priors.yaml: ") and "\n" not in msg


@pytest.mark.parametrize(
    ("data", "needle"),
    [
        ({"sweep": {"beta": [0, 5]}}, "sweep.beta: [0.0, 5.0] is outside the allowed range (0.0"),
        ({"sweep": {"gap": [3, 1]}}, "sweep.gap: range must be [low, high]"),
        ({"sweep": {"fs_ratio": [2, 100]}}, "sweep.fs_ratio"),
        ({"n_trajectories": 0}, "n_trajectories"),
        ({"bogus": 1}, "bogus: Extra inputs are not permitted"),
        ({"effects": [{"name": "nope"}]}, "unknown effect 'nope'"),
        ({"effects": [{"name": "adc", "params": {"bits": 99}}]}, "bits=99.0 is outside"),
        ({"effects": [{"name": "adc", "params": {"volume": 1}}]}, "volume"),
        (
            {"classes": [{"name": "a", "beta": [5, 10]}, {"name": "b", "beta": [12, 100]}]},
            "a ends at 10.0 but b starts at 12.0",
        ),
        ({"sweep": {"beta": [5, 200]}}, "not covered by the classes"),
    ],
)
def test_invalid_config_names_field_and_range(data, needle):
    with pytest.raises(ConfigError) as info:
        validate_config(SimulationConfig, data, "cfg.yaml")
    msg = str(info.value)
    assert needle in msg and msg.startswith("cfg.yaml: ")
    assert "\n" not in msg


def test_yaml_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(SimulationConfig, tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("sweep: [1, 2\n")
    with pytest.raises(ConfigError, match="invalid YAML at line"):
        load_config(SimulationConfig, bad)


def test_shipped_settings_validate_the_file_or_give_the_defaults(tmp_path, monkeypatch):
    from pydantic import BaseModel, ConfigDict

    import stiffnet.shipped
    from stiffnet.config import shipped_settings

    class Settings(BaseModel):
        model_config = ConfigDict(extra="forbid")
        level: float = 0.5

    monkeypatch.setattr(stiffnet.shipped, "default_config", lambda name: tmp_path / name)
    assert shipped_settings(Settings, "s.yaml").level == 0.5  # no file: the defaults
    (tmp_path / "s.yaml").write_text("level: 0.25\n", encoding="utf-8")
    assert shipped_settings(Settings, "s.yaml").level == 0.25
    (tmp_path / "s.yaml").write_text("levle: 0.25\n", encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        shipped_settings(Settings, "s.yaml")
    assert "\n" not in str(err.value) and "levle" in str(err.value)

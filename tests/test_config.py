"""Simulation config: defaults, YAML loading and one-line validation errors."""

from pathlib import Path

import pytest

from stiffnet.config import load_config, validate_config
from stiffnet.config.sim import SimulationConfig
from stiffnet.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]


def test_shipped_configs_validate_and_default_matches_model():
    default = load_config(SimulationConfig, ROOT / "configs/sim/default.yaml")
    assert default == SimulationConfig()  # the YAML restates the model's defaults
    assert default.class_names() == ["no_contact", "soft", "medium", "hard", "very_hard"]
    quick = load_config(SimulationConfig, ROOT / "configs/sim/quick.yaml")
    assert quick.n_trajectories < default.n_trajectories


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

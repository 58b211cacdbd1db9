"""Shipped files are found in the checkout's models/, else in ./models (a regular install)."""

import stiffnet.shipped as shipped
from stiffnet.geometry.calibration import CALIBRATION_FILE, load_calibration


def test_checkout_first_then_current_folder(tmp_path, monkeypatch):
    assert shipped.shipped_file(CALIBRATION_FILE) == shipped.REPO_MODELS_DIR / CALIBRATION_FILE
    # a regular install: no models/ next to the package; the current folder has them
    real = shipped.REPO_MODELS_DIR / CALIBRATION_FILE
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / CALIBRATION_FILE).write_bytes(real.read_bytes())
    elsewhere = tmp_path / "site-packages" / "models"
    monkeypatch.setattr(shipped, "REPO_MODELS_DIR", elsewhere)
    monkeypatch.chdir(tmp_path)
    found = shipped.shipped_file(CALIBRATION_FILE)
    assert found == tmp_path / "models" / CALIBRATION_FILE
    assert load_calibration().to_dict() == load_calibration(real).to_dict()
    # neither: the checkout's path, so a "not found" message says where the file belongs
    monkeypatch.chdir(tmp_path / "models")
    assert shipped.shipped_file("nothing.json") == elsewhere / "nothing.json"


def test_default_configs_come_with_the_package_not_the_current_folder(tmp_path, monkeypatch):
    from stiffnet.config import load_config
    from stiffnet.config.sim import SimulationConfig

    path = shipped.default_config("sim/default.yaml")
    assert path == shipped.REPO_CONFIGS_DIR / "sim" / "default.yaml" and path.is_file()
    # a folder with its own configs/ does not change the default
    (tmp_path / "configs" / "sim").mkdir(parents=True)
    (tmp_path / "configs" / "sim" / "default.yaml").write_text("n_trajectories: 3\n")
    monkeypatch.chdir(tmp_path)
    assert shipped.default_config("sim/default.yaml") == path
    assert load_config(SimulationConfig, path).n_trajectories != 3

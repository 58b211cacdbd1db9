"""Where the shipped files live (models, calibration, OOD reference, default configs).

They sit in the repository's ``models/`` folder, which an editable install (the
README's) finds next to the package. A regular install copies only the Python
packages, so the current folder's ``models/`` is the fallback: run from a
checkout, or pass explicit paths.
"""

from __future__ import annotations

from pathlib import Path

#: The source checkout's ``models/`` folder.
REPO_MODELS_DIR = Path(__file__).resolve().parents[1] / "models"


def shipped_file(name: str) -> Path:
    """``models/NAME`` of the checkout, else of the current folder.

    When neither exists the checkout's path is returned, so the caller's
    "not found" message names where the file belongs.
    """
    for folder in (REPO_MODELS_DIR, Path.cwd() / "models"):
        if (folder / name).is_file():
            return folder / name
    return REPO_MODELS_DIR / name


#: The source checkout's ``configs/`` folder: the default YAML configs.
REPO_CONFIGS_DIR = Path(__file__).resolve().parents[1] / "configs"


def default_config(name: str) -> Path:
    """The default config ``configs/NAME`` shipped with stiffnet, e.g. ``sim/default.yaml``.

    Found next to the installed package (the checkout of the README's editable
    install), never in the current folder: a command's defaults do not depend on
    where it runs. Commands fall back to the pydantic defaults where the file is
    missing, or say which file they looked for.
    """
    return REPO_CONFIGS_DIR / name

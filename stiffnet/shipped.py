"""Where the shipped files live (models, calibration, OOD reference).

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

"""Campaigns: a folder of recordings described by a ``manifest.csv``.

A campaign is how users bring measurements to stiffnet (see ``docs/campaign.md``)::

    my_campaign/
        manifest.csv          recording,fs_hz[,natural_frequency_hz,...,beta]
        run01.csv             t,accel   (or .npy / .wav / .tdms)
        day2/run02.tdms

- :mod:`stiffnet.campaign.manifest`: the model of a manifest row (physical-unit
  columns included), reading and writing manifests, :class:`Campaign`.
- :mod:`stiffnet.campaign.simulate`: manifest rows -> simulator, the one mapping used
  by ``simulate-campaign``, ``compare``, ``diagnose`` and ``evaluate``.
- :mod:`stiffnet.campaign.synthetic`: :func:`simulate_campaign`, a manifest of
  parameters -> a synthetic campaign folder with its ``campaign_card.json``.
"""

import importlib
from typing import Any

from stiffnet.campaign.loaded import LoadedCampaign
from stiffnet.campaign.manifest import (
    CARD_NAME,
    COLUMNS,
    MANIFEST_NAME,
    MODEL_LENGTH_MM,
    MODEL_LENGTH_UNIT_M,
    READ_COLUMNS,
    REQUIRED_COLUMNS,
    STANDARD_GRAVITY,
    Campaign,
    ManifestRow,
    load_campaign,
    read_manifest,
    read_manifest_with_columns,
    write_manifest,
)

# The simulation side loads the simulator (numba) on first use only: reading a manifest
# (``predict`` on a campaign's recording: its row's f_n) stays as light as the predictor.
_LAZY = {
    **dict.fromkeys(
        ("DEFAULT_NOISE", "DEFAULT_SEED", "FIT_SETTINGS", "FIT_SETTINGS_NUMERICAL",
         "SIMULATION_COLUMNS", "CampaignSolverSettings", "check_rows", "sensor_gain",
         "simulate_row", "simulate_rows"),
        "stiffnet.campaign.simulate",
    ),
    "simulate_campaign": "stiffnet.campaign.synthetic",
}  # fmt: skip


def __getattr__(name: str) -> Any:
    """The simulation side's names, imported on first use (PEP 562)."""
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "CARD_NAME",
    "COLUMNS",
    "DEFAULT_NOISE",
    "DEFAULT_SEED",
    "FIT_SETTINGS",
    "FIT_SETTINGS_NUMERICAL",
    "MANIFEST_NAME",
    "MODEL_LENGTH_MM",
    "MODEL_LENGTH_UNIT_M",
    "READ_COLUMNS",
    "REQUIRED_COLUMNS",
    "SIMULATION_COLUMNS",
    "STANDARD_GRAVITY",
    "Campaign",
    "CampaignSolverSettings",
    "LoadedCampaign",
    "ManifestRow",
    "check_rows",
    "load_campaign",
    "read_manifest",
    "read_manifest_with_columns",
    "sensor_gain",
    "simulate_campaign",
    "simulate_row",
    "simulate_rows",
    "write_manifest",
]

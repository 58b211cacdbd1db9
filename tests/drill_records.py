"""Synthetic drilling records: segments at different beta, concatenated.

Each segment is one row of stiffnet's campaign simulator
(:func:`stiffnet.campaign.simulate.simulate_row`) with damped contact and white noise:
the bit crosses a layer boundary where one segment ends and the next begins. The
record carries no beta column: the truth stays here, with the change times.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from stiffnet.campaign.manifest import ManifestRow
from stiffnet.campaign.simulate import RowJob, simulate_row
from stiffnet.effects.registry import build_effect

#: The training world's natural frequency (the paper's rig).
FN_HZ = 9.48


def layered_record(
    betas: Sequence[float],
    durations_s: Sequence[float],
    *,
    fs_hz: float = 2000.0,
    noise: float = 0.03,
    contact_damping: float = 0.15,
    seed: int = 0,
    natural_frequency_hz: float = FN_HZ,
    extra_effects: Sequence[tuple[str, dict]] = (),
) -> tuple[np.ndarray, list[float]]:
    """Acceleration (g) of consecutive layers and the change times (s) between them.

    ``extra_effects``: further effects as ``(name, params)``, on top of the damped contact.
    """
    parts, changes, t = [], [], 0.0
    for i, (beta, dur) in enumerate(zip(betas, durations_s, strict=True)):
        row = ManifestRow(
            recording=f"layer{i}.csv",
            fs_hz=fs_hz,
            natural_frequency_hz=natural_frequency_hz,
            frequency_ratio=1.0,
            amplitude=1.2,
            gap=1.0,
            damping_ratio=0.02,
            beta=beta,
            duration_s=dur,
            noise=noise,
        )
        effects = [build_effect("contact_damping", {"damping_ratio": contact_damping})]
        effects += [build_effect(name, params) for name, params in extra_effects]
        accel, _ = simulate_row(RowJob(row, effects, seed + 7919 * i, dur, row.recording))
        parts.append(accel)
        t += accel.size / fs_hz
        changes.append(t)
    return np.concatenate(parts), changes[:-1]

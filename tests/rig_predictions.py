"""The shipped model on the independent rig's recordings (tests/independent_rig.py).

Shared by the alarm's tests that replay one of ``benchmarks/bench_alarm.py``'s rig draws
through the real predictor.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from independent_rig import RigRun, record

#: The lab's mounted accelerometer of benchmarks/bench_alarm.py (resonance 25 f_n).
LAB_MOUNT = {"resonance_hz": 237.0, "resonance_damping": 0.05, "highpass_hz": 1.0}


@functools.lru_cache(maxsize=1)
def shipped_predictor() -> Any:
    """The shipped CNN's predictor, loaded once per test process."""
    from serving.predictor import Predictor

    return Predictor.load(str(Path(__file__).resolve().parents[1] / "models" / "cnn.onnx"))


def predict_rig_run(run: RigRun, seed: int) -> dict[str, Any]:
    """The shipped predictor's answer on the rig's record of ``run`` (noise seed ``seed``)."""
    _, accel = record(run, seed=seed)
    return shipped_predictor().predict(
        accel, run.fs_hz, natural_frequency_hz=run.natural_frequency_hz
    )

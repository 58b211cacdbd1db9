"""The predictor's input checks (serving/checks.py) that warn without refusing."""

from __future__ import annotations

import numpy as np
import pytest

from serving.checks import checked_recording, dropout_samples, held_runs

FS, FN = 1000.0, 9.48


def _signal(n: int = 20_000, seed: int = 0) -> np.ndarray:
    t = np.arange(n) / FS
    rng = np.random.default_rng(seed)
    return 3.0 * np.sin(2 * np.pi * FN * t) + rng.normal(0, 0.05, n)


def test_runs_of_a_held_value_are_found_with_their_samples():
    a = np.array([1.0, 2, 2, 2, 2, 3, 0, 0, 0, 0, 0, 4])
    assert held_runs(a, 4) == [(1, 5), (6, 11)]
    assert held_runs(a, 5) == [(6, 11)]
    assert held_runs(a, 6) == []
    assert held_runs(np.zeros(3), 4) == []
    assert dropout_samples(FS, FN) == 106  # one natural period at 1 kHz


@pytest.mark.parametrize("value", [0.0, -1.25])
def test_a_dropout_is_a_warning_with_its_times_and_value(value):
    a = _signal()
    a[5000:5400] = value  # 0.4 s: four natural periods
    _, warnings = checked_recording(a, FS, FN, 16, "rec")
    (said,) = [w for w in warnings if "a dropout" in w]
    assert f"({value:.6g}) for 0.4 s in 1 run(s)" in said and "5.00-5.40 s" in said
    # a held stretch shorter than a natural period is not one (a coarse ADC holds a code)
    b = _signal()
    b[5000:5050] = value
    assert not [w for w in checked_recording(b, FS, FN, 16, "rec")[1] if "dropout" in w]


def test_a_clipped_signal_names_the_value_as_recorded():
    """The samples are scaled by a power of two before the checks; the clipping warning
    named the scaled value ('at the maximum 0.625' for a sensor clipped at 10 g)."""
    a = np.clip(_signal() * 4, -10.0, 10.0)
    _, warnings = checked_recording(a, FS, FN, 16, "rec")
    (said,) = [w for w in warnings if "clipped" in w]
    assert "at the maximum 10," in said and "at the minimum -10)" in said, said
    assert not [w for w in warnings if "dropout" in w]  # each clip lasts under a period

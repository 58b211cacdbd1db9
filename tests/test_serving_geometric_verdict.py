"""The predictor's geometric verdict: windows of the recording's orbit through that orbit's map."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from serving.aggregate import geometric_verdict
from stiffnet.geometry import fit_calibration


def _calibration():
    """Main map: beta from a known law; the period-n map reads the same law 25 deg lower."""
    rng = np.random.default_rng(0)
    beta = np.exp(rng.uniform(np.log(5), np.log(100), 300))
    after = np.degrees(np.arctan(10 ** (0.5 + 0.8 * np.log10(beta))))
    before = np.degrees(np.arctan(10 ** (0.2 + 0.4 * np.log10(beta))))
    main = fit_calibration(before, after, beta, degree=1)
    return replace(main, period_n=fit_calibration(before - 25.0, after, beta, degree=1))


def _window(beta, pattern):
    after = np.degrees(np.arctan(10 ** (0.5 + 0.8 * np.log10(beta))))
    before = np.degrees(np.arctan(10 ** (0.2 + 0.4 * np.log10(beta))))
    if pattern != (1, 1):
        before -= 25.0
    return SimpleNamespace(
        contact_detected=True,
        inclination_before_deg=before,
        inclination_after_deg=after,
        impact_pattern=pattern,
        polarity=-1,
    )


def test_verdict_uses_the_map_and_windows_of_the_recordings_orbit():
    cal = _calibration()
    period_n = [_window(40.0, (2, 3))] * 3 + [_window(40.0, (1, 1))]
    v = geometric_verdict(period_n, cal)
    assert v["beta"] == pytest.approx(40.0, rel=1e-6) and v["class"] == "hard"
    # the odd period-1 window is left out of the means, not mixed in
    assert v["inclination_before_deg"] == pytest.approx(period_n[0].inclination_before_deg)
    one = geometric_verdict([_window(20.0, (1, 1))] * 3 + [_window(20.0, None)], cal)
    assert one["beta"] == pytest.approx(20.0, rel=1e-6) and one["class"] == "medium"
    # a one-map calibration reads the period-n angles as period-1 ones: far too soft
    main_only = replace(cal, period_n=None)
    assert geometric_verdict(period_n, main_only)["beta"] < 20.0

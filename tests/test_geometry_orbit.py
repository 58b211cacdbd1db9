"""The orbit the geometric method sees: n impacts every m forcing periods."""

import numpy as np
import pytest

from stiffnet.geometry import geometric_estimate
from stiffnet.geometry.orbit import describe_pattern, impact_pattern
from stiffnet.geometry.paper import PAPER_FS_RATIO, simulate_paper
from stiffnet.simulator.batch import PAPER_NATURAL_FREQUENCY_HZ as FN

T = 95.25  # forcing period, samples


@pytest.mark.parametrize(
    "offsets, span, expected",
    [
        ([0.3], 1, (1, 1)),
        ([0.2, 0.8], 3, (2, 3)),  # the paper's rest branch: 0.82 and 2.18 periods apart
        ([0.5], 2, (1, 2)),  # one impact every other period
        ([0.1, 0.6], 1, (2, 1)),  # two impacts per period
    ],
)
def test_impact_pattern_of_periodic_trains(offsets, span, expected):
    rng = np.random.default_rng(1)
    t = np.array([(k * span + o) * T for k in range(10) for o in offsets])
    t = np.round(t + rng.normal(0, 0.01 * T, t.size)).astype(int)
    assert impact_pattern(t, T) == expected


def test_irregular_impacts_have_no_pattern():
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.3, 2.5, 30) * T).astype(int)
    assert impact_pattern(t, T) is None
    assert impact_pattern([10, 100], T) is None  # too few
    assert "no repeating" in describe_pattern(None)
    assert describe_pattern((2, 3)) == "2 impacts every 3 forcing periods"


def test_paper_orbits_named_and_flagged():
    """beta = 47 with the paper's parameters: period-1 orbit, or 2 impacts every 3 periods
    from rest, where the 'before' inclination drops (~88 -> ~61 deg) and the estimate says so."""
    fs = PAPER_FS_RATIO * FN
    one = geometric_estimate(simulate_paper([47.0], branch="period1").accel[0], fs)
    rest = geometric_estimate(simulate_paper([47.0], branch="rest").accel[0], fs)
    assert one.impact_pattern == (1, 1) and "orbit" not in one.reason
    assert rest.impact_pattern == (2, 3)
    assert "2 impacts every 3 forcing periods" in rest.reason
    assert rest.inclination_before_deg < one.inclination_before_deg - 15
    assert rest.to_dict()["impact_pattern"] == [2, 3]

"""benchmarks/bench_model_swap.py: its per-set score and its restoring-force cache."""

from pathlib import Path

import numpy as np
import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.fixture
def swap(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import bench_model_swap

    return bench_model_swap


def test_score_counts_what_a_user_is_not_told(swap):
    """Four contact recordings and one without contact: a right answer, a wrong class with an
    alarm, a wrong class without one, a right class whose interval misses beta (silent only in
    the wider count) and a no-contact recording read right."""
    recs = [dict(beta=b, **{"class": c}) for b, c in
            [(10.0, "soft"), (20.0, "medium"), (40.0, "hard"), (70.0, "very_hard"),
             (50.0, "no_contact")]]  # fmt: skip
    got = [
        dict(cls="soft", beta=11.0, interval=[8.0, 12.0], flag=False, cpu_s=1.0, rf_cls="soft"),
        dict(
            cls="soft",
            beta=14.0,
            interval=[10.0, 18.0],
            flag=True,
            cpu_s=1.0,
            rf_cls=None,
            fired=["chain_class", "sensor"],
        ),
        dict(cls="medium", beta=30.0, interval=[25.0, 36.0], flag=False, cpu_s=1.0, rf_cls="hard"),
        dict(
            cls="very_hard", beta=63.0, interval=[61.0, 66.0], flag=False, cpu_s=1.0, rf_cls="hard"
        ),
        dict(
            cls="no_contact", beta=None, interval=None, flag=False, cpu_s=3.0, rf_cls="no_contact"
        ),
    ]
    for g in got:
        g.setdefault("fired", ["embedding"] if g["flag"] else [])
    s = swap.score(recs, got)
    assert s["n"] == 5 and s["n_contact"] == 4
    assert s["accuracy"] == pytest.approx(2 / 4)
    assert s["beta_mape"] == pytest.approx(np.mean([0.1, 0.3, 0.25, 0.1]))
    assert s["coverage"] == pytest.approx(1 / 4)  # only the first interval holds its beta
    assert s["alarms"] == 1 and s["wrong"] == 2
    assert s["wrong_silent"] == 1  # the hard recording read medium without an alarm
    assert s["silent"] == 2  # ... and the very hard one whose interval misses 70
    assert s["alarms_on_right"] == 0
    assert s["cpu_s_per_recording"] == pytest.approx(7 / 5)
    # the restoring force over the contact recordings: a refusal (no class) counts wrong
    assert s["rf_accuracy"] == pytest.approx(2 / 4) and s["rf_refusals"] == 1
    # the chain spread's alarm, and the median interval width (high over low) with contact
    assert s["chain_class"] == 1
    assert s["width"] == pytest.approx(np.median([12 / 8, 18 / 10, 36 / 25, 66 / 61]))


def test_the_restoring_force_check_runs_once_per_recording(swap):
    calls = []

    def check(a, fs, fn, sensor):
        calls.append(fs)
        return {"beta": float(a.sum()), "sensor": {"lowpass_hz": None}}

    cached = swap.CachedRestoringForce(check)
    a = np.arange(5.0)
    first = cached(a, 1000.0, 9.48, None)
    first["sensor"]["lowpass_hz"] = 1.0  # a caller's change does not reach the cache
    again = cached(a.copy(), 1000.0, 9.48, None)
    assert calls == [1000.0] and again == {"beta": 10.0, "sensor": {"lowpass_hz": None}}
    cached(a, 2000.0, 9.48, None)  # another rate: another check
    cached(a, 1000.0, 9.48, {"lowpass_hz": 300.0})  # a data sheet: another check
    assert calls == [1000.0, 2000.0, 1000.0]

"""Is an effect's improvement real? Paired tests on per-recording discrepancies, in words.

An effect is compared with the model it is added to (the base model, or the
effects already selected): ``before`` and ``after`` are the per-recording
discrepancies of the two (same simulations, same nuisances, same settings),
and ``deltas = before - after`` the per-recording reductions. It is
**significant** when every test of :data:`TESTS` passes:

``above_floor``
    the model before is not already at the recordings' own noise floors
    (:meth:`stiffnet.measurement.noise_floor.Floors.judge`: more recordings above
    :data:`AT_FLOOR_FACTOR` times their floor than chance allows), so there is
    something to explain;
``effect_size``
    it removes at least :data:`MIN_EXCESS_REDUCTION` of the discrepancy
    *above the recordings' floors* (the part a perfect model would remove; each
    recording's excess over its own floor, non-repeatable recordings weighted down,
    :meth:`~stiffnet.measurement.noise_floor.Floors.excess`);
``bootstrap``
    in at least :data:`BOOTSTRAP_LEVEL` of :data:`N_BOOTSTRAP` paired bootstrap
    resamples of the recordings the mean (weighted) reduction of the excess is positive (a one-sided
    95 % interval above zero; meaningful from 5 recordings, where a sign test
    cannot reach 5 % with one recording against);
``not_one_recording``
    without the recording it helps most, it still removes at least
    :data:`MIN_LEAVE_ONE_OUT` of the excess (one outlier is not an effect);
``pays_for_parameters``
    a BIC-like likelihood-ratio score ``N ln(D_after / D_before) + k ln N`` is
    negative (``N`` = recordings x statistic components, ``k`` = parameters): the
    discrepancy is a chi-square with fixed tolerances, so ``N ln`` of its ratio
    is the likelihood ratio; each parameter must buy about ``ln N / N``
    (a few per cent).

Each failed test gives one sentence in ``reasons`` (the terminal table, the
JSON and the report show them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from stiffnet.measurement.discrepancy import COMPONENTS, campaign_discrepancy
from stiffnet.measurement.noise_floor import AT_FLOOR_FACTOR, Floors

MIN_EXCESS_REDUCTION = 0.2
MIN_LEAVE_ONE_OUT = 0.1
BOOTSTRAP_LEVEL = 0.95
N_BOOTSTRAP = 2000
TESTS = ("above_floor", "effect_size", "bootstrap", "not_one_recording", "pays_for_parameters")


def bootstrap_positive_fraction(deltas: np.ndarray, n: int = N_BOOTSTRAP, seed: int = 0) -> float:
    """Fraction of paired bootstrap resamples of the recordings with a positive mean reduction."""
    deltas = np.asarray(deltas, float)
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, deltas.size, size=(n, deltas.size))
    return float(np.mean(deltas[idx].mean(axis=1) > 0))


def excess_reduction(before: np.ndarray, after: np.ndarray, floors: Floors | float) -> float:
    """Fraction of the discrepancy above the recordings' floors that ``after`` removes."""
    floors = _floors(floors, np.asarray(before).size)
    excess = floors.excess(before)
    return float((excess - floors.excess(after)) / excess) if excess > 0 else 0.0


def _floors(floors: Floors | float, n: int) -> Floors:
    return floors if isinstance(floors, Floors) else Floors.uniform(float(floors), n)


def significance(
    before: np.ndarray,
    after: np.ndarray,
    k: int,
    floor: Floors | float,
    recordings: Sequence[str] | None = None,
) -> dict[str, Any]:
    """The evidence for an effect (see the module notes).

    Parameters
    ----------
    before, after : numpy.ndarray
        Per-recording discrepancies without and with the effect.
    k : int
        Parameters the effect adds.
    floor : Floors or float
        The recordings' own noise floors (a number: the same for every recording).
    recordings : sequence of str, optional
        Recording names (for the reasons).

    Returns
    -------
    dict
        ``relative_reduction`` (of the discrepancy), ``excess_reduction`` (of the
        part above the floor), ``improved_fraction``, ``bootstrap_positive``,
        ``leave_one_out_excess_reduction``, ``bic_delta``, ``tests`` (name -> passed),
        ``reasons`` (one sentence per failed test) and ``significant``.
    """
    before, after = np.asarray(before, float), np.asarray(after, float)
    floors = _floors(floor, before.size)
    w, fl = floors.weights(), floors.effective()
    # each recording's reduction of its excess over its own floor, weighted
    deltas = w * (np.maximum(before - fl, 0.0) - np.maximum(after - fl, 0.0))
    names = list(recordings) if recordings is not None else [f"#{i}" for i in range(deltas.size)]
    d_b, d_a = campaign_discrepancy(before, w), campaign_discrepancy(after, w)
    excess = excess_reduction(before, after, floors)
    top = int(np.argmax(deltas))
    keep = np.arange(deltas.size) != top
    loo = (
        excess_reduction(before[keep], after[keep], floors.subset(np.flatnonzero(keep)))
        if keep.any()
        else 0.0
    )
    n_obs = deltas.size * len(COMPONENTS)
    bic = n_obs * math.log(max(d_a, 1e-12) / max(d_b, 1e-12)) + k * math.log(n_obs)
    boot = bootstrap_positive_fraction(deltas)
    judged = floors.judge(before)
    tests = {
        "above_floor": not judged["at_floor"],
        "effect_size": excess >= MIN_EXCESS_REDUCTION,
        "bootstrap": boot >= BOOTSTRAP_LEVEL,
        "not_one_recording": loo >= MIN_LEAVE_ONE_OUT,
        "pays_for_parameters": bic < 0,
    }
    words = {
        "above_floor": f"nothing to explain: the model without it is at the recordings' own "
        f"noise floors ({judged['n_above']} of {judged['n']} above {AT_FLOOR_FACTOR:g}x their own, "
        f"p = {judged['p_value']:.2g})",
        "effect_size": f"too small: it removes {excess:.1%} of the discrepancy above the "
        f"recordings' floors (needs {MIN_EXCESS_REDUCTION:.0%})",
        "bootstrap": f"not consistent across recordings: the mean reduction is positive in "
        f"{boot:.0%} of {N_BOOTSTRAP} paired bootstrap resamples (needs "
        f"{BOOTSTRAP_LEVEL:.0%})",
        "not_one_recording": f"carried by one recording: without {names[top]} it removes "
        f"{loo:.1%} of the excess (needs {MIN_LEAVE_ONE_OUT:.0%})",
        "pays_for_parameters": f"does not pay for its {k} parameter{'s' if k != 1 else ''}: "
        f"N ln(D_after/D_before) + k ln N = {bic:+.3g} (needs < 0)",
    }
    return {
        "relative_reduction": float((d_b - d_a) / d_b) if d_b > 0 else 0.0,
        "excess_reduction": excess,
        "improved_fraction": float(np.mean(deltas > 0)),
        "bootstrap_positive": boot,
        "leave_one_out_excess_reduction": float(loo),
        "bic_delta": float(bic),
        "tests": tests,
        "reasons": [words[t] for t in TESTS if not tests[t]],
        "significant": all(tests.values()),
    }

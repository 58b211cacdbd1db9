"""The restoring-force fits kept across evaluations (stiffnet.restoring_force.kept_fits).

A record of the independent rig behind a 240 Hz mount (its chain is fitted, its high-pass
corner profiled, its law refitted with an onset per impact): read plainly, then inside
``fits_kept`` by a model without a learned law and one with a two-stage law (a loop's
iterations 0 and 1), then in a new store read back from its file (a resumed loop). Fits are
counted with spies on the three fitting functions.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import stiffnet.restoring_force.chain as chain_mod
import stiffnet.restoring_force.estimate as estimate_mod
from serving.restoring_force_check import restoring_force_check
from stiffnet.restoring_force.kept_fits import fit_key, fits_kept
from tests.independent_rig import RigRun, record

#: The two-stage law's ratio range a loop's iteration-1 model reads beta with.
STAGE_RATIO = (1.9, 2.1)


@pytest.fixture(scope="module")
def mounted() -> tuple[np.ndarray, float, float]:
    """A two-stage contact behind a 240 Hz mount (the held-out two_stage_mount's rig)."""
    mount = {"resonance_hz": 240.0, "resonance_damping": 0.04}
    run = RigRun("rec/mounted.csv", beta=30.0, contact="two_stage", knee_mm=0.3,
                 stage_ratio=2.0, sensor=mount)  # fmt: skip
    _, accel = record(run)
    return accel, run.fs_hz, run.natural_frequency_hz


@pytest.fixture
def fits(monkeypatch) -> dict[str, int]:
    """Calls of the chain fit, of the high-pass corner's profile and of the onsets' law."""
    counts = {"chain": 0, "corner": 0, "onsets": 0}

    def spy(name: str, module, attr: str) -> None:
        real = getattr(module, attr)

        def counted(*args, **kwargs):
            counts[name] += 1
            return real(*args, **kwargs)

        monkeypatch.setattr(module, attr, counted)

    spy("chain", chain_mod, "_fitted_chain")
    spy("corner", estimate_mod, "_corner_map")
    spy("onsets", estimate_mod, "fit_impact_onset_law")
    return counts


def _check(mounted, stage_ratio=None) -> str:
    accel, fs, fn = mounted
    return json.dumps(restoring_force_check(accel, fs, fn, None, stage_ratio), sort_keys=True)


def test_kept_fits_read_the_same_and_fit_once_per_loop(mounted, fits, tmp_path):
    plain = _check(mounted), _check(mounted, STAGE_RATIO)
    assert min(fits.values()) >= 2  # the record needs a chain: it is fitted
    path = tmp_path / "fits.pkl"
    with fits_kept(path) as kept:
        before = dict(fits)
        first = _check(mounted)
        fitted = {k: fits[k] - before[k] for k in fits}
        assert min(fitted.values()) >= 1
        # the next model (a learned two-stage law) reads the same record: nothing fitted again
        before = dict(fits)
        second = _check(mounted, STAGE_RATIO)
        assert fits == before
        assert kept.reused >= kept.fitted > 0
    assert (first, second) == plain  # the same readings, to the last digit
    # a resumed loop (a new store from the file): the same, still without a fit
    with fits_kept(path) as kept:
        assert _check(mounted, STAGE_RATIO) == plain[1]
        assert fits == before and kept.fitted == 0


def test_a_changed_record_is_fitted_again(mounted, fits, tmp_path):
    accel, fs, fn = mounted
    with fits_kept(tmp_path / "fits.pkl"):
        _check(mounted)
        before = dict(fits)
        changed = accel.copy()
        changed[len(changed) // 2] += 1e-9  # one sample in the analysed middle, barely
        restoring_force_check(changed, fs, fn)
        assert all(fits[k] > before[k] for k in fits)


def test_a_fits_key_names_every_input_exactly():
    a = np.linspace(0.0, 1.0, 11)
    key = fit_key("chain", (a, 1.0, None, True))
    assert fit_key("chain", (a.copy(), 1.0, None, True)) == key
    assert fit_key("chain", (a, np.nextafter(1.0, 2.0), None, True)) != key
    assert fit_key("chain", (a.astype(np.float32), 1.0, None, True)) != key
    assert fit_key("chain", (a, 1.0, None, False)) != key
    assert fit_key("chain", (a, 1.0, 0.0, True)) != key
    assert fit_key("highpass corner", (a, 1.0, None, True)) != key
    with pytest.raises(TypeError):
        fit_key("chain", ([1.0],))


def test_outside_a_loop_nothing_is_kept(mounted, fits):
    _check(mounted)
    before = dict(fits)
    _check(mounted)
    assert fits["chain"] > before["chain"]


def test_a_file_of_other_code_is_ignored(mounted, fits, tmp_path, monkeypatch):
    import stiffnet.restoring_force.kept_fits as kept_mod

    path = tmp_path / "fits.pkl"
    with fits_kept(path):
        _check(mounted)
    monkeypatch.setattr(kept_mod, "code_version", lambda: "another version")
    with fits_kept(path) as kept:
        assert len(kept) == 0

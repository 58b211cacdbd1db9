"""The numerical engine's dense output for oversampled records (``oversampled`` > 1).

An analog sensor chain is simulated at 8x the logger's rate; the motion itself needs only
the logger's rate. With ``oversampled = k`` the engine integrates as for samples k times
coarser and fills the samples in between from the RK4 stages (or, in a substep with an
event, by partial steps from the start of the smooth piece). Expectations: at substep ends
the states are those of the coarse run bit for bit; in between, the error is of the coarse
run's order (against the closed form, exact); contact entries fall in the very sample the
exact solution puts them in.
"""

from __future__ import annotations

import numpy as np
import pytest

from stiffnet.effects.base import DynamicsEffect, ParamArrays
from stiffnet.effects.dry_friction import DryFriction
from stiffnet.effects.hertz_contact import HertzContact
from stiffnet.effects.restraint_mass import RestraintMass
from stiffnet.simulator.compiled import simulate_closed_form
from stiffnet.simulator.numerical import simulate_numerical
from tests.test_simulator_numerical import LinearHooks, W, _rm, closed_form, paper_batch

K = 8  # oversampling, as the campaign simulations'
N = 3200


def _params(effects: list[DynamicsEffect], n: int) -> list[ParamArrays]:
    rng = np.random.default_rng(0)
    out = []
    for e in effects:
        out.append(_rm(n) if isinstance(e, RestraintMass) else e.batch_params(n, rng))
    return out


def _runs(effects: list[DynamicsEffect]):
    batch = paper_batch()
    p = _params(effects, len(batch))
    h = 2 * np.pi / (W * np.array([800.0, 960.0, 880.0]))  # fine: 8x a logger's rate
    x0, v0 = np.zeros(3), np.array([0.0, 1.0, -0.5])
    dense = simulate_numerical(batch, effects, p, x0, v0, 8 * h, 100, h, N, 2, oversampled=K)
    coarse = simulate_numerical(batch, effects, p, x0, v0, 8 * h, 100, 8 * h, N // K, 2)
    return batch, h, x0, v0, dense, coarse


@pytest.mark.parametrize(
    "effects",
    [[], [LinearHooks()], [HertzContact()], [DryFriction()]],
    ids=["base", "linear_hooks", "hertz", "dry_friction"],
)
def test_substep_ends_are_the_coarse_run_bit_for_bit(effects: list[DynamicsEffect]) -> None:
    """2 substeps per logger sample, 8 samples per logger sample: a substep every 4 samples,
    whose end states equal the coarse run's; every contact entry lies in the logger sample
    the coarse run counts it in. (A mode that needs 3 substeps per logger sample gets a
    substep every 2 samples instead: finer, and no longer the coarse run's grid.)"""
    _, _, _, _, dense, coarse = _runs(effects)
    for key in ("x", "v", "accel", "contact_force"):
        np.testing.assert_array_equal(getattr(dense, key)[:, K - 1 :: K], getattr(coarse, key))
    assert coarse.impacts.sum(axis=1).min() >= 3  # every row impacts repeatedly
    per_logger_sample = dense.impacts.reshape(3, -1, K).sum(axis=2)
    np.testing.assert_array_equal(per_logger_sample, coarse.impacts)
    assert np.isfinite(dense.accel).all() and np.all(dense.contact_force >= 0)


@pytest.mark.parametrize("effects", [[], [LinearHooks()]], ids=["base", "linear_hooks"])
def test_dense_samples_are_as_accurate_as_the_integration(effects) -> None:
    """Against the exact piecewise-linear solution at every fine sample: the filled samples
    are within a few times the substep ends' own error, and the impacts are counted in the
    same fine samples as the closed form's."""
    batch, h, x0, v0, dense, _ = _runs(effects)
    ref = simulate_closed_form(closed_form(batch, effects), x0, v0, 100 * 8 * h + h, h, N)
    peak = np.abs(ref.accel).max()
    err = np.abs(dense.accel - ref.accel) / peak
    at_ends = err[:, K - 1 :: K].max()
    assert 0 < at_ends < 2e-4  # 2 substeps per logger sample of 100 per period
    assert err.max() < 5 * at_ends
    np.testing.assert_allclose(dense.x, ref.x, atol=1e-5 * np.abs(ref.x).max())
    np.testing.assert_array_equal(dense.impacts, ref.impacts)
    np.testing.assert_allclose(dense.t0, ref.t0, rtol=1e-12)


@pytest.mark.parametrize("effects", [[HertzContact()], [DryFriction()], [RestraintMass()]],
                         ids=["hertz", "dry_friction", "restraint_mass"])  # fmt: skip
def test_dense_samples_match_integrating_every_sample(effects) -> None:
    """The nonlinear effects against the old way (one RK4 substep per fine sample, 4x
    the work): the same motion within 2e-3 of the peak, the same impacts per logger sample,
    and rows stop at their own length."""
    batch = paper_batch()
    p = _params(effects, 3)
    h = 2 * np.pi / (W * np.array([800.0, 960.0, 880.0]))
    x0, v0 = np.zeros(3), np.array([0.0, 1.0, -0.5])
    need = np.array([N, N - 37, N // 2])
    # the same transient (200 substeps of 4 h), then one substep per fine sample
    fine = simulate_numerical(batch, effects, p, x0, v0, 4 * h, 200, h, N, 1, row_samples=need)
    dense = simulate_numerical(
        batch, effects, p, x0, v0, 8 * h, 100, h, N, 2, row_samples=need, oversampled=K
    )
    for i, n in enumerate(need):
        peak = np.abs(fine.accel[i]).max()
        # 2e-5 - 2e-4 of the peak; 1.5e-3 for the restraint's ringing (rate x substep ~ 1,
        # the step a record at the logger's rate gets)
        assert np.abs(dense.accel[i, :n] - fine.accel[i, :n]).max() < 2e-3 * peak
        assert np.all(dense.accel[i, n:] == 0)
        ip = fine.impacts[i, : n - n % K].reshape(-1, K).sum(axis=1)
        dp = dense.impacts[i, : n - n % K].reshape(-1, K).sum(axis=1)
        assert ip.sum() >= 2
        assert np.abs(ip - dp).sum() <= 2  # an entry within a hair of a logger sample's end


def test_campaign_simulations_with_an_analog_sensor_use_the_dense_output(monkeypatch) -> None:
    """``simulate_rows`` with a numerical effect and the sensor chain asks the engine for the
    logger's substeps (2) and 8x oversampled samples, not 1 substep per oversampled sample."""
    from pathlib import Path

    from stiffnet.campaign import simulate as cs
    from stiffnet.campaign.manifest import read_manifest
    from stiffnet.effects.registry import effect_class
    from stiffnet.simulator import simulator

    seen = []
    engine = simulator.simulate_numerical

    def spy(*a, **k):
        seen.append((k["substeps"], k["oversampled"]))
        return engine(*a, **k)

    monkeypatch.setattr(simulator, "simulate_numerical", spy)
    rows = read_manifest(Path(__file__).parents[1] / "examples" / "hidden_effect_manifest.csv")
    rows = [rows[0], rows[-1]]  # 1 and 2 kHz
    sensor = effect_class("sensor_dynamics")(resonance_hz=237, lowpass_hz=0, highpass_hz=0)
    settings = cs.FIT_SETTINGS_NUMERICAL.model_copy(update={"periods": 3.0})
    out = cs.simulate_rows(rows, [HertzContact(), sensor], [4000, 8000], settings=settings)
    assert seen == [(2, cs.ANALOG_OVERSAMPLING)]
    assert [a.size for a in out] == [int(np.ceil(3.0 * r.fs_hz / 9.48)) for r in rows]
    assert all(np.isfinite(a).all() and np.std(a) > 0 for a in out)
    cs.simulate_rows(rows, [HertzContact()], [4000, 8000], settings=settings)
    assert seen[-1] == (2, 1)  # no analog effect: the logger's samples, as before

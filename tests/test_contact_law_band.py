"""The contact law fitted through a band (what a known chain's inverse keeps)."""

import numpy as np
import pytest
from scipy import optimize
from scipy.optimize._numdiff import approx_derivative

from stiffnet.restoring_force import contact_law
from stiffnet.restoring_force.contact_law import (
    _law_bounds,
    _LawResiduals,
    contact_force,
    fit_contact_law,
)


def _orbit(n: int = 4096, periods: int = 12) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 2 * np.pi * periods, n, endpoint=False)
    w = 2 * np.pi * periods / n  # rad per sample
    return np.sin(t) + 0.1 * np.sin(3 * t), w * n / (2 * np.pi * periods) * (
        np.cos(t) + 0.3 * np.cos(3 * t)
    )


def test_a_law_seen_through_a_band_is_fitted_back():
    x, v = _orbit()
    truth = dict(stiffness=40.0, onset=0.6, damping=0.8, exponent=1.0, reference_penetration=0.3)
    freq = np.fft.rfftfreq(x.size)
    band = 1.0 / (1.0 + 1j * freq / 0.02) ** 2  # a second-order low-pass with its phase
    seen = np.fft.irfft(np.fft.rfft(contact_force(x, v, **truth)) * band, x.size)
    near = x > 0.45
    law = fit_contact_law(seen, x, v, near, (25.0, 0.5, 0.3), 0.3, exponent=1.0, band=band)
    assert law.r2 > 1 - 1e-9
    assert law.stiffness == pytest.approx(40.0, rel=1e-4)
    assert law.onset == pytest.approx(0.6, abs=1e-5)
    assert law.damping == pytest.approx(0.8, rel=1e-4)


def _band_case(exponent: float | None):
    """A law seen through a second-order low-pass, with 1 % noise: the residuals of its fit."""
    x, v = _orbit(n=2897)  # a prime length: the transform's slowest
    truth = dict(stiffness=40.0, onset=0.6, damping=0.8, exponent=1.3, reference_penetration=0.3)
    band = 1.0 / (1.0 + 1j * np.fft.rfftfreq(x.size) / 0.02) ** 2
    seen = np.fft.irfft(np.fft.rfft(contact_force(x, v, **truth)) * band, x.size)
    seen = seen + 0.01 * np.random.default_rng(3).standard_normal(x.size)
    near = x > 0.45
    return seen, x, v, near, band


@pytest.mark.parametrize("exponent", [None, 1.0])
def test_forward_differences_are_scipys_bit_for_bit(exponent, monkeypatch):
    """The law's Jacobian through a band, its steps in one batch: scipy's 2-point Jacobian
    bit for bit (steps reversed at the damping's and the exponent's bounds), one transform."""
    seen, x, v, near, band = _band_case(exponent)
    resid = _LawResiduals(x, v, seen[near], 0.3, exponent, band, near)
    lo, hi = _law_bounds(exponent)
    calls = []
    monkeypatch.setattr(contact_law.fft, "rfft", _counted(contact_law.fft.rfft, calls))
    points = [[np.log(40.0), 0.6, 0.8], [np.log(25.0), 0.5, 0.0], [np.log(1e3), -0.2, 3.0]]
    for p, point in zip([1.3, 3.0, 1.0], points, strict=True):
        theta = np.array(point + ([p] if exponent is None else []))
        f0 = resid(theta)
        calls.clear()
        ours = resid.jacobian(theta)
        assert len(calls) == 1  # the stepped points in one transform; f0 the last residual's
        theirs = approx_derivative(resid, theta, method="2-point", f0=f0, bounds=(lo, hi))
        assert np.array_equal(ours, theirs)
        assert ours.strides == theirs.strides  # the solver's products round by the layout
        assert np.all(np.isfinite(ours)) and np.any(ours != 0)


def _counted(fun, calls):
    def wrapped(*args, **kwargs):
        calls.append(1)
        return fun(*args, **kwargs)

    return wrapped


@pytest.mark.parametrize("exponent", [None, 1.0])
def test_the_band_fit_is_the_finite_difference_fits_bit_for_bit(exponent):
    """fit_contact_law through a band reaches, bit for bit, the end point least_squares
    reaches with its own 2-point Jacobian and numpy's transform of each point alone."""
    seen, x, v, near, band = _band_case(exponent)
    start, dr = (25.0, 0.5, 0.3), 0.3
    law = fit_contact_law(seen, x, v, near, start, dr, exponent=exponent, band=band)

    unit = contact_law.force_unit(seen[near])
    f, xs, vs = seen[near] / unit, x / unit, v / unit

    def reference(t):
        p = t[3] if exponent is None else exponent
        with np.errstate(over="ignore", invalid="ignore"):
            out = contact_force(xs, vs, np.exp(t[0]), t[1], t[2], p, dr / unit)
            return np.fft.irfft(np.fft.rfft(out) * band, out.size)[near] - f

    lo, hi = _law_bounds(exponent)
    best = None
    for gain in contact_law.BAND_START_GAINS:
        theta0 = [np.log(gain * start[0]), start[1] / unit, start[2]]
        theta0 += [1.0] if exponent is None else []
        sol = optimize.least_squares(reference, np.clip(theta0, lo, hi), bounds=(lo, hi),
                                     x_scale="jac", max_nfev=60)  # fmt: skip
        best = sol if best is None or sol.cost < best.cost else best
    assert law.stiffness == float(np.exp(best.x[0]))
    assert law.onset == float(best.x[1]) * unit
    assert law.damping == float(best.x[2])
    assert law.sse == float(np.sum(best.fun**2)) * unit**2
    if exponent is None:  # the free law is the truth's (p 1.3)
        assert law.exponent == float(best.x[3])
        assert law.stiffness == pytest.approx(40.0, rel=0.01)
        assert law.exponent == pytest.approx(1.3, abs=0.01)

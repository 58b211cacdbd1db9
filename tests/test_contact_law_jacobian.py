"""The contact law's analytic Jacobian (what :func:`fit_contact_law` gives the solver)."""

import numpy as np
import pytest
from scipy.optimize._numdiff import approx_derivative

from stiffnet.restoring_force.contact_law import (
    contact_force,
    contact_force_jacobian,
    fit_contact_law,
)


def _orbit(n: int = 4096, periods: int = 12) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 2 * np.pi * periods, n, endpoint=False)
    w = 2 * np.pi * periods / n  # rad per sample
    return np.sin(t) + 0.1 * np.sin(3 * t), w * n / (2 * np.pi * periods) * (
        np.cos(t) + 0.3 * np.cos(3 * t)
    )


@pytest.mark.parametrize("fit_exponent", [False, True])
def test_the_jacobian_is_the_law_s_derivative(fit_exponent):
    x, v = _orbit()
    dr = 0.3
    theta = np.array([np.log(40.0), 0.6, 0.8, 1.4])
    k = 4 if fit_exponent else 3

    def law(t):
        return contact_force(x, v, np.exp(t[0]), t[1], t[2], t[3] if fit_exponent else 1.4, dr)

    jac = contact_force_jacobian(x, v, 40.0, 0.6, 0.8, 1.4, dr, fit_exponent=fit_exponent)
    numeric = approx_derivative(law, theta[:k], method="3-point")
    # away from onset and release, where the law has kinks (a difference straddles them)
    d = x - 0.6
    push = 40.0 * dr * (np.maximum(d, 0) / dr) ** 1.4 + 0.8 * v
    smooth = (np.abs(d) > 1e-3) & (np.abs(push) > 1e-2)
    assert jac.shape == (x.size, k)
    assert np.count_nonzero(jac[:, 0]) > 100  # the law pushes on many samples
    np.testing.assert_allclose(jac[smooth], numeric[smooth], rtol=1e-6, atol=1e-6)
    assert np.all(jac[~((d > 0) & (push > 0))] == 0.0)  # no force, no derivative


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

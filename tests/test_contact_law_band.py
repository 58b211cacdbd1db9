"""The contact law fitted through a band (what a known chain's inverse keeps)."""

import numpy as np
import pytest

from stiffnet.restoring_force.contact_law import (
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

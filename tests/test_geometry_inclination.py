"""Inclinations before and after impact in the x-z projection (eqs 7-10, Table 1)."""

import numpy as np
import pytest

from stiffnet.errors import SignalError
from stiffnet.geometry import (
    curve_inclination,
    gradient_inclinations,
    impact_regions,
    polynomial_inclinations,
    separate_contact,
    tangent_inclinations,
    tangent_magnitudes,
    tangent_vectors,
)
from stiffnet.nlts import delay_embed


def test_tangent_inclination_is_atan_c_over_a():
    v = np.array([[1.0, 5.0, 1.0], [1.0, 0.0, np.sqrt(3)], [0.0, 1.0, 2.0], [-1.0, 0.0, -1.0]])
    np.testing.assert_allclose(tangent_inclinations(v), [45.0, 60.0, 90.0, 45.0])


def test_curve_inclination_of_lines_flat_and_steep():
    x = np.linspace(-1, 1, 50)
    for deg in (30.0, 60.0, 85.0, 89.5):
        z = np.tan(np.radians(deg)) * x + 3.0
        assert curve_inclination(x, z) == pytest.approx(deg, abs=1e-9)
        # polarity (x, z) -> (-x, -z) and gain leave it unchanged
        assert curve_inclination(-1000 * x, -1000 * z) == pytest.approx(deg, abs=1e-9)
    # a parabola: the gradient at the centroid (x = 0) is 0.5
    curve = 0.5 * x + 0.2 * x**2
    assert curve_inclination(x, curve, degree=2) == pytest.approx(np.degrees(np.arctan(0.5)))
    assert curve_inclination(np.zeros(5), np.arange(5.0)) == 90.0


def test_impact_regions_merge_short_gaps():
    m = np.array([0, 1, 1, 0, 1, 0, 0, 0, 1, 1, 0], bool)
    s, e = impact_regions(m)
    assert s.tolist() == [1, 4, 8] and e.tolist() == [3, 5, 10]
    s, e = impact_regions(m, merge_gap=1)
    assert s.tolist() == [1, 8] and e.tolist() == [5, 10]


def _spiky(beta_like: float, n: int = 4000, period: float = 95.2) -> np.ndarray:
    """A sine with a narrow negative spike per period: taller and shorter as beta_like grows."""
    t = np.arange(n)
    phase = np.mod(t, period) - 0.55 * period
    width = 6.0 / np.sqrt(beta_like)
    return np.sin(2 * np.pi * t / period) - 2 * np.sqrt(beta_like) * np.exp(
        -0.5 * (phase / width) ** 2
    )


def _inclinations(s: np.ndarray, tau: int = 17, lag: int = 1):
    y = delay_embed(s, 3, tau)
    v = tangent_vectors(y, lag)
    sep = separate_contact(tangent_magnitudes(v))
    assert sep.contact_detected
    hit = np.abs(v[:, 2]) > sep.threshold
    g = gradient_inclinations(v, sep.mask, hit, approach=tau, merge_gap=tau // 2)
    p = polynomial_inclinations(y, sep.mask, hit, approach=tau, lag=lag, merge_gap=tau // 2)
    return g, p


def test_orbits_and_steeper_contact_branch_for_sharper_spikes():
    g5, p5 = _inclinations(_spiky(5.0))
    g50, p50 = _inclinations(_spiky(50.0))
    assert g5.n_orbits >= 38 and p5.n_orbits == g5.n_orbits
    assert g50.mean_after > g5.mean_after and p50.mean_after > p5.mean_after
    assert g5.before.shape == g5.after.shape == (g5.n_orbits,)
    assert np.all((g5.after >= 0) & (g5.after <= 90))
    # the contact branch is steeper than the free-flight approach
    assert p50.mean_after > p50.mean_before


def test_inclinations_do_not_depend_on_polarity_or_gain():
    s = _spiky(20.0)
    g, p = _inclinations(s)
    g2, p2 = _inclinations(-1000.0 * s)
    np.testing.assert_allclose(g2.after, g.after, atol=1e-9)
    np.testing.assert_allclose(p2.before, p.before, atol=1e-9)


def test_no_orbits_without_impact_regions():
    y = delay_embed(np.sin(np.arange(500) / 10), 3, 5)
    v = tangent_vectors(y)
    none = np.zeros(v.shape[0], bool)
    g = gradient_inclinations(v, none, none, approach=5)
    assert g.n_orbits == 0 and np.isnan(g.mean_before) and np.isnan(g.mean_after)


def test_mask_length_is_checked():
    y = delay_embed(np.sin(np.arange(100) / 5), 3, 3)
    v = tangent_vectors(y)
    with pytest.raises(SignalError):
        gradient_inclinations(v, np.zeros(3, bool), np.zeros(3, bool), approach=5)
    with pytest.raises(SignalError):
        polynomial_inclinations(y, np.zeros(3, bool), np.zeros(3, bool), approach=5)


def _reference_sets(contact, impact, approach, merge_gap):
    """The orbits' tangent sets, one orbit at a time (the definition the vectorised code
    implements, see :func:`stiffnet.geometry.inclination._orbit_sets`)."""
    starts, stops = impact_regions(impact, merge_gap)
    free, out, prev_stop = ~contact, [], 0
    for start, stop in zip(starts, stops, strict=True):
        lo, prev_stop = prev_stop, stop
        if stop >= impact.size:
            break
        app = (np.flatnonzero(free[lo:start]) + lo)[-approach:]
        if app.size < 3 or start - app[-1] > approach:
            continue
        hit = np.flatnonzero(impact[start:stop]) + start
        if hit.size >= 2:
            out.append((app, hit, start, stop))
    return out


@pytest.fixture(scope="module")
def rig_trajectories():
    """Embedded trajectories of the independent rig (not stiffnet's simulator): a damped
    contact seen through a ringing 237-Hz mount (its spikes split into regions that merge)
    and a soft restraint, 2 s at 2 kHz, with the geometric chain's delay, lag and masks."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from independent_rig import RigRun, record

    from stiffnet.geometry import tangent_lag
    from stiffnet.geometry.estimate import dominant_period, smoothing_window
    from stiffnet.nlts import savgol_smooth

    out = []
    for kw in (
        dict(beta=20.0, contact="kelvin_voigt", contact_zeta=0.25,
             sensor={"resonance_hz": 237.0, "resonance_damping": 0.03}),
        dict(beta=5.0, noise=0.05),
    ):  # fmt: skip
        _, a = record(RigRun("incl", fs_hz=2000.0, duration_s=2.0, **kw))
        a = (a - a.mean()) / a.std()
        period = dominant_period(a)
        s = savgol_smooth(a, smoothing_window(period), 2)
        tau, lag = max(1, round(0.18 * period)), tangent_lag(period)
        y = delay_embed(s, 3, tau)
        v = tangent_vectors(y, lag)
        sep = separate_contact(tangent_magnitudes(v))
        assert sep.contact_detected
        out.append((y, v, sep.mask, np.abs(v[:, 2]) > sep.threshold, tau, lag))
    return out


@pytest.mark.parametrize("merge", ["none", "half_delay"])
def test_every_orbit_at_once_equals_one_orbit_at_a_time(rig_trajectories, merge):
    """The vectorised inclinations return the per-orbit definition's values to rounding
    (gradient means; polynomial fits of degree 1 and 2), orbit by orbit, on rig records
    with several orbits, with and without merged impact regions."""
    merged_somewhere = False
    for y, v, contact, hit, tau, lag in rig_trajectories:
        gap = 0 if merge == "none" else max(lag, tau // 2)
        merged_somewhere |= impact_regions(hit, gap)[0].size < impact_regions(hit)[0].size
        ref = _reference_sets(contact, hit, tau, gap)
        assert len(ref) >= 5
        ang = tangent_inclinations(v)
        g = gradient_inclinations(v, contact, hit, tau, gap)
        assert g.starts.tolist() == [s for _, _, s, _ in ref]
        assert g.stops.tolist() == [e for _, _, _, e in ref]
        np.testing.assert_allclose(g.before, [ang[a].mean() for a, _, _, _ in ref], 0, 1e-12)
        np.testing.assert_allclose(g.after, [ang[h].mean() for _, h, _, _ in ref], 0, 1e-12)
        x, z = y[:, 0], y[:, 2]
        for degree in (1, 2):
            p = polynomial_inclinations(y, contact, hit, tau, lag, gap, degree)
            for got, which in ((p.before, 0), (p.after, 1)):
                want = []
                for sets in ref:
                    pts = np.union1d(sets[which], sets[which] + lag)
                    want.append(curve_inclination(x[pts], z[pts], degree))
                np.testing.assert_allclose(got, want, 0, 1e-11 if degree > 1 else 1e-12)
    assert merged_somewhere == (merge != "none")


def test_a_degree_needs_enough_points_in_every_orbit():
    """A set with fewer points than the degree needs is an error, as one curve's fit is."""
    s = _spiky(20.0)
    y = delay_embed(s, 3, 17)
    v = tangent_vectors(y, 1)
    sep = separate_contact(tangent_magnitudes(v))
    hit = np.abs(v[:, 2]) > sep.threshold
    hit &= np.concatenate(([True], ~hit[:-1]))  # two-tangent impact regions: 3 points each
    hit[1:] |= hit[:-1]
    p = polynomial_inclinations(y, sep.mask, hit, approach=17, degree=1)
    assert p.n_orbits > 0
    with pytest.raises(SignalError, match=">= 4 points"):
        polynomial_inclinations(y, sep.mask, hit, approach=17, degree=2)

"""Signatures of the measurement effects on an acceleration-like signal.

The synthetic signal mimics the mass acceleration of the paper's rig in model
units: a sine at 1.05 f_n of amplitude a w^2 (a = 1.9, w = 1.05) plus sharp
negative impact spikes ten times higher, sampled at fs = 500 f_n, f_n = 9.48 Hz.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal as sps

from stiffnet.effects.adc import ADC, lsb
from stiffnet.effects.base import MeasurementEffect
from stiffnet.effects.colored_noise import ColoredNoise
from stiffnet.effects.sensor_dynamics import SensorDynamics
from stiffnet.errors import ConfigError

FN = 9.48  # natural frequency, Hz (paper section 5.2)
FS = 500 * FN  # sampling rate, Hz
SCALE = 1.9 * 1.05**2  # forcing scale a w^2, model units
N = 4096
SPIKES = (1000, 2000, 3000)  # sample index where each impact spike starts
SPIKE_SAMPLES = 4  # spike duration in samples (~0.8 ms: a stiff contact)
SPIKE_HEIGHT = 10.0  # in units of SCALE


def acceleration(n: int = N, fs: float = FS) -> np.ndarray:
    """Sine at 1.05 f_n plus half-sine impact spikes (pointing down), shape ``(n,)``."""
    t = np.arange(n) / fs
    x = SCALE * np.sin(2 * np.pi * 1.05 * FN * t)
    bump = np.sin(np.pi * np.arange(SPIKE_SAMPLES + 1) / SPIKE_SAMPLES)
    for i in SPIKES:
        if i + SPIKE_SAMPLES < n:
            x[i : i + SPIKE_SAMPLES + 1] -= SPIKE_HEIGHT * SCALE * bump
    return x


def run(
    effect: MeasurementEffect,
    signal: np.ndarray,
    fs: float | np.ndarray = FS,
    scale: float | np.ndarray = SCALE,
    seed: int = 0,
    **overrides: np.ndarray,
) -> np.ndarray:
    """Apply ``effect`` to a (B, N) batch with the effect's batch parameters plus context."""
    b = signal.shape[0]
    rng = np.random.default_rng(seed)
    p = effect.batch_params(b, rng)
    p["_forcing_scale"] = np.broadcast_to(np.asarray(scale, float), (b,)).copy()
    p["_natural_frequency_hz"] = np.full(b, FN)
    p.update({k: np.asarray(v, float) for k, v in overrides.items()})
    fs_rows = np.broadcast_to(np.asarray(fs, float), (b,)).copy()
    return effect.apply(signal, fs_rows, p, rng)


def post_spike(y: np.ndarray, x: np.ndarray, length: int) -> np.ndarray:
    """``y - x`` just after the first spike has ended (the sensor's own response)."""
    start = SPIKES[0] + SPIKE_SAMPLES + 2
    return (y - x)[start : start + length]


# ---------------------------------------------------------------- sensor dynamics


@pytest.mark.parametrize("resonance_hz", [300.0, 1500.0])
def test_sensor_rings_at_resonance_after_impact(resonance_hz: float) -> None:
    x = acceleration()
    eff = SensorDynamics(resonance_hz=resonance_hz, highpass_hz=0, lowpass_hz=0)
    y = run(eff, x[None])[0]
    ring = post_spike(y, x, 400)
    # the ringing is a sizeable fraction of the spike, and absent before the first impact
    # (but for a small start-up ring: the filter state assumes a constant history)
    assert np.abs(ring).max() > 0.2 * SCALE
    assert np.abs(y - x)[300 : SPIKES[0]].max() < 0.01 * SCALE
    nfft = 1 << 15
    spectrum = np.abs(np.fft.rfft(ring * np.hanning(ring.size), nfft))
    peak_hz = np.fft.rfftfreq(nfft, 1 / FS)[spectrum.argmax()]
    assert abs(peak_hz - resonance_hz) < 0.1 * resonance_hz


@pytest.mark.parametrize("damping", [0.02, 0.05])
def test_sensor_ringing_decays_at_damping_rate(damping: float) -> None:
    resonance_hz = 300.0
    x = acceleration()
    eff = SensorDynamics(
        resonance_hz=resonance_hz, resonance_damping=damping, highpass_hz=0, lowpass_hz=0
    )
    decay_rate = damping * 2 * np.pi * resonance_hz  # envelope exp(-zeta w_r t)
    length = int(3 / decay_rate * FS)  # three time constants
    ring = post_spike(run(eff, x[None])[0], x, length)
    peaks, _ = sps.find_peaks(ring)
    slope = np.polyfit(peaks / FS, np.log(ring[peaks]), 1)[0]
    assert slope == pytest.approx(-decay_rate, rel=0.15)


def test_sensor_highpass_removes_dc_offset() -> None:
    x = acceleration()
    offset = 3.0 * SCALE  # e.g. a sensor bias
    with_hp = SensorDynamics()  # defaults: 1 Hz charge-amplifier high-pass
    no_hp = SensorDynamics(highpass_hz=0)
    y = run(with_hp, np.stack([x, x + offset]))
    assert abs(np.mean(x + offset)) > 2.9 * SCALE
    assert abs(np.mean(y[1])) < 0.05 * SCALE
    np.testing.assert_allclose(y[1] - y[0], 0.0, atol=1e-9 * offset)
    # without the high-pass the chain has unit DC gain: the offset passes unchanged
    y = run(no_hp, np.stack([x, x + offset]))
    np.testing.assert_allclose(y[1] - y[0], offset, rtol=1e-9)


def test_sensor_lowpass_reduces_spike_height() -> None:
    x = acceleration()
    window = slice(SPIKES[0] - 10, SPIKES[0] + 40)
    heights = {}
    for lowpass_hz in (0.0, 1000.0, 500.0, 200.0):
        eff = SensorDynamics(resonance_hz=50000, highpass_hz=0, lowpass_hz=lowpass_hz)
        heights[lowpass_hz] = -run(eff, x[None])[0][window].min()
    spike = -x[window].min()
    assert heights[0.0] == pytest.approx(spike, rel=1e-12)  # every stage off: untouched
    assert heights[1000.0] < 0.95 * spike
    assert heights[500.0] < 0.7 * spike
    assert heights[200.0] < 0.35 * spike


def test_sensor_is_causal_and_skips_stages_above_nyquist() -> None:
    x = acceleration()
    eff = SensorDynamics()
    late = x.copy()
    late[3500] -= 5 * SCALE
    y = run(eff, np.stack([x, late]))
    # causal (hardware-like, not filtfilt): a change at sample 3500 changes nothing before it
    np.testing.assert_array_equal(y[0, :3500], y[1, :3500])
    assert np.abs(y[0, 3500:] - y[1, 3500:]).max() > SCALE
    # a 3 kHz resonance and a 5 kHz low-pass cannot act at 4.74 kHz: skipped, no crash;
    # at 20 kHz in the same batch they do act (per-row design)
    eff = SensorDynamics(resonance_hz=3000, highpass_hz=0, lowpass_hz=5000)
    batch = np.stack([x, x])
    y = run(eff, batch, fs=np.array([FS, 20000.0]))
    np.testing.assert_array_equal(y[0], x)
    assert np.abs(y[1] - x).max() > 0.1 * SCALE
    np.testing.assert_allclose(y[1], run(eff, x[None], fs=20000.0)[0], rtol=1e-12, atol=0)
    np.testing.assert_array_equal(batch, np.stack([x, x]))  # input not modified


# ---------------------------------------------------------------- coloured noise


@pytest.mark.parametrize("exponent", [0.5, 1.0, 1.5])
def test_pink_noise_slope_and_level(exponent: float) -> None:
    b, n, level = 8, 8192, 0.05
    scales = SCALE * np.arange(1, b + 1)
    eff = ColoredNoise(pink_level=level, pink_exponent=exponent, narrowband_level=0.0)
    clean = np.tile(acceleration(n), (b, 1))
    noise = run(eff, clean, scale=scales) - clean
    # additive and independent of the signal: the same draw on a zero signal
    np.testing.assert_allclose(noise, run(eff, np.zeros((b, n)), scale=scales), atol=1e-12)
    np.testing.assert_allclose(noise.std(axis=1), level * scales, rtol=0.01)
    f, psd = sps.welch(noise / scales[:, None], fs=FS, nperseg=1024, axis=1)
    band = (f > 4 * FS / 1024) & (f < FS / 4)
    slope = np.polyfit(np.log(f[band]), np.log(psd.mean(axis=0)[band]), 1)[0]
    assert slope == pytest.approx(-exponent, abs=0.15)


def test_narrowband_noise_concentrated_at_centre() -> None:
    b, n, level = 3, 8192, 0.05
    centres = np.array([50.0, 60.0, 3000.0])  # the last is above Nyquist (2370 Hz): skipped
    eff = ColoredNoise(pink_level=0.0, narrowband_level=level, narrowband_width_hz=1.0)
    noise = run(eff, np.zeros((b, n)), narrowband_hz=centres)
    np.testing.assert_allclose(noise[:2].std(axis=1), level * SCALE, rtol=0.01)
    np.testing.assert_array_equal(noise[2], 0.0)
    f = np.fft.rfftfreq(n, 1 / FS)
    power = np.abs(np.fft.rfft(noise[:2], axis=1)) ** 2
    for row, centre in enumerate(centres[:2]):
        near = np.abs(f - centre) < 10.0  # 10 widths; the 1/f^2 tails hold ~3 % on average
        assert power[row, near].sum() > 0.8 * power[row].sum()


def test_colored_noise_reproducible_with_rng() -> None:
    x = np.tile(acceleration(), (4, 1))
    eff = ColoredNoise()
    a, again, other = run(eff, x, seed=7), run(eff, x, seed=7), run(eff, x, seed=8)
    np.testing.assert_array_equal(a, again)
    assert np.abs(a - other).max() > 0.01 * SCALE
    # defaults: 2 % pink + 1 % mains, independent, so the total std is about 2.24 % of a w^2
    assert (a - x).std() == pytest.approx(np.hypot(0.02, 0.01) * SCALE, rel=0.1)
    silent = ColoredNoise(pink_level=0.0, narrowband_level=0.0)
    np.testing.assert_array_equal(run(silent, x), x)


# ---------------------------------------------------------------- ADC


@pytest.mark.parametrize("bits", [4, 8, 12])
def test_adc_levels_and_half_lsb_error(bits: int) -> None:
    full_scale = 12.0  # spikes reach ~11 a w^2: no clipping
    x = acceleration()[None]
    y = run(ADC(bits=bits, full_scale=full_scale), x)
    q = lsb(full_scale * SCALE, bits)
    assert np.unique(y).size <= 2**bits
    np.testing.assert_allclose(y / q, np.rint(y / q), atol=1e-9)  # on the level grid
    err = np.abs(y - x).max()
    assert err <= 0.5 * q * (1 + 1e-9)
    assert err > 0.3 * q  # it really quantises


def test_adc_distinct_values_with_rounded_bits() -> None:
    # a full-range ramp visits every level; bits drawn from a range are rounded per row
    ramp = np.tile(np.linspace(-2 * SCALE, 2 * SCALE, 20000), (32, 1))
    eff = ADC(bits=[4.0, 7.0], full_scale=1.0)
    rng = np.random.default_rng(0)
    p = eff.batch_params(32, rng)
    p["_forcing_scale"] = np.full(32, SCALE)
    y = eff.apply(ramp, np.full(32, FS), p, rng)
    for row, bits in zip(y, np.rint(p["bits"]), strict=True):
        assert np.unique(row).size == 2 ** int(bits) - 1  # symmetric mid-tread levels


@pytest.mark.parametrize("full_scale", [0.8, 3.0])
def test_adc_clips_flat_at_full_scale(full_scale: float) -> None:
    x = acceleration()[None]
    y = run(ADC(bits=16, full_scale=full_scale), x)[0]
    top = full_scale * SCALE
    over, under = x[0] > top, x[0] < -top
    assert under.sum() >= len(SPIKES)  # the spikes exceed the range
    np.testing.assert_allclose(y[under], -top, rtol=1e-12)
    np.testing.assert_allclose(y[over], top, rtol=1e-12)
    assert np.abs(y).max() == pytest.approx(top, rel=1e-12)
    inside = ~(over | under)
    assert np.abs(y[inside] - x[0, inside]).max() <= 0.5 * lsb(top, 16) * (1 + 1e-9)


# ---------------------------------------------------------------- parameters

EFFECTS = [SensorDynamics, ColoredNoise, ADC]


@pytest.mark.parametrize(
    ("cls", "field", "bad", "allowed"),
    [
        (SensorDynamics, "resonance_hz", 10.0, "[50.0, 50000.0]"),
        (SensorDynamics, "lowpass_order", 9, "[1, 8]"),
        (ColoredNoise, "pink_level", 0.9, "[0.0, 0.5]"),
        (ColoredNoise, "pink_exponent", [0.5, 2.5], "[0.0, 2.0]"),
        (ADC, "bits", 30, "[4, 24]"),
        (ADC, "full_scale", 0.1, "[0.5, 10000.0]"),
    ],
)
def test_out_of_range_rejected_naming_field_and_range(
    cls: type[MeasurementEffect], field: str, bad: float | list[float], allowed: str
) -> None:
    with pytest.raises(ConfigError) as info:
        cls(**{field: bad})
    message = str(info.value)
    assert f"{field}=" in message
    assert f"outside the allowed range {allowed}" in message


@pytest.mark.parametrize("cls", EFFECTS)
def test_ranges_accepted_and_drawn_within(cls: type[MeasurementEffect]) -> None:
    table = cls.parameter_table()
    assert cls.name and cls.kind == "measurement"
    ranges = {}
    for row in table:
        lo, hi = row["range"]
        assert lo <= row["default"] <= hi, row["name"]
        assert row["description"]
        # the middle half of the allowed range
        ranges[row["name"]] = [lo + 0.25 * (hi - lo), lo + 0.75 * (hi - lo)]
    eff = cls(**ranges)
    draws = eff.batch_params(500, np.random.default_rng(1))
    for name, (lo, hi) in ranges.items():
        assert draws[name].shape == (500,)
        assert lo <= draws[name].min() < draws[name].max() <= hi
    with pytest.raises(ConfigError, match="range must be"):
        cls(**{table[0]["name"]: [ranges[table[0]["name"]][1], ranges[table[0]["name"]][0]]})
    with pytest.raises(ConfigError):
        cls(not_a_parameter=1.0)


@pytest.mark.parametrize("cls", EFFECTS)
def test_effects_return_new_float_array(cls: type[MeasurementEffect]) -> None:
    x = np.tile(acceleration(), (3, 1))
    before = x.copy()
    y = run(cls(), x)
    assert y.shape == x.shape and y.dtype == np.float64
    assert not np.shares_memory(x, y)
    np.testing.assert_array_equal(x, before)

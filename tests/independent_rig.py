"""An impact-oscillator rig simulated independently of stiffnet, in physical units.

The people steering stiffnet check it on campaigns written by a code it has never
seen. This module is a small stand-in for that code: it imports nothing from
stiffnet's simulator, effects or campaign packages, integrates the paper's
base-excited impact oscillator (eqs 11-12) in SI units with
:func:`scipy.integrate.solve_ivp` (DOP853, contact onset and release located as
events), passes the absolute acceleration of the mass through an optional sensor
chain built with :mod:`scipy.signal`, and writes a campaign folder the way a lab
would: ``t,accel`` CSV files in g and a ``manifest.csv`` in Hz, g and mm.

Model (relative displacement ``x`` of the mass, positive towards the restraint,
metres; base acceleration ``-A sin(Ω t)``)::

    x'' = A sin(Ω t) - 2 ζ ω_n x' - ω_n² x - F_c / m
    F_c / m = max(0, β ω_n² δ + damping),  δ = x - e > 0

with contact damping either Kelvin-Voigt, ``2 ζ_c sqrt(β) ω_n δ'``, or
Hunt-Crossley, ``β ω_n² δ λ δ'`` (λ in s/m: damping proportional to the
penetration, so the force starts at zero); or an elastic law other than the
linear spring: a two-stage restraint (``(r - 1) β ω_n² (δ - δ_k)₊`` added beyond
the knee) or a power law (``β ω_n² d0 (δ/d0)^n``). The accelerometer on the mass reads
its absolute acceleration ``x'' - A sin(Ω t) = -(2 ζ ω_n x' + ω_n² x + F_c/m)``:
impacts are negative spikes.

The stop may also be the tip of a beam (``contact="beam"``) represented by its first
modes at the tip, each a modal mass ``m_i``, frequency ``ω_i`` and damping ratio ``ζ_b``::

    m_i y_i'' + 2 ζ_b ω_i m_i y_i' + m_i ω_i² y_i = F_c,   F_c = β m ω_n² (x - e - Σ y_i)_+

the modes ringing freely between impacts (a tip still ringing at the next impact is part of
the physics). For a uniform Euler-Bernoulli cantilever of mass ``M_b`` each mode's shape
normalised to ``∫ φ_i² = L`` has ``|φ_i(L)| = 2``, so every mode's mass at the tip is
``M_b / 4`` and the frequencies go as ``λ_i²``, ``λ L = 1.8751, 4.6941, 7.8548``:
1 : 6.267 : 17.55 (:func:`cantilever_tip_modes`). The base's motion on the beam's modes is
left out: its forcing sits at a tenth of their frequencies or less, a quasi-static tip
deflection of ``(ω_n / ω_1)²`` of the mass's excursion at most. Beta is then the
contact's stiffness behind the beam, which the campaign shares; or (``beam_material``) the
beam is the impacted material, as on the paper's rig: beta is its static tip stiffness, each
recording's beam its own (:func:`material_beam_tip_modes`), struck through a stiff contact.
"""

from __future__ import annotations

import csv
import math
import zlib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.integrate import solve_ivp

G = 9.80665  # m/s^2 per g


@dataclass
class RigRun:
    """One recording of the rig, in the units a lab would write down."""

    recording: str
    beta: float
    natural_frequency_hz: float = 9.48
    forcing_frequency_hz: float = 9.95
    base_acceleration_g: float = 0.75
    gap_mm: float = 2.0
    damping_ratio: float = 0.02
    fs_hz: float = 1000.0
    duration_s: float = 4.0
    #: None, "kelvin_voigt" (uses contact_zeta), "hunt_crossley" (uses hc_lambda_s_per_m),
    #: "two_stage" (stiffness x stage_ratio beyond knee_mm), "power_law" (F = k d^n with
    #: the secant stiffness beta at power_d0_mm) or "preloaded_power_law" (the power law
    #: of a restraint already compressed by preload_mm: F = k d0 ((d + p) / d0)^n).
    contact: str | None = None
    contact_zeta: float = 0.0
    hc_lambda_s_per_m: float = 0.0
    knee_mm: float = 0.2
    stage_ratio: float = 1.0
    power_exponent: float = 1.0
    power_d0_mm: float = 0.5
    #: A restraint compressed by ``preload_mm`` before the mass arrives (linear and
    #: two-stage laws): the force jumps to ``beta ω_n² preload`` at touch, ``k (δ + p)``
    #: after, and the knee sits at ``knee_mm`` of penetration.
    preload_mm: float = 0.0
    #: Sensor chain: mounted resonance (Hz, damping), high-pass and anti-alias corners (Hz).
    sensor: dict | None = field(default=None)
    #: White noise std as a fraction of the base-acceleration amplitude.
    noise: float = 0.02
    #: The shaker's frequency drifting linearly, Hz per second from the integration's start:
    #: the base acceleration is ``-A sin(Ω t + π drift t²)`` (harmonics follow the phase).
    forcing_drift_hz_per_s: float = 0.0
    #: Shaker distortion: ``(order, level, phase)`` terms added to the base acceleration,
    #: ``-A [sin Ωt + Σ level sin(order Ωt + phase)]``.
    harmonics: tuple = ()
    #: ``contact="beam"``: the stop is the tip of a cantilever of mass ``beam_mass_ratio`` m
    #: whose first mode rings at ``beam_f1_ratio`` natural frequencies, ``beam_modes`` modes
    #: (Euler-Bernoulli, :func:`cantilever_tip_modes`), each of damping ratio ``beam_damping``;
    #: ``beam_tip_modes``: ``(mass over m, frequency over f_n)`` per mode instead.
    beam_mass_ratio: float = 0.3
    beam_f1_ratio: float = 10.0
    beam_modes: int = 2
    beam_damping: float = 0.02
    beam_tip_modes: tuple = ()
    #: ``contact="beam"`` with ``beam_material``: the beam is the impacted material (the
    #: paper's rig, whose "effective stiffness ... is controlled by adjusting the length of
    #: the elastic beam"): beta labels the cantilever's static tip stiffness, the beam's
    #: length sets it at a fixed section (mass ``beam_mass_ratio (30 / beta)^(1/3)`` m,
    #: :func:`material_beam_tip_modes`), and the tip is struck through a stiff local contact
    #: of ``beam_contact_ratio`` beta. Else beta is the contact's own stiffness behind a beam
    #: the campaign shares.
    beam_material: bool = False
    beam_contact_ratio: float = 20.0
    #: ``contact="cubic_hunt_crossley"``: a face that stiffens as it is compressed, a
    #: Duffing-like ``k δ (1 + (δ / cubic_mm)²)``, whose dissipation grows with the
    #: penetration as Hunt-Crossley's: the force times ``(1 + hc_lambda_s_per_m δ')``.
    cubic_mm: float = 0.3

    @property
    def contact_beta(self) -> float:
        """The contact's stiffness over the primary spring's: beta, or the local contact
        in front of a beam that is the material."""
        if self.contact == "beam" and self.beam_material:
            return self.beam_contact_ratio * self.beta
        return self.beta

    @property
    def omega_n(self) -> float:
        return 2 * math.pi * self.natural_frequency_hz

    @property
    def base_acceleration_ms2(self) -> float:
        return self.base_acceleration_g * G

    @property
    def tip_modes(self) -> list[tuple[float, float]]:
        """``(modal mass over m, angular frequency in rad/s)`` of each beam mode at the tip."""
        if self.contact != "beam":
            return []
        if self.beam_tip_modes:
            modes = self.beam_tip_modes
        elif self.beam_material:
            modes = material_beam_tip_modes(self.beam_modes, self.beam_mass_ratio, self.beta)
        else:
            modes = cantilever_tip_modes(self.beam_modes, self.beam_mass_ratio, self.beam_f1_ratio)
        return [(float(mu), float(r) * self.omega_n) for mu, r in modes]

    @property
    def base_displacement_mm(self) -> float:
        """The table's displacement amplitude, ``A / Ω²``, in mm."""
        return self.base_acceleration_ms2 / (2 * math.pi * self.forcing_frequency_hz) ** 2 * 1e3


#: ``λ_i L`` of a uniform cantilever's first bending modes (``cos λL cosh λL = -1``).
CANTILEVER_LAMBDA_L = (1.8751041, 4.6940911, 7.8547574)


def cantilever_tip_modes(n: int, mass_ratio: float, f1_ratio: float) -> list[tuple[float, float]]:
    """``(tip modal mass over m, frequency over f_n)`` of a uniform cantilever's first ``n``
    modes: a quarter of the beam's mass each, frequencies as ``(λ_i / λ_1)²``."""
    lam = CANTILEVER_LAMBDA_L[:n]
    return [(0.25 * mass_ratio, f1_ratio * (li / lam[0]) ** 2) for li in lam]


#: The beta at which a material beam's mass is ``beam_mass_ratio`` m.
MATERIAL_BEAM_REFERENCE_BETA = 30.0


def material_beam_tip_modes(n: int, mass_ratio: float, beta: float) -> list[tuple[float, float]]:
    """``(tip modal mass over m, frequency over f_n)`` of the first ``n`` modes of a uniform
    cantilever whose static tip stiffness is ``beta`` m ω_n², its length set by beta at a
    fixed section: mass ``mass_ratio (30 / beta)^(1/3)`` m (mass ~ L, stiffness ~ L^-3).

    Each mode's tip compliance is ``4 / (λ_i L)^4`` of ``L^3 / (EI)``, and all of them sum to
    the static ``1 / 3`` (97.1 % in the first), so ``(ω_i / ω_n)^2 = beta (λ_i L)^4 /
    (3 M_b / m)`` with the tip modal mass ``M_b / 4``."""
    m_beam = mass_ratio * (MATERIAL_BEAM_REFERENCE_BETA / beta) ** (1 / 3)
    lam = CANTILEVER_LAMBDA_L[:n]
    return [(0.25 * m_beam, math.sqrt(beta * li**4 / (3 * m_beam))) for li in lam]


def _contact_force(run: RigRun, x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Contact force per unit mass (m/s²), zero out of contact; never pulls."""
    e = run.gap_mm * 1e-3
    d = x - e
    k = run.beta * run.omega_n**2
    f = k * (d + run.preload_mm * 1e-3)
    if run.contact == "kelvin_voigt":
        f = f + 2 * run.contact_zeta * np.sqrt(run.beta) * run.omega_n * v
    elif run.contact == "hunt_crossley":
        f = f * (1 + run.hc_lambda_s_per_m * v)
    elif run.contact == "cubic_hunt_crossley":
        f = f * (1 + (d / (run.cubic_mm * 1e-3)) ** 2) * (1 + run.hc_lambda_s_per_m * v)
    elif run.contact == "two_stage":
        f = f + (run.stage_ratio - 1) * k * np.maximum(d - run.knee_mm * 1e-3, 0.0)
    elif run.contact == "power_law":
        d0 = run.power_d0_mm * 1e-3
        f = k * d0 * (np.maximum(d, 0.0) / d0) ** run.power_exponent
    elif run.contact == "preloaded_power_law":
        d0 = run.power_d0_mm * 1e-3
        p = run.preload_mm * 1e-3
        f = k * d0 * ((np.maximum(d, 0.0) + p) / d0) ** run.power_exponent
    return np.where(d > 0, np.maximum(f, 0.0), 0.0)


def simulate(
    run: RigRun,
    transient_s: float | None = None,
    beta_schedule: list[tuple[float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Integrate the rig from rest and return ``(t, absolute acceleration in m/s²)``.

    The motion is integrated phase by phase (free flight / contact) so that the
    integrator never steps across the contact's switch; each phase ends at an event.
    ``beta_schedule``: ``(time from the record's start in s, beta)`` pairs, a drill bit
    entering a new layer at each time; the motion carries on across the change (each
    contact phase uses the beta of its start).
    """
    wn, zeta = run.omega_n, run.damping_ratio
    big_a, om = run.base_acceleration_ms2, 2 * math.pi * run.forcing_frequency_hz
    e = run.gap_mm * 1e-3
    if run.contact == "beam" and transient_s is None:
        # the impacts on a ringing tip damp the start within a few periods; the modes' steps
        # make every second of transient cost what the record's do
        transient_s = 30 / run.forcing_frequency_hz
    if transient_s is None:  # free oscillations down to 1e-4, at least 20 forcing periods
        transient_s = max(math.log(1e4) / (zeta * wn), 20 / run.forcing_frequency_hz)
    if run.contact == "beam":
        if beta_schedule:
            raise ValueError("a beta schedule is not available with contact='beam'")
        return _simulate_beam(run, transient_s)
    n = int(round(run.duration_s * run.fs_hz))
    t_rec = transient_s + np.arange(n) / run.fs_hz
    t_end = t_rec[-1]
    schedule = sorted(beta_schedule or [])

    def beta_at(t: float) -> float:
        beta = run.beta
        for start, b in schedule:
            if t - transient_s >= start:
                beta = b
        return beta

    drift = run.forcing_drift_hz_per_s

    def forcing(t: float) -> float:
        phase = om * t + math.pi * drift * t * t
        return big_a * (
            math.sin(phase) + sum(h * math.sin(k * phase + ph) for k, h, ph in run.harmonics)
        )

    def rhs(contact: bool, r: RigRun):
        def f(t, y):
            fc = _contact_force(r, np.array(y[0]), np.array(y[1])) if contact else 0.0
            return [y[1], forcing(t) - 2 * zeta * wn * y[1] - wn**2 * y[0] - fc]

        return f

    def touch(t, y):
        return y[0] - e

    touch.terminal, touch.direction = True, 1

    def release_of(r: RigRun):
        def release(t, y):  # the force reaches zero (or the penetration does)
            d = y[0] - e
            if r.contact == "kelvin_voigt":
                return r.beta * wn**2 * d + 2 * r.contact_zeta * math.sqrt(r.beta) * wn * y[1]
            if r.contact == "hunt_crossley":
                return d * (1 + r.hc_lambda_s_per_m * y[1])
            if r.contact == "cubic_hunt_crossley":  # the cubic factor is positive
                return d * (1 + r.hc_lambda_s_per_m * y[1])
            return d

        release.terminal, release.direction = True, -1
        return release

    x_out = np.empty(n)
    v_out = np.empty(n)
    beta_out = np.full(n, float(run.beta))
    in_contact = np.zeros(n, bool)
    t0, y0, contact = 0.0, [0.0, 0.0], False
    max_step = 1 / (20 * max(run.natural_frequency_hz, run.forcing_frequency_hz))
    while t0 < t_end:
        r = replace(run, beta=beta_at(t0)) if schedule else run
        sol = solve_ivp(
            rhs(contact, r),
            (t0, t_end),
            y0,
            method="DOP853",
            rtol=1e-9,
            atol=1e-12,
            max_step=max_step if not contact else max_step / 4,
            events=release_of(r) if contact else touch,
            dense_output=True,
        )
        t1 = sol.t[-1]
        sel = (t_rec >= t0) & (t_rec <= t1)
        if sel.any():
            xs, vs = sol.sol(t_rec[sel])
            x_out[sel], v_out[sel], in_contact[sel] = xs, vs, contact
            beta_out[sel] = r.beta
        if sol.status != 1:
            break
        y0 = list(sol.y[:, -1])
        t0, contact = t1, not contact
    fc = np.where(in_contact, _contact_force(replace(run, beta=beta_out), x_out, v_out), 0.0)
    accel = -(2 * zeta * wn * v_out + wn**2 * x_out + fc)
    return t_rec - t_rec[0], accel


def _simulate_beam(run: RigRun, transient_s: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`simulate` with the stop at a beam's tip: state ``(x, x', y_1, y_1', ...)``,
    phases ended by the penetration ``x - e - Σ y_i`` crossing zero (touch rising, release
    falling), the modes integrated in both phases."""
    wn, zeta = run.omega_n, run.damping_ratio
    big_a, om = run.base_acceleration_ms2, 2 * math.pi * run.forcing_frequency_hz
    e, k = run.gap_mm * 1e-3, run.contact_beta * run.omega_n**2
    modes = run.tip_modes
    mu = np.array([m for m, _ in modes])
    wb = np.array([w for _, w in modes])
    cb = 2 * run.beam_damping * wb
    n = int(round(run.duration_s * run.fs_hz))
    t_rec = transient_s + np.arange(n) / run.fs_hz

    mus, wbs, cbs = mu.tolist(), (wb**2).tolist(), cb.tolist()
    nm = len(mus)
    harmonics = [(k_ * om, h, ph) for k_, h, ph in run.harmonics]

    def forcing(t: float) -> float:
        return big_a * (math.sin(om * t) + sum(h * math.sin(w * t + ph) for w, h, ph in harmonics))

    def penetration(y) -> float:
        return y[0] - e - sum(y[2 + 2 * i] for i in range(nm))

    def rhs(contact: bool):
        def f(t, y):  # plain floats: the rhs runs ~10^6 times a record
            fc = max(k * penetration(y), 0.0) if contact else 0.0
            out = [y[1], forcing(t) - 2 * zeta * wn * y[1] - wn * wn * y[0] - fc]
            for i in range(nm):
                yi, wi = y[2 + 2 * i], y[3 + 2 * i]
                out += [wi, fc / mus[i] - cbs[i] * wi - wbs[i] * yi]
            return out

        return f

    def touch(t, y):
        return penetration(y)

    def release(t, y):
        return penetration(y)

    touch.terminal, touch.direction = True, 1
    release.terminal, release.direction = True, -1
    states = np.empty((n, 2 + 2 * len(modes)))
    in_contact = np.zeros(n, bool)
    t0, y0, contact = 0.0, np.zeros(2 + 2 * len(modes)), False
    # DOP853's error control keeps its steps within the fastest mode's ringing
    max_step = 1 / (20 * max(run.natural_frequency_hz, run.forcing_frequency_hz))
    while t0 < t_rec[-1]:
        sol = solve_ivp(rhs(contact), (t0, t_rec[-1]), y0, method="DOP853", rtol=1e-8,
                        atol=1e-12, max_step=max_step, events=release if contact else touch,
                        dense_output=True)  # fmt: skip
        t1 = sol.t[-1]
        sel = (t_rec >= t0) & (t_rec <= t1)
        if sel.any():
            states[sel] = sol.sol(t_rec[sel]).T
            in_contact[sel] = contact
        if sol.status != 1:
            break
        y0 = sol.y[:, -1]
        t0, contact = t1, not contact
    pen = states[:, 0] - e - states[:, 2::2].sum(axis=1)
    fc = np.where(in_contact, k * np.maximum(pen, 0.0), 0.0)
    accel = -(2 * zeta * wn * states[:, 1] + wn**2 * states[:, 0] + fc)
    return t_rec - t_rec[0], accel


def sensor_chain(accel: np.ndarray, fs_hz: float, sensor: dict) -> np.ndarray:
    """Mounted resonance, then a 1st-order high-pass, then a Butterworth anti-alias low-pass,
    discretised by the bilinear transform *without* prewarping (the digital resonance falls
    below the analog one, the more so the lower the rate: 237 Hz rings at 204 Hz at 1 kHz):
    a digital stand-in kept for comparison; :func:`record` uses :func:`analog_sensor_chain`.

    ``sensor`` keys: ``resonance_hz``, ``resonance_damping``, ``highpass_hz``,
    ``lowpass_hz``, ``lowpass_order`` (default 4; any stage left out or 0 is skipped).
    Causal filters, as in hardware.
    """
    y = accel
    fr = sensor.get("resonance_hz") or 0
    if fr:
        wr, zr = 2 * math.pi * fr, sensor.get("resonance_damping", 0.05)
        b, a = signal.bilinear([wr**2], [1, 2 * zr * wr, wr**2], fs=fs_hz)
        y = signal.lfilter(b, a, y)
    if sensor.get("highpass_hz"):
        y = signal.sosfilt(
            signal.butter(1, sensor["highpass_hz"], "high", fs=fs_hz, output="sos"), y
        )
    if sensor.get("lowpass_hz"):
        order = int(sensor.get("lowpass_order", 4))
        sos = signal.butter(order, sensor["lowpass_hz"], "low", fs=fs_hz, output="sos")
        y = signal.sosfilt(sos, y)
    return y


#: The analog sensor chain runs on the motion sampled this many times faster than the logger
#: (a sensor entry ``oversample: m`` sets another factor).
OVERSAMPLE = 8


def analog_sensor_chain(t: np.ndarray, accel: np.ndarray, sensor: dict) -> np.ndarray:
    """The sensor chain of :func:`sensor_chain` in continuous time, as the hardware is:
    mounted resonance, 1st-order high-pass and Butterworth anti-alias low-pass (order
    ``lowpass_order``, default 4) cascaded as one analog transfer function, integrated by
    :func:`scipy.signal.lsim` on a finely sampled input (the logger then samples the output)."""
    num, den = np.array([1.0]), np.array([1.0])
    fr = sensor.get("resonance_hz") or 0
    if fr:
        wr, zr = 2 * math.pi * fr, sensor.get("resonance_damping", 0.05)
        num, den = np.polymul(num, [wr**2]), np.polymul(den, [1, 2 * zr * wr, wr**2])
    if sensor.get("highpass_hz"):
        wh = 2 * math.pi * sensor["highpass_hz"]
        num, den = np.polymul(num, [1, 0]), np.polymul(den, [1, wh])
    if sensor.get("lowpass_hz"):
        order = int(sensor.get("lowpass_order", 4))
        b, a = signal.butter(order, 2 * math.pi * sensor["lowpass_hz"], "low", analog=True)
        num, den = np.polymul(num, b), np.polymul(den, a)
    _, y, _ = signal.lsim((num, den), accel, t)
    return y


def record(
    run: RigRun, seed: int = 0, beta_schedule: list[tuple[float, float]] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """``(t in s, accel in g)`` as the data logger stores it: chain, then white noise.

    ``beta_schedule``: layers along the record (see :func:`simulate`). With a sensor, the
    motion is integrated at :data:`OVERSAMPLE` (or the sensor's ``oversample``) times the
    logger's rate, passed through the analog chain (:func:`analog_sensor_chain`: a mounted
    resonance rings at its own frequency whatever the logger's rate), then sampled."""
    if run.sensor:
        m = int(run.sensor.get("oversample", OVERSAMPLE))
        chain = {k: v for k, v in run.sensor.items() if k != "oversample"}
        fine = replace(run, fs_hz=run.fs_hz * m)
        t, acc = simulate(fine, beta_schedule=beta_schedule)
        acc = analog_sensor_chain(t, acc, chain)
        t, acc = t[::m], acc[::m]
    else:
        t, acc = simulate(run, beta_schedule=beta_schedule)
    rng = np.random.default_rng([seed, zlib.crc32(run.recording.encode())])
    acc = acc + rng.normal(0.0, run.noise * run.base_acceleration_ms2, acc.shape)
    return t, acc / G


MANIFEST_COLUMNS = ["recording", "fs_hz", "natural_frequency_hz", "forcing_frequency_hz",
                    "base_acceleration_g", "gap_mm", "damping_ratio", "beta"]  # fmt: skip


def write_campaign(
    folder: Path,
    runs: list[RigRun],
    seed: int = 0,
    tolerances: dict | None = None,
    errors: list[dict] | None = None,
    accel_unit: str = "g",
) -> Path:
    """Write ``folder/manifest.csv`` (physical units) and one ``t,accel`` CSV per run.

    ``tolerances`` maps a manifest column to its relative ± (written as
    ``<column>_tol`` in the column's unit); ``errors`` gives per run the relative
    error of the *declared* value of some columns (the lab's nominal is off);
    ``accel_unit`` ``"ms2"`` writes ``base_acceleration_ms2`` instead of ``_g``.
    A ``<folder>_rig_truth.csv`` beside the campaign keeps every run's true settings.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tol = tolerances or {}
    base = MANIFEST_COLUMNS
    if accel_unit == "ms2":
        base = [c.replace("_g", "_ms2") if c == "base_acceleration_g" else c for c in base]
    cols = base + [f"{c}_tol" for c in tol]
    with open(folder / "manifest.csv", "w", encoding="utf-8", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for i, run in enumerate(runs):
            t, acc = record(run, seed)
            path = folder / run.recording
            path.parent.mkdir(parents=True, exist_ok=True)
            np.savetxt(path, np.column_stack([t, acc]), delimiter=",", header="t,accel",
                       comments="", fmt=["%.9f", "%.8e"])  # fmt: skip
            err = errors[i] if errors else {}
            declared = {c: getattr(run, c) for c in base}
            declared.update({c: declared[c] * (1 + e) for c, e in err.items()})
            vals = [declared[c] for c in base] + [abs(declared[c]) * r for c, r in tol.items()]
            w.writerow(vals)
    with open(
        folder.parent / f"{folder.name}_rig_truth.csv", "w", encoding="utf-8", newline=""
    ) as fh:
        rows = [asdict(r) for r in runs]
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return folder

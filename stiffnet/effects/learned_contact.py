r"""A contact law learned from the recordings (:mod:`stiffnet.discovery`), as an effect.

The law is a sparse combination of the discovery's candidate terms, each with
its coefficient, in the model's units (docs/simulator.md) and *per unit beta*::

    F_c = max(0, beta * shape(delta, v)),   delta = x - e > 0,   else 0

    shape = d_r ((delta + delta_0) / d_r)**p          elastic leading term (p = 1: linear)
          + (r - 1) * max(delta - delta_k, 0)         second stage beyond the knee delta_k
          + alpha * d_r (delta / d_r)**p * v          Hunt-Crossley dissipation
    plus  2 zeta_c sqrt(beta) v                       Kelvin-Voigt dissipation

``delta_0`` (``preload``) is the restraint's compression before first touch: the force
jumps to ``beta d_r (delta_0 / d_r)**p`` at touch (``beta delta_0`` for a linear law) and
the leading term carries on from there, as a spring set against its stop does. For
``p = 1`` it is a force step ``beta delta_0`` added to the shape; for a power law the step
alone would bend the law's curve away from a preloaded spring's (``(delta + delta_0)**p``,
not ``delta**p + delta_0**p``).

A restraint with its own dynamics (``face_mass`` ``mu > 0``): the law acts on the
penetration of a face that recoils, ``delta = x - e - y``, ``v -> v - y'``, the
face a mass on its support (one mode, the library's ``restraint_mass`` physics)::

    mu y'' + 2 zeta_f sqrt(kappa mu) y' + kappa y = F_c

with ``kappa`` (``face_stiffness``) and ``zeta_f`` (``face_damping``) shared by the
rigs (absolute, in the model's units: the face is the rig's, the contact the
rock's). A face with a second mode (``face2_mass`` ``mu_2 > 0``; a beam's tip, whose
bending modes act in parallel there) adds two more states, the mode driven by the same
force, and the law acts on ``delta = x - e - y - y_2``::

    mu_2 y_2'' + 2 zeta_2 sqrt(kappa_2 mu_2) y_2' + kappa_2 y_2 = F_c

(``face2_stiffness``, ``face2_damping``); ``face2_mass: 0`` is no second mode, and a law
without one runs with the one-mode face's two states, as before. Beta is then the
contact's own stiffness, in series with the face's support: the static stiffness is
``beta kappa / (beta + kappa)``.

A face that scales with beta (``face_stiffness_ratio`` ``r > 0``; the paper's rig, where the
beam is the material and every recording has its own): the restraint is the material, so
its support and modal mass are each recording's own, set by its beta::

    kappa = r beta,   mu = face_mass (beta / beta_ref)**q,   contact: beta r / (r - 1)

(``face_mass_exponent`` q, ``face_reference_beta`` beta_ref). Beta is then the
restraint's static stiffness at the contact, the contact in series with the support
(``1 / (r - 1) beta r + 1 / r beta = 1 / beta``): for a beam struck through a contact
much stiffer than it (``r`` near 1), its static tip stiffness. A campaign's manifest may
label another quantity (the beam's own tip stiffness, without the contact in front): the
law's beta is then ``s`` times the row's (``face_beta_scale``, 1 unless
``diagnose``'s simulation fitted it), in every one of the three. The face's two states carry
a third, the row's beta held constant (the face's derivative needs it and
:meth:`LearnedContact.state_derivative` is not given the batch).

**What beta means** for such a law (docs/crosscheck.md, "beta for a nonlinear
law"): the coefficient of the leading elastic term. For a law whose leading
term is linear (``p = 1``) that is the elastic slope at first contact,
``dF/d delta (0+) = beta``, whatever the stages, dissipation and preload
beyond; for a power law (``p != 1``, whose slope at first touch is 0 or
infinite) it is the secant stiffness at the reference penetration ``d_r``,
``F(d_r) / d_r = beta`` (the convention of ``hertz_contact``). The discovery,
this effect and a dataset generated with it all use this one definition, so
the models' labels, the learned law and the restoring-force reading report the
same quantity.

Every parameter is a plain number in the simulator config's YAML (readable,
hand-editable); the neutral values (``exponent`` 1, ``knee_ratio`` 1, the rest
0) give the paper's linear restraint. The Hunt-Crossley term needs the
numerical engine's ``contact_dissipation`` hook, a damping that depends on the
penetration; onset and release are located exactly (``G = min(delta, F_c)``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
from pydantic import model_validator

from stiffnet.effects.base import DynamicsEffect, EffectParams, ParamArrays, ParamValue, param
from stiffnet.effects.fit_space import FitParam, FitSpace

#: Parameter names of the law, in the order the equation is written.
LAW_PARAMS = (
    "exponent",
    "reference_penetration",
    "knee",
    "knee_ratio",
    "preload",
    "hunt_crossley",
    "damping_ratio",
    "face_mass",
    "face_stiffness",
    "face_damping",
    "face2_mass",
    "face2_stiffness",
    "face2_damping",
    "face_stiffness_ratio",
    "face_mass_exponent",
    "face_reference_beta",
)
#: "Effect off": the paper's linear restraint.
NEUTRAL = {"exponent": 1.0, "knee_ratio": 1.0, "preload": 0.0, "hunt_crossley": 0.0,
           "damping_ratio": 0.0, "face_mass": 0.0, "face2_mass": 0.0,
           "face_stiffness_ratio": 0.0, "face_beta_scale": 1.0}  # fmt: skip


def scaled_face(beta: Any, p: Mapping[str, Any]) -> tuple[Any, Any, Any]:
    """A face that scales with beta (``face_stiffness_ratio`` ``r > 0``, see the module notes):
    the contact's own stiffness, the face's support stiffness and its mass for the row's
    ``beta``, ``(b r / (r - 1), r b, face_mass (b / beta_ref)**q)`` with the law's beta
    ``b = s beta`` (``face_beta_scale`` s); where ``r`` is 0 (an absolute face, or none)
    ``(beta, face_stiffness, face_mass)``."""
    r = np.asarray(p["face_stiffness_ratio"], float)
    on = r > 0
    beta = np.asarray(beta, float) * np.where(on, np.asarray(p["face_beta_scale"], float), 1.0)
    rs = np.where(on, r, 2.0)  # any ratio above 1 where off: no division by zero
    contact = np.where(on, beta * rs / (rs - 1.0), beta)
    kappa = np.where(on, rs * beta, p["face_stiffness"])
    ratio = beta / np.asarray(p["face_reference_beta"], float)
    mass = np.asarray(p["face_mass"], float) * np.where(on, ratio ** np.asarray(
        p["face_mass_exponent"], float), 1.0)  # fmt: skip
    return contact, kappa, mass


def leading_term(delta: np.ndarray, exponent: Any, reference_penetration: Any) -> np.ndarray:
    """``d_r (delta / d_r)**p`` for ``delta >= 0`` (exactly ``delta`` when ``p = 1``)."""
    d = np.maximum(delta, 0.0)
    dr = np.asarray(reference_penetration, float)
    p = np.asarray(exponent, float)
    # The numerical engine calls this several times per RK4 substep on a few rows, where
    # the power and the selection cost more than the rest of the right-hand side; a law
    # linear on every row (the usual two-stage one) needs neither: the same numbers.
    if p.shape in ((), d.shape) and dr.shape in ((), d.shape) and not np.any(p != 1.0):
        return d
    return np.where(p == 1.0, d, dr * (d / dr) ** p)


def stage_slope(p: Mapping[str, Any]) -> np.ndarray:
    """``r - 1``: the second stage's slope per unit beta beyond the knee."""
    return np.asarray(p["knee_ratio"], float) - 1.0


def hunt_crossley_gain(p: Mapping[str, Any], beta: Any) -> np.ndarray:
    """``beta alpha``: the Hunt-Crossley force per unit ``d_r (delta / d_r)**p delta'``."""
    return np.asarray(beta, float) * np.asarray(p["hunt_crossley"], float)


def mode_coefficients(
    mass: Any, stiffness: Any, damping: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One mode of the face: ``(has, m, c)``, whether the row has the mode (its mass > 0),
    the mass it divides by (1 where it has none) and its support's damping
    ``2 zeta sqrt(kappa m)``."""
    mu = np.asarray(mass, float)
    has = mu > 0
    m = np.where(has, mu, 1.0)
    return has, m, 2.0 * damping * np.sqrt(stiffness * m)


def law_coefficients(
    p: Mapping[str, Any], beta: Any, scaled: bool = False
) -> dict[str, np.ndarray]:
    """The law's per-row coefficients as its hooks compute them, for a compiled right-hand
    side (:mod:`stiffnet.simulator.rk4_kernel`): the contact's own stiffness (beta, or a
    scaled face's ``beta r / (r - 1)``, :func:`scaled_face`), the knee, the stage slope
    (:func:`stage_slope`), the preload, the Hunt-Crossley gain (:func:`hunt_crossley_gain`)
    and each face mode's ``has, m, c`` (:func:`mode_coefficients`) with its stiffness
    (``face_*`` and ``face2_*``), and whether the first mode's rate moves the face
    (``face_on``: its declared mass > 0, as :meth:`LearnedContact.restraint_rate` reads it).
    With ``scaled`` (the law's face scales with beta, :attr:`LearnedContact.scaled`) the first
    mode's support and mass are the rows' own, :func:`scaled_face` of ``beta``."""
    contact, kappa, mass = scaled_face(beta, p)
    out = {
        "contact": contact,
        "knee": np.asarray(p["knee"], float),
        "stage_slope": stage_slope(p),
        "preload": np.asarray(p["preload"], float),
        "hunt_crossley_gain": hunt_crossley_gain(p, contact),
        "face_on": np.asarray(p["face_mass"], float) > 0,
    }
    for mode in ("face", "face2"):
        stiffness, m_raw = p[f"{mode}_stiffness"], p[f"{mode}_mass"]
        if scaled and mode == "face":
            stiffness, m_raw = kappa, mass
        has, m, c = mode_coefficients(m_raw, stiffness, p[f"{mode}_damping"])
        out.update({f"{mode}_has": has, f"{mode}_m": m, f"{mode}_c": c,
                    f"{mode}_stiffness": np.asarray(stiffness, float)})  # fmt: skip
    return out


def linear_leading_term(p: Mapping[str, Any]) -> bool:
    """Whether the law's leading term is linear (``p = 1``) on every row."""
    return not np.any(np.asarray(p["exponent"], float) != 1.0)


def elastic_shape(delta: np.ndarray, p: dict[str, Any]) -> np.ndarray:
    """The elastic part of ``shape`` (per unit beta) for penetrations ``delta >= 0``."""
    d = np.maximum(delta, 0.0)
    lead = leading_term(d, p["exponent"], p["reference_penetration"])
    stage = stage_slope(p) * np.maximum(d - p["knee"], 0.0)
    preload = np.asarray(p["preload"], float)
    # without a preload on any row its term is zeros: skipped (see leading_term)
    if preload.shape in ((), d.shape) and not np.any(preload):
        return lead + stage
    # a linear law's preload is a step added last, in the compiled right-hand side's order
    # (stiffnet.simulator.rk4_kernel: the same numbers)
    linear = lead + stage + np.where(d > 0, preload, 0.0)
    if linear_leading_term(p):
        return linear
    # a power law carries on from the restraint's compression before touch
    expo = np.asarray(p["exponent"], float)
    compressed = leading_term(d + preload, expo, p["reference_penetration"])
    return np.where(expo == 1.0, linear, np.where(d > 0, compressed, 0.0) + stage)


def learned_contact_force(
    delta: np.ndarray, vel: np.ndarray, beta: Any, p: dict[str, Any]
) -> np.ndarray:
    """The contact force of the law, ``max(0, beta shape + c_c v)`` in contact, else 0.

    Parameters
    ----------
    delta, vel : numpy.ndarray
        Penetration ``x - e`` and its rate (model units); the force is 0 where ``delta <= 0``.
    beta : float or numpy.ndarray
        The law's beta (see the module notes), broadcast against ``delta``.
    p : dict
        The law's parameters (:data:`LAW_PARAMS`), numbers or arrays broadcast against ``delta``.

    Returns
    -------
    numpy.ndarray
        Contact force (model units), never negative (the restraint pushes, never pulls).
    """
    beta = np.asarray(beta, float)
    lead = leading_term(delta, p["exponent"], p["reference_penetration"])
    force = beta * (elastic_shape(delta, p) + p["hunt_crossley"] * lead * vel)
    force = force + 2.0 * np.asarray(p["damping_ratio"], float) * np.sqrt(beta) * vel
    return np.where(delta > 0, np.maximum(force, 0.0), 0.0)


#: A refit from a discovered face searches its mass and stiffness within this factor of the
#: discovered values (the discovery reads them within 15 %; the box leaves room for more).
FACE_REFIT_FACTOR = 1.5
#: A refit from a scaled face searches its mass exponent within this much of the discovered
#: one (the maps read a beam's -1/3 as -0.73 where its modes alias into the force).
MASS_EXPONENT_REACH = 0.5


def _around(cls: Any, name: str, value: float, factor: float) -> FitParam:
    """A log-scale coordinate from ``value / factor`` to ``value * factor``, within the
    parameter's declared range."""
    extra = cls.Params.model_fields[name].json_schema_extra
    low = max(value / factor, float(extra["ge"]), 1e-6)
    return FitParam(name, low, min(value * factor, float(extra["le"])), log=True)


def _mode_derivative(
    s: np.ndarray, contact_force: np.ndarray, mass: Any, stiffness: Any, damping: Any
) -> np.ndarray:
    """``(y', y'')`` of one mode of the face pushed by the contact force, (B, 2); rows whose
    mode has no mass stay at rest."""
    has, m, c = mode_coefficients(mass, stiffness, damping)
    y, w = s[:, 0], s[:, 1]
    out = np.empty_like(s)
    out[:, 0] = np.where(has, w, 0.0)
    out[:, 1] = np.where(has, (contact_force - stiffness * y - c * w) / m, 0.0)
    return out


class LearnedContact(DynamicsEffect):
    """A contact law discovered from a campaign (see the module notes for the equation)."""

    name = "learned_contact"
    neutral: ClassVar[dict[str, float] | None] = dict(NEUTRAL)

    class Params(EffectParams):
        exponent: ParamValue = param(1.0, 0.5, 4.0, "exponent p of the leading elastic term")
        reference_penetration: ParamValue = param(
            0.5, 1e-3, 10.0, "d_r: the power law's secant stiffness is beta there", "model length"
        )
        knee: ParamValue = param(
            0.1, 0.0, 10.0, "penetration where the second stage begins", "model length"
        )
        knee_ratio: ParamValue = param(
            1.0, 0.05, 50.0, "stiffness added beyond the knee, as (ratio - 1) beta"
        )
        preload: ParamValue = param(
            0.0, -1.0, 1.0, "delta_0: compression before first touch", "model length"
        )
        hunt_crossley: ParamValue = param(
            0.0, 0.0, 20.0, "alpha: Hunt-Crossley dissipation beta alpha d_r (d/d_r)^p v",
            "model time / length",
        )  # fmt: skip
        damping_ratio: ParamValue = param(
            0.0, 0.0, 1.0, "Kelvin-Voigt damping ratio, c_c = 2 zeta_c sqrt(beta)"
        )
        face_mass: ParamValue = param(
            0.0, 0.0, 10.0, "mu: mass of the restraint's face over the mass m (0: no face)"
        )
        face_stiffness: ParamValue = param(
            100.0, 0.1, 1e4, "kappa: the face's support stiffness over the primary spring"
        )
        face_damping: ParamValue = param(0.05, 0.0, 2.0, "damping ratio of the face's support")
        face2_mass: ParamValue = param(
            0.0, 0.0, 10.0, "mu_2: the face's second mode's mass over the mass m (0: none)"
        )
        face2_stiffness: ParamValue = param(
            1000.0, 0.1, 1e5, "kappa_2: the second mode's stiffness over the primary spring"
        )
        face2_damping: ParamValue = param(0.05, 0.0, 2.0, "damping ratio of the second mode")
        face_stiffness_ratio: ParamValue = param(
            0.0, 0.0, 100.0,
            "r: a face that scales with beta, support r beta, contact beta r / (r - 1) "
            "(0: the face is absolute, face_stiffness; above 1 when used)",
        )  # fmt: skip
        face_mass_exponent: ParamValue = param(
            0.0, -1.0, 1.0, "q: a scaled face's mass face_mass (beta / beta_ref)^q"
        )
        face_reference_beta: ParamValue = param(
            30.0, 0.1, 1e4, "beta_ref: the beta at which a scaled face's mass is face_mass"
        )
        face_beta_scale: ParamValue = param(
            1.0, 0.1, 10.0, "s: a scaled face's beta over the row's (the manifest's): s beta"
        )

        @model_validator(mode="after")
        def _ratio_above_one(self) -> LearnedContact.Params:
            r = np.asarray(self.face_stiffness_ratio, float)
            if np.any((r > 0) & (r <= 1.0)):
                raise ValueError(
                    "face_stiffness_ratio must be 0 (no scaled face) or above 1 (the contact "
                    "in series with the support is beta)"
                )
            return self

    #: The shape of the law (exponent, second stage, Hunt-Crossley dissipation) when fitted by
    #: ``diagnose --only learned_contact``; d_r, preload and the Kelvin-Voigt damping stay at
    #: their values (the discovery sets all of them from the maps, where they are measured).
    fit_space = FitSpace(
        (
            FitParam("exponent", 0.7, 3.0),
            FitParam("knee", 0.01, 2.0, log=True),
            FitParam("knee_ratio", 0.2, 20.0, log=True),
            FitParam("hunt_crossley", 0.0, 5.0),
        ),
    )

    @classmethod
    def fit_space_at(cls, params: Mapping[str, Any], fs_hz_min: float) -> FitSpace:
        """The space of a refit from a discovered law (``params``): the shape terms the law
        has (its non-neutral ones, within their class ranges), and, when the law has a face,
        the face's mass, stiffness and damping within :data:`FACE_REFIT_FACTOR` of their
        discovered values (the damping, weakly identified, within its square; a scaled
        face's beta scale within the same factor and its mass exponent within
        :data:`MASS_EXPONENT_REACH`); everything
        else held at its value (d_r, the preload, the terms the law lacks). The face's
        ringing frequency ``sqrt(kappa / mu)`` has one basin per mode the impacts can lock
        onto: its stiffness is declared multimodal (swept at the mass held)."""
        full = {**cls().params.model_dump(), **dict(params)}
        shape = [fp for fp in cls.fit_space.free
                 if fp.name == "knee" and full["knee_ratio"] != 1.0
                 or fp.name in NEUTRAL and full[fp.name] != NEUTRAL[fp.name]]  # fmt: skip
        free = list(shape)
        multimodal: tuple[str, ...] = ()
        if float(full["face_mass"]) > 0:
            f = FACE_REFIT_FACTOR
            zeta = max(float(full["face_damping"]), 1e-3)
            free += [
                _around(cls, "face_mass", float(full["face_mass"]), f),
                _around(cls, "face_damping", zeta, f * f),
            ]
            r = float(full["face_stiffness_ratio"])
            if r > 0:  # a scaled face: its support's share of the compliance, 1 - 1/r, around
                free.append(FitParam("face_stiffness_ratio", 1.0 + (r - 1.0) / f,
                                     1.0 + (r - 1.0) * f))  # fmt: skip
                free.append(_around(cls, "face_beta_scale", float(full["face_beta_scale"]), f))
                q = float(full["face_mass_exponent"])
                free.append(FitParam("face_mass_exponent", max(q - MASS_EXPONENT_REACH, -1.0),
                                     min(q + MASS_EXPONENT_REACH, 1.0)))  # fmt: skip
            else:
                free.insert(1, _around(cls, "face_stiffness", float(full["face_stiffness"]), f))
                multimodal = ("face_stiffness",)
        names = {fp.name for fp in free}
        fixed = {k: float(v) for k, v in full.items() if k not in names}
        return FitSpace(tuple(free), fixed, multimodal=multimodal)

    def fastest_rate(self, p: ParamArrays, batch: Any) -> np.ndarray:
        """Upper bound of the contact mode's rate, (B,): the stiffest slope the law reaches up
        to twice ``d_r`` and twice the knee, with both dampings at that penetration."""
        beta, kappa_f, mu = scaled_face(batch.beta, p)  # the contact's own stiffness
        reach = 2.0 * np.maximum(p["reference_penetration"], p["knee"])
        # a preloaded restraint is that much further along its curve
        compressed = reach + np.maximum(np.asarray(p["preload"], float), 0.0)
        slope = np.maximum(p["exponent"], 1.0) * np.maximum(
            (compressed / p["reference_penetration"]) ** (p["exponent"] - 1.0), 1.0
        ) + np.maximum(p["knee_ratio"] - 1.0, 0.0)
        lead = leading_term(reach, p["exponent"], p["reference_penetration"])
        c = 2.0 * p["damping_ratio"] * np.sqrt(beta) + beta * p["hunt_crossley"] * lead
        rate = 0.5 * c + np.sqrt(0.25 * c * c + 1.0 + beta * slope)
        if not np.any(mu > 0):
            return rate
        # the face in contact: its support and the contact's steepest slope on its mass, plus
        # the contact's damping on it (trace bound, as restraint_mass's)
        m = np.where(mu > 0, mu, 1.0)
        k = (kappa_f + beta * slope) / m
        cf = (2.0 * p["face_damping"] * np.sqrt(kappa_f * m) + c) / m
        face = 0.5 * cf + np.sqrt(0.25 * cf * cf + k + 1.0 + beta * slope)
        rate = np.where(mu > 0, np.maximum(rate, face), rate)
        mu2 = np.asarray(p["face2_mass"], float)
        if not np.any(mu2 > 0):
            return rate
        # the second mode in contact, bounded as the first (its support and the contact on it)
        m2 = np.where(mu2 > 0, mu2, 1.0)
        k2 = (p["face2_stiffness"] + beta * slope) / m2
        c2 = (2.0 * p["face2_damping"] * np.sqrt(p["face2_stiffness"] * m2) + c) / m2
        second = 0.5 * c2 + np.sqrt(0.25 * c2 * c2 + k2 + k + 1.0 + beta * slope)
        return np.where(mu2 > 0, np.maximum(rate, second), rate)

    @property
    def _second_mode(self) -> bool:
        """A second mode on some row: its two states after the first mode's."""
        return bool(np.any(np.asarray(self.params.face2_mass, float) > 0))

    @property
    def scaled(self) -> bool:
        """A face that scales with beta on some row: the row's beta held as the last state."""
        return bool(np.any(np.asarray(self.params.face_stiffness_ratio, float) > 0)) and bool(
            np.any(np.asarray(self.params.face_mass, float) > 0)
        )

    @property
    def n_states(self) -> int:  # type: ignore[override]
        """The face's recoil and its rate when the law has a face (any row), two more when
        it has a second mode (any row), one more (the row's beta) when the face scales with
        beta (any row), else none."""
        if not np.any(np.asarray(self.params.face_mass, float) > 0) and not self._second_mode:
            return 0
        return 2 + 2 * self._second_mode + self.scaled

    def initial_states(self, p: ParamArrays, batch: Any) -> np.ndarray:
        """The face at rest, (B, n_states); a scaled face's last state is the row's beta."""
        out = np.zeros((len(batch), self.n_states))
        if self.scaled:
            out[:, -1] = np.asarray(batch.beta, float)
        return out

    def restraint_position(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        """The face's recoil ``y`` (plus the second mode's ``y_2``), (B,) (0 on rows without)."""
        return s[:, 0] + s[:, 2] if self._second_mode else s[:, 0]

    def restraint_rate(self, s: np.ndarray, p: ParamArrays) -> np.ndarray:
        """The recoil's rate ``y'`` (plus ``y_2'``), (B,): the modes' velocity states (0 on
        rows without a mode, as :meth:`state_derivative` holds them)."""
        rate = np.where(np.asarray(p["face_mass"], float) > 0, s[:, 1], 0.0)
        if self._second_mode:
            rate = rate + np.where(np.asarray(p["face2_mass"], float) > 0, s[:, 3], 0.0)
        return rate

    def state_derivative(
        self, t: np.ndarray, s: np.ndarray, contact_force: np.ndarray, p: ParamArrays
    ) -> np.ndarray:
        """``(y', y'')`` of the face pushed by the contact force (and ``(y_2', y_2'')`` of its
        second mode), (B, 2) or (B, 4), and 0 for a scaled face's beta; rows without a mode
        (its mass 0) keep it at rest."""
        out = np.zeros_like(s)
        kappa, mass = p["face_stiffness"], p["face_mass"]
        if self.scaled:
            _, kappa, mass = scaled_face(s[:, -1], p)
        out[:, :2] = _mode_derivative(s[:, :2], contact_force, mass, kappa, p["face_damping"])
        if self._second_mode:
            out[:, 2:4] = _mode_derivative(s[:, 2:4], contact_force, p["face2_mass"],
                                           p["face2_stiffness"], p["face2_damping"])  # fmt: skip
        return out

    @property
    def nonlinear_contact(self) -> bool:
        """True unless every value (or prior range) of the law's nonlinear terms is neutral:
        a face with its own mass and a Kelvin-Voigt dashpot keep the contact linear."""
        params = self.params.model_dump()
        return any(
            np.any(np.asarray(params[k], float) != NEUTRAL[k])
            for k in ("exponent", "knee_ratio", "preload", "hunt_crossley")
        )

    def elastic_contact(self, delta: np.ndarray, p: ParamArrays, batch: Any) -> np.ndarray:
        """The contact's stiffness (beta, or a scaled face's ``beta r / (r - 1)``) times the
        elastic shape, (B,)."""
        return scaled_face(batch.beta, p)[0] * elastic_shape(delta, p)

    def bound_elastic_contact(self, p: ParamArrays, batch: Any) -> Callable[[np.ndarray], Any]:
        """:meth:`elastic_contact` for these rows: where the law is linear on every row and
        has no preload (the usual two-stage law), ``beta (delta + (r - 1) max(delta - k, 0))``
        without deciding so again at each call (the same numbers, fewer numpy calls)."""
        if not linear_leading_term(p) or np.any(np.asarray(p["preload"], float)):
            return super().bound_elastic_contact(p, batch)
        beta = scaled_face(batch.beta, p)[0]
        ratio = stage_slope(p)
        knee = p["knee"]

        def elastic(delta: np.ndarray) -> np.ndarray:
            d = np.maximum(delta, 0.0)
            return beta * (d + ratio * np.maximum(d - knee, 0.0))

        return elastic

    def bound_contact_dissipation(
        self, p: ParamArrays, batch: Any
    ) -> Callable[[np.ndarray, np.ndarray], Any] | None:
        """:meth:`contact_dissipation` for these rows; None without the Hunt-Crossley term on
        any row."""
        if not np.any(np.asarray(p["hunt_crossley"], float)):
            return None
        return super().bound_contact_dissipation(p, batch)

    def contact_damping(self, p: ParamArrays, batch: Any) -> np.ndarray:
        """Kelvin-Voigt coefficient ``2 zeta_c sqrt(beta)``, (B,) (beta the contact's own)."""
        return 2.0 * p["damping_ratio"] * np.sqrt(scaled_face(batch.beta, p)[0])

    def contact_dissipation(
        self, delta: np.ndarray, rate: np.ndarray, p: ParamArrays, batch: Any
    ) -> np.ndarray:
        """Hunt-Crossley force ``beta alpha d_r (delta/d_r)^p delta'``, (B,)."""
        alpha = np.asarray(p["hunt_crossley"], float)
        # a law without the term on any row (the engine calls this hook at every
        # right-hand side, once the law is in the batch): zeros, without the terms' work
        if alpha.shape in ((), np.shape(delta)) and not np.any(alpha):
            return np.zeros(np.shape(delta))
        lead = leading_term(delta, p["exponent"], p["reference_penetration"])
        return hunt_crossley_gain(p, scaled_face(batch.beta, p)[0]) * lead * rate

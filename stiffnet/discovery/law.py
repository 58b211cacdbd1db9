"""A discovered contact law: its terms, coefficients with intervals, equation and words."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from stiffnet.discovery.terms import TERMS

#: A fitted exponent this close to 1 or to Hertz's 3/2 is the library's law.
EXPONENT_TOLERANCE = 0.12
#: Below this explained fraction the law does not describe the contact (a restraint with
#: its own mass: 51 % on mu 0.5, kappa 30, where no candidate term enters).
POOR_FIT = 0.9

WORDS = {
    "linear": "a linear spring",
    "power": "a power-law spring (stiffening or softening with the penetration)",
    "hertz": "a Hertz spring (exponent 3/2)",
    "hinge": "a second stage that stiffens beyond a knee",
    "damping": "viscous (Kelvin-Voigt) dissipation",
    "hunt_crossley": "dissipation growing with the penetration (Hunt-Crossley)",
    "preload": "a preload (the restraint compressed before first touch: a force step there)",
    "face": "a restraint face with its own mass on a support spring (it recoils and rings)",
    "face2": "a second mode of the face (a beam's tip: two modes in parallel, recoils summed)",
    "face_scaled": "a restraint face that is each recording's own (the beam is the material: "
    "its support and mass scale with beta, a stiffer contact in front)",
}


def is_new_term(term: str, params: dict[str, float]) -> bool:
    """Whether a term lies outside the library's laws (linear, Kelvin-Voigt, Hertz)."""
    if term in ("damping", "hertz"):
        return False
    if term == "power":
        p = params["exponent"]
        return min(abs(p - 1.0), abs(p - 1.5)) > EXPONENT_TOLERANCE
    return True


def _mode(y: str, mass: float, stiffness: float, damping: float) -> str:
    """One mode of the face as its equation, ``mu y'' + 2 zeta sqrt(kappa mu) y' + kappa y``."""
    return (f"{mass:.3g} {y}'' + 2 ({damping:.3g}) sqrt({stiffness:.4g} ({mass:.3g})) {y}' "
            f"+ {stiffness:.4g} {y} = F_c")  # fmt: skip


@dataclass(frozen=True)
class DiscoveredLaw:
    """Result of :func:`stiffnet.discovery.discover_contact_law`.

    Attributes
    ----------
    terms : tuple of str
        Terms beyond the linear spring, in the order of :data:`.terms.TERMS`.
    params : dict
        The law as ``learned_contact`` parameters (model units, per unit beta).
    intervals : dict
        Bootstrap intervals (over impacts) of the fitted shared parameters.
    recordings, betas, beta_intervals, onsets : tuple
        Per recording: its name, beta (the law's, docs/crosscheck.md) with its
        interval, contact onset (model length).
    explained_fraction : float
        Fraction of the contact force's variance the law explains (each recording
        weighted alike).
    library_explained_fraction, library_terms, library_params, library_betas, library_onsets :
        The same for the best of the library's laws (linear, Kelvin-Voigt, Hertz),
        with its parameters.
    path : list of dict
        The forward path: every step's term, whether it entered, BIC, held-out
        error and gain, explained fraction.
    new_terms : tuple of str
        Terms outside the library's laws (empty: nothing new).
    n_impacts : int
    coverage : float
    reference : str
        What fixes ``d_r``, the penetration of a power law's secant beta: the campaign's
        median peak penetration, or the manifest's beta (:meth:`referred_to`).
    """

    terms: tuple[str, ...]
    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    recordings: tuple[str, ...]
    betas: tuple[float, ...]
    beta_intervals: tuple[Any, ...]
    onsets: tuple[float, ...]
    explained_fraction: float
    library_explained_fraction: float
    library_terms: tuple[str, ...]
    path: list[dict[str, Any]] = field(default_factory=list)
    new_terms: tuple[str, ...] = ()
    n_impacts: int = 0
    coverage: float = 0.9
    library_params: dict[str, float] = field(default_factory=dict)
    library_betas: tuple[float, ...] = ()
    library_onsets: tuple[float, ...] = ()
    reference: str = "median peak penetration"

    @property
    def new(self) -> bool:
        """Whether the law has terms the library lacks."""
        return bool(self.new_terms)

    @property
    def effect_params(self) -> dict[str, float]:
        """The ``learned_contact`` effect's parameters, rounded to 4 significant digits."""
        return {k: float(f"{v:.4g}") for k, v in self.params.items()}

    def coefficient(self, term: str, beta: float) -> float:
        """A term's coefficient in absolute model units for a recording of this ``beta``."""
        p = self.params
        if term == "power":
            return beta * p["reference_penetration"] ** (1 - p["exponent"])
        if term == "hinge":
            return beta * (p["knee_ratio"] - 1.0)
        if term == "hunt_crossley":
            return beta * p["hunt_crossley"] * p["reference_penetration"] ** (1 - p["exponent"])
        if term == "damping":
            return 2 * p["damping_ratio"] * np.sqrt(beta)
        if term == "preload":  # the force step at first touch
            return beta * p["reference_penetration"] * (
                p["preload"] / p["reference_penetration"]) ** p["exponent"]  # fmt: skip
        if term == "face":
            return p["face_stiffness"]
        if term == "face2":
            return p["face2_stiffness"]
        if term == "face_scaled":
            return beta * p["face_stiffness_ratio"]
        raise KeyError(term)

    def referred_to(self, betas: Sequence[float | None]) -> DiscoveredLaw:
        """The same law with ``d_r`` chosen so that its betas are the given ones.

        A power law's beta is its secant stiffness at ``d_r`` (docs/crosscheck.md, "Beta
        for a nonlinear contact law"), so it is a convention: a manifest whose beta is
        the secant at another penetration labels the same rig differently, by
        ``(d_r' / d_r)^(p - 1)``. Where the manifest gives beta, the law is referred to
        the manifest's penetration, ``d_r' = d_r s^(1/(p-1))`` with ``s`` the geometric
        mean of manifest over law betas, so the learned law, the datasets generated with
        it (the models' labels) and the campaign's truth are one quantity. The force is
        unchanged: betas, the second stage's ``(r - 1)`` and ``zeta^2`` are rescaled by
        ``1/s``; ``alpha``, the exponent and the preload (a compression, a length) stay. A
        law whose leading term is linear (beta is its slope at first contact, no
        convention) comes back unchanged, as does one without any given beta.

        Parameters
        ----------
        betas : sequence of float or None
            The manifest's beta per recording, in the order of :attr:`recordings`.
        """
        p = self.params
        given = np.array([np.nan if b is None else float(b) for b in betas])
        ok = np.isfinite(given) & (given > 0) & (np.asarray(self.betas) > 0)
        if abs(p["exponent"] - 1.0) < 1e-9 or not ok.any():
            return self
        s = float(np.exp(np.mean(np.log(given[ok] / np.asarray(self.betas)[ok]))))
        dr = float(f"{p['reference_penetration'] * s ** (1.0 / (p['exponent'] - 1.0)):.3g}")
        if not 1e-3 <= dr <= 10.0:  # outside learned_contact's range: keep the campaign's
            return self
        s = (dr / p["reference_penetration"]) ** (p["exponent"] - 1.0)  # d_r as rounded
        scale = {"knee_ratio": lambda v: 1.0 + (v - 1.0) / s,
                 "damping_ratio": lambda v: v / np.sqrt(s)}  # fmt: skip
        params = {k: float(scale[k](v)) if k in scale else v for k, v in p.items()}
        params["reference_penetration"] = dr
        intervals = {
            k: tuple(sorted(float(scale[k](v)) for v in iv)) if k in scale else iv
            for k, iv in self.intervals.items()
        }
        return replace(
            self,
            params=params,
            intervals=intervals,
            betas=tuple(b * s for b in self.betas),
            beta_intervals=tuple(
                None if iv is None else (iv[0] * s, iv[1] * s) for iv in self.beta_intervals
            ),  # fmt: skip
            reference="the manifest's beta",
        )

    def with_preload(self, preload: float) -> DiscoveredLaw:
        """The same law with the restraint compressed by ``preload`` before first touch (a
        preload the campaign's simulation found where the maps do not resolve it,
        :mod:`stiffnet.measurement.preload_by_simulation`): a term outside the library."""
        terms = tuple(t for t in TERMS if t in self.terms or t == "preload")
        terms += tuple(t for t in self.terms if t not in TERMS)
        new = tuple(t for t in terms if t in self.new_terms or t == "preload")
        return replace(self, terms=terms, new_terms=new,
                       params={**self.params, "preload": float(preload)})  # fmt: skip

    @property
    def equation(self) -> str:
        """The law per unit beta, as an equation with its numbers."""
        p = self.params
        expo = p["exponent"]
        dr = p["reference_penetration"]
        lead = "delta" if expo == 1.0 else f"{dr:.3g} (delta/{dr:.3g})^{expo:.3g}"
        parts = [lead]
        if "preload" in self.terms:  # the restraint's compression before first touch
            pre = f"delta + {p['preload']:.3g}"
            parts = [pre if expo == 1.0 else f"{dr:.3g} (({pre})/{dr:.3g})^{expo:.3g}"]
        if "hinge" in self.terms:
            parts.append(f"{p['knee_ratio'] - 1:.3g} max(delta - {p['knee']:.3g}, 0)")
        if "hunt_crossley" in self.terms:
            parts.append(f"{p['hunt_crossley']:.3g} [{lead}] v")
        eq = "F_c = max(0, beta [" + " + ".join(parts) + "]"
        if "damping" in self.terms:
            eq += f" + 2 ({p['damping_ratio']:.3g}) sqrt(beta) v"
        if "face_scaled" in self.terms:
            r = p["face_stiffness_ratio"]
            return eq.replace("beta [", f"{r / (r - 1):.4g} beta [", 1) + (
                f")  for delta = x - e - y > 0, v = x' - y'; the face, each recording's own: "
                f"mu y'' + 2 ({p['face_damping']:.3g}) sqrt({r:.4g} beta mu) y' + {r:.4g} beta y "
                f"= F_c, mu = {p['face_mass']:.3g} (beta/{p['face_reference_beta']:.3g})^"
                f"{p['face_mass_exponent']:.3g} (beta: the contact in series with the support"
                + _beta_scale_words(p)
                + ")"
            )
        if "face2" in self.terms:
            return eq + (
                ")  for delta = x - e - y - y2 > 0, v = x' - y' - y2'; the face's modes: "
                + _mode("y", p["face_mass"], p["face_stiffness"], p["face_damping"])
                + ", "
                + _mode("y2", p["face2_mass"], p["face2_stiffness"], p["face2_damping"])
            )
        if "face" in self.terms:
            return eq + (
                f")  for delta = x - e - y > 0, v = x' - y'; the face: {p['face_mass']:.3g} y'' "
                f"+ 2 ({p['face_damping']:.3g}) sqrt({p['face_stiffness']:.4g} "
                f"({p['face_mass']:.3g})) y' + {p['face_stiffness']:.4g} y = F_c"
            )
        return eq + ")  for delta = x - e > 0"

    @property
    def words(self) -> str:
        """The law in words."""
        names = ["power" if "power" in self.terms else "linear"]
        names += [t for t in self.terms if t != "power"]
        text = ", ".join(WORDS[n] for n in names)
        new = (
            f"; outside the library: {', '.join(self.new_terms)}"
            if self.new_terms
            else "; nothing outside the library's laws"
        )
        poor = (
            f"; it explains only {self.explained_fraction:.0%}: the contact has dynamics no "
            "candidate term describes (a restraint with its own mass or modes?)"
            if self.poorly_explained
            else ""
        )
        return (
            f"{text} (explains {self.explained_fraction:.1%} of the contact force; the "
            f"library's best law {self.library_explained_fraction:.1%}){new}{poor}"
        )

    @property
    def poorly_explained(self) -> bool:
        """Whether the law leaves more than ``1 - POOR_FIT`` of the contact force unexplained."""
        return bool(self.explained_fraction < POOR_FIT)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "terms": list(self.terms),
            "new_terms": list(self.new_terms),
            "new": self.new,
            "poorly_explained": self.poorly_explained,
            "equation": self.equation,
            "words": self.words,
            "params": self.effect_params,
            "intervals": {k: list(v) for k, v in self.intervals.items()},
            "coverage": self.coverage,
            "explained_fraction": self.explained_fraction,
            "library_explained_fraction": self.library_explained_fraction,
            "library_terms": list(self.library_terms),
            "path": [
                {k: (float(v) if isinstance(v, np.floating) else v) for k, v in s.items()}
                for s in self.path
            ],
            "n_impacts": self.n_impacts,
            "beta_reference": self.reference,
            "per_recording": [
                {"recording": n, "beta": b, "beta_interval": list(iv) if iv else None, "onset": e}
                for n, b, iv, e in zip(
                    self.recordings, self.betas, self.beta_intervals, self.onsets, strict=True
                )
            ],  # fmt: skip
        }


def _beta_scale_words(p: dict[str, float]) -> str:
    """A scaled face's beta over the manifest's, where the simulation fitted it (not 1)."""
    scale = float(p.get("face_beta_scale", 1.0))
    return "" if scale == 1.0 else f", {scale:.3g} of the manifest's beta where it gives one"

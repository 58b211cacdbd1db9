"""The high-pass corner's share of beta's interval, where the corner is the record's own.

A charge amplifier's high-pass that no data sheet gives is profiled on the record
(:func:`~.estimate._profiled_corner`): the corner whose map lets the contact law explain
the most of the contact force. Behind a mount and with a damped contact that profile is
flat: on the independent rig (1 Hz high-pass, 237 Hz mount, Kelvin-Voigt contact zeta
0.25) the contact law's misfit moves by 10-30 % between 0.4 and 1.4 Hz, where beta moves by
10-20 %, and the corner read spans 0-2.1 Hz for 1 Hz. The bootstrap over impacts holds the
corner fixed, so the interval left out what the corner's choice moves.

The corners the record cannot exclude are those whose contact law misfits by no more than
an F test allows: ``SSE_c / SSE_min <= 1 + chi2_1(coverage) / n_eff`` with ``n_eff`` the
impacts over :attr:`CornerProfileSettings.impacts_per_error` (the misfit's errors are
shared within an impact, and the refits between corners move the onset and the samples in
contact, so the profile is rougher than independent samples would make it). Beta's interval
is the union of the intervals at those corners (:func:`corner_readings` gives their readings;
each interval is as wide in log beta as the read corner's): the interval of a nuisance
parameter's profile, with the bootstrap's and the systematic terms at each of its values.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import stats

#: The shipped settings (``configs/corner_profile.yaml``), relative to the package.
SETTINGS_CONFIG = "corner_profile.yaml"


class CornerProfileSettings(BaseModel):
    """Settings of the corner's share of the interval (``configs/corner_profile.yaml``)."""

    model_config = ConfigDict(extra="forbid")

    #: Whether the interval spans the readings at the corners the record cannot exclude.
    enabled: bool = True
    #: Impacts per independent error of the contact law's misfit (``n_eff = n / this``).
    impacts_per_error: float = Field(default=1.0, gt=0.0)


@lru_cache(maxsize=1)
def corner_profile_settings() -> CornerProfileSettings:
    """The shipped settings: ``configs/corner_profile.yaml``, else the defaults above."""
    from stiffnet.config import shipped_settings

    return shipped_settings(CornerProfileSettings, SETTINGS_CONFIG)


def corner_readings(
    profile: list[tuple[float, float]],
    n_impacts: int,
    coverage: float,
    settings: CornerProfileSettings | None = None,
) -> list[float]:
    """Beta at every corner of `profile` the record cannot exclude at `coverage`.

    Parameters
    ----------
    profile : list of (float, float)
        ``(1 - R2, beta)`` of the contact law at each corner profiled (the map read among
        them): the misfit share and the reading.
    n_impacts : int
        Impacts the contact law was fitted on.
    coverage : float
        Nominal coverage of beta's interval.
    settings : CornerProfileSettings, optional
        Default: the shipped ones (:func:`corner_profile_settings`).

    Returns
    -------
    list of float
        The readings whose misfit is within the F test's bound of the least (empty when
        disabled, with fewer than two corners or no impacts).
    """
    s = corner_profile_settings() if settings is None else settings
    good = [(e, b) for e, b in profile if np.isfinite(e) and np.isfinite(b) and b > 0 and e >= 0]
    if not s.enabled or len(good) < 2 or n_impacts < 1:
        return []
    least = min(e for e, _ in good)
    n_eff = max(n_impacts / s.impacts_per_error, 1.0)
    bound = least * (1.0 + float(stats.chi2.ppf(coverage, 1)) / n_eff)
    return [float(b) for e, b in good if e <= bound]

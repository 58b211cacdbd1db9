"""A campaign held in memory: each recording read once, derived results computed once.

:class:`~stiffnet.campaign.manifest.Campaign` reads a recording file at every
access (a campaign can be larger than memory). One diagnosis or loop
iteration, though, goes over the same recordings several times: the
nuisances (forcing frequency, β from the predictor), the measured statistics,
the noise floor, the restoring-force evidence, ``evaluate`` and ``compare``.
:class:`LoadedCampaign` is the same campaign with its recordings kept after
the first read and a memo of what is computed from them (the resolved rows,
the measured statistics, the predictor's result per recording and model), so
``compare``, ``diagnose``, ``evaluate`` and ``loop`` share one object and
read, resolve and predict once. The memo's keys name everything the value
depends on (rows, settings, model file); the recordings never change.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from stiffnet.campaign.manifest import Campaign
from stiffnet.recordings import Recording

T = TypeVar("T")


@dataclass
class LoadedCampaign(Campaign):
    """A :class:`Campaign` whose recordings are read once (see the module notes).

    Attributes
    ----------
    reads : int
        Recording files read so far (each at most once).
    """

    _recordings: dict[int, Recording] = field(default_factory=dict, repr=False)
    _memo: dict[Hashable, Any] = field(default_factory=dict, repr=False)
    reads: int = 0

    @classmethod
    def of(cls, campaign: Campaign) -> LoadedCampaign:
        """The campaign held in memory (itself when it already is)."""
        if isinstance(campaign, LoadedCampaign):
            return campaign
        return cls(campaign.folder, campaign.manifest_path, list(campaign.rows))

    def recording(self, key: int | str) -> Recording:
        """The recording at index ``key`` (or named ``key``), read on first access only."""
        i = key if isinstance(key, int) else self.rows.index(self.row(key))
        if i not in self._recordings:
            self._recordings[i] = super().recording(i)
            self.reads += 1
        return self._recordings[i]

    def memo(self, key: Hashable, compute: Callable[[], T]) -> T:
        """``compute()`` once per ``key`` (which must name all it depends on)."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]


def memo(campaign: Campaign, key: Hashable, compute: Callable[[], T]) -> T:
    """``campaign.memo(key, compute)`` for a :class:`LoadedCampaign`, else ``compute()``."""
    if isinstance(campaign, LoadedCampaign):
        return campaign.memo(key, compute)
    return compute()

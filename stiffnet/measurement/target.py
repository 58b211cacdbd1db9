"""What a fit compares against: a campaign's rows, measured statistics and base model.

:class:`CampaignTarget` holds the rows (with the nuisance parameters as last
estimated, :mod:`stiffnet.measurement.nuisance`), the measured statistics, the
recordings' lengths and the current model's effects, and turns a list of
effects into per-recording discrepancies (one simulated batch,
:func:`stiffnet.campaign.simulate.simulate_rows`, common random numbers).
It is picklable, so a fit can run on a Dask worker.
"""

from __future__ import annotations

import hashlib
import pickle
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from stiffnet.campaign import Campaign, ManifestRow
from stiffnet.campaign.loaded import memo
from stiffnet.campaign.simulate import (
    DEFAULT_SEED,
    FIT_SETTINGS,
    FIT_SETTINGS_NUMERICAL,
    natural_frequency,
    simulate_rows,
)
from stiffnet.campaign.simulate import CampaignSolverSettings as SolverSettings
from stiffnet.effects.base import Effect
from stiffnet.effects.registry import effect_class
from stiffnet.errors import SignalError, StiffnetError
from stiffnet.measurement.discrepancy import normalised_differences, recording_discrepancy
from stiffnet.measurement.statistics import (
    SignalStatistics,
    batch_signal_statistics,
    signal_statistics,
)

#: The identified chain's entries that seed ``sensor_dynamics`` (its parameter names).
SENSOR_STAGES = ("resonance_hz", "resonance_damping", "lowpass_hz", "lowpass_order", "highpass_hz")

#: Discrepancy scored by a recording whose simulation cannot be analysed.
FAILED_DISCREPANCY = 100.0
#: At most this many per-recording results are kept by a target (:attr:`CampaignTarget.known`).
MEMO_ENTRIES = 4096


def needs_numerical(name: str) -> bool:
    """True when the effect switches the simulator to the numerical engine."""
    cls = effect_class(name)
    return cls.kind == "dynamics" and not cls().closed_form


def settings_for(names: Sequence[str]) -> SolverSettings:
    """Solver settings for a model holding these effects (numerical engine: short records)."""
    return FIT_SETTINGS_NUMERICAL if any(needs_numerical(n) for n in names) else FIT_SETTINGS


@dataclass
class CampaignTarget:
    """Rows, measured statistics, lengths and base effects of a campaign (see module notes)."""

    rows: list[ManifestRow]
    measured: list[SignalStatistics]
    lengths: list[int]
    base_effects: list[Effect] = field(default_factory=list)
    seed: int = DEFAULT_SEED
    inclination: bool = True
    #: Initial-state variant per row (multistable orbits; profiled as a nuisance).
    starts: list[int] | None = None
    #: Per-recording weights of the objective (non-repeatable recordings weigh less;
    #: :meth:`stiffnet.measurement.noise_floor.Floors.weights`); None: equal.
    weights: list[float] | None = None
    #: The campaign's shared sensor chain identified from its contact pulses
    #: (:func:`stiffnet.restoring_force.chain.shared_chain`: ``resonance_hz``,
    #: ``resonance_damping``, ``lowpass_hz``, ``lowpass_order``, ``highpass_hz``; None for a
    #: stage not seen); None: not identified. A fit starts from it (:meth:`observed`).
    sensor: dict[str, Any] | None = None
    #: The shaker's harmonics read off the free flights
    #: (:func:`stiffnet.measurement.forcing_lines.campaign_forcing_lines`: ``second``,
    #: ``phase_second``, ``third``, ``phase_third``); None: not read. Seeds their fit.
    forcing: dict[str, float] | None = None
    #: Per-recording discrepancies already computed, by a digest of everything they depend on
    #: (:meth:`memo_key`). A diagnosis asks for the same model again and again: each
    #: candidate's fit scores "effect off", the nuisances' fine grid holds the coarse grid's
    #: best point, a joint refit starts from the conditional fit. Not shared by
    #: :meth:`subset` or :func:`dataclasses.replace`; travels with the target to a worker.
    known: dict[bytes, np.ndarray] = field(
        default_factory=dict, init=False, repr=False, compare=False
    )

    def memo_key(
        self,
        effects: Sequence[Effect],
        settings: SolverSettings,
        rows: Sequence[ManifestRow],
        starts: Sequence[int] | None,
        inclination: bool,
        oversample: bool,
    ) -> bytes | None:
        """A digest of what :meth:`per_recording` depends on besides the measured statistics
        (the target's own): rows (values), effects (class and values), lengths, seed,
        settings, starts, statistics and oversampling; None when an effect cannot be pickled
        (its result is then never reused)."""
        h = hashlib.blake2b(digest_size=20)
        for r in rows:
            h.update(r.model_dump_json().encode())
        try:
            for e in effects:
                cls = type(e)
                extra = {k: v for k, v in vars(e).items() if k != "params"}
                h.update(f"|{cls.__module__}.{cls.__qualname__}|".encode())
                h.update(e.params.model_dump_json().encode())
                h.update(pickle.dumps(extra, protocol=5))
        except Exception:  # noqa: BLE001 - a user effect holding what pickle cannot: no reuse
            return None
        starts_ = None if starts is None else [int(k) for k in starts]
        h.update(
            repr(
                ([int(n) for n in self.lengths], int(self.seed), starts_, inclination, oversample)
            ).encode()
        )
        h.update(settings.model_dump_json().encode())
        return h.digest()

    def simulated_statistics(
        self,
        effects: Sequence[Effect],
        settings: SolverSettings,
        rows: Sequence[ManifestRow] | None = None,
        starts: Sequence[int] | None = None,
        inclination: bool | None = None,
        oversample: bool = True,
    ) -> list[SignalStatistics | None]:
        """Statistics of the campaign simulated with ``effects`` (one batch; ``inclination``:
        override the target's choice, e.g. False while a fit searches; ``oversample``: see
        :func:`~stiffnet.campaign.simulate.simulate_rows`)."""
        rows, starts = self._rows_and_starts(rows, starts)
        sims = simulate_rows(
            rows, effects, self.lengths, self.seed, settings, starts, oversample=oversample
        )
        return self._statistics(sims, rows, inclination)

    def _statistics(
        self, sims: Sequence[np.ndarray], rows: Sequence[ManifestRow], inclination: bool | None
    ) -> list[SignalStatistics | None]:
        incl = self._inclination(inclination)
        return batch_signal_statistics(
            sims,
            [r.fs_hz for r in rows],
            [natural_frequency(r) for r in rows],
            [r.frequency_ratio for r in rows],
            inclination=incl,
        )

    def discrepancies_of(self, sims: Sequence[SignalStatistics | None]) -> np.ndarray:
        """Per-recording discrepancies of simulated statistics (a failed one scores
        :data:`FAILED_DISCREPANCY`)."""
        out = np.full(len(self.rows), FAILED_DISCREPANCY)
        for i, (m, s) in enumerate(zip(self.measured, sims, strict=True)):
            if s is not None:
                d = recording_discrepancy(normalised_differences(m, s))
                out[i] = d if np.isfinite(d) else FAILED_DISCREPANCY
        return out

    def call_key(
        self,
        effects: Sequence[Effect],
        settings: SolverSettings,
        rows: Sequence[ManifestRow] | None = None,
        starts: Sequence[int] | None = None,
        inclination: bool | None = None,
        oversample: bool = True,
    ) -> bytes | None:
        """The :meth:`memo_key` :meth:`per_recording` files a call with these arguments under
        (the target's own rows, starts and inclination where they are None)."""
        rows_, starts_ = self._rows_and_starts(rows, starts)
        return self.memo_key(
            effects, settings, rows_, starts_, self._inclination(inclination), oversample
        )

    def _rows_and_starts(
        self, rows: Sequence[ManifestRow] | None, starts: Sequence[int] | None
    ) -> tuple[list[ManifestRow], Sequence[int] | None]:
        """A call's rows and starts, the target's own where None."""
        rows_ = self.rows if rows is None else list(rows)
        return rows_, self.starts if starts is None else starts

    def _inclination(self, inclination: bool | None) -> bool:
        """Whether a call computes the inclination statistics: the target's choice, which a
        call may only turn off (e.g. while a fit searches)."""
        return self.inclination if inclination is None else self.inclination and inclination

    def per_recording(
        self,
        effects: Sequence[Effect],
        settings: SolverSettings,
        rows: Sequence[ManifestRow] | None = None,
        starts: Sequence[int] | None = None,
        inclination: bool | None = None,
        oversample: bool = True,
    ) -> np.ndarray:
        """Per-recording discrepancies of the campaign simulated with ``effects``
        (``rows``, ``starts``: other nuisance values than the target's; ``inclination``,
        ``oversample``: see :meth:`simulated_statistics`). Computed once per inputs
        (:attr:`known`)."""
        key = self.call_key(effects, settings, rows, starts, inclination, oversample)
        if key is not None and key in self.known:
            return self.known[key].copy()
        out = self.discrepancies_of(
            self.simulated_statistics(effects, settings, rows, starts, inclination, oversample)
        )
        if key is not None and len(self.known) < MEMO_ENTRIES:
            self.known[key] = out.copy()
        return out

    def per_recording_points(
        self,
        effects: Sequence[Effect],
        name: str,
        points: Sequence[dict[str, float]],
        settings: SolverSettings,
        inclination: bool | None = None,
        oversample: bool = True,
    ) -> list[np.ndarray]:
        """Per-recording discrepancies of ``effects`` plus effect ``name`` at each of ``points``,
        simulated as **one** batch (the campaign's rows once per point).

        For the numerical engine: its cost is per time step, hardly per row, so a
        whole design costs about one evaluation. The first point's rows draw the
        same noise as :meth:`per_recording`; the other points' draw other noise
        (one generator for the batch), so their values carry the scatter of the
        noise floor: a design to pick a point from, to be scored again alone.
        """
        n, k = len(self.rows), len(points)
        if k == 0:
            return []
        cls = effect_class(name)
        first = cls(**points[0])
        rng = np.random.default_rng(0)  # fixed parameters: batch_params draws nothing
        per_point = [cls(**p).batch_params(n, rng) for p in points]
        stacked = {first.name: {key: np.concatenate([pp[key] for pp in per_point])
                                for key in per_point[0]}}  # fmt: skip
        starts = None if self.starts is None else list(self.starts) * k
        sims = simulate_rows(
            self.rows * k, [*effects, first], self.lengths * k, self.seed, settings, starts,
            effect_params=stacked, oversample=oversample,
        )  # fmt: skip
        return [
            self.discrepancies_of(
                self._statistics(sims[j * n : (j + 1) * n], self.rows, inclination)
            )
            for j in range(k)
        ]

    def subset(self, idx: Sequence[int]) -> CampaignTarget:
        """The target restricted to the recordings ``idx`` (same model, seed and nuisances)."""
        idx = [int(i) for i in idx]
        return CampaignTarget(
            [self.rows[i] for i in idx],
            [self.measured[i] for i in idx],
            [self.lengths[i] for i in idx],
            list(self.base_effects),
            self.seed,
            self.inclination,
            None if self.starts is None else [self.starts[i] for i in idx],
            None if self.weights is None else [self.weights[i] for i in idx],
            self.sensor,
            self.forcing,
        )

    def observed(self) -> dict[str, float]:
        """What the measurement shows that seeds a fit: ``ringing_hz``, the median post-impact
        ringing frequency (Hz) of the recordings that ring (ringing above 0.2 decades), and
        the identified chain's stages as ``sensor_<parameter>`` (effect units: Hz, ratio,
        order; a stage the chain lacks is absent) and the shaker's harmonics read off the
        free flights as ``forcing_<parameter>`` (:attr:`forcing`)."""
        f = [
            m.ringing_frequency * m.natural_frequency_hz
            for m in self.measured
            if np.isfinite(m.ringing) and m.ringing > 0.2 and np.isfinite(m.ringing_frequency)
        ]
        out = {"ringing_hz": float(np.median(f))} if f else {}
        for key, value in (self.sensor or {}).items():
            if key in SENSOR_STAGES and value is not None and np.isfinite(value):
                out[f"sensor_{key}"] = float(value)
        for key, value in (self.forcing or {}).items():
            if np.isfinite(value):
                out[f"forcing_{key}"] = float(value)
        return out


def measured_statistics(
    campaign: Campaign,
    rows: Sequence[ManifestRow] | None = None,
    inclination: bool = True,
) -> tuple[list[SignalStatistics], list[int], list[np.ndarray]]:
    """Statistics, lengths and samples of every recording (``rows``: resolved rows; computed
    once per rows and ``inclination`` for a :class:`~stiffnet.campaign.LoadedCampaign`)."""
    rows = list(campaign.rows) if rows is None else list(rows)
    key = ("measured_statistics", inclination, rows_key(rows))
    return memo(campaign, key, lambda: _measured_statistics(campaign, rows, inclination))


def rows_key(rows: Sequence[ManifestRow]) -> tuple:
    """What the measured statistics of ``rows`` depend on (hashable)."""
    return tuple((r.recording, r.fs_hz, natural_frequency(r), r.frequency_ratio) for r in rows)


def _measured_statistics(
    campaign: Campaign, rows: list[ManifestRow], inclination: bool
) -> tuple[list[SignalStatistics], list[int], list[np.ndarray]]:
    stats_, lengths, signals = [], [], []
    for row, (_, rec) in zip(rows, campaign.recordings(), strict=True):
        try:
            stats_.append(
                signal_statistics(
                    rec.accel,
                    rec.fs_hz,
                    natural_frequency(row),
                    row.frequency_ratio,
                    inclination=inclination,
                )
            )
        except SignalError as exc:
            raise StiffnetError(f"{row.recording}: {exc}") from None
        lengths.append(len(rec.accel))
        signals.append(np.asarray(rec.accel, dtype=np.float64))
    return stats_, lengths, signals

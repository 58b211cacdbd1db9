"""Batched fixed-step RK4 integrator with event location, for any dynamics effect.

The closed-form engine (:mod:`stiffnet.simulator.compiled`) is exact but
needs a piecewise-linear model. Effects that override the numerical hooks of
:class:`~stiffnet.effects.base.DynamicsEffect` (a Hertz contact law, a
restraint with its own mass, dry friction, user effects) are integrated here.

The right-hand side composes every hook (see :mod:`stiffnet.effects.base`)::

    x' = v
    v' = F(t) - 2 xi v - x - F_c + sum(extra forces)
    F(t)  = a w^2 sin(w t) + sum(forcing_terms)
    delta = x - e(t) - y_r,   e(t) = e + sum(gap_terms),  y_r = sum(restraint_position)
    F_c   = elastic(delta) + c_c delta' + dissipation(delta, delta')   in contact, else 0
    s'    = state_derivative(t, s, F_c)   (extra states, e.g. a restraint's DOF)

with ``elastic`` the (single) effect's ``elastic_contact`` or ``beta delta`` and
``c_c`` the sum of ``contact_damping``.

Integration is classical RK4 with ``substeps`` fixed substeps per sample, the
whole batch marching together, each row with its own step. Inside a substep
the region (free / contact) and the effects' discrete modes are frozen, so the
right-hand side is smooth there. Switching functions are checked at the end of
every substep:

* contact: ``G = min(delta, F_c)`` (as in the closed form): the mass is in
  contact exactly when ``G > 0``; with contact damping the restraint lets go
  when its force would turn into a pull;
* each effect's ``event_function``: **the current mode holds while it is
  positive**; the event fires when it reaches ``<= 0`` and ``next_mode`` gives
  the new mode.

A sign change inside a substep is located by a safeguarded secant (Illinois)
iteration on RK4 partial steps of length ``s`` from the substep's start (a
smooth function of ``s``), for the rows that need it only; the region or mode
is switched there and the substep is finished from the event with a fresh RK4
step. A contact that begins and ends inside one substep (grazing) is found from
the interior extremum of the penetration; a double sign change of an effect's
event function inside one substep is not looked for (substeps are short).
Without contact damping the root is located on ``delta`` itself, which has
G's sign but no kink at the root (the secant would crawl on ``min``). Across
the nonsmooth points this
keeps the global error at RK4's fourth order, as long as the force law itself
is smooth on either side (see :class:`~stiffnet.effects.hertz_contact.HertzContact`
for one that is not).

Conventions the hooks rely on:

* ``elastic_contact`` receives ``max(delta, 0)``; the default ``beta delta`` is
  used unclipped, its smooth extension past the release point;
* ``other``, passed to ``extra_force`` of effect *i*, is the sum of the base
  forces (forcing, spring, damper, contact) and the extra forces of the effects
  listed before it; to ``event_function`` and ``next_mode`` it is the total
  minus the effect's own force. Put an effect that balances ``other`` (sticking
  friction) last;
* the rate of the restraint position is the effect's ``restraint_rate``, or where it
  gives none ``restraint_position(s + s'_0) - restraint_position(s)`` with ``s'_0`` the
  state derivative under zero contact force: exact when the position is affine
  in the states and its rate does not depend on the force (a mechanical DOF);
* discrete modes start at 0; rows whose event function is ``<= 0`` at ``t = 0``
  get ``next_mode`` first.

Stability: ``substeps`` is a minimum. RK4 is stable for ``|lambda| h < 2.8``;
the engine takes more substeps where the fastest rate of the linearised system
times the substep would exceed ``_MAX_RATE_STEP`` (the contact mode
``sqrt(1 + beta)`` with its damping, and an effect's optional
``fastest_rate(p, batch)``: an upper bound of its rates, (B,) in rad per model
time, e.g. a light restraint's ringing). A run that still diverges raises
:class:`~stiffnet.errors.ConfigError`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from stiffnet.effects.base import DynamicsEffect, ParamArrays, Sinusoids
from stiffnet.errors import ConfigError
from stiffnet.simulator.batch import OscillatorBatch
from stiffnet.simulator.events import (  # noqa: F401  (_illinois: tests reach it here)
    _brackets,
    _finish,
    _first_roots,
    _illinois,
    _Partial,
    _switch,
)
from stiffnet.simulator.result import EngineResult
from stiffnet.simulator.rk4 import _dense_states, _rk4, _rk4_dense
from stiffnet.simulator.rk4_kernel import (
    kernel_form,
    kernel_pack,
    rhs_full,
    rk4_step,
    secant_rows,
    substep,
)

_MAX_EVENTS_PER_SUBSTEP = 8
_MAX_RATE_STEP = 1.0  # fastest rate x substep: RK4 stable (< 2.8) and the mode resolved
_CHECK_EVERY = 64  # steps between divergence checks
#: Take the RK4 steps in the compiled kernel where the model's effects allow
#: (:mod:`.rk4_kernel`; bitwise the same states). False: numpy's path for every model
#: (the kernel's tests and benchmark compare the two).
COMPILED_STEP = True


def _overrides(effect: DynamicsEffect, hook: str) -> bool:
    return getattr(type(effect), hook) is not getattr(DynamicsEffect, hook)


class _Sines:
    """A :class:`~stiffnet.effects.base.Sinusoids` evaluated many times per substep: the same
    values, without the general sum's overhead where it holds one sinusoid (the forcing
    alone) or none (the gap of most models); the engine's Python overhead per call is most
    of its cost on batches of a few rows (event location marches one or two rows)."""

    def __init__(self, sines: Sinusoids) -> None:
        self.sines = sines
        self.n_terms = sines.amp.shape[1]
        if self.n_terms == 1:
            self.amp = np.ascontiguousarray(sines.amp[:, 0])
            self.freq = np.ascontiguousarray(sines.freq[:, 0])
            self.phase = np.ascontiguousarray(sines.phase[:, 0])

    def value(self, t: np.ndarray) -> np.ndarray:
        """Value at times ``t`` (B,), as ``Sinusoids.value``."""
        if self.n_terms == 1:
            return self.amp * np.sin(self.freq * t + self.phase)
        s = self.sines
        return (s.amp * np.sin(s.freq * t[:, None] + s.phase)).sum(axis=1)

    def rate(self, t: np.ndarray) -> np.ndarray:
        """Time derivative at times ``t`` (B,), as ``Sinusoids.rate``."""
        if self.n_terms == 1:
            return self.amp * self.freq * np.cos(self.freq * t + self.phase)
        s = self.sines
        return (s.amp * s.freq * np.cos(s.freq * t[:, None] + s.phase)).sum(axis=1)


def _batch_subset(batch: OscillatorBatch, idx: np.ndarray) -> OscillatorBatch:
    """Rows ``idx`` of a batch already validated (``OscillatorBatch.subset`` checks every
    field again, a cost paid at every located event)."""
    out = object.__new__(OscillatorBatch)
    for f in dataclasses.fields(batch):
        value = getattr(batch, f.name)
        setattr(out, f.name, None if value is None else value[idx])
    return out


class _Model:
    """The composed right-hand side for a set of rows (the batch, or a subset)."""

    def __init__(
        self, batch: OscillatorBatch, effects: list[DynamicsEffect], params: list[ParamArrays]
    ) -> None:
        if len(params) != len(effects):
            raise ConfigError(f"{len(effects)} effects but {len(params)} parameter dicts")
        n = len(batch)
        forcing = Sinusoids(batch.forcing_scale[:, None], batch.omega[:, None], np.zeros((n, 1)))
        gap = Sinusoids.empty(n)
        cc = np.zeros(n)
        for eff, p in zip(effects, params, strict=True):
            f = eff.forcing_terms(p, batch)
            forcing = forcing if f is None else forcing + f
            g = eff.gap_terms(p, batch)
            gap = gap if g is None else gap + g
            c = eff.contact_damping(p, batch)
            cc = cc if c is None else cc + np.asarray(c, float)
        self._setup(batch, effects, params, forcing, gap, cc)

    def _setup(
        self,
        batch: OscillatorBatch,
        effects: list[DynamicsEffect],
        params: list[ParamArrays],
        forcing: Sinusoids,
        gap: Sinusoids,
        cc: np.ndarray,
    ) -> None:
        self.effects = effects
        elastic = [k for k, e in enumerate(effects) if _overrides(e, "elastic_contact")]
        if len(elastic) > 1:
            names = ", ".join(effects[k].name for k in elastic)
            raise ConfigError(f"only one effect may set the elastic contact law, got {names}")
        self.elastic = elastic[0] if elastic else None
        self.dissipative = [
            k for k, e in enumerate(effects) if _overrides(e, "contact_dissipation")
        ]
        self.force_fx = [k for k, e in enumerate(effects) if _overrides(e, "extra_force")]
        self.event_fx = [k for k, e in enumerate(effects) if _overrides(e, "event_function")]
        # the event functions whose rate the effect gives (Newton steps for their events)
        self.rated_fx = [
            j for j, k in enumerate(self.event_fx) if _overrides(effects[k], "event_rate")
        ]
        self.slices: list[tuple[int, slice]] = []
        i = 2
        for k, e in enumerate(effects):
            if e.n_states:
                self.slices.append((k, slice(i, i + e.n_states)))
                i += e.n_states
        self.n_y = i
        self.restraints = [
            (k, sl) for k, sl in self.slices if _overrides(effects[k], "restraint_position")
        ]
        self._set_rows(batch, params, forcing, gap, cc)
        self.kernel = kernel_form(effects, params, forcing, gap) if COMPILED_STEP else None
        self._pack = (
            None
            if self.kernel is None
            else kernel_pack(self.kernel, effects, params, batch, forcing, gap, cc)
        )

    def _set_rows(
        self,
        batch: OscillatorBatch,
        params: list[ParamArrays],
        forcing: Sinusoids,
        gap: Sinusoids,
        cc: np.ndarray,
    ) -> None:
        """The per-row part of the model (the rest depends on the effects alone)."""
        self.batch, self.params = batch, params
        self.forcing, self.gap, self.cc = forcing, gap, cc
        self._forcing, self._gap = _Sines(forcing), _Sines(gap)
        self.n = len(batch)
        self.xi2, self.beta, self.e0 = 2.0 * batch.damping, batch.beta, batch.gap
        self.has_gap = gap.amp.shape[1] > 0 and bool(np.any(gap.amp != 0))
        self.has_cc = bool(np.any(cc != 0))
        self.zero = np.zeros(self.n)
        self._hooks: tuple[Any, list[Any]] | None = None  # bound by numpy's path, when used

    def _bound_hooks(self) -> tuple[Any, list[Any]]:
        """The contact law's hooks bound to these rows' parameters (elastic law or None,
        dissipations), once per set of rows: numpy's right-hand side runs hundreds of
        thousands of times. Bound on first use, not in :meth:`_set_rows`: a subset is made
        at every event, and a model the compiled kernel steps never calls them."""
        if self._hooks is None:
            k, batch, params = self.elastic, self.batch, self.params
            elastic = None if k is None else self.effects[k].bound_elastic_contact(params[k], batch)
            bound = [self.effects[k].bound_contact_dissipation(params[k], batch)
                     for k in self.dissipative]  # fmt: skip
            self._hooks = (elastic, [f for f in bound if f is not None])
        return self._hooks

    def subset(self, idx: np.ndarray) -> _Model:
        """The same model restricted to rows ``idx`` (hooks are not called again)."""
        new = object.__new__(_Model)
        # the effects' hook lists and state layout do not depend on the rows: copied, not
        # derived again (a subset is made at every event)
        new.__dict__.update(self.__dict__)
        new._set_rows(
            _batch_subset(self.batch, idx),
            [{k: v[idx] for k, v in p.items()} for p in self.params],
            self.forcing.subset(idx),
            self.gap.subset(idx),
            self.cc[idx],
        )
        if self._pack is not None:
            new._pack = self._pack[idx]
        return new

    def rk4_stages(
        self,
        t: np.ndarray,
        y: np.ndarray,
        k1: np.ndarray,
        s: np.ndarray,
        contact: np.ndarray,
        modes: np.ndarray,
    ) -> tuple[np.ndarray, tuple[np.ndarray, ...]]:
        """An RK4 step and its stages by the compiled kernel (:func:`.rk4_kernel.rk4_step`),
        for a model whose :attr:`kernel` is set."""
        return rk4_step(
            self.kernel, self._pack, self.has_gap, self.has_cc, t, y, k1, s, contact, modes
        )

    def kernel_substep(
        self,
        t: np.ndarray,
        y: np.ndarray,
        k1: np.ndarray,
        s: np.ndarray,
        t1: np.ndarray,
        contact: np.ndarray,
        modes: np.ndarray,
        aux0: dict[str, np.ndarray],
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray]:
        """A substep of the march by the compiled kernel (:func:`.rk4_kernel.substep`: the
        state, its right-hand side and ``aux`` at ``t1``, the rows to resolve), for a model
        whose :attr:`kernel` is set."""
        return substep(
            self.kernel, self._pack, self.has_gap, self.has_cc, len(self.effects), t, y, k1,
            s, t1, contact, modes, aux0,
        )  # fmt: skip

    def kernel_secant(
        self,
        start: tuple[np.ndarray, ...],
        root: str | int,
        bracket: tuple[np.ndarray, ...],
        iters: int,
        tiny: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The event locator's secant on the rows' RK4 partial steps by the compiled kernel
        (:func:`.rk4_kernel.secant_rows`), for a model whose :attr:`kernel` is set."""
        return secant_rows(
            self.kernel, self._pack, self.has_gap, self.has_cc, len(self.effects), start,
            root, bracket, iters, tiny,
        )  # fmt: skip

    def initial_state(self, x0: np.ndarray, v0: np.ndarray) -> np.ndarray:
        y = np.zeros((self.n, self.n_y))
        y[:, 0], y[:, 1] = x0, v0
        for k, sl in self.slices:
            y[:, sl] = self.effects[k].initial_states(self.params[k], self.batch)
        return y

    def rate_bound(self) -> np.ndarray:
        """Upper bound of the linearised system's fastest rate per row, (B,)."""
        c = self.xi2 + self.cc
        k = 1.0 + self.beta
        rate = 0.5 * c + np.sqrt(0.25 * c * c + k)
        for eff, p in zip(self.effects, self.params, strict=True):
            fastest = getattr(eff, "fastest_rate", None)
            if fastest is not None:
                rate = np.maximum(rate, fastest(p, self.batch))
        return rate

    def forcing_at(self, t: np.ndarray) -> np.ndarray:
        return self._forcing.value(t)

    def reads_state(self, key: str) -> bool:
        """Whether ``aux[key]`` is a function of time and state alone (:meth:`state_value`):
        the penetration rate, and the contact's root function where it is the penetration
        (no contact damping, no penetration-dependent dissipation), without a moving
        restraint (whose position needs its effect's hooks)."""
        if self.restraints:
            return False
        if key == "dd":
            return True
        return key == "Gr" and not self.has_cc and not self.dissipative

    def root_on_penetration(self) -> np.ndarray:
        """Per row (B,), whether the contact's root function ``aux["Gr"]`` is the penetration
        ``delta`` in both regions, whose rate ``aux["dd"]`` the right-hand side also gives
        (the event locator's Newton steps, :func:`~stiffnet.simulator.events._newton`): no
        contact damping on the row and no penetration-dependent dissipation."""
        if self.dissipative:
            return np.zeros(self.n, dtype=bool)
        return self.cc == 0 if self.has_cc else np.ones(self.n, dtype=bool)

    def state_value(self, t: np.ndarray, y: np.ndarray, key: str) -> np.ndarray:
        """``aux[key]`` of :meth:`rhs` at ``(t, y)`` without the forces (bitwise the same
        numbers), for a ``key`` where :meth:`reads_state` holds. The root finder evaluates
        only this function, 4-6 times per event; the right-hand side's forces are not
        needed for it."""
        if key == "dd":
            return y[:, 1] - self._gap.rate(t) if self.has_gap else y[:, 1]
        e = self.e0 + self._gap.value(t) if self.has_gap else self.e0
        return y[:, 0] - e

    def event_rates(
        self, t: np.ndarray, y: np.ndarray, dy: np.ndarray, aux: dict, modes: np.ndarray
    ) -> np.ndarray:
        """The event functions' rates at states ``y`` with right-hand side ``dy`` and ``aux``
        (:meth:`rhs`), (B, n_event_effects): an effect's :meth:`event_rate` where it gives
        one, NaN elsewhere (those events keep the secant)."""
        out = np.full((y.shape[0], len(self.event_fx)), np.nan)
        for j in self.rated_fx:
            k = self.event_fx[j]
            r = self.effects[k].event_rate(
                t, y[:, 0], y[:, 1], dy[:, 1], aux["other"][:, k], modes[k], self.params[k]
            )
            if r is not None:
                out[:, j] = r
        return out

    def rhs(
        self,
        t: np.ndarray,
        y: np.ndarray,
        contact: np.ndarray,
        modes: np.ndarray,
        full: bool = False,
        forcing: np.ndarray | None = None,
    ) -> tuple[np.ndarray, dict[str, np.ndarray] | None]:
        """dy/dt, and with ``full`` the switching data (``aux``) at the state.

        ``aux`` holds, per row: ``G`` (contact switching function), ``Gr`` (a
        smooth function with G's sign near its root, for the root finder), ``dd``
        (penetration rate), ``delta``, ``fc`` (contact force, 0 in free flight),
        ``extra`` (sum of extra forces), ``other`` (B, n_effects) and ``g``
        (B, n_event_effects), the effects' event functions.
        """
        if full and forcing is None and self.kernel is not None:  # compiled: the same numbers
            return rhs_full(
                self.kernel, self._pack, self.has_gap, self.has_cc, len(self.effects),
                t, y, contact, modes,
            )  # fmt: skip
        effects, params = self.effects, self.params
        x, v = y[:, 0], y[:, 1]
        f_t = self.forcing_at(t) if forcing is None else forcing
        if self.has_gap:
            e, de = self.e0 + self._gap.value(t), self._gap.rate(t)
        else:
            e, de = self.e0, 0.0
        yr: Any = 0.0
        dyr: Any = 0.0
        for k, sl in self.restraints:
            eff, p, s = effects[k], params[k], y[:, sl]
            r = eff.restraint_position(s, p)
            if r is not None:
                yr = yr + r
                rate = eff.restraint_rate(s, p)
                if rate is None:
                    ds0 = eff.state_derivative(t, s, self.zero, p)
                    rate = eff.restraint_position(s + ds0, p) - r
                dyr = dyr + rate
        delta = x - e - yr
        dd = v - de - dyr
        bound_elastic, dissipations = self._bound_hooks()
        if bound_elastic is None:
            elastic = self.beta * delta
        else:
            elastic = bound_elastic(np.maximum(delta, 0.0))
        fpot = elastic + self.cc * dd if self.has_cc else elastic
        for dissipation in dissipations:  # a damping growing with the penetration
            fpot = fpot + dissipation(np.maximum(delta, 0.0), dd)
        fc = np.where(contact, fpot, 0.0)
        base = f_t - self.xi2 * v - x - fc
        total = base
        own: dict[int, np.ndarray] = {}
        for k in self.force_fx:
            fk = effects[k].extra_force(t, x, v, total, modes[k], params[k])
            if fk is not None:
                own[k] = fk
                total = total + fk
        dy = np.empty_like(y)
        dy[:, 0] = v
        dy[:, 1] = total
        for k, sl in self.slices:
            dy[:, sl] = effects[k].state_derivative(t, y[:, sl], fc, params[k])
        if not full:
            return dy, None
        other = np.empty((self.n, len(effects)))
        for k in range(len(effects)):
            other[:, k] = total - own[k] if k in own else total
        g = np.empty((self.n, len(self.event_fx)))
        for j, k in enumerate(self.event_fx):
            gk = effects[k].event_function(t, x, v, other[:, k], modes[k], params[k])
            g[:, j] = np.inf if gk is None else gk
        g_contact = np.minimum(delta, fpot)
        # G has a kink at its root when F_c is a function of delta alone (no
        # contact damping): the secant then crawls. There delta has G's sign and
        # is smooth, so the root is located on delta instead.
        g_root = np.where(self.cc != 0, g_contact, delta) if self.has_cc else delta
        if self.dissipative:  # the force may reach zero first while the mass leaves
            g_root = np.where(dd < 0, g_contact, delta)
        aux = {
            "G": g_contact,
            "Gr": g_root,
            "dd": dd,
            "delta": delta,
            "fc": np.where(contact, np.maximum(fpot, 0.0), 0.0),
            "extra": total - base,
            "other": other,
            "g": g,
        }
        return dy, aux


class _Stepper:
    """Marches the batch substep by substep, resolving events for the rows that need them."""

    def __init__(
        self, model: _Model, x0: np.ndarray, v0: np.ndarray, t_start: np.ndarray | float = 0.0
    ) -> None:
        self.m = model
        n = model.n
        self.t = np.array(np.broadcast_to(np.asarray(t_start, float), (n,)))
        self.y = model.initial_state(np.asarray(x0, float), np.asarray(v0, float))
        self.modes = np.zeros((len(model.effects), n))
        self.contact = np.zeros(n, dtype=bool)
        _, aux = model.rhs(self.t, self.y, self.contact, self.modes, full=True)
        self.contact = aux["G"] > 0
        for _ in range(3):  # modes inconsistent with the initial state switch first
            _, aux = model.rhs(self.t, self.y, self.contact, self.modes, full=True)
            for j, k in enumerate(model.event_fx):
                bad = aux["g"][:, j] <= 0
                if np.any(bad):
                    new = model.effects[k].next_mode(
                        self.y[:, 0],
                        self.y[:, 1],
                        aux["other"][:, k],
                        self.modes[k],
                        model.params[k],
                    )
                    self.modes[k] = np.where(bad, new, self.modes[k])
        self.f, self.aux = model.rhs(self.t, self.y, self.contact, self.modes, full=True)

    def check_bounded(self) -> None:
        """Raise if a row has blown up (RK4 unstable for a mode faster than the step)."""
        m = self.m
        scale = 1.0 + np.abs(m.e0) + np.sum(np.abs(m.forcing.amp), axis=1) / m.xi2
        bad = ~np.all(np.isfinite(self.y), axis=1) | (np.abs(self.y[:, 0]) > 1e6 * scale)
        if np.any(bad):
            raise ConfigError(
                f"numerical integration diverged for {int(bad.sum())} of {m.n} trajectories "
                "(an effect faster than the step resolves): increase substeps"
            )

    def march(
        self,
        h: np.ndarray,
        n_steps: int,
        substeps: int | np.ndarray,
        out: dict | None,
        row_steps: np.ndarray | None = None,
    ) -> None:
        """``n_steps`` steps of ``h``, each of ``substeps`` RK4 substeps; record into ``out``.

        ``substeps`` is one count for every row or one per row, (B,): the batch marches
        substep by substep together, each row on its own grid of ``h / substeps``, and a
        row records its step when its count of substeps completes one. ``row_steps``
        (B,), optional: the steps a row needs (at most ``n_steps``); the march ends when
        every row has made its own, and a row's later steps stay unwritten. ``out`` holds
        ``(n_steps, B)`` arrays, one row per recorded step.
        """
        m = self.m
        per = np.broadcast_to(np.asarray(substeps, dtype=np.int64), (m.n,))
        need = np.full(m.n, n_steps, np.int64) if row_steps is None else np.asarray(row_steps)
        hs = h / per
        t_start = self.t.copy()
        entries = np.zeros(m.n, dtype=np.int64)
        uniform = bool(np.all(per == per[0]))
        total = int(np.max(need * per)) if m.n else 0
        cols = np.arange(m.n)
        for q in range(1, total + 1):
            # times from the substep count, not by accumulation, so rows stay on their grid
            t1 = t_start + q * hs
            if m.kernel is not None:  # one compiled call, the same numbers
                y1, f1, aux1, sus = m.kernel_substep(
                    self.t, self.y, self.f, hs, t1, self.contact, self.modes, self.aux
                )
            else:
                y1 = _rk4(m, self.t, self.y, self.f, hs, self.contact, self.modes)
                f1, aux1 = m.rhs(t1, y1, self.contact, self.modes, full=True)
                sus = self._suspects(aux1, hs)
            if sus.size:
                trial = (y1[sus], f1[sus], {k: v[sus] for k, v in aux1.items()})
                res = self._resolve(sus, hs[sus], trial)
                y1[sus], f1[sus] = res["y"], res["f"]
                for key, val in res["aux"].items():
                    aux1[key][sus] = val
                self.contact[sus] = res["contact"]
                self.modes[:, sus] = res["modes"]
                entries[sus] += res["entries"]
            self.t, self.y, self.f, self.aux = t1, y1, f1, aux1
            if uniform:
                if q % per[0]:
                    continue
                done = cols
            else:
                done = (q % per == 0).nonzero()[0]
            step = q // per[done] - 1
            keep = step < need[done]
            done, step = done[keep], step[keep]
            if step.size and (step.max() % _CHECK_EVERY == _CHECK_EVERY - 1 or q == total):
                self.check_bounded()
            if out is not None and done.size:
                self._record(out, step, done, entries)
            entries[done] = 0
        if total:
            self.check_bounded()

    def march_dense(self, h: np.ndarray, per_step: np.ndarray, out: dict, need: np.ndarray) -> None:
        """Record ``need[i]`` steps of ``h[i]`` per row, integrating one RK4 substep per
        ``per_step[i]`` of them (B,) and filling the steps in between by dense output.

        For records sampled finer than the motion needs (an analog sensor's oversampled
        chain): the states between substep ends come from the step's own stages
        (:func:`_dense_states`), or, in a substep with an event, from an RK4 partial step
        from the start of the smooth piece that holds them; the acceleration and contact
        force are the right-hand side's at those states. Impacts are counted at the step
        in which the contact begins. The integration is the one :meth:`march` does with
        steps of ``h * per_step`` (bitwise the same states at substep ends).
        """
        m = self.m
        per = np.asarray(per_step, dtype=np.int64)
        need = np.asarray(need, dtype=np.int64)
        hs = h * per
        t_start = self.t.copy()
        # the points between substep ends: row, and fraction of the substep
        rows_d = np.repeat(np.arange(m.n), per - 1)
        j_d = np.arange(rows_d.size) - np.repeat(np.cumsum(per - 1) - (per - 1), per - 1) + 1
        theta_d = j_d / per[rows_d]
        md = m.subset(rows_d) if rows_d.size else None
        total = int(np.max(-(-need // per))) if m.n else 0
        cols = np.arange(m.n)
        for q in range(1, total + 1):
            t0, y0, f0 = self.t, self.y, self.f
            c0, mo0 = self.contact, self.modes
            y1, stages = _rk4_dense(m, t0, y0, f0, hs, c0, mo0)
            t1 = t_start + q * hs
            f1, aux1 = m.rhs(t1, y1, c0, mo0, full=True)
            sus = self._suspects(aux1, hs)
            entry_step = None
            if rows_d.size:
                yd = _dense_states(y0, hs, stages, rows_d, theta_d)
                cd, mod = c0[rows_d], mo0[:, rows_d]
            if sus.size:
                segs: list = []
                trial = (y1[sus], f1[sus], {k: v[sus] for k, v in aux1.items()})
                res = self._resolve(sus, hs[sus], trial, segs)
                y1[sus], f1[sus] = res["y"], res["f"]
                for key, val in res["aux"].items():
                    aux1[key][sus] = val
                self.contact[sus] = res["contact"]
                self.modes[:, sus] = res["modes"]
                entry_step = self._entry_steps(sus, segs, t0, h, per, q)
                if rows_d.size:
                    self._dense_in_events(sus, segs, t0, h, rows_d, j_d, yd, cd, mod)
            self.t, self.y, self.f, self.aux = t1, y1, f1, aux1
            if rows_d.size:
                _, auxd = md.rhs(t0[rows_d] + j_d * h[rows_d], yd, cd, mod, full=True)
                step = (q - 1) * per[rows_d] + j_d - 1
                keep = step < need[rows_d]
                self._record_points(out, step[keep], rows_d[keep], yd[keep], auxd, keep)
            step = q * per - 1
            keep = step < need
            done = cols[keep]
            if done.size:
                self._record_points(out, step[keep], done, y1[done], aux1, done)
            if entry_step is not None:  # a row's last substep may end past its length
                r, k = entry_step
                ok = k < need[r]
                np.add.at(out["impacts"], (k[ok], r[ok]), 1)
            if q % _CHECK_EVERY == 0:
                self.check_bounded()
        if total:
            self.check_bounded()

    def _entry_steps(
        self, sus: np.ndarray, segs: list, t0: np.ndarray, h: np.ndarray, per: np.ndarray, q: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """(row, recorded step) of each contact entry in substep ``q`` of rows ``sus``: a
        smooth piece that begins in contact after one that did not."""
        prev = np.zeros(sus.size, dtype=bool)  # set by the first piece (the substep's start)
        rows, steps = [], []
        for k, (a, t, _, _, c, _) in enumerate(segs):
            if k:
                new = c & ~prev[a]
                j = np.ceil((t[new] - t0[sus[a[new]]]) / h[sus[a[new]]] - 1e-9)
                j = np.clip(j, 1, per[sus[a[new]]]).astype(np.int64)
                rows.append(sus[a[new]])
                steps.append((q - 1) * per[sus[a[new]]] + j - 1)
            prev[a] = c
        if not rows:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(rows), np.concatenate(steps)

    def _dense_in_events(self, sus, segs, t0, h, rows_d, j_d, yd, cd, mod) -> None:
        """Replace the dense points of rows ``sus`` (a substep with an event) by RK4 partial
        steps from the start of the smooth piece that holds each point."""
        pos = np.full(self.m.n, -1)
        pos[sus] = np.arange(sus.size)
        pts = (pos[rows_d] >= 0).nonzero()[0]
        if pts.size == 0:
            return
        local = pos[rows_d[pts]]
        tau = t0[rows_d[pts]] + j_d[pts] * h[rows_d[pts]]
        which = np.full(pts.size, -1)
        at = np.full(pts.size, -1)
        where = np.full(sus.size, -1)
        for k, (a, t, *_) in enumerate(segs):  # passes in time order: the last piece wins
            where[:] = -1
            where[a] = np.arange(a.size)
            w = where[local]
            ok = w >= 0
            ok[ok] = t[w[ok]] <= tau[ok] + 1e-12 * np.abs(tau[ok])
            which[ok], at[ok] = k, w[ok]
        for k, (_a, t, y, f, c, mo) in enumerate(segs):
            sel = (which == k).nonzero()[0]
            if sel.size == 0:
                continue
            i = at[sel]
            ms = self.m.subset(rows_d[pts[sel]])
            s = tau[sel] - t[i]
            yd[pts[sel]] = _rk4(ms, t[i], y[i], f[i], s, c[i], mo[:, i])
            cd[pts[sel]] = c[i]
            mod[:, pts[sel]] = mo[:, i]

    def _record_points(
        self, out: dict, step: np.ndarray, rows: np.ndarray, y: np.ndarray, aux: dict, sel
    ) -> None:
        """Write states ``y`` (one per point) of rows ``rows`` as their step ``step``;
        ``aux[...][sel]`` is the right-hand side's data at those states."""
        x, v, fc = y[:, 0], y[:, 1], aux["fc"][sel]
        out["x"][step, rows], out["v"][step, rows] = x, v
        out["contact_force"][step, rows] = fc
        out["accel"][step, rows] = aux["extra"][sel] - (self.m.xi2[rows] * v + x + fc)

    def _record(self, out: dict, step: np.ndarray, rows: np.ndarray, entries: np.ndarray) -> None:
        """Write rows ``rows``'s state as their step ``step`` into ``out``."""
        m, y, aux = self.m, self.y, self.aux
        x, v = y[rows, 0], y[rows, 1]
        out["x"][step, rows], out["v"][step, rows] = x, v
        out["contact_force"][step, rows] = aux["fc"][rows]
        # absolute acceleration: the real forces on the mass (no base forcing)
        out["accel"][step, rows] = aux["extra"][rows] - (m.xi2[rows] * v + x + aux["fc"][rows])
        out["impacts"][step, rows] = np.minimum(entries[rows], 127)

    def _suspects(self, aux1: dict, hs: np.ndarray) -> np.ndarray:
        """Rows whose contact function or an event function may change sign in the substep."""
        a0 = self.aux
        crossed = (aux1["G"] > 0) != self.contact
        if aux1["g"].shape[1]:
            crossed |= (aux1["g"] <= 0).any(axis=1)
        # A hidden double crossing of the restraint needs an extremum of the
        # penetration inside the substep, close enough to the restraint.
        d0, d1, dd0, dd1 = a0["delta"], aux1["delta"], a0["dd"], aux1["dd"]
        span = (np.abs(dd0) + np.abs(dd1)) * hs
        turn_free = ~self.contact & (dd0 > 0) & (dd1 <= 0) & (np.maximum(d0, d1) + span > 0)
        turn_con = self.contact & (dd0 < 0) & (dd1 >= 0) & (np.minimum(d0, d1) - span < 0)
        return (crossed | turn_free | turn_con).nonzero()[0]

    def _resolve(
        self, idx: np.ndarray, hs: np.ndarray, trial: tuple, segments: list | None = None
    ) -> dict[str, Any]:
        """March rows ``idx`` through their substep, locating and switching at events.

        ``trial``: the full-substep RK4 result ``(y, f, aux)`` of these rows. Each pass
        brackets every switching function's first crossing (:func:`_brackets`), locates
        them (:func:`_first_roots`) and switches at the earliest (:func:`_switch`); rows
        with nothing left to cross finish the substep. ``segments``: a list that gets, per
        pass, where its rows' smooth pieces begin ``(rows (positions in idx), t, y, f,
        contact, modes)``, for :meth:`march_dense`.
        """
        model = self.m.subset(idx)
        st = {
            "t": self.t[idx].copy(), "y": self.y[idx].copy(), "f": self.f[idx].copy(),
            "aux": {k: v[idx].copy() for k, v in self.aux.items()},
            "contact": self.contact[idx].copy(), "modes": self.modes[:, idx].copy(),
            "left": hs.copy(), "entries": np.zeros(idx.size, dtype=np.int64),
        }  # fmt: skip
        active = np.arange(idx.size)
        for it in range(_MAX_EVENTS_PER_SUBSTEP + 1):
            if active.size == 0:
                break
            a = active
            if segments is not None:
                segments.append(
                    (a, st["t"][a].copy(), st["y"][a].copy(), st["f"][a].copy(),
                     st["contact"][a].copy(), st["modes"][:, a].copy())
                )  # fmt: skip
            ma = model if a.size == idx.size else model.subset(a)
            ta, la = st["t"][a], st["left"][a]
            if it == 0:  # nothing has moved yet: the main loop's trial step is this one
                y1, f1, aux1 = trial
            else:
                ca, mo = st["contact"][a], st["modes"][:, a]
                y1 = _rk4(ma, ta, st["y"][a], st["f"][a], la, ca, mo)
                f1, aux1 = ma.rhs(ta + la, y1, ca, mo, full=True)
            if it == _MAX_EVENTS_PER_SUBSTEP:  # chattering: finish without further events
                _finish(st, a, np.ones(a.size, bool), y1, f1, aux1)
                break
            s_hi, g_hi, rate_hi = _brackets(st, ma, a, y1, f1, aux1, hs)
            any_ev = np.isfinite(s_hi).any(axis=1)
            _finish(st, a, ~any_ev, y1, f1, aux1)
            if not any_ev.any():
                break
            ev = any_ev.nonzero()[0]
            s_root, known, y_known = _first_roots(st, ma, a, s_hi, g_hi, hs, rate_hi)
            e_rows = _switch(st, ma, a, ev, (s_root[ev], known[ev], y_known[ev]))
            active = e_rows[st["left"][e_rows] > 0]
        out = {k: st[k] for k in ("y", "f", "aux", "contact", "modes", "entries")}
        return out


def recording_substeps(
    h: np.ndarray, rate: np.ndarray, substeps: int, longest: float = 0.0
) -> np.ndarray:
    """RK4 substeps per sample of each row when rows are sampled at different rates, (B,).

    Rule: the most coarsely sampled row takes ``substeps`` per sample and no row a
    longer substep than that row's (``h_max / substeps``), nor one longer than its
    fastest mode allows (``_MAX_RATE_STEP / rate``): every row is integrated at least
    as finely as the coarsest one asked, and a row sampled ten times finer is not
    integrated ten times finer (its samples are already short steps). ``longest`` > 0
    lets the substep grow to it where ``h_max / substeps`` is shorter (the transient's
    substep, ``SolverSettings.record_substeps``), at least one substep per sample.
    """
    h_sub = max(np.max(h) / substeps, longest)
    return (
        np.maximum(np.ceil(h / h_sub - 1e-9), np.ceil(h * rate / _MAX_RATE_STEP - 1e-9))
        .astype(np.int64)
        .clip(1)
    )


def simulate_numerical(
    batch: OscillatorBatch,
    effects: list[DynamicsEffect],
    params: list[ParamArrays],
    x0: np.ndarray,
    v0: np.ndarray,
    h_transient: np.ndarray,
    n_transient: int,
    h: np.ndarray,
    n_samples: int,
    substeps: int = 8,
    row_samples: np.ndarray | None = None,
    oversampled: int = 1,
    t_start: np.ndarray | float = 0.0,
    record_as_transient: bool = False,
) -> EngineResult:
    """March ``n_transient`` steps of ``h_transient``, then record ``n_samples`` of ``h``.

    Returns the same :class:`~stiffnet.simulator.result.EngineResult` as the
    closed-form engine.

    Parameters
    ----------
    batch : OscillatorBatch
        The B parameter sets of eqs (11)-(12).
    effects : list of DynamicsEffect
        The dynamics effects, composed as described in the module docstring.
    params : list of dict
        ``params[i]``: per-row parameter arrays (B,) of ``effects[i]``
        (from ``effects[i].batch_params``).
    x0, v0 : numpy.ndarray
        Initial relative displacement and velocity, (B,) (extra states start at
        the effects' ``initial_states``).
    h_transient, h : numpy.ndarray
        Per-row step of the transient and of the recorded samples, (B,).
    n_transient, n_samples : int
        Number of transient (not recorded) and recorded steps.
    substeps : int
        RK4 substeps per step (at least; more where a fast mode needs them, see
        the module docstring); the global error falls as ``substeps**-4``.
    row_samples : numpy.ndarray, optional
        The samples each row needs, (B,) (at most ``n_samples``; a row's later samples
        are left at 0): rows sampled at different rates then take
        :func:`recording_substeps` each, so a finely sampled row is not integrated
        ``substeps`` times per sample, and the batch stops when every row has its own.
    oversampled : int
        The samples are this many times finer than the motion needs (an analog sensor's
        chain filters the oversampled signal): the motion is integrated with the substeps
        a record sampled ``oversampled`` times coarser would get (``substeps`` per sample,
        as above), and the samples between substep ends are filled by RK4's dense output
        (:meth:`_Stepper.march_dense`), not integrated one by one.
    t_start : numpy.ndarray or float
        Model time of the initial state, (B,) or scalar (default 0): a transient begun by
        another engine (the closed form's warm start,
        :meth:`~stiffnet.simulator.simulator.Simulator.transient_split`) is continued here
        from its state at that time; the forcing's phase is ``w t`` at absolute time.
    record_as_transient : bool
        Integrate the record (not an oversampled one) with substeps no shorter than the
        transient's finest, ``min(h_transient) / substeps`` (at least one per sample,
        :func:`recording_substeps`' ``longest``), where ``substeps`` per sample would be
        finer (:class:`~stiffnet.simulator.settings.SolverSettings`' ``record_substeps``).

    Returns
    -------
    EngineResult
        ``x``, ``v``, ``accel`` (absolute acceleration of the mass: the spring,
        damper, contact and extra forces), ``contact_force`` (all (B, n_samples)),
        ``impacts`` (int8, contact entries during the step that ends at each
        sample) and ``t0`` (B,), the time of the first sample.

    Raises
    ------
    ConfigError
        Two effects set the contact law, ``substeps < 1``, non-positive steps, or
        the integration diverged.
    """
    if substeps < 1:
        raise ConfigError(f"substeps must be >= 1, got {substeps}")
    model = _Model(batch, list(effects), list(params))
    n = model.n
    h = np.broadcast_to(np.asarray(h, float), (n,)).copy()
    h_transient = np.broadcast_to(np.asarray(h_transient, float), (n,)).copy()
    if np.any(h <= 0) or (n_transient > 0 and np.any(h_transient <= 0)):
        raise ConfigError("steps h and h_transient must be positive")
    x0 = np.broadcast_to(np.asarray(x0, float), (n,))
    v0 = np.broadcast_to(np.asarray(v0, float), (n,))
    rate = model.rate_bound()

    def n_sub(step: np.ndarray) -> int:
        return max(substeps, int(np.ceil(np.max(step * rate) / _MAX_RATE_STEP)))

    st = _Stepper(model, x0, v0, t_start)
    if n_transient > 0:
        st.march(h_transient, n_transient, n_sub(h_transient), None)
    # (N, B) while recording: each sample writes one contiguous row
    alloc = np.empty if row_samples is None else np.zeros
    out: dict[str, np.ndarray] = {
        k: alloc((n_samples, n)) for k in ("x", "v", "accel", "contact_force")
    }
    out["impacts"] = np.zeros((n_samples, n), dtype=np.int8)
    t0 = st.t + h
    need = np.minimum(
        np.broadcast_to(np.asarray(n_samples if row_samples is None else row_samples), (n,)),
        n_samples,
    ).astype(np.int64)
    if oversampled > 1:
        coarse = h * oversampled
        per_coarse = (
            np.full(n, n_sub(coarse), np.int64)
            if row_samples is None
            else recording_substeps(coarse, rate, substeps)
        )
        per_step = oversampled // per_coarse  # samples per RK4 substep
        if np.all(per_step >= 1):
            st.march_dense(h, per_step, out, need)
            return EngineResult(t0=t0, **{k: v.T for k, v in out.items()})
        # a mode too fast for a substep of even one sample: integrate every sample
        substeps = -(-substeps // oversampled)
    longest = 0.0
    if record_as_transient and n_transient > 0:
        longest = float(np.min(h_transient)) / n_sub(h_transient)
    if row_samples is None and not longest:
        st.march(h, n_samples, n_sub(h), out)
    else:
        st.march(h, n_samples, recording_substeps(h, rate, substeps, longest), out, need)
    return EngineResult(t0=t0, **{k: v.T for k, v in out.items()})  # (B, N) views

"""Data-driven evidence beside diagnose's simulation fits: the restoring-force map's contact law.

The restoring-force estimate (:mod:`stiffnet.restoring_force`) fits each
recording's contact law directly on its force-displacement map, with no
simulation: the **loop area** of the map is the contact's dissipation (its
damping ratio ``zeta_c``; a restitution ``e = exp(-pi zeta_c / sqrt(1 - zeta_c**2))``)
and its **curvature** is stiffening (the exponent ``p``: 1 linear, 1.5 Hertz).
Summarised over a campaign, they say which contact effects the data themselves
show, independently of the simulation fits that ``diagnose`` ranks
(``contact_damping``, ``hertz_contact``). One estimate per recording, as parallel
tasks on diagnose's workers (:func:`stiffnet.distributed.tasks.run_tasks`).

A campaign has one accelerometer, so its sensor chain is fitted
(:func:`~stiffnet.restoring_force.chain.fit_chain`) on
:data:`CHAIN_RECORDINGS` recordings spread over the campaign (as many more while they
share no stage), and the chain they share
(:func:`~stiffnet.restoring_force.chain.shared_chain`) is undone on the others as a
data sheet would be. On the diagnosis bench's campaign (24 recordings x 6 s at 2 kHz,
one process, a shared machine at load 6-8) a recording whose chain is fitted cost 3.1-4.1 s
of CPU (the chain, and the high-pass corner profiled by the contact law), one read through
the shared chain 0.05-0.6 s (median 0.14 s): the three fitted recordings are three quarters
of the evidence's ~14 s. The shared chain is also undone
on the fitted recordings themselves: where it reads them about as well as their own chains
do (the median R² it loses there is at most :data:`CHAIN_CONFIRMED_SHORTFALL`), it is the
campaign's chain, and a recording it leaves poorly explained is hard to read whatever chain
is undone (a contact too fast for the map) and is not fitted again; where it does not, the
shared chain is not the campaign's, and such a recording has its own chain fitted. The
evidence says so (``chain_fitted_on``, ``chain_shortfall``). A row with its own data sheet
is read with it; where the fitted recordings share no chain stage, every recording is
fitted.

Whether the shared chain is a sensor's at all is the contact-law discovery's question, and
its rule decides it here too
(:func:`~stiffnet.discovery.chain_choice.shared_chain_verdict`): each recording is also read
as recorded, and where the shared chain, undone on every recording, makes the contact force
clearly less a function of the state than their own readings (a fitted recording's own
chain, the others as recorded) and fewer than half of them kept a chain, it is refuted and
every recording is read as recorded (``chain_refuted``; the chains still seed
``sensor_dynamics`` as before, fitted and not undone). A stiffening contact reads as a
low-pass whose corner follows it, and its inverse sharpens the pulse into a linear one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stiffnet.campaign import Campaign, ManifestRow, sensor_gain
from stiffnet.discovery.chain_choice import shared_and_own_unexplained, shared_chain_verdict
from stiffnet.discovery.samples import chain_outcome, result_samples
from stiffnet.errors import StiffnetError
from stiffnet.restoring_force import restoring_force_estimate
from stiffnet.restoring_force.chain import (
    CHAIN_CONFIRMED_SHORTFALL,
    SENSOR_KEYS,
    shared_chain,
    shared_chain_sheet,
    shared_chain_shortfall,
)

#: Forcing periods read per recording (the predictor's cross-check reads as many).
PERIODS = 24.0
#: A median contact damping ratio above this is dissipation worth naming (restitution < 0.86).
DISSIPATION_ZETA = 0.05
#: A median exponent above this is stiffening worth naming (Hertz is 1.5).
STIFFENING_EXPONENT = 1.15
#: Evidence needs the contact law of at least this many recordings.
MIN_ANSWERED = 2
#: Recordings whose sensor chain is fitted; the others are read through the chain they share.
#: Three: the shared chain's median then outvotes one recording's odd stage.
CHAIN_RECORDINGS = 3
#: A recording read through the shared chain whose contact law explains less than this (or
#: that is refused) has its own chain fitted, unless the chain is confirmed
#: (:data:`CHAIN_CONFIRMED_SHORTFALL`): a chain undone as a data sheet is never rejected,
#: where a fitted one is when the record as recorded reads better.
SHARED_CHAIN_MIN_R2 = 0.9
#: The third item of :func:`_contact_law_task` that reads a record as recorded (no chain).
AS_RECORDED = "as recorded"


def restitution(zeta: float) -> float:
    """Restitution coefficient of a linear Kelvin-Voigt contact of damping ratio ``zeta`` (< 1)."""
    return float(np.exp(-np.pi * zeta / np.sqrt(1.0 - zeta**2))) if zeta < 1 else 0.0


def contact_law_per_recording(
    campaign: Campaign,
    rows: list[ManifestRow],
    client: Any = None,
    chain_recordings: int | None = CHAIN_RECORDINGS,
) -> list[dict[str, Any]]:
    """The restoring-force contact law of each recording (or why there is none).

    ``rows`` are diagnose's resolved rows (natural frequency and forcing ratio
    filled in where the manifest had none). ``client``: a Dask client whose workers
    read the recordings in parallel (in-process without one); the results do not
    depend on where they ran. ``chain_recordings``: the sensor chain is fitted on
    that many recordings (spread over the rows without a data sheet; that many more
    while they share no stage) and the chain they share is undone on the others (their
    ``chain_shared`` is True, ``chain_shortfall`` the median R² the shared chain loses on
    the fitted recordings), except where the law then explains less than
    :data:`SHARED_CHAIN_MIN_R2` and the shared chain is not confirmed on the fitted
    recordings (:data:`CHAIN_CONFIRMED_SHORTFALL`; fitted there too); None, or no more rows
    than that: fitted on every recording.
    """
    sheets = [row.sensor_sheet() for row in rows]
    fit = [i for i, sheet in enumerate(sheets) if sheet is None]
    found: dict[int, dict[str, Any]] = {}
    rest: list[int] = []
    left, sheet = list(fit), None
    # rounds of `chain_recordings` until the fitted chains share a stage (a fast contact
    # or a rejected chain shows none), the rest read through it
    while chain_recordings and sheet is None and len(left) > chain_recordings > 0:
        found |= _read(campaign, rows, [(i, None) for i in _spread(left, chain_recordings)],
                       client)  # fmt: skip
        left = [i for i in left if i not in found]
        sheet = shared_chain_sheet(
            shared_chain([found[i].get("sensor") for i in fit if i in found])
        )
    if sheet is not None:
        rest = left
        sheets = [sheet if i in rest else s for i, s in enumerate(sheets)]
    fitted = [i for i in fit if i in found]
    jobs = [(i, sheets[i]) for i in range(len(rows)) if i not in found]
    # the shared chain undone on the recordings it was fitted on too: is it theirs?
    checks = [(i, sheet) for i in fitted] if rest else []
    read = _read(campaign, rows, jobs + checks, client, keyed=False)
    found |= {i: r for (i, _), r in zip(jobs, read[: len(jobs)], strict=True)}
    if rest:
        through = {i: r for (i, _), r in zip(checks, read[len(jobs) :], strict=True)}
        refuted = _refuted_chain(campaign, rows, found, through, fitted, rest, client)
        if refuted is not None:
            return refuted
    shortfall = shared_chain_shortfall([found[i] for i, _ in checks], read[len(jobs) :])
    # where the shared chain is not the campaign's, a recording it reads poorly gets its own
    poor = [i for i in rest if (found[i].get("contact_r2") or 0.0) < SHARED_CHAIN_MIN_R2]
    if shortfall is not None and shortfall <= CHAIN_CONFIRMED_SHORTFALL:
        poor = []
    found |= _read(campaign, rows, [(i, None) for i in poor], client)
    rest = [i for i in rest if i not in poor]
    for i in rest:
        found[i]["chain_shared"] = True
        found[i]["chain_fitted_on"] = [rows[j].recording for j in sorted(set(fit) - set(rest))]
        found[i]["chain_shortfall"] = shortfall
    return [_public(found[i]) for i in range(len(rows))]


def _refuted_chain(
    campaign: Campaign,
    rows: list[ManifestRow],
    found: dict[int, dict[str, Any]],
    through: dict[int, dict[str, Any]],
    fitted: list[int],
    rest: list[int],
    client: Any,
) -> list[dict[str, Any]] | None:
    """Every recording read as recorded where the discovery's rule refutes the shared chain
    (:func:`~stiffnet.discovery.chain_choice.shared_chain_verdict`), else None.

    The rule compares each record's own reading (a fitted record's chain as its fit kept it,
    the others as recorded: their chain was never asked for) with its reading through the
    shared chain (``through`` on the fitted records, ``found`` on the rest). Behind a 250 Hz
    low-pass, a power-law contact (exponent 1.6) fitted 135, 131 and 209 Hz low-passes on its
    three records and the shared 135 Hz, undone on all, read the contact as linear
    (exponent 1.09, where the discovery, which refutes it, read 1.71).
    """
    plain = _read(campaign, rows, [(i, AS_RECORDED) for i in rest], client)
    order = fitted + rest
    own = [found[i] if i in fitted else plain[i] for i in order]
    shared = [through[i] if i in fitted else found[i] for i in order]
    keeping = sum(bool(found[i].get("_kept")) for i in fitted)
    answered = sum("_samples" in p for p in own)
    samples = [[p.get("_samples") for p in own], [p.get("_samples") for p in shared]]
    if shared_chain_verdict(*samples, keeping, answered) != "recorded":
        return None
    unexplained = shared_and_own_unexplained(*samples)
    sheet = next((p["sensor"] for p in shared if p.get("sensor")), {})
    plain |= _read(campaign, rows, [(i, AS_RECORDED) for i in fitted], client)
    note = {
        "fitted_on": [rows[i].recording for i in fitted],
        "chain": {k: sheet.get(k) for k in SENSOR_KEYS},
        "unexplained_own": unexplained[0] if unexplained else None,
        "unexplained_shared": unexplained[1] if unexplained else None,
    }
    for i in order:
        plain[i]["chain_refuted"] = note
    # sensor_dynamics' start is still the chain identified, fitted and not undone (as the
    # discovery reports a rejected chain), one vote per recording as before: a start, not a
    # reading. On an independent-rig campaign behind a 260 Hz mount, the three fits read the
    # mount's resonance with a 133 Hz low-pass the rig lacks; the pair is refuted as a reading,
    # the resonance still seeds the fit
    for i in order:
        if found[i].get("sensor"):
            plain[i]["sensor"] = {**found[i]["sensor"], "applied": False}
    return [_public(plain[i] if i in plain else found[i]) for i in range(len(rows))]


def _public(reading: dict[str, Any]) -> dict[str, Any]:
    """A recording's evidence without what only the chain's rule reads (its samples)."""
    return {k: v for k, v in reading.items() if not k.startswith("_")}


def _spread(indices: list[int], n: int) -> list[int]:
    """`n` of `indices` evenly spread (first and last included)."""
    picks = {indices[round(j * (len(indices) - 1) / max(n - 1, 1))] for j in range(n)}
    return sorted(picks)


def _read(
    campaign: Campaign,
    rows: list[ManifestRow],
    jobs: list[tuple[int, dict[str, float] | None]],
    client: Any,
    keyed: bool = True,
) -> Any:
    """:func:`_contact_law_task` of each ``(row index, sheet)`` of `jobs`, as one batch of
    tasks: by row index (``keyed``) or as a list in the jobs' order."""
    from stiffnet.distributed.tasks import run_tasks

    if not jobs:
        return {} if keyed else []
    items = [(campaign.recording(i), rows[i], sheet) for i, sheet in jobs]
    report = run_tasks(_contact_law_task, items, client=client,
                       names=[rows[i].recording for i, _ in jobs])  # fmt: skip
    report.raise_failures()
    if keyed:
        return dict(zip([i for i, _ in jobs], report.results, strict=True))
    return list(report.results)


def _contact_law_task(
    item: tuple[Any, ManifestRow, dict[str, float] | str | None],
) -> dict[str, Any]:
    """One recording's restoring-force estimate as evidence (a picklable task); the third
    item is the data sheet undone (None: the chain is fitted; :data:`AS_RECORDED`: none is):
    the row's own, or else the campaign's shared chain, fitted to its recordings
    (``sensor_fitted``). The private ``_samples`` (its force-state samples) and ``_kept``
    (a fitted chain kept) are what the chain's rule reads (:func:`_refuted_chain`)."""
    rec, row, sheet = item
    fn = row.natural_frequency_hz
    ff = fn * row.frequency_ratio if fn and row.frequency_ratio else None
    recorded = isinstance(sheet, str)
    options = (
        {"chain_fit_below_r2": -np.inf}
        if recorded
        else {"sensor": sheet, "sensor_fitted": sheet is not None and sheet != row.sensor_sheet()}
    )
    try:
        r = restoring_force_estimate(
            rec.accel, rec.fs_hz, natural_frequency_hz=fn, forcing_frequency_hz=ff,
            max_periods=PERIODS, **options,
        )  # fmt: skip
    except (StiffnetError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        return {"recording": row.recording, "ok": False, "reason": str(exc)}
    # the rule's held-out R2 is scale-free: a row without f_n is read at unit gain
    gain = sensor_gain(fn) if fn else 1.0
    return {
        "recording": row.recording, "ok": r.ok, "beta": r.beta,
        "contact_damping_ratio": r.contact_damping_ratio, "exponent": r.exponent,
        "contact_r2": r.contact_r2 if r.ok else None, "reason": r.reason,
        "sensor": r.sensor.to_dict() if r.sensor is not None else None,
        "_samples": result_samples(r, rec.fs_hz, gain, row.recording),
        "_kept": chain_outcome(r) == "kept",
    }  # fmt: skip


def contact_evidence(per_recording: list[dict[str, Any]]) -> dict[str, Any]:
    """Rule: the campaign's median contact damping and exponent, and the effects they support.

    Returns
    -------
    dict
        ``answered`` / ``n``, ``contact_damping_ratio`` and ``exponent`` (medians
        and 10-90 % ranges over the answered recordings), ``restitution``,
        ``supports`` (effect names the map shows), ``supported_values`` (per supported
        effect, the parameters the map reads directly: a fit's start), ``summary`` (one line),
        ``per_recording``.
    """
    ok = [p for p in per_recording if p["ok"]]
    n = len(per_recording)
    res: dict[str, Any] = {"n": n, "answered": len(ok), "per_recording": per_recording,
                           "supports": [], "supported_values": {}}  # fmt: skip
    # sensor_dynamics' start, one vote per recording: one read well through the shared
    # chain (its law explains >= SHARED_CHAIN_MIN_R2) votes for that chain, as a recording
    # whose own chain was fitted votes for its own
    res["sensor"] = shared_chain([p.get("sensor") for p in per_recording])
    shared = [p for p in per_recording if p.get("chain_shared")]
    refuted = next((p["chain_refuted"] for p in per_recording if p.get("chain_refuted")), None)
    chain_words = ""
    if refuted:
        res["chain_refuted"] = refuted
        chain_words = f" (read as recorded: {_refuted_words(refuted)})"
    elif shared:
        res["chain_fitted_on"] = shared[0]["chain_fitted_on"]
        chain_words = (
            f" (the sensor chain fitted on {len(res['chain_fitted_on'])} of them, "
            f"{', '.join(res['chain_fitted_on'])}, and undone as shared on the other "
            f"{len(shared)})"
        )
    if len(ok) < MIN_ANSWERED:
        res["summary"] = (
            f"restoring-force evidence: the contact law was read on {len(ok)} of {n} "
            f"recordings{chain_words}, too few to say anything about the contact"
        )
        return res
    zeta = np.array([p["contact_damping_ratio"] for p in ok], dtype=float)
    expo = np.array([p["exponent"] for p in ok], dtype=float)
    z_med, p_med = float(np.median(zeta)), float(np.median(expo))
    res.update(
        contact_damping_ratio=z_med,
        contact_damping_ratio_range=[float(v) for v in np.quantile(zeta, [0.1, 0.9])],
        restitution=restitution(z_med),
        exponent=p_med,
        exponent_range=[float(v) for v in np.quantile(expo, [0.1, 0.9])],
    )
    words = []
    if z_med > DISSIPATION_ZETA:
        res["supports"].append("contact_damping")
        res["supported_values"]["contact_damping"] = {"damping_ratio": z_med}
        words.append(f"the loops dissipate (contact damping ratio {z_med:.2f}, restitution "
                     f"{restitution(z_med):.2f}): supports contact_damping")  # fmt: skip
    else:
        words.append(f"no dissipation in the contact (damping ratio {z_med:.2f})")
    if p_med > STIFFENING_EXPONENT:
        res["supports"].append("hertz_contact")
        words.append(f"the contact stiffens (exponent {p_med:.2f}): supports hertz_contact")
    else:
        words.append(f"a linear contact (exponent {p_med:.2f})")
    res["summary"] = (
        f"restoring-force evidence on {len(ok)} of {n} recordings{chain_words}: " + "; ".join(words)
    )
    return res


def _refuted_words(note: dict[str, Any]) -> str:
    """Why a shared chain was refuted, in words (:func:`_refuted_chain`'s note)."""
    chain = note["chain"]
    names = {"resonance_hz": "resonance", "lowpass_hz": "low-pass", "highpass_hz": "high-pass"}
    stages = [f"{chain[k]:.0f} Hz {w}" for k, w in names.items() if chain.get(k)]
    medians = ""
    if note.get("unexplained_shared") is not None:
        medians = (f", {note['unexplained_shared']:.2g} of the contact force unexplained against "
                   f"{note['unexplained_own']:.2g} as read alone")  # fmt: skip
    return (
        f"the sensor chain fitted on {len(note['fitted_on'])} of them and shared "
        f"({', '.join(stages) or 'no stage'}), undone on every recording, made the force less a "
        f"function of the state{medians}: no sensor's chain"
    )


def restoring_force_evidence(
    campaign: Campaign, rows: list[ManifestRow], client: Any = None
) -> dict[str, Any]:
    """:func:`contact_evidence` of :func:`contact_law_per_recording` (diagnose's JSON key)."""
    return contact_evidence(contact_law_per_recording(campaign, rows, client))

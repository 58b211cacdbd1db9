"""Evaluate the learned model and both cross-checks on a campaign against its known betas.

Every recording goes through the ONNX predictor (:class:`serving.predictor.Predictor`,
with the manifest's ``natural_frequency_hz``); its result holds the learned class
and beta, the geometric method's class and beta and the restoring-force
estimate's (``restoring_force_*``; a refusal counts as a wrong class). Metrics per method:
accuracy, macro-F1 over the classes present, beta MAPE (recordings with a
known beta and an estimate), sliced by beta class, gap, frequency ratio,
amplitude and impact regime, with the worst recordings listed. A fourth method, beta by
simulation against the same dynamics, and the reading the loop reports are added by
:mod:`stiffnet.measurement.simulation_reading` (``configs/simulated_beta.yaml``).

Impact regime. From a simulation of the row with the manifest's parameters
and the current model's dynamics (:func:`stiffnet.campaign.simulate.simulated_contact`,
or the contact facts of a simulation the caller already ran: the loop passes its
discrepancy's, :func:`stiffnet.measurement.compare.compare_campaign` with ``contact``):
``no_contact`` when the mass never reaches the restraint, ``grazing`` when the
deepest penetration is under 5 % of the amplitude of the motion, else
``impacting``. Rows without the simulation columns fall back to the recording:
``impacting`` when the geometric method detected contact, else ``no_contact``.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import Any

from stiffnet.campaign import SIMULATION_COLUMNS, Campaign
from stiffnet.campaign.loaded import memo
from stiffnet.campaign.simulate import (
    CampaignSolverSettings,
    impact_regime,
    natural_frequency,
    simulated_contact,
)
from stiffnet.effects.base import Effect
from stiffnet.errors import StiffnetError
from stiffnet.geometry.calibration import NO_CONTACT
from stiffnet.measurement.metrics import (
    alarm_metrics,
    flag_share,
    interval_coverage,
    method_metrics,
    sliced_metrics,
    true_class,
)
from stiffnet.measurement.nuisance import predicted
from stiffnet.measurement.simulated_beta import SimulatedBetaConfig
from stiffnet.measurement.simulation_reading import with_simulation
from stiffnet.uncertainty.campaign_law import campaign_law_alarms
from stiffnet.uncertainty.reference_penetration import campaign_reference_decision

N_WORST = 5


def evaluate_campaign(
    campaign: Campaign,
    model_path: str | None = None,
    dynamics: Sequence[Effect] = (),
    require_beta: bool = True,
    simulation: SimulatedBetaConfig | None = None,
    settings: CampaignSolverSettings | None = None,
    contact: Sequence[dict[str, float]] | None = None,
) -> dict[str, Any]:
    """Predictions and metrics of the learned model and the geometric method on a campaign.

    Parameters
    ----------
    campaign : Campaign
    model_path : str, optional
        ONNX model (default: the predictor's, ``models/cnn.onnx``).
    dynamics : sequence of Effect
        The current model's effects, for the impact regime by simulation.
    require_beta : bool
        Refuse a campaign without any β (the ``evaluate`` command); the loop
        evaluates field campaigns too, where only the agreements mean something.
    simulation : SimulatedBetaConfig, optional
        The reading by simulation (default: ``configs/simulated_beta.yaml``).
    settings : CampaignSolverSettings, optional
        The simulator config's solver settings, for the reading by simulation.
    contact : sequence of dict, optional
        Per recording, the contact facts of a simulation of the rows with ``dynamics``
        already run (:func:`stiffnet.campaign.simulate.motion_contact`); default: simulated
        here (:func:`stiffnet.campaign.simulate.simulated_contact`).

    Returns
    -------
    dict
        ``model`` (name, sha256, kind), ``sensor`` (the campaign's pooled sensor chain
        and how many recordings identified it, or why none was pooled:
        :func:`serving.campaign_chain.campaign_chain`), ``campaign_law`` (whether the
        campaign's contact law lies outside the model's world, judged on all its recordings:
        :func:`stiffnet.uncertainty.campaign_law.campaign_law_decision`; where it does, every
        recording's alarm has ``campaign_law`` fired), ``recordings`` (each ``recording``,
        ``beta``, ``class``, ``beta_estimate``, ``geometric_class``,
        ``geometric_beta``, ``true_class``, ``impact_regime``, ``chain_source``, ...),
        ``metrics`` (``learned``, ``geometric`` and ``restoring_force``:
        ``accuracy``, ``macro_f1``, ``beta_mape``; the last also
        ``interval_coverage`` and ``agreement_with_learned``), ``slices``, ``worst``;
        the reading by simulation adds ``metrics.simulation``, ``metrics.reading``,
        ``simulation`` and fields per recording
        (:mod:`stiffnet.measurement.simulation_reading`).
    """
    from serving.predictor import Predictor
    from serving.verdict import model_facts

    if require_beta and all(r.beta is None for r in campaign.rows):
        raise StiffnetError(
            f"{campaign.manifest_path}: no recording has a known beta (manifest column beta): "
            "evaluate needs a calibration campaign; use predict-batch for unknown ones"
        )
    predictor = memo(campaign, ("predictor", model_path), lambda: Predictor.load(model_path))
    simulable = all(getattr(r, c) is not None for r in campaign.rows for c in SIMULATION_COLUMNS)
    if not simulable:
        contact = None
    elif contact is None:
        contact = simulated_contact(campaign.rows, dynamics)
    results, chain = campaign_predictions(campaign, model_path)
    results, law = campaign_law_alarms(results)
    # one rig, one convention for a stiffening law's beta: judged over the campaign's depths
    results, reference = campaign_reference_decision(
        results, [row.amplitude for row in campaign.rows], model_facts(predictor)
    )
    rows = [_evaluated_row(row, res, None if contact is None else contact[i])
            for i, (row, res) in enumerate(zip(campaign.rows, results, strict=True))]  # fmt: skip
    worst = sorted(rows, key=lambda r: -r["error"])[:N_WORST]
    evaluation = {
        "campaign": str(campaign.folder),
        "model": {"name": predictor.name, "sha256": predictor.sha256, "kind": predictor.kind},
        "sensor": chain,
        "campaign_law": law,
        "campaign_reference": reference,
        "recordings": rows,
        "metrics": {
            "learned": {**method_metrics(rows, "class", "beta_estimate"), **alarm_metrics(rows)},
            "geometric": method_metrics(rows, "geometric_class", "geometric_beta"),
            "restoring_force": {
                **method_metrics(rows, "restoring_force_class", "restoring_force_beta"),
                "interval_coverage": interval_coverage(rows, "restoring_force_beta_interval"),
                "agreement_with_learned": flag_share(r["restoring_force_agreement"] for r in rows),
            },
        },
        "slices": sliced_metrics(rows),
        "worst": [
            {k: r[k] for k in ("recording", "beta", "class", "beta_estimate", "error")}
            for r in worst
        ],
    }
    # the fourth method: beta by simulation against the same dynamics, beside the others
    return with_simulation(evaluation, campaign, dynamics, simulation, settings)


def campaign_predictions(
    campaign: Campaign, model_path: str | None
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """The predictor's result per recording, read through the campaign's sensor chain.

    A campaign has one accelerometer: the chains the restoring-force check identified on
    some recordings are pooled (:func:`serving.campaign_chain.campaign_chain`) and, where
    they agree, every recording without its own data sheet is predicted again with the
    pooled chain as its sheet (its stages profiled over the campaign's contact laws,
    :func:`serving.campaign_chain.profiled_campaign_chain`); kept where it reads the contact
    laws about as well as the first reading (:func:`serving.campaign_chain.confirmed`),
    except on a recording whose own contact law it reads much worse
    (:func:`serving.campaign_chain.reads_alone`: its first reading is kept). Returns the
    results (``chain_source`` in each) and the campaign's ``sensor`` decision.
    """
    from serving.campaign_chain import (
        campaign_sheets,
        chain_fitted_regardless,
        confirmed,
        dissipation_readers,
        identify_regardless,
        labelled,
        profile_readers,
        profiled_campaign_chain,
        read_through,
        reads_alone,
    )
    from serving.predictor import Predictor

    rows = campaign.rows
    first = [predicted(campaign, i, row, model_path) for i, row in enumerate(rows)]
    sheets = [row.sensor_sheet() for row in rows]
    # the pooling's readings share one predictor (a campaign not held in memory memoises
    # nothing, and each of its ~200 readings loaded the model again)
    pred = memo(campaign, ("predictor", model_path), lambda: Predictor.load(model_path))
    read: dict[int, Any] = {}  # each recording loaded once for the fits and profiles below
    fns = [natural_frequency(row) for row in rows]

    def recording(i: int) -> Any:
        return read[i] if i in read else read.setdefault(i, campaign.recording(i))

    def identify(i: int) -> dict | None:  # the chain fitted regardless of the gate
        rec = recording(i)
        return chain_fitted_regardless(rec.accel, rec.fs_hz, fns[i], pred)

    chain, sensors = identify_regardless(
        [(r.get("restoring_force") or {}).get("sensor") for r in first],
        [row.recording for row in rows], sheets, identify,
    )  # fmt: skip

    def through(i: int, sheet: dict, dissipation: bool = False) -> Any:  # read through sheet
        rec = recording(i)
        return read_through(rec.accel, rec.fs_hz, fns[i], pred, sheet, dissipation)

    contact_r2, free_damping = profile_readers(through)  # in this campaign's scope only
    # the same readings with the contact's dissipation growing with penetration fitted free
    dissipation = dissipation_readers(functools.partial(through, dissipation=True))

    dampings = [row.damping_ratio for row in rows]  # the rig's, where the manifest gives it
    chain = profiled_campaign_chain(chain, sensors, contact_r2, free_damping, lambda: fns,
                                    dampings, sheets, dissipation, identify)  # fmt: skip
    if not chain["pooled"]:
        return [labelled(r, False) for r in first], chain
    # a campaign whose low-pass was its contacts' dissipation is read with it free
    hc = True if chain.get("contact_dissipation") else None
    again = [
        None
        if sheets[i] is not None
        else predicted(
            campaign,
            i,
            row,
            model_path,
            sensor=sheet,
            sensor_fitted=True,
            penetration_dissipation=hc,
        )  # fmt: skip
        for i, (row, sheet) in enumerate(zip(rows, campaign_sheets(chain, sheets), strict=True))
    ]  # the user's own sheet wins
    read = [i for i, r in enumerate(again) if r is not None]
    chain = confirmed(chain, [first[i].get("restoring_force") for i in read],
                      [again[i].get("restoring_force") for i in read])  # fmt: skip
    if not chain["pooled"]:
        return [labelled(r, False) for r in first], chain
    alone = [r is None or reads_alone(first[i].get("restoring_force"), r.get("restoring_force"))
             for i, r in enumerate(again)]  # fmt: skip
    return [labelled(first[i], False) if keep else labelled(again[i], True)
            for i, keep in enumerate(alone)], chain  # fmt: skip


def _evaluated_row(row: Any, res: dict[str, Any], contact: Any) -> dict[str, Any]:
    """One recording's row: the three methods' readings beside the truth, the alarm, the
    impact regime (by simulation where `contact` is given, else the geometric method's
    contact), and its error (a wrong class counts 1, plus the relative beta error)."""
    geo = res.get("geometric") or {}
    if contact is not None:
        regime = impact_regime(contact)
    else:
        regime = "impacting" if geo.get("contact_detected") else NO_CONTACT
    has_contact = regime != NO_CONTACT
    r = {
        "recording": row.recording,
        "beta": row.beta,
        "class": res.get("class"),
        "beta_estimate": res.get("beta"),
        "beta_interval": res.get("beta_interval"),
        "geometric_class": geo.get("class"),
        "geometric_beta": geo.get("beta"),
        "agreement": res.get("agreement"),
        # the alarm: did it fire, how far past its threshold, which checks
        "ood": bool(res.get("ood_flag")),
        "restoring_force_class": res.get("restoring_force_class"),
        "restoring_force_beta": res.get("restoring_force_beta"),
        "restoring_force_beta_interval": res.get("restoring_force_beta_interval"),
        "restoring_force_agreement": res.get("restoring_force_agreement"),
        "restoring_force_reason": (res.get("restoring_force") or {}).get("reason"),
        "sensor": (res.get("restoring_force") or {}).get("sensor"),
        # the chain the recording was read through: "campaign" (pooled), "data sheet",
        # "fitted" (its own) or None
        "chain_source": res.get("chain_source"),
        # the model's readings through the other chains a fitted one stands for (the
        # interval spans them): none behind a data sheet or where no chain was undone
        "chain_readings": res.get("chain_readings"),
        "ood_score": res.get("ood_score"),
        "ood_threshold": res.get("ood_threshold"),
        "ood_checks": list((res.get("alarm") or {}).get("fired") or []),
        "alarm": res.get("alarm"),
        "true_class": true_class(row.beta, has_contact),
        "impact_regime": regime,
        "gap": row.gap,
        "frequency_ratio": row.frequency_ratio,
        "amplitude": row.amplitude,
    }
    err = 0.0
    if r["true_class"] is not None and r["class"] != r["true_class"]:
        err += 1.0
    if r["beta"] and r["beta_estimate"] is not None:
        err += abs(r["beta_estimate"] - r["beta"]) / r["beta"]
    r["error"] = err
    return r

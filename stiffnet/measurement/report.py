"""One self-contained HTML page: evaluate, compare and diagnose tables with their figures.

Figures are inline base64 PNGs and the CSS is inline, so the page can be mailed
or archived alone. It is written atomically.

:func:`render_report` assembles one function per section, each deciding what its
part shows: :func:`provenance_section` (what made the page), :func:`evaluate_section`
(metrics, every recording with both beta intervals and its operating point in the
manifest's units, :func:`alarm_section`, :func:`slices_section`),
:func:`compare_section` (with :mod:`~stiffnet.measurement.report_figures`: every
recording drawn within a stated bound), :func:`diagnose_section` and
:func:`loop_section`. The words come from :mod:`~stiffnet.measurement.report_words`.

A **field campaign** (no recording has a known beta) has no accuracy to show: its
page puts the three readings of beta side by side per recording (the learned
model with its interval and alarm, the restoring-force estimate with its
interval, and the beta ``diagnose`` profiled as a nuisance of the simulator), how
often the cross-checks agree with the model, and, for each recording, why its
readings differ (:func:`why_betas_differ`).
"""

from __future__ import annotations

import base64
import html
import tempfile
from pathlib import Path
from typing import Any

from stiffnet.io_utils import write_bytes_atomic
from stiffnet.measurement.metrics import SLICE_EDGES, bin_label
from stiffnet.measurement.report_figures import comparison_figures, loop_alt, ranking_alt
from stiffnet.measurement.report_units import nuisance_lines, reading_of
from stiffnet.measurement.report_words import (
    Units,
    check_sentences,
    command_line,
    discrepancy_note,
    profiled_nuisances,
    provenance,
    provenance_rows,
)

_CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1240px;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:2em}
.wrap{max-width:100%;overflow-x:auto}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0;width:100%;table-layout:auto}
td,th{border:1px solid #ddd;padding:3px 6px;text-align:right;overflow-wrap:break-word}
th{background:#f3f3f3;font-weight:600;vertical-align:bottom}
td:first-child,th:first-child{text-align:left}
.sig{background:#d9f2d9}.bad{background:#fde2e2}img{max-width:100%;height:auto}
.note{color:#666;font-size:.85em}
"""
#: Column headers with the quantity and its unit (keys are the JSON names).
_HEADERS = {
    "n": "n (recordings)",
    "beta_mape": "beta MAPE (fraction)",
    "macro_f1": "macro-F1",
    "beta_estimate": "beta (learned)",
    "geometric_beta": "beta (geometric)",
    "error": "error (1 if wrong class + relative beta error)",
    "discrepancy": "discrepancy (mean d²)",
    "discrepancy_reduction": "discrepancy reduction (abs.)",
    "relative_reduction": "relative reduction (fraction)",
    "improved_fraction": "recordings improved (fraction)",
    "sign_test_p": "sign test p",
    "bootstrap_positive": "bootstrap P(reduction > 0)",
    "leave_one_out_relative_reduction": "leave-one-out relative reduction",
    "bic_delta": "BIC delta (lower is better)",
    "contact": "contact Σd²",
    "free_flight": "free-flight Σd²",
    "global": "global Σd²",
    "worst": "worst statistic",
}


def _fmt(v: Any) -> str:
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, dict):
        return ", ".join(f"{html.escape(str(k))}={_fmt(x)}" for k, x in v.items())
    return html.escape(str(v))


def _table(rows: list[dict[str, Any]], cols: list[str], row_class: Any = None) -> str:
    head = "".join(f"<th>{html.escape(_HEADERS.get(c, c.replace('_', ' ')))}</th>" for c in cols)
    body = []
    for r in rows:
        cls = f' class="{row_class(r)}"' if row_class and row_class(r) else ""
        body.append(f"<tr{cls}>" + "".join(f"<td>{_fmt(r.get(c))}</td>" for c in cols) + "</tr>")
    return f"<div class='wrap'><table><tr>{head}</tr>{''.join(body)}</table></div>"


#: PNG files start with these bytes.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Largest figure embedded.
MAX_FIGURE_BYTES = 20 * 1024 * 1024


def loop_chart(loop: dict[str, Any]) -> tuple[Path | None, str]:
    """The chart of a ``loop --json`` result, if the report may embed it, else why not.

    The page embeds only what stiffnet's own commands produced: a PNG (regular file,
    no symbolic link) inside the loop's run folder, which carries the loop's
    completion marker. A ``--loop`` file naming any other path embeds nothing.
    """
    from stiffnet.io_utils import is_run_folder
    from stiffnet.measurement.loop import LOOP_KIND

    run, chart = loop.get("out"), loop.get("chart")
    if not isinstance(run, str) or not isinstance(chart, str):
        return None, "the loop result names no run folder and chart"
    run_dir, path = Path(run).resolve(), Path(chart)
    if not is_run_folder(run_dir, LOOP_KIND):
        return None, f"{run} is not a finished loop run folder"
    if path.is_symlink() or not path.resolve().is_relative_to(run_dir):
        return None, "the chart is not a file inside the loop's run folder"
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(PNG_SIGNATURE))
        size = path.stat().st_size
    except OSError:
        return None, "the chart cannot be read"
    if not path.is_file() or head != PNG_SIGNATURE or size > MAX_FIGURE_BYTES:
        return None, "the chart is not a PNG figure"
    return path, ""


def _img(path: Path, alt: str) -> str:
    """The figure inline, with an alt text that says what it shows and for which recordings."""
    data = base64.b64encode(path.read_bytes()).decode()
    return f'<p><img alt="{html.escape(alt, quote=True)}" src="data:image/png;base64,{data}"></p>'


#: How diagnose reaches its beta (stiffnet.measurement.nuisance): a grid of this many
#: values within this factor of the model's estimate, per recording.
DIAGNOSE_BETA_GRID = 7
DIAGNOSE_BETA_FACTOR = 2.0


def is_field_campaign(evaluation: dict[str, Any] | None) -> bool:
    """True when no recording of the evaluated campaign has a known beta."""
    rows = (evaluation or {}).get("recordings") or []
    return bool(rows) and all(r.get("beta") is None for r in rows)


def _disjoint(a: list[float] | None, b: list[float] | None) -> bool | None:
    if not a or not b:
        return None
    return a[1] < b[0] or b[1] < a[0]


def why_betas_differ(row: dict[str, Any], diagnose_beta: float | None, profiled: list[str]) -> str:
    """Why the learned, restoring-force and diagnose readings of one recording's beta differ.

    Parameters
    ----------
    row : dict
        The recording's row of ``evaluate`` (model and restoring-force readings).
    diagnose_beta : float or None
        The beta ``diagnose`` profiled for it (its JSON ``nuisances.beta``).
    profiled : list of str
        The other nuisances diagnose profiled with it (e.g. ``gap``).
    """
    learned, iv = row.get("beta_estimate"), row.get("beta_interval")
    phys, piv = _rf(row, "beta"), _rf(row, "beta_interval")
    reasons = []
    fired = row.get("ood_checks") or []
    if "layers" in fired:
        reasons.append("beta changes along the record: the model's beta is a blend of layers")
    if learned is None:
        reasons.append(f"the model reads no contact ({row.get('class')})")
    if phys is None:
        reasons.append(f"no restoring-force beta: {_rf(row, 'reason') or 'refused'}")
    elif _disjoint(iv, piv):
        why = _rf(row, "reason") or ""
        weak = " (its contact law fits poorly: weak evidence)" if "explains only" in why else ""
        reasons.append(
            f"the restoring force reads the contact law itself and its interval misses the "
            f"model's{weak}: the rig's physics may lie outside the model's training data"
        )
    if diagnose_beta is not None and learned is not None and iv:
        if not iv[0] <= diagnose_beta <= iv[1]:
            others = ", ".join(p for p in profiled if p != "beta") or "nothing else"
            reasons.append(
                f"diagnose's beta is a nuisance of the simulator, profiled on {DIAGNOSE_BETA_GRID} "
                f"values within x/÷{DIAGNOSE_BETA_FACTOR:g} of the model's estimate jointly with "
                f"{others}, to match phase-independent statistics: it trades off against them "
                "(beta and the gap both set the impact), the simulator's best match, not a "
                "measurement"
            )
    other = [f for f in fired if f not in ("layers",)]
    if other:
        reasons.append(f"the model's alarm fired ({', '.join(other)})")
    if not reasons:
        return "the readings agree (intervals overlap; diagnose's beta inside the model's)"
    return "; ".join(reasons)


def field_section(
    evaluation: dict[str, Any], diagnosis: dict[str, Any] | None, coverage: float | None = None
) -> list[str]:
    """HTML of a field campaign: the three betas side by side, agreement, reasons
    (``coverage``: the nominal coverage of the model's interval, from its card)."""
    level = f"{100 * coverage:.0f} % " if coverage else ""
    rows = evaluation["recordings"]
    nuis = (diagnosis or {}).get("nuisances") or {}
    dbeta = nuis.get("beta") if isinstance(nuis.get("beta"), list) else None
    profiled = profiled_nuisances(diagnosis)
    table = []
    for i, r in enumerate(rows):
        db = dbeta[i] if dbeta is not None and i < len(dbeta) else None
        table.append(
            {
                "recording": r["recording"],
                "class": r.get("class"),
                "beta (learned)": r.get("beta_estimate"),
                f"learned {level}interval": _interval(r.get("beta_interval")),
                "alarm": ", ".join(r.get("ood_checks") or []) or "none",
                "beta (restoring force)": _rf(r, "beta"),
                "restoring-force interval": _interval(_rf(r, "beta_interval")),
                "beta (diagnose fit)": db,
                "why they differ": why_betas_differ(r, db, profiled),
            }
        )
    n = len(rows)
    share = lambda flags: sum(1 for f in flags if f is True) / n if n else None  # noqa: E731
    geometric = share(r.get("agreement") for r in rows)
    restoring = share(_rf(r, "agreement") for r in rows)
    checked = [r for r in rows if _rf(r, "agreement") is not None]
    parts = [
        "<h2>Field campaign: no beta is known, the readings side by side</h2>",
        f"<p>model {_fmt(evaluation['model'])}. Cross-check agreement with the model's class: "
        f"geometric <b>{_fmt(geometric)}</b> of {n} recordings, restoring force "
        f"<b>{_fmt(restoring)}</b> ({len(checked)} with an estimate). "
        f"Alarm on {sum(1 for r in rows if r.get('ood'))} of {n}."
        + ("" if dbeta is not None else " No diagnose result: its fitted beta is not shown.")
        + "</p>",
        _table(table, list(table[0]) if table else ["recording"],
               lambda r: "" if r["why they differ"].startswith("the readings agree") else "bad"),
    ]  # fmt: skip
    with_ = nuis.get("profiled_with")
    if dbeta is not None and isinstance(with_, list):  # which model's nuisance it is
        model = f"the base model with {', '.join(map(str, with_))}" if with_ else "the base model"
        parts.append(f"<p class='note'>beta (diagnose fit): profiled with {html.escape(model)}"
                     " (the diagnosis' final model).</p>")  # fmt: skip
    return parts


def _rf(row: dict[str, Any], what: str) -> Any:
    """A restoring-force reading of an evaluated row (``restoring_force_*``; results saved
    under earlier key names are renamed where they are read back)."""
    return row.get(f"restoring_force_{what}")


def _interval(iv: list[float] | None) -> str | None:
    return None if not iv else f"[{iv[0]:.3g}, {iv[1]:.3g}]"


def render_report(
    title: str,
    evaluation: dict[str, Any] | None,
    comparison: Any | None,
    diagnosis: dict[str, Any] | None,
    loop: dict[str, Any] | None = None,
    provenance: dict[str, Any] | None = None,
    units: Units | None = None,
) -> str:
    """The HTML page (``comparison`` is a :class:`~stiffnet.measurement.compare.Comparison`).

    ``provenance`` (:func:`stiffnet.measurement.report_words.provenance`) heads the
    page; ``units`` (:class:`~stiffnet.measurement.report_words.Units`) says how the
    operating points read (mm and Hz for a physical-unit manifest).
    """
    units = units or Units()
    coverage = (provenance or {}).get("interval_coverage")
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
        f"</title><style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>"
    ]
    parts += provenance_section(provenance, (evaluation or {}).get("model"))
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        if evaluation is not None and is_field_campaign(evaluation):
            parts += field_section(evaluation, diagnosis, coverage)
            parts += alarm_section(evaluation["recordings"])
        elif evaluation is not None:
            parts += evaluate_section(evaluation, units, coverage)
        if comparison is not None:
            parts += compare_section(comparison, diagnosis, t)
        if diagnosis is not None:
            parts += diagnose_section(diagnosis, t)
        if loop is not None:
            parts += loop_section(loop)
    parts.append("</body></html>")
    return "\n".join(parts)


def provenance_section(prov: dict[str, Any] | None, model: dict[str, Any] | None) -> list[str]:
    """Where the page comes from: date, version, command line, input files and their hashes."""
    if prov is None:
        return ["<p class='note'>No provenance: this page was rendered outside "
                "<code>stiffnet report</code>.</p>"]  # fmt: skip
    lines = "".join(
        f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
        for k, v in provenance_rows(prov, model)
    )
    return [f"<h2>Provenance</h2><div class='wrap'><table class='prov'>{lines}</table></div>"]


def evaluate_section(
    evaluation: dict[str, Any], units: Units, coverage: float | None = None
) -> list[str]:
    """Metrics per method, every recording with its intervals and alarm, the slices
    (``coverage``: the nominal coverage of the model's interval, from its card)."""
    m = evaluation["metrics"]
    parts = [
        "<h2>Evaluate: learned model, the cross-checks and beta by simulation</h2>",
        f"<p class='note'>model {_fmt(evaluation['model'])}</p>",
        _table([{"method": k, **v} for k, v in m.items()],
               ["method", "n", "accuracy", "macro_f1", "beta_mape", "interval_coverage",
                "alarm_rate", "alarm_rate_wrong"]),
    ]  # fmt: skip
    level = f"{100 * coverage:.0f} % " if coverage else ""
    rows = [_evaluated_row(r, units, level) for r in evaluation["recordings"]]
    parts.append(
        _table(rows, list(rows[0]) if rows else ["recording"],
               lambda r: "bad" if r["class"] != r["true class"] else "")
    )  # fmt: skip
    parts += alarm_section(evaluation["recordings"])
    parts += slices_section(evaluation, units)
    return parts


def _evaluated_row(r: dict[str, Any], units: Units, level: str) -> dict[str, Any]:
    """One recording of the evaluate table: readings with their intervals (``level``: the
    model interval's nominal coverage, "90 % "), operating point."""
    fired = r.get("ood_checks") or []
    return {
        "recording": r["recording"],
        "beta": r.get("beta"),
        **units.operating_point(r),
        "true class": r.get("true_class"),
        "class": r.get("class"),
        "beta (learned)": r.get("beta_estimate"),
        f"learned {level}interval": _interval(r.get("beta_interval")),
        "geometric class": r.get("geometric_class"),
        "beta (geometric)": r.get("geometric_beta"),
        "restoring-force class": _rf(r, "class"),
        "beta (restoring force)": _rf(r, "beta"),
        "restoring-force interval": _interval(_rf(r, "beta_interval")),
        **_simulation_columns(r),
        "impact regime": r.get("impact_regime"),
        "alarm": ("fired: " + ", ".join(map(str, fired))) if fired else "none",
        _HEADERS["error"]: r.get("error"),
    }


def _simulation_columns(r: dict[str, Any]) -> dict[str, Any]:
    """Beta by simulation and the reading, where the evaluation ran them (none otherwise)."""
    if "simulation_class" not in r:
        return {}
    cols = {
        "simulation class": r.get("simulation_class"),
        "beta (simulation)": r.get("simulation_beta"),
        "simulation interval": _interval(r.get("simulation_beta_interval")),
        "reproduced": r.get("simulation_reproduced"),
    }
    if "reading_class" in r:
        undecided = ", undecided" if r.get("reading_undecided") else ""
        cols["reading"] = f"{r['reading_class']} ({r.get('reading_method')}{undecided})"
    return cols


def alarm_section(recordings: list[dict[str, Any]]) -> list[str]:
    """Each recording's alarm checks, one sentence a check (what, score, threshold, verdict)."""
    items = []
    for r in recordings:
        said = check_sentences(r.get("alarm"), r.get("ood_checks") or [])
        if not said:
            continue
        lis = "".join(f"<li>{html.escape(s)}</li>" for s in said)
        state = "fired" if r.get("ood") else "quiet"
        items.append(f"<details><summary>{html.escape(str(r['recording']))}: alarm {state}"
                     f"</summary><ul>{lis}</ul></details>")  # fmt: skip
    if not items:
        return ["<p class='note'>The model reported no alarm checks.</p>"]
    return ["<h3>Alarm checks per recording</h3>", *items]


def slices_section(evaluation: dict[str, Any], units: Units) -> list[str]:
    """The metrics by beta class, impact regime and operating point (in ``units``)."""
    parts = []
    recs = evaluation["recordings"]
    for name, groups in evaluation["slices"].items():
        rows = []
        for g, v in groups.items():
            if name in SLICE_EDGES:
                members = [r for r in recs if bin_label(r.get(name), SLICE_EDGES[name]) == g]
                label = units.slice_label(name, g, members)
            else:
                label = f"{name.replace('_', ' ')} {g}"
            rows.append({
                "slice": label,
                "n": v["learned"]["n"],
                "learned accuracy": v["learned"]["accuracy"],
                "learned beta MAPE": v["learned"]["beta_mape"],
                "geometric accuracy": v["geometric"]["accuracy"],
                "geometric beta MAPE": v["geometric"]["beta_mape"],
                "restoring-force accuracy": v.get("restoring_force", {}).get("accuracy"),
                "restoring-force beta MAPE": v.get("restoring_force", {}).get("beta_mape"),
                **{f"{m} {what}": v[m][key] for m in ("simulation", "reading") if m in v
                   for what, key in (("accuracy", "accuracy"), ("beta MAPE", "beta_mape"))},
            })  # fmt: skip
        parts.append(_table(rows, list(rows[0]) if rows else ["slice"]))
    return parts


def compare_section(comparison: Any, diagnosis: dict[str, Any] | None, t: Path) -> list[str]:
    """Where the simulator fails, every recording's discrepancy and the figures."""
    res = comparison.result
    f = res["failure"]
    parts = [
        "<h2>Compare: simulator versus measurement</h2>",
        f"<p>Campaign discrepancy <b>{res['discrepancy']:.3g}</b>. It fails mostly in "
        f"<b>{_fmt(f['group'])}</b> (shares: {_fmt(res['by_group'])}), statistic "
        f"<b>{_fmt(f['component'])}</b>, beta class <b>{_fmt(f['beta_class'])}</b>, "
        f"recording <b>{_fmt(f['recording'])}</b>.</p>",
    ]
    if diagnosis is not None:
        note = discrepancy_note(res, diagnosis)
        if note:
            parts.append(f"<p class='note'>{html.escape(note)}</p>")
    rows = [{"recording": r["recording"], "beta": r["beta"], "discrepancy": r["discrepancy"],
             "worst": r.get("worst_component"), **(r.get("groups") or {})}
            for r in res["recordings"]]  # fmt: skip
    cols = ["recording", "beta", "discrepancy", "worst", "contact", "free_flight", "global"]
    parts.append(_table(rows, cols))
    figures, said = comparison_figures(comparison, t)
    parts.append(f"<p class='note'>{html.escape(' '.join(said))}</p>")
    parts += [_img(fig.path, fig.alt) for fig in figures]
    return parts


def diagnose_section(diagnosis: dict[str, Any], t: Path) -> list[str]:
    """The verdict, the ranking with its chart, each recording against its floor, the law."""
    from stiffnet.measurement import plots
    from stiffnet.measurement.learned_law import learned_law_html

    verdict = diagnosis.get("verdict")
    first = diagnosis.get("missing_effect")
    selected = diagnosis.get("missing_effects") or ([first] if first else [])
    parts = [
        "<h2>Diagnose: which effect is missing</h2>",
        f"<p>Baseline discrepancy {diagnosis['baseline_discrepancy']:.3g}, the "
        f"campaign's noise floor {diagnosis.get('noise_floor', float('nan')):.3g}. "
        f"Selected: <b>{html.escape(', '.join(map(str, selected)) or 'none')}"
        f"</b>. Verdict: <b>{html.escape(str(verdict))}</b> "
        f"({html.escape(str(diagnosis.get('summary', '')))}).</p>",
    ]
    evidence = _evidence(diagnosis).get("summary")
    if evidence:
        parts.append(f"<p>{html.escape(str(evidence))}.</p>")
    ranking = [
        {**r, "params": _fitted_text(r), "why not": "; ".join(r.get("reasons", []))}
        for r in diagnosis["ranking"]
    ]
    cols = ["effect", "selected", "params", "discrepancy_reduction", "excess_reduction",
            "bootstrap_positive", "leave_one_out_excess_reduction", "bic_delta",
            "why not"]  # fmt: skip
    parts.append(_table(ranking, cols, lambda r: "sig" if r.get("selected") is True else ""))
    said = (diagnosis.get("units") or {}).get("said")
    if said:
        parts.append(f"<p class='note'>{html.escape(str(said))}.</p>")
    parts.append(_img(plots.ranking_figure(diagnosis, t / "ranking.png"), ranking_alt(diagnosis)))
    if diagnosis.get("per_recording"):
        parts.append("<h3>Per recording: the final model against its own floor</h3>")
        cols = ["recording", "floor", "residual", "ratio", "above_floor",
                "non_repeatable", "measured_orbit", "simulated_orbit",
                "starts_on_measured_orbit", "distinct_orbits", "note"]  # fmt: skip
        parts.append(_table(diagnosis["per_recording"], cols))
    parts += nuisances_section(diagnosis)
    parts += learned_law_html(diagnosis.get("learned_law"), t / "law.png")
    return parts


def _fitted_text(entry: dict[str, Any]) -> str:
    """A ranking entry's fitted parameters, ``k=v unit``: in the campaign's units where
    :func:`~stiffnet.measurement.report_units.with_physical_units` gave them."""
    params = entry.get("params") or {}
    said = entry.get("params_physical") or {}
    names = [k for k in (entry.get("fitted") or params) if k in params]
    return ", ".join(
        f"{k}={reading_of(said[k]) if isinstance(said.get(k), dict) else _fmt(params[k])}"
        for k in names
    )


def nuisances_section(diagnosis: dict[str, Any]) -> list[str]:
    """The profiled nuisances per recording, in the campaign's units: with the final model's
    effects and, when an effect was selected, with none (the baseline's)."""
    lines = nuisance_lines(diagnosis)
    names = diagnosis.get("recordings") or []
    selected = ", ".join(map(str, (diagnosis.get("nuisances") or {}).get("profiled_with") or []))
    rows = []
    for key, label in (("nuisances", selected or "no effect"),
                       ("nuisances_effect_free", "no effect")):  # fmt: skip
        said = diagnosis.get(f"{key}_physical")
        if not isinstance(said, dict) or (key != "nuisances" and not selected):
            continue  # nothing selected: the final model's nuisances are the baseline's
        for i, name in enumerate(names):
            rows.append({"recording": name, "profiled with": label,
                         **{k: reading_of(v[i]) if i < len(v) else "–"
                            for k, v in said.items() if isinstance(v, list)}})  # fmt: skip
    if not rows:
        return []
    cols = list(dict.fromkeys(k for r in rows for k in r))
    return [
        "<h3>Nuisances: what diagnose fitted besides the effects</h3>",
        "".join(f"<p class='note'>{html.escape(line)}.</p>" for line in lines),
        _table(rows, cols),
    ]


def _evidence(diagnosis: dict[str, Any]) -> dict[str, Any]:
    """The restoring-force evidence of a diagnosis (earlier key names are renamed where a
    saved diagnosis is read back)."""
    v = diagnosis.get("restoring_force")
    return v if isinstance(v, dict) else {}


def loop_section(loop: dict[str, Any]) -> list[str]:
    """The loop's iterations (or its before/after) and its chart when it may be embedded."""
    cols = ["accuracy", "beta_mape", "restoring_force_agreement", "discrepancy"]
    rows = [
        {"iteration": f"{it.get('index')}: {it.get('label')}",
         **{c: (it.get("metrics") or {}).get(c) for c in cols},
         "model_version": it.get("model_version"), "run_id": it.get("run_id")}
        for it in loop.get("iterations") or [] if isinstance(it, dict)
    ] or [{"iteration": k, **{c: loop[k].get(c) for c in cols},
           "run_id": loop[k].get("run_id")} for k in ("before", "after")]  # fmt: skip
    parts = ["<h2>Loop</h2>", _table(rows, ["iteration", *cols, "model_version", "run_id"])]
    chart, why = loop_chart(loop)
    if chart is not None:
        parts.append(_img(chart, loop_alt(loop)))
    else:
        parts.append(f"<p class='note'>loop chart not embedded: {html.escape(why)}</p>")
    return parts


def report_provenance(
    campaign: Any,
    out: Path,
    model: Path | None,
    config: Path | None,
    diagnosis: Path | None,
    loop: Path | None,
    run_diagnose: bool,
    json_path: Path | None,
    config_used: Path | None = None,
) -> dict[str, Any]:
    """The provenance of a ``stiffnet report`` page from its options (the command line is
    written back from them, with absolute paths, so it can be pasted and rerun;
    ``config_used``: the config file read when ``config`` is not given)."""
    from serving.model import default_model_path

    args: list[Any] = [Path(campaign.folder).resolve(), "--out", Path(out).resolve()]
    for flag, value in (("--model", model), ("--config", config), ("--diagnosis", diagnosis),
                        ("--loop", loop), ("--json", json_path)):  # fmt: skip
        if value is not None:
            args += [flag, value if str(value) == "-" else Path(value).resolve()]
    if not run_diagnose:
        args.append("--no-diagnose")
    how = "run by this report" if run_diagnose else "not run (--no-diagnose)"
    from stiffnet.effects.registry import plugin_files

    command = command_line("report", args, plugins=list(plugin_files().values()))
    return provenance(campaign, command, config or config_used, diagnosis,
                      "" if diagnosis else how, loop,
                      model=model if model is not None else default_model_path())  # fmt: skip


def write_report(path: str | Path, page: str) -> Path:
    """Write the page atomically."""
    write_bytes_atomic(path, page.encode("utf-8"))
    return Path(path)

"""Figures of an analysis, the ones a person checks before trusting the numbers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stiffnet.analyze import Analysis
from stiffnet.io_utils import write_bytes_atomic
from stiffnet.nlts import delay_embed, savgol_smooth


def _figure():
    import matplotlib

    matplotlib.use("Agg")  # files only, never a window
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    write_bytes_atomic(path, buf.getvalue())
    return path


def analysis_plots(a: Analysis, raw: np.ndarray, out_dir: str | Path) -> list[Path]:
    """Write the analysis figures as PNG files into ``out_dir``; returns their paths."""
    plt = _figure()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    g = a.geometric

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(np.arange(a.ami.size), a.ami, lw=1.2)
    ax.axvline(a.delay, color="C3", ls="--", label=f"delay {a.delay} ({a.delay_rule})")
    ax.set(xlabel="lag [samples]", ylabel="mutual information [nats]",
           title=f"AMI (eq. 2): embedding delay {a.delay} samples")  # fmt: skip
    ax.legend()
    paths.append(_save(fig, out / "ami.png"))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    d = np.arange(1, a.cao_e1.size + 1)
    ax.plot(d, a.cao_e1, "o-", label="Cao E1")
    ax.plot(d, a.cao_e2, "s--", label="Cao E2")
    ax.plot(np.arange(1, a.fnn.size + 1), a.fnn, "^-", label="FNN fraction")
    ax.axvline(a.dimension, color="C3", ls=":", label=f"dimension {a.dimension}")
    ax.set(xlabel="embedding dimension m", ylabel="E1, E2, FNN fraction [dimensionless]",
           title="Embedding dimension (eq. 3)")  # fmt: skip
    ax.legend()
    paths.append(_save(fig, out / "dimension.png"))
    plt.close(fig)

    # The attractor as the geometric method saw it, x-z projection (Fig. 10).
    x = (raw - raw.mean()) / raw.std()
    s = savgol_smooth(x, g.smoothing_window)
    y = delay_embed(s, 3, g.delay)
    mask = g.separation.mask
    n = min(len(mask), len(y))
    fig, ax = plt.subplots(figsize=(5, 5))
    ax.plot(y[:n, 0], y[:n, 2], ",", color="0.6", label="free flight")
    ax.plot(y[:n, 0][mask[:n]], y[:n, 2][mask[:n]], ".", ms=2, color="C3", label="contact")
    # the geometric method's delay (0.18 T by default), not the AMI embedding delay:
    # the axis and the title say which, so they match the numbers analyze reports
    ax.set(xlabel="x(t) [standardised]", ylabel=f"x(t + 2 tau) = x(t + {2 * g.delay} samples)",
           title=f"Attractor, x-z projection (geometric delay tau = {g.delay} samples; "
           f"AMI embedding delay {a.delay})")  # fmt: skip
    ax.legend(markerscale=4)
    paths.append(_save(fig, out / "attractor_xz.png"))
    plt.close(fig)

    sep = g.separation
    fig, ax = plt.subplots(figsize=(6, 3.5))
    edges = 10.0**sep.edges  # the histogram is of log10 magnitudes
    ax.bar(edges[:-1], sep.counts, width=np.diff(edges), align="edge", color="C0")
    if np.isfinite(sep.threshold):
        ax.axvline(sep.threshold, color="C3", ls="--", label=f"threshold {sep.threshold:.3g}")
        ax.legend()
    ax.set(xscale="log", yscale="log", xlabel="tangent-vector magnitude [standardised units]",
           ylabel="count [vectors]", title="Contact separation (Fig. 8)")  # fmt: skip
    ax.xaxis.set_minor_formatter(plt.NullFormatter())  # minor log labels collide
    paths.append(_save(fig, out / "tangent_histogram.png"))
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 4))
    if g.orbit_before_deg.size:
        ax.plot(g.orbit_before_deg, g.orbit_after_deg, ".", alpha=0.6, label="orbits")
        ax.plot([g.inclination_before_deg], [g.inclination_after_deg], "r*", ms=14, label="mean")
        ax.legend()
    title = f"geometric: {g.geometric_class}"
    if g.geometric_beta is not None:
        title += f", beta ~ {g.geometric_beta:.1f}"
    ax.set(xlabel="inclination before impact [deg]", ylabel="inclination after impact [deg]",
           title=title)  # fmt: skip
    paths.append(_save(fig, out / "inclinations.png"))
    plt.close(fig)
    if a.restoring_force is not None:
        paths.append(force_displacement_plot(a.restoring_force, out / "force_displacement.png"))
    return paths


def force_displacement_plot(r, path: Path) -> Path:
    """The force-displacement map with the fitted contact law (the restoring-force estimate).

    Points: the residual (contact) force against the reconstructed relative
    displacement, in the record's units; line: the law's elastic part
    ``K d_r (d / d_r)**p``; crosses: the whole law (with its damping) at the
    samples in contact. A damped contact shows as a loop whose lower branch
    (release) reaches zero force before the onset.
    """
    from stiffnet.restoring_force import contact_force

    plt = _figure()
    fig, ax = plt.subplots(figsize=(6, 4.5))
    x, f = r.displacement, r.force
    ax.plot(x, f, ".", ms=2, color="0.5", label="measured (residual force)")
    law = r.law
    if law is not None:
        model = contact_force(x, r.velocity, law.stiffness, law.onset, law.damping,
                              law.exponent, law.reference_penetration)  # fmt: skip
        on = model > 0
        ax.plot(x[on], model[on], "x", ms=3, color="C3", label="fitted law at the samples")
        d = np.linspace(0.0, max(float(x.max() - law.onset), 1e-12), 100)
        elastic = (
            law.stiffness
            * law.reference_penetration
            * (d / law.reference_penetration) ** law.exponent
        )
        ax.plot(law.onset + d, elastic, "-", color="C1", label="elastic part")
        ax.axvline(law.onset, color="C2", ls=":", label="contact onset")
    if r.ok:
        lo, hi = r.beta_interval
        title = (f"restoring force: beta {r.beta:.1f} [{lo:.1f}, {hi:.1f}], "
                 f"zeta_c {r.contact_damping_ratio:.2f}, p {r.exponent:.2f}")  # fmt: skip
    else:
        title = "restoring force: no estimate"
    ax.set(xlabel="relative displacement [record units x rad^2]", ylabel="contact force",
           title=title)  # fmt: skip
    ax.title.set_fontsize(9)
    ax.legend(fontsize=8, markerscale=3)
    _save(fig, path)
    plt.close(fig)
    return path

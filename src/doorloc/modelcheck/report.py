"""Writing a model check's ``report.json``, ``report.md`` and plots (PNG) into REPORT_DIR, atomically."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from doorloc.fileio import atomic_write_bytes, atomic_write_text
from doorloc.modelcheck.forward import COMPONENTS

if TYPE_CHECKING:
    from doorloc.modelcheck.check import ModelCheckReport

__all__ = ["write_report", "report_markdown"]

_UNIT = {"x_mm": "mm", "z_mm": "mm", "yaw_deg": "deg", "thickness_mm": "mm", "lever_mm": "mm"}


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def _plots(rep: ModelCheckReport, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    obs = rep.observations
    if not obs:
        return []
    names = []
    err = np.array([o.error for o in obs])
    feats = {
        "x_mm (reference)": np.array([o.item.reference.x_mm for o in obs]),
        "z_mm (reference)": np.array([o.item.reference.z_mm for o in obs]),
        "yaw_deg (reference)": np.array([o.item.reference.yaw_deg for o in obs]),
        "width_mm": np.array([o.item.door.width_mm for o in obs]),
        "thickness_mm": np.array([o.item.door.thickness_mm for o in obs]),
        "corner u px": np.array([o.corner_px[0] for o in obs]),
        "corner v px": np.array([o.corner_px[1] for o in obs]),
    }
    held = np.zeros(len(obs), bool)
    if rep.heldout_rows is not None:
        held[rep.heldout_rows] = True
    fig, axes = plt.subplots(4, len(feats), figsize=(3.0 * len(feats), 10), squeeze=False)
    for i, comp in enumerate(COMPONENTS):
        for j, (fname, f) in enumerate(feats.items()):
            ax = axes[i, j]
            ax.scatter(f[~held], err[~held, i], s=10, c="tab:blue", label="training")
            ax.scatter(f[held], err[held, i], s=14, c="tab:orange", marker="s", label="held out")
            if rep.train_prediction is not None and rep.train_rows is not None and rep.causes:
                ax.scatter(
                    f[rep.train_rows], rep.train_prediction[:, i], s=8, c="k", marker="x", label="model"
                )
            if i == 3:
                ax.set_xlabel(fname)
            if j == 0:
                ax.set_ylabel(f"error {comp}")
            ax.axhline(0, color="0.6", lw=0.5)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(
        "Pose error (measured - reference) with the given cell; x: the fitted model on training images"
    )
    fig.tight_layout()
    atomic_write_bytes(out / "residuals.png", _png(fig))
    plt.close(fig)
    names.append("residuals.png")

    uv = np.concatenate([o.edge_uv for o in obs])
    res = np.concatenate([o.edge_residual_mm for o in obs])
    if uv.size:
        fig, ax = plt.subplots(figsize=(8, 5))
        lim = float(np.nanpercentile(np.abs(res), 98)) * 1e3 or 1.0
        sc = ax.scatter(uv[:, 0], uv[:, 1], c=res * 1e3, s=2, cmap="coolwarm", vmin=-lim, vmax=lim)
        ax.invert_yaxis()
        ax.set_xlabel("u px")
        ax.set_ylabel("v px")
        ax.set_title("Edge points' distance from their fitted lines (um), all images")
        fig.colorbar(sc, ax=ax)
        fig.tight_layout()
        atomic_write_bytes(out / "edge_residuals.png", _png(fig))
        plt.close(fig)
        names.append("edge_residuals.png")

    fig, ax = plt.subplots(figsize=(7, 4))
    comps = [*COMPONENTS[:3], "lever_mm"]
    b = [rep.heldout_rms_before.get(c, np.nan) for c in comps]
    a = [rep.heldout_rms_after.get(c, np.nan) for c in comps]
    x = np.arange(len(comps))
    ax.bar(x - 0.2, b, 0.4, label="given cell")
    ax.bar(x + 0.2, a, 0.4, label="extended cell")
    ax.set_yscale("log")
    ax.set_xticks(x, [f"{c} ({_UNIT[c]})" for c in comps])
    ax.set_title(f"Held-out RMS error ({len(rep.heldout_images)} images), gain {rep.heldout_gain:.1f}x")
    ax.legend()
    fig.tight_layout()
    atomic_write_bytes(out / "heldout.png", _png(fig))
    plt.close(fig)
    names.append("heldout.png")
    return names


def report_markdown(rep: ModelCheckReport) -> str:
    """A person's summary of the check."""
    lines = [
        "# Model check",
        "",
        f"- data set: `{rep.dataset}`",
        f"- cell: `{rep.cell}`",
        f"- images: {len(rep.train_images)} training, {len(rep.heldout_images)} held out, "
        f"{len(rep.refused)} refused by locate",
        "",
    ]
    if rep.causes == []:
        lines.append(
            "**Causes: none** - no significant effect; the cell model explains these data to their noise."
        )
    else:
        lines.append("**Causes: " + ", ".join(f"`{c}`" for c in rep.causes) + "**")
    lines += ["", "## Fitted parameters (1 sigma)", ""]
    for cause, ps in rep.parameters.items():
        for p, v in ps.items():
            lines.append(f"- `{cause}`.{p} = {v['value']:.6g} +- {v['sigma']:.2g}")
    if not rep.parameters:
        lines.append("- none")
    if rep.indistinguishable:
        lines += ["", "## Not distinguishable on these data", ""]
        for cause, alts in rep.indistinguishable.items():
            lines.append(f"- `{cause}`: " + "; ".join(alts))
    lines += [
        "",
        "## Held-out error (images not used to fit)",
        "",
        "| | given cell | extended cell |",
        "|---|---|---|",
    ]
    for c in [*COMPONENTS, "lever_mm"]:
        b, a = rep.heldout_rms_before.get(c), rep.heldout_rms_after.get(c)
        if b is not None and a is not None:
            lines.append(f"| {c} ({_UNIT[c]}) | {b:.5f} | {a:.5f} |")
    if rep.heldout_refused_after:
        lines += [
            "",
            f"**The extended cell's locate refused {len(rep.heldout_refused_after)} held-out image(s)** "
            f"({', '.join(rep.heldout_refused_after[:5])}): no gain is claimed.",
        ]
    lines += [
        "",
        f"Gain: **{rep.heldout_gain:.1f}x** (RMS error of a point 1 m up the door, before / after).",
        "",
        "## Alternatives (cross-validated weighted RMS, first selection step)",
        "",
    ]
    for alt in rep.alternatives:
        lines.append(f"- `{alt['cause']}`: {alt['cv_rms_weighted']:.3g}")
    lines += ["", "## Selection steps", ""]
    for s in rep.selection_steps:
        lines.append(
            f"- step {s['step']}: `{s['candidate']}` held-out SSE ratio {s['cv_ratio']:.3g}, "
            f"F-test p = {s['f_test_p']:.2g} -> {'accepted' if s['accepted'] else 'rejected'}"
        )
    ref = rep.refined_by_relocation
    if ref.get("steps"):
        moved = "; ".join(
            f"`{name}` {', '.join(f'{a:.4g}' for a in v['analytic'])} -> {', '.join(f'{b:.4g}' for b in v['relocated'])}"
            for name, v in ref["values"].items()
        )
        lines.append(
            f"- refined on the training images located again ({ref['steps']} Gauss-Newton steps, cost "
            f"{ref['cost_before']:.4g} -> {ref['cost_after']:.4g}): {moved}"
        )
    ev = rep.response_measured_by_locate
    if ev.get("added"):
        lines.append(
            f"- `response_gamma` from locate's own measurement: on {ev['images']} of {ev['of']} training images "
            f"it found the camera's response on plain edges and used it instead of the cell's (their poses show "
            f"nothing of it): median {ev['median']:.3f} +- {ev['sigma']:.3f}"
        )
    u = rep.unexplained_test
    lines += [
        "",
        f"Structure left after the model (linear in pose, door size, corner pixel): p = "
        f"{u.get('f_test_p', 1.0):.2g}, held-out ratio {u.get('cv_ratio', 1.0):.3g} -> "
        f"{'structured (unexplained)' if u.get('structured') else 'noise'}",
        "",
        "Noise per component (1 sigma, weights): " + ", ".join(f"{k} {v:.2g}" for k, v in rep.noise.items()),
        "",
        f"Extended cell: `{rep.extended_cell}` (locate, batch and serve read it like any cell file).",
        "",
    ]
    rb = rep.response_bound
    if rb.get("written"):
        lines[-1:-1] = [
            f"Camera response: the training poses put it at {rb['gamma']:.3f} +- {rb['sigma']:.3f} "
            f"({rb['source']}); the extended cell doubts it by a factor {rb['factor']:.3f} where an image "
            f"cannot check it itself (`locate.response_unmeasured_factor`, was {rb['cell_factor']:g}).",
            "",
        ]
    for p in rep.plots:
        lines.append(f"![{p}]({p})")
    return "\n".join(lines) + "\n"


def write_report(rep: ModelCheckReport, out: Path) -> None:
    """Plots first, then ``report.md`` and ``report.json`` (last: a folder with a report.json is complete)."""
    rep.plots = _plots(rep, out)
    atomic_write_text(out / "report.md", report_markdown(rep))
    atomic_write_text(out / "report.json", json.dumps(rep.to_dict(), indent=2))

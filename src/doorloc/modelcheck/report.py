"""Writing a model check's ``report.json``, ``report.md`` and plots (PNG) into REPORT_DIR, atomically."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from doorloc.fileio import atomic_write_bytes, atomic_write_text
from doorloc.modelcheck.forward import COMPONENTS
from doorloc.modelcheck.priors import IMPLAUSIBLE_SIGMAS
from doorloc.modelcheck.verdict import LEVER_EXPLAINED, meaning, verdict_of

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


def _comment(c: str, b: float, a: float, noise: float) -> str:
    """Why a held-out component moved the way it did, in words."""
    if not (np.isfinite(a) and np.isfinite(b)):
        return "not measured (refused images)"
    if a <= b * 0.95:
        return "better"
    if a <= b * 1.05:
        return "unchanged"
    if np.isfinite(noise) and max(a, b) <= 2 * noise:
        return (
            f"worse, but both within twice its noise ({noise:.2g} {_UNIT[c]}): this component was already "
            "right and moved by noise only"
        )
    return "worse: the extended model trades this component for the others; look at heldout.png"


def _headline_sections(rep: ModelCheckReport) -> list[str]:
    v = verdict_of(rep)
    return [
        f"# Model check: {v.status.replace('_', ' ')}",
        "",
        f"**Verdict.** {v.headline}",
        "",
        f"**Action.** {v.action}",
        "",
        f"Data set `{rep.dataset}`, cell `{rep.cell}`: {len(rep.train_images)} images to fit, "
        f"{len(rep.heldout_images)} held out to judge (never used to fit or choose), {len(rep.refused)} that "
        "locate refused with the given cell.",
        "",
    ]


def _considered_sections(rep: ModelCheckReport) -> list[str]:
    if not rep.considered:
        return []
    lines = [
        "## Causes considered",
        "",
        "Each known cause was fitted alone to the training images. *Explains* is the share of the pose error "
        "it takes away on images left out of its fit (cross-validated). *Prior* is how many sigmas its fitted "
        "value lies from the cell's own, against what the calibration and the shop allow (1 sigma shown); a "
        f"cause beyond {IMPLAUSIBLE_SIGMAS:g} sigma is implausible. *Score* = held-out error + prior "
        "penalty (sigmas squared), in noise units squared: lowest wins.",
        "",
        "| cause | explains | fitted value | prior (1 sigma) | sigmas from cell | score |",
        "|---|---|---|---|---|---|",
    ]
    for t in rep.considered:
        label = t["cause"] + (f" ({t['variant']})" if t.get("variant") else "")
        vals = ", ".join(f"{k} {v:+.4g}" for k, v in t["values"].items())
        prior = rep.priors.get(t["cause"], {})
        psig = ", ".join(f"{x:.3g}" for x in prior.get("sigma", ()))
        away = float(np.sqrt(t["prior_chi2"]))
        lines.append(
            f"| `{label}` | {100 * (1 - t['cv_ratio']):.1f} % | {vals} | {psig} | {away:.1f} | {t['score']:.4g} |"
        )
    named = [c for c in rep.causes if c != "unexplained"]
    winner = rep.considered[0]
    runner = next((t for t in rep.considered[1:] if t["cause"] != winner["cause"]), None)
    lines.append("")
    if named:
        lines.append(
            f"**Why `{named[0]}`.** It has the lowest score: it explains "
            f"{100 * (1 - winner['cv_ratio']):.1f} % of the error on images outside its fit with a value "
            f"{np.sqrt(winner['prior_chi2']):.1f} sigma from the cell's."
            + (
                f" Together with it: {', '.join(f'`{c}`' for c in named[1:])} (selection steps below)."
                if len(named) > 1
                else ""
            )
        )
    if runner is not None:
        what = meaning(runner["cause"], runner["values"], runner.get("variant", ""))
        lines.append(
            f"**Runner-up `{runner['cause']}`** would mean {what}; it explains "
            f"{100 * (1 - runner['cv_ratio']):.1f} % at {np.sqrt(runner['prior_chi2']):.1f} sigma from the "
            f"cell's value (score {runner['score']:.4g} against {winner['score']:.4g})."
        )
    lines.append("")
    return lines


def report_markdown(rep: ModelCheckReport) -> str:
    """A person's summary of the check: verdict and action first, every figure explained."""
    lines = _headline_sections(rep)
    named = [c for c in rep.causes if c != "unexplained"]
    lines += ["## What was found", ""]
    if not rep.causes:
        lines.append("No cause: the cell model explains these data to their noise.")
    for cause in named:
        pl = rep.plausibility.get(cause, {})
        vals = {p: v["value"] for p, v in rep.parameters.get(cause, {}).items()}
        lines.append(f"- `{cause}`: {meaning(cause, vals, pl.get('variant', ''))}.")
        for p, v in rep.parameters.get(cause, {}).items():
            lines.append(f"  - {p} = {v['value']:.6g} +- {v['sigma']:.2g} (1 sigma from these data)")
        if pl:
            flag = "**implausible**" if pl["implausible"] else "plausible"
            lines.append(
                f"  - {pl['sigmas_from_cell']:.1f} sigma from the cell's value under its prior "
                f"({', '.join(f'{k} {s:.3g}' for k, s in pl['prior_sigma'].items())}, {pl['prior_source']}): {flag}"
            )
    if "unexplained" in rep.causes:
        lines.append(
            "- `unexplained`: the errors left over still follow the door's pose, size or image position "
            "(test below); no known cause accounts for that part."
        )
    if rep.indistinguishable:
        lines += ["", "Not distinguishable on these data:", ""]
        for cause, alts in rep.indistinguishable.items():
            lines.append(f"- `{cause}`: " + "; ".join(alts))
    lines.append("")
    lines += _considered_sections(rep)
    lines += [
        "## Held-out check (images not used to fit)",
        "",
        "RMS error of the held-out images' poses, located with the given cell and again with the extended "
        f"cell. `lever_mm` is {LEVER_EXPLAINED}; the gain is its before / after.",
        "",
        "| | given cell | extended cell | |",
        "|---|---|---|---|",
    ]
    for c in [*COMPONENTS, "lever_mm"]:
        b, a = rep.heldout_rms_before.get(c), rep.heldout_rms_after.get(c)
        if b is not None and a is not None:
            noise = (
                float(np.hypot(rep.noise.get("x_mm", np.nan), rep.noise.get("z_mm", np.nan)))
                if c == "lever_mm"
                else rep.noise.get(c, np.nan)
            )
            lines.append(f"| {c} ({_UNIT[c]}) | {b:.5f} | {a:.5f} | {_comment(c, b, a, noise)} |")
    if rep.heldout_refused_after:
        lines += [
            "",
            f"**Locate with the extended cell refused {len(rep.heldout_refused_after)} held-out image(s)** "
            f"({', '.join(rep.heldout_refused_after[:5])}): no gain is claimed. Why: "
            + "; ".join(rep.heldout_refusal_reasons[:3]),
        ]
    lines += ["", f"Gain: **{rep.heldout_gain:.1f}x**.", ""]
    lines += [
        "## Selection steps",
        "",
        "A cause is added when it is real and worth it. *Real*: the F-test's p is the chance that noise alone "
        "would improve the fit this much (small = real). *Worth it*: on images left out of the fit it takes "
        "away at least 75 % of what the model before it left (held-out ratio < 0.25). A cause that takes away "
        "much but not enough is kept provisionally while a second is tried with it.",
        "",
    ]
    for s in rep.selection_steps:
        verdict = (
            "accepted"
            if s["accepted"]
            else "kept provisionally"
            if s.get("provisional")
            else "rejected: "
            + ("not real (p too large)" if s["f_test_p"] >= 1e-4 else "not worth it (ratio too large)")
        )
        lines.append(
            f"- step {s['step']}: `{s['candidate']}` leaves {s['cv_ratio']:.3g} of the held-out error, "
            f"p = {s['f_test_p']:.2g} -> {verdict}"
        )
    ref = rep.refined_by_relocation
    if ref.get("steps"):
        moved = "; ".join(
            f"`{name}` {', '.join(f'{a:.4g}' for a in v['analytic'])} -> {', '.join(f'{b:.4g}' for b in v['relocated'])}"
            for name, v in ref["values"].items()
        )
        lines.append(
            f"- refined by locating the training images again ({ref['steps']} Gauss-Newton steps, cost "
            f"{ref['cost_before']:.4g} -> {ref['cost_after']:.4g}): {moved}"
        )
    for key, grey in rep.grey_levels_refined.items():
        if len(grey) > 1:
            lines.append(
                f"- `{key}` located again at its own best value before the selection (its table is exact "
                f"only there): {grey[0]['value']:.4g} (weighted SSE {grey[0]['sse']:.4g}) -> "
                f"{grey[-1]['value']:.4g} ({grey[-1]['sse']:.4g})"
            )
    ev = rep.response_measured_by_locate
    if ev.get("added"):
        lines.append(
            f"- `response_gamma` from locate's own measurement: on {ev['images']} of {ev['of']} training images "
            f"it found the camera's response on plain edges and used it instead of the cell's (their poses show "
            f"nothing of it): median {ev['median']:.3f} +- {ev['sigma']:.3f}"
        )
    u = rep.unexplained_test
    left = "yes: reported as `unexplained`" if u.get("structured") else "no: what is left is noise"
    lines += [
        "",
        "## Anything left?",
        "",
        "The opposite question: after the causes above, do the errors still follow the door's pose, size or "
        "image position (a linear fit)? Here a small p means *something is left*; it must also hold on "
        "images left out (ratio < 0.5) and be at least 2 % of the original error to count. "
        f"p = {u.get('f_test_p', 1.0):.2g}, held-out ratio {u.get('cv_ratio', 1.0):.3g}, "
        f"share {100 * u.get('share_of_original', 0.0):.1f} % -> {left}.",
        "",
        "Noise per component (1 sigma; locate's own uncertainty with the reference's): "
        + ", ".join(f"{k} {v:.2g}" for k, v in rep.noise.items()),
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

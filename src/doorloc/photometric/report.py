"""Write a board check: ``report.json`` (the shared specification's section 8b), ``report.md`` (the verdict and
what to do first, in plain words), plots a person can read, and the calibration file with the photometric
model added.

Every file is written atomically (:mod:`doorloc.fileio`), the calibration last: a failed run leaves no
half-written report.
"""

from __future__ import annotations

import io
import json
import math
import os
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile, CalibrationFileError, dump_opencv_yaml, load_calibration
from doorloc.fileio import atomic_write_bytes, atomic_write_text
from doorloc.photometric.catalogue import CAUSES_BY_NAME
from doorloc.photometric.check import BoardCheck, BoardCheckError, BoardCheckOptions, check_boards
from doorloc.photometric.model import PARAMETER_UNITS, PhotometricModel

__all__ = [
    "report_dict",
    "report_markdown",
    "write_board_report",
    "extended_calibration",
    "board_model_check",
    "EXTENDED_CALIBRATION",
    "PLOTS",
]

EXTENDED_CALIBRATION = "camera_photometric.yaml"
PLOTS = ("residual_profile.png", "offset_against.png")
#: the least difference (grey levels) between the outer field's edges facing out and in that the report
#: reads as optics that change over the field (rendered boards without: 0.2; with a hidden ghost up to 6.8;
#: Bouguet's photographs 13.0, OpenCV's 3.5)
FIELD_FLIP_GREY = 3.0


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), 6)


def report_dict(check: BoardCheck) -> dict:
    """``report.json``'s content."""
    off = check.heldout_rms("offset")
    prof = check.heldout_rms("profile_rms")
    return {
        "causes": list(check.causes),
        "parameters": {
            c: {
                n: {
                    "value": _num(v["value"]),
                    "sigma": _num(v["sigma"]),
                    "unit": PARAMETER_UNITS.get(n, ""),
                    "at_bound": bool(v.get("at_bound", 0.0)),
                }
                for n, v in ps.items()
            }
            for c, ps in check.parameters.items()
        },
        "images": [
            {
                "image": p.image,
                "heldout": p.heldout,
                "n_edges": p.n_edges,
                "edge_offset_px": {"before": _num(p.offset_before_px), "after": _num(p.offset_after_px)},
                "edge_offset_standard_error_px": _num(p.noise_px),
                "profile_rms": {"before": _num(p.profile_rms_before), "after": _num(p.profile_rms_after)},
                "noise": _num(p.noise_grey),
                "noise_rms": _num(p.noise_rms_grey),
                **(
                    {
                        "twin": {
                            "profile_rms": _num(t.misfit),
                            "read_noise": _num(t.read_noise),
                            "jpeg_quality": t.jpeg_quality,
                            "blur_px": _num(t.blur_px),
                            "plateau_spread": _num(t.plateau_spread),
                        }
                    }
                    if t is not None
                    else {}
                ),
                **(
                    {
                        "field_offset_px": {
                            "u": _num(f.u_px),
                            "v": _num(f.v_px),
                            "sigma_u": _num(f.sigma_u_px),
                            "sigma_v": _num(f.sigma_v_px),
                        }
                    }
                    if f is not None
                    else {}
                ),
            }
            for p, f, t in zip(
                check.photographs,
                check.fields.own if check.fields is not None else [None] * len(check.photographs),
                check.twins or [None] * len(check.photographs),
                strict=True,
            )
        ],
        "heldout_edge_offset_rms_px": {k: _num(v) for k, v in off.items()},
        "heldout_edge_offset_standard_error_px": _num(check.offset_standard_error_px),
        "heldout_profile_rms": {k: _num(v) for k, v in prof.items()},
        # the same over what the photographs' rendered twins leave (noise and compression): 1 = drawn fully
        "heldout_profile_over_twin": {k: _num(v) for k, v in check.profile_over_twin().items()},
        "noise": _num(check.noise_grey),
        "noise_rms": _num(check.noise_rms_grey),
        # the mean residual at each distance from the edge (the plot's), over all scan lines and over those
        # along the image rows and the columns apart (a camera's scan lines act along the rows only; a
        # print may lay one direction of the board's edges differently)
        "residual_profile": _residual_profile_dict(check),
        "extended_model": EXTENDED_CALIBRATION,
        "photometric_model": check.model.to_dict(),
        "alternatives": check.alternatives,
        "not_tried": check.selection.not_tried,
        "selection_steps": [{k: _num(v) for k, v in step.items()} for step in check.selection.steps],
        "blur_terms_gain": {
            k: {"gain": _num(g), "standard_error": _num(s)} for k, (g, s) in check.blur.gains.items()
        },
        "psf_tail_gain": {"gain": _num(check.tail_gain[0]), "standard_error": _num(check.tail_gain[1])},
        # (held out by each photograph's edges: grey levels^2 of mean squared profile misfit taken off)
        "interlaced_fields_gain": (
            {"gain": _num(check.fields.gain[0]), "standard_error": _num(check.fields.gain[1])}
            if check.fields is not None
            else None
        ),
        "calibration": check.calibration_source,
        # the bits the camera stores its levels at in 16-bit photographs, read with them (null: 8 or all 16)
        "stored_bits": check.stored_bits,
        "skipped": check.skipped,
        "plots": list(PLOTS),
    }


def _residual_profile_dict(check: BoardCheck) -> dict:
    plain, extended = check.residual_profiles
    gap, at = extended.direction_gap()
    flip = check.field_flip.largest() if check.field_flip is not None else (float("nan"), float("nan"))

    def grey(v: np.ndarray) -> list[float | None]:
        return [_num(round(float(x), 3)) for x in v]

    return {
        "distance_px": [float(x) for x in extended.distance_px],
        **{
            label: {
                "all": grey(p.all),
                "along_rows": grey(p.along_rows),
                "along_columns": grey(p.along_columns),
            }
            for label, p in (("plain", plain), ("extended", extended))
        },
        "outward_less_inward": {"largest": _num(flip[0]), "at_px": _num(flip[1])},
        "rows_less_columns": {
            "largest": _num(gap),
            "at_px": _num(at),
            "source": check.gap_source[0],
            "at_px_by_photograph": [_num(x) for x in check.gap_source[1]],
            "px_per_mm_by_photograph": [_num(x) for x in check.gap_source[2]],
        },
    }


def _action(named: list[str], residual_edge_px: float, clip_level: float = 1.0) -> str:
    """The report's action: the extended calibration wherever the camera's is read, where it holds a cause
    or a measured residual (locate counts that residual on every edge in place of the doubt it grants a
    camera whose optics nobody measured, ``locate.optics_edge_sigma_px``, and refuses a door whose bright
    side or arris strips sit at a clip below full scale, ``clip_level``)."""
    use = (
        f"use `{EXTENDED_CALIBRATION}` (this calibration with the photometric model added) wherever the "
        "camera's calibration is read"
    )
    residual = (
        f"locate then counts the {residual_edge_px:.3f} px these photographs' edges keep, held out, on every "
        "edge, in place of the doubt it grants a camera whose optics nobody measured (locate.optics_edge_sigma_px)"
    )
    if named and clip_level < 1.0:
        use += (
            f"; locate then refuses a door whose bright side or arris strips sit at this camera's clip "
            f"({255 * clip_level:.0f} grey), where an image alone may not show the clip"
        )
    if named and residual_edge_px > 0:
        return f"{use}; {residual}."
    if named:
        return f"{use}."
    if residual_edge_px > 0:
        return f"nothing to model, but {use}: {residual}."
    return "none."


def _compression(check: BoardCheck) -> str:
    """The photographs' JPEG qualities in words."""
    q = sorted({t.jpeg_quality for t in check.twins if t is not None})
    if not q:
        return "no twins"
    if q == [0]:
        return "none"
    return "JPEG quality " + ", ".join(str(v) if v else "none" for v in q)


def _render_hint(check: BoardCheck) -> str:
    """Where the photographs are JPEG: how to render doors as this camera stores them (the model file holds
    what the camera does to light, not its files' compression)."""
    q = [t.jpeg_quality for t in check.twins if t is not None and t.jpeg_quality]
    if not q:
        return ""
    return f" Doors rendered as this camera stores them: `doorloc render ... --effect jpeg_quality={int(np.median(q))}`."


def report_markdown(check: BoardCheck) -> str:
    """``report.md``: the verdict and the action first, then the figures."""
    off = check.heldout_rms("offset")
    prof = check.heldout_rms("profile_rms")
    twin = check.profile_over_twin()
    se = check.offset_standard_error_px
    named = [c for c in check.causes if c != "unexplained"]
    lines = ["# Model check on board photographs", ""]
    if not check.causes:
        lines.append(
            "**Verdict: the plain model (linear response, even blur, a true print) explains these edges.** "
            "Nothing to add to it."
        )
    else:
        lines.append(
            "**Verdict: the plain image model misplaces this camera's edges** by "
            f"{off['before']:.3f} px (RMS over photographs of each one's median edge offset); with "
            + (", ".join(named) if named else "no catalogue cause")
            + f" fitted on other photographs, {off['after']:.3f} px (noise alone: {se:.3f} px)."
        )
        if "unexplained" in check.causes:
            lines.append("")
            lines.append(
                "**Part of the error is unexplained** by the catalogue: the model is extended with what was "
                "found, but edges on this camera keep a bias beyond noise; treat its edge positions with that doubt."
            )
    lines += ["", "**Action:** " + _action(named, check.model.residual_edge_px, check.model.clip_level), ""]
    for c in named:
        cause = CAUSES_BY_NAME.get(c)
        ps = ", ".join(
            f"{n} = {v['value']:.4g} +- {v['sigma']:.2g} {PARAMETER_UNITS.get(n, '')}"
            for n, v in check.parameters.get(c, {}).items()
        )
        lines.append(f"- **{c}**: {cause.signature if cause else ''}. {ps}")
        if any(v.get("at_bound") for v in check.parameters.get(c, {}).values()):
            lines.append(
                "  (a value at the end of its range: the data ask for more than this form of the cause allows; "
                "read it as a direction, not a measurement)"
            )
    if check.alternatives:
        lines += ["", "The data cannot tell these apart (held-out figures within one standard error):"]
        lines += [f"- {k}: also {', '.join(v)}" for k, v in check.alternatives.items()]
    if check.selection.not_tried:
        lines += ["", "Not tried, too few photographs:"]
        lines += [f"- {k}: {v}" for k, v in check.selection.not_tried.items()]
    if named and prof["after"] > prof["before"] + 0.05 * prof["before"]:
        lines += [
            "",
            f"**The extended model draws these edges' profiles worse** than the plain one ({prof['before']:.2f} "
            f"-> {prof['after']:.2f} grey levels, held out): its causes are fitted to where the edges lie, not to "
            "their shapes, and a response that places them may still bend their profiles wrongly; what shapes "
            "them is beyond this catalogue.",
        ]
    lines += [
        "",
        "## Figures",
        "",
        "| | plain model | extended model |",
        "|---|---|---|",
        f"| held-out edge offset, RMS over photographs (px) | {off['before']:.4f} | {off['after']:.4f} |",
        f"| held-out profile misfit, RMS (grey levels) | {prof['before']:.2f} | {prof['after']:.2f} |",
        f"| the same over its twins' (1 = drawn up to noise and compression) | {twin['before']:.2f} | "
        f"{twin['after']:.2f} |",
        "",
        f"Noise on the plateaus: {check.noise_grey:.2f} grey levels (median of each scan line's spread), "
        f"{check.noise_rms_grey:.2f} as an RMS over the windows (what a model leaves where nothing but noise "
        "is left, without compression); "
        f"standard error of a photograph's median offset from its edges' scatter: {se:.4f} px. "
        f"Calibration: {check.calibration_source}."
        + (
            f" The 16-bit photographs' levels stay within {check.stored_bits} bits: read as a {check.stored_bits}-bit "
            f"camera's, stored from 0 (`stored_bits: {check.stored_bits}` in the extended calibration)."
            if check.stored_bits is not None
            else ""
        ),
        "",
        _direction_sentence(check) + _field_sentence(check),
        "",
        "Each photograph's twin is its board rendered at its pose through the extended model, with its blur, "
        "its squares' levels, read noise that spreads its plateaus as the photograph's are spread and the "
        f"compression its file says ({_compression(check)}), measured and fitted as the photograph is: the "
        "misfit a model that drew everything this camera does would leave." + _render_hint(check),
        "",
        "| photograph | edges | offset before (px) | offset after, held out (px) | profile RMS before | after "
        "| twin |",
        "|---|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {p.image} | {p.n_edges} | {p.offset_before_px:+.3f} | {p.offset_after_px:+.3f} | "
        f"{p.profile_rms_before:.2f} | {p.profile_rms_after:.2f} | "
        + (f"{t.misfit:.2f} |" if t is not None else "- |")
        for p, t in zip(check.photographs, check.twins or [None] * len(check.photographs), strict=True)
    ]
    lines += [
        "",
        "Offsets are + towards the brighter square; the reference is the line (through the distortion) "
        "between the edge's two inner corners, which never place an edge.",
        "",
    ]
    lines += [
        f"Plots: `{PLOTS[0]}` (mean residual profile across the edges), `{PLOTS[1]}` (each edge's "
        "offset against blur, contrast, level, position in the field and direction)."
    ]
    if check.skipped:
        lines += ["", "Skipped: " + "; ".join(check.skipped)]
    return "\n".join(lines) + "\n"


def _field_sentence(check: BoardCheck) -> str:
    flip = check.field_flip
    gap, at = flip.largest() if flip is not None else (float("nan"), float("nan"))
    if not np.isfinite(gap):
        return ""
    return (
        f" In the outer half of the field, edges whose bright side faces away from the image centre and those "
        f"facing it, their normals pointing the same way in the image, are {abs(gap):.1f} grey levels apart at "
        f"most ({at:+.2f} px from the edge)"
        + (
            ": optics alike over the field would draw them alike. A point spread whose asymmetry follows the "
            "radius (coma, a lens tilted on its sensor) draws them as mirror images, and so, in part, may a "
            "ghost fixed in the image (`psf_asymmetry`, which the catalogue draws as a shift only); neither "
            "moves an edge against its corners, and no cause of the catalogue draws the profiles' shape."
            if abs(gap) >= FIELD_FLIP_GREY
            else "."
        )
    )


def _direction_sentence(check: BoardCheck) -> str:
    gap, at = check.residual_profiles[1].direction_gap()
    if not np.isfinite(gap):
        return "The edges across the rows and across the columns are too few to compare their profiles."
    # the board one way in every photograph whose edges' directions are known: print and lines confounded,
    # unless the gap's place against the boards' scales tells them
    confounded = len({p.edges.board_turned() for p in check.photographs} - {None}) == 1
    source, places, scales = check.gap_source
    ok = np.isfinite(places)
    told = (
        f" Photograph by photograph it lies at {np.min(places[ok]):+.2f} to {np.max(places[ok]):+.2f} px "
        f"while the board's scale runs {np.min(scales[ok]):.2f}-{np.max(scales[ok]):.2f} px/mm: "
        + (
            "one distance in pixels, not on the board, so it is the camera's, along its scan lines."
            if source == "camera"
            else "one distance on the board, not in pixels, so it is the print's."
        )
        if source is not None
        else ""
    )
    return (
        "Mean residual profile of the extended model, edges across the image rows against those across the "
        f"columns: {abs(gap):.1f} grey levels apart at most ({at:+.2f} px from the edge, the rows' "
        f"{'above' if gap > 0 else 'below'}). Optics and a response draw an edge alike whichever way it runs; "
        "a gap of several grey levels, beyond the noise, comes from what acts on one direction of edges only: "
        "the camera's scan lines (an analogue line's filter, clamp or sharpening, along the rows) or the "
        "board's print (a printer lays the edges across and along its paper's travel differently). No cause "
        "of the catalogue and no twin draws either."
        + told
        + (
            " In every photograph here the board's rows run the same way in the image, so the two cannot be "
            "told apart: add photographs with the board turned a quarter turn, or at distances further apart."
            if confounded and source is None
            else ""
        )
    )


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def plots(check: BoardCheck) -> dict[str, bytes]:
    """The two plots as PNG bytes."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4))
    ax = fig.add_subplot(1, 1, 1)
    plain, extended = check.residual_profiles
    x = extended.distance_px
    ax.plot(x, plain.all, "-o", ms=3, color="tab:red", label="plain model")
    ax.plot(x, extended.all, "-o", ms=3, color="tab:blue", label="extended model")
    ax.plot(x, extended.along_rows, "--", color="tab:blue", lw=1, label="extended, edges across the rows")
    ax.plot(
        x, extended.along_columns, ":", color="tab:blue", lw=1, label="extended, edges across the columns"
    )
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("distance from the true edge (px, + towards bright)")
    ax.set_ylabel("photograph - model (grey levels)")
    ax.set_title("Mean residual edge profile")
    ax.legend(fontsize=7)
    out = {PLOTS[0]: _png(fig)}

    fig = Figure(figsize=(12, 7))
    feats = []
    for p in check.photographs:
        e = p.edges
        eo = e.edge_offsets_px()
        w, h = e.image_size
        r = np.hypot(e.mid_px[:, 0] - (w - 1) / 2, e.mid_px[:, 1] - (h - 1) / 2) / np.hypot(w / 2, h / 2)
        lvl = np.full(e.n_edges, np.nan)
        con = np.full(e.n_edges, np.nan)
        ok = np.isfinite(e.offset_px)
        for arr, vals in ((lvl, e.bright), (con, e.bright - e.dark)):
            s = np.bincount(e.windows.edge[ok], vals[ok], minlength=e.n_edges)
            c = np.bincount(e.windows.edge[ok], minlength=e.n_edges)
            arr[:] = np.where(c > 0, s / np.maximum(c, 1), np.nan)
        ang = np.degrees(np.arctan2(e.normal[:, 1], e.normal[:, 0]))
        feats.append(np.stack([eo, p.profiles_before.blur_px, con, lvl, r, ang], 1))
    F = np.concatenate(feats)
    names = (
        "blur (px, plain fit)",
        "contrast (grey levels)",
        "bright level (grey)",
        "field position r / r_corner",
        "normal direction (deg)",
    )
    for k, nm in enumerate(names):
        ax = fig.add_subplot(2, 3, k + 1)
        ax.plot(F[:, k + 1], F[:, 0], ".", ms=2, alpha=0.4)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(nm)
        ax.set_ylabel("edge offset, plain model (px)")
    ax = fig.add_subplot(2, 3, 6)
    x = np.arange(len(check.photographs))
    ax.plot(x, [p.offset_before_px for p in check.photographs], "o", color="tab:red", label="plain")
    ax.plot(
        x, [p.offset_after_px for p in check.photographs], "o", color="tab:blue", label="extended, held out"
    )
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("photograph")
    ax.set_ylabel("median edge offset (px)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    out[PLOTS[1]] = _png(fig)
    return out


def extended_calibration(
    check: BoardCheck, base: CalibrationFile, command: str, date: str
) -> CalibrationFile:
    """``base`` with the check's photometric model added and what made it (``photometric_model_provenance``:
    ``command``, the photographs, the causes named, ``date`` as YYYY-MM-DD), and the depth the photographs
    were read at where the check read one (``stored_bits``)."""
    return replace(
        base,
        stored_bits=base.stored_bits if check.stored_bits is None else check.stored_bits,
        photometric_model=check.model.to_dict(),
        photometric_model_provenance=(
            f"{command}; {len(check.photographs)} photographs; causes {', '.join(check.causes) or 'none'}; {date}"
        ),
    )


def write_board_report(
    check: BoardCheck, out_dir: str | os.PathLike, calibration: CalibrationFile | None, provenance: str
) -> Path:
    """Write the report files into ``out_dir`` (made if missing); returns the extended calibration's path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in plots(check).items():
        atomic_write_bytes(out / name, data)
    atomic_write_text(out / "report.json", json.dumps(report_dict(check), indent=2, allow_nan=False) + "\n")
    atomic_write_text(out / "report.md", report_markdown(check))
    camera = calibration.camera if calibration is not None else check.camera
    if camera is None:
        raise ValueError("a board check without a camera needs the calibration to extend")
    ext = extended_calibration(
        check, calibration or CalibrationFile(camera), provenance, datetime.now(UTC).strftime("%Y-%m-%d")
    )
    path = out / EXTENDED_CALIBRATION
    atomic_write_text(path, dump_opencv_yaml(ext))
    return path


def board_model_check(
    images_dir: str | os.PathLike,
    board_pattern: tuple[int, int],
    square_mm: float,
    calibration_path: str | os.PathLike | None,
    out_dir: str | os.PathLike,
    options: BoardCheckOptions = BoardCheckOptions(),
    progress: Callable[[str], None] | None = None,
) -> tuple[BoardCheck, Path]:
    """``doorloc check-model --boards``: read the calibration (if given), check, write the report.

    Raises :class:`~doorloc.photometric.check.BoardCheckError` for input it cannot use (a bad board, an
    unreadable calibration or one whose photometric model is not valid, too few photographs); OSError when
    the report cannot be written.
    """
    try:
        board = Chessboard(int(board_pattern[0]), int(board_pattern[1]), float(square_mm))
    except ValueError as e:
        raise BoardCheckError(str(e)) from None
    calibration = None
    if calibration_path is not None:
        try:
            calibration = load_calibration(calibration_path)
            if calibration.photometric_model is not None:
                PhotometricModel.from_dict(
                    calibration.photometric_model
                )  # a file whose model is invalid is refused
        except (CalibrationFileError, ValueError) as e:
            raise BoardCheckError(f"{calibration_path}: {e}") from None
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise BoardCheckError(f"{out} exists and is not a folder; give a folder for the report")
    check = check_boards(images_dir, board, calibration, options, progress)
    provenance = (
        f"doorloc check-model --boards {Path(images_dir).name} --pattern {board.cols}x{board.rows} "
        f"--square {board.square_mm:g}"
    )
    return check, write_board_report(check, out, calibration, provenance)

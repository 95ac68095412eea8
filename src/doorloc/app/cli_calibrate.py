"""`doorloc calibrate`, `doorloc calibrate-cell` and `doorloc validity`.

The commands read files and print; the work is in :mod:`doorloc.calib`. Nothing is written
unless the work succeeded, and then atomically (temporary file + rename).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from doorloc.app.errors import EXIT_FAILED, EXIT_REFUSED, EXIT_USAGE, fail

if TYPE_CHECKING:  # the calibration modules load only when a command runs (fast `doorloc --help`)
    import numpy as np

    from doorloc.app.services import CameraCalibration, CameraPlacement
    from doorloc.calib.calibrate import Candidate
    from doorloc.calib.camera import CameraModel, DistortionValidity
    from doorloc.calib.detect import SkippedImage
    from doorloc.calib.folder import CalibrationOutcome
    from doorloc.photometric.check import BoardCheck
    from doorloc.vision.board_response import BoardResponse


def parse_pattern(text: str) -> tuple[int, int]:
    """``"9x6"`` -> ``(9, 6)``; raises ValueError with a sentence."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX*,]\s*(\d+)\s*", text or "")
    if not m:
        raise ValueError(f"--pattern must look like 9x6 (columns x rows), got {text!r}")
    return int(m.group(1)), int(m.group(2))


def _board(pattern: str, square: float, charuco: bool, marker: float | None, dictionary: str, legacy: bool):
    from doorloc.calib.detect import CharucoSpec, Chessboard

    cols, rows = parse_pattern(pattern)
    if charuco:
        if marker is None:
            raise ValueError("a ChArUco board needs --marker MM (the ArUco marker side)")
        return CharucoSpec(cols, rows, square, marker, dictionary, legacy)
    return Chessboard(cols, rows, square)


def _candidates(model: str) -> tuple[Candidate, ...]:
    """``--model``: ``auto`` (every candidate) or one candidate by name; ValueError names the choices."""
    from doorloc.calib.calibrate import CANDIDATES, CANDIDATES_BY_NAME

    if model == "auto":
        return tuple(CANDIDATES)
    if model in CANDIDATES_BY_NAME:
        return (CANDIDATES_BY_NAME[model],)
    raise ValueError(f"--model must be auto or one of {', '.join(CANDIDATES_BY_NAME)}; got {model!r}")


def _echo_skipped(skipped: list[SkippedImage]) -> None:
    for s in skipped:
        typer.echo(f"skipped {s.name}: {s.reason}", err=True)


def _echo_calibration(outcome: CalibrationOutcome, out: Path, fmt: str) -> None:
    """What ``doorloc calibrate`` prints after writing: model, intrinsics with their 1-sigma, the candidates."""
    from doorloc.calib.report import calibration_warnings

    result = outcome.result
    cam, s = result.camera, result.std_intrinsics
    typer.echo(
        f"wrote {out} ({fmt}): model {result.fit.candidate.name}, {len(result.views)} views, "
        f"RMS {result.fit.rms_px:.3f} px"
    )
    typer.echo(
        f"fx {cam.fx:.3f} +- {s['fx']:.3f}  fy {cam.fy:.3f} +- {s['fy']:.3f}  "
        f"cx {cam.cx:.3f} +- {s['cx']:.3f}  cy {cam.cy:.3f} +- {s['cy']:.3f}  (1 sigma, px)"
    )
    jk = result.std_jackknife
    if jk:
        typer.echo(
            f"view-to-view (jackknife over {result.n_folds} folds): fx +- {jk['fx']:.3f}  fy +- {jk['fy']:.3f}  "
            f"cx +- {jk['cx']:.3f}  cy +- {jk['cy']:.3f} px"
        )
    typer.echo("dist " + " ".join(f"{v:.6g}" for v in cam.dist_coeffs))
    typer.echo(
        f"observed radius {cam.observed_radius_px:.0f} px; projection uncertainty inside it "
        f"<= {result.projection_sigma_px['max_observed']:.3f} px (1 sigma)"
    )
    aligned, aligned95 = (
        result.projection_sigma_px.get(k) for k in ("max_observed_aligned", "max_observed_aligned_95")
    )
    if aligned is not None and aligned95 is not None:
        # What matters once a cell calibration has absorbed a small camera rotation.
        typer.echo(
            f"  after the camera's small rotation is absorbed: <= {aligned:.3f} px (1 sigma); "
            f"largest error below {aligned95:.3f} px in 95 % of calibrations"
        )
    for sc in result.scores:
        typer.echo(
            f"  {'*' if sc.chosen else ' '} {sc.name:24s} params {sc.n_params:2d}  train {sc.train_rms_px:.4f}  "
            f"held-out {sc.held_out_rms_px:.4f} px"
        )
    for w in calibration_warnings(result, outcome.detected.scan):
        typer.echo(f"warning: {w}", err=True)


def _echo_depth(stored_bits: int | None) -> None:
    """The depth a camera stores its levels at in 16-bit photographs, where they showed one."""
    if stored_bits is not None:
        typer.echo(
            f"camera levels: {stored_bits} bits stored from 0 in 16-bit photographs (stored_bits: {stored_bits} in "
            "the calibration file: locate reads the cell's 16-bit images at that depth)"
        )


def _echo_response(response: BoardResponse | None, stored_bits: int | None = None) -> None:
    """The measured camera response and the cell-file lines it allows (SPEC section 2), after the depth its
    levels are stored at where the photographs showed one."""
    _echo_depth(stored_bits)
    if response is None:
        typer.echo(
            "camera response: not measured (a chessboard in 5 photographs or more, squares over about 30 px)"
        )
        return
    f = response.unmeasured_factor
    typer.echo(
        f"camera response: gamma {response.gamma:.2f} +- {response.sigma:.2f} (1 sigma, median of "
        f"{len(response.per_image)} photographs); for the cell file: camera.response_gamma: "
        f"{response.gamma:.2f}, camera.response_gamma_sigma: {response.sigma:.2f} (a cell that names "
        f"this calibration file and no response takes both; the doubt they allow where an image cannot "
        f"check the response, locate.response_unmeasured_factor: {f:.2f})"
        + (
            ""
            if f < 1.5
            else " (too uncertain to narrow the default 2.2 much: JPEG or in-camera sharpening?)"
        )
    )


def _echo_warnings(done: CameraCalibration) -> None:
    """The photographs skipped, and a measurement that failed without costing the calibration, on stderr."""
    _echo_skipped(done.outcome.detected.skipped)
    if done.response_problem:
        typer.echo(f"warning: the camera response was not measured ({done.response_problem})", err=True)
    if done.optics_problem:
        typer.echo(f"warning: the camera optics were not measured ({done.optics_problem})", err=True)


def _echo_optics(check: BoardCheck | None, images_dir: Path, pattern: str, square: float, out: Path) -> None:
    """What ``calibrate --optics`` measured of the camera's optics (``check``), or that the calibration left
    them unmeasured and the command that measures them on the same photographs (chessboards only)."""
    from doorloc.vision.config import LocateConfig

    if check is not None:
        _echo_measured_optics(check)
        return
    typer.echo(
        "camera optics: not measured; locate counts locate.optics_edge_sigma_px "
        f"({LocateConfig().optics_edge_sigma_px:g} px by default) on every edge for them, and doubts a "
        "shoulder in the response. To measure them on these photographs (minutes): run this command again "
        f"without --no-optics, or, with a report of what they show, doorloc check-model --boards {images_dir} "
        f"--pattern {pattern} --square {square:g} --calibration {out} --out REPORT_DIR, then name "
        "REPORT_DIR/camera_photometric.yaml in the cell's camera.calibration"
    )


def _echo_measured_optics(check: BoardCheck) -> None:
    """What ``calibrate --optics`` measured and wrote: the causes named, the response's shoulder where one was
    found, the held-out edge residual locate counts in place of ``locate.optics_edge_sigma_px``."""
    m = check.model
    shoulder = (
        f"; its response compresses the levels above {m.shoulder:.2f} of full scale (a shoulder)"
        if m.shoulder < 1.0
        else "; no shoulder in its response"
    )
    typer.echo(
        f"camera optics: measured on {len(check.photographs)} photographs: "
        f"{', '.join(check.causes) or 'nothing beyond the plain edge model'}{shoulder}; the edges keep "
        f"{m.residual_edge_px:.3f} px held out, which locate counts on every edge in place of "
        "locate.optics_edge_sigma_px. The photometric model is in the calibration file: a cell that names it "
        "(camera.calibration) uses it"
    )


def _warn_beyond_valid_radius(camera: CameraModel, pixels: list[np.ndarray], cell_path: Path) -> None:
    """Warn when the board or the reference corner lies where the camera model is not to be trusted."""
    import numpy as np

    from doorloc.calib.camera import distortion_validity

    valid = distortion_validity(camera).valid_radius_px
    if valid is None:
        return
    c = np.array([camera.cx, camera.cy])
    reach = max(float(np.linalg.norm(np.reshape(px, (-1, 2)) - c, axis=1).max()) for px in pixels)
    if reach > valid:
        typer.echo(
            f"warning: the board or the reference corner lies {reach:.0f} px from the principal point, "
            f"beyond the camera model's valid radius {valid:.0f} px (doorloc validity "
            f"{cell_path}); recalibrate the camera with views reaching there",
            err=True,
        )


Vec3 = tuple[float, float, float]
BoardSide = Annotated[float, typer.Option("--square", metavar="MM", help="square side, mm")]
CharucoFlag = Annotated[bool, typer.Option("--charuco", help="the board is a ChArUco board")]
MarkerOption = Annotated[float | None, typer.Option(metavar="MM", help="ChArUco marker side, mm")]
DictionaryOption = Annotated[str, typer.Option(help="ChArUco ArUco dictionary")]
LegacyFlag = Annotated[bool, typer.Option("--legacy", help="ChArUco board in OpenCV's pre-4.6 layout")]
OpticsFlag = Annotated[
    bool | None,
    typer.Option(
        "--optics/--no-optics",
        help="also measure the camera's optics and its response beyond a power law on the same photographs, "
        "as check-model --boards does, into the calibration file (a chessboard's default; a minute or "
        "more); --no-optics leaves them unmeasured",
    ),
]


def _board_or_fail(
    pattern: str, square: float, charuco: bool, marker: float | None, dictionary: str, legacy: bool
):
    """:func:`_board`, exit 2 with its sentence for a bad ``--pattern``, ``--square`` or ``--marker``."""
    try:
        return _board(pattern, square, charuco, marker, dictionary, legacy)
    except ValueError as e:
        raise fail(str(e)) from None


def _calibrated(
    images_dir: Path, board, model: str, folds: int, min_views: int, camera_name: str, optics: bool = False
) -> CameraCalibration:
    """:func:`doorloc.app.services.calibrate_camera`; exit 3 (nothing written) when too few views show the
    board or the fit fails, 2 for no images or a bad ``--model``."""
    from doorloc.app.services import calibrate_camera
    from doorloc.calib.calibrate import CalibrationError
    from doorloc.calib.folder import CalibrationInputError, TooFewViewsError

    try:
        return calibrate_camera(
            images_dir,
            board,
            candidates=_candidates(model),
            n_folds=folds,
            min_views=min_views,
            camera_name=camera_name,
            measure_optics=optics,
            progress=(lambda m: typer.echo(f"camera optics: {m}", err=True)) if optics else None,
        )
    except TooFewViewsError as e:
        _echo_skipped(e.detected.skipped)
        raise fail(f"{e} (nothing written)", EXIT_FAILED) from None
    except CalibrationError as e:
        raise fail(f"{e} (nothing written)", EXIT_FAILED) from None
    except (CalibrationInputError, ValueError) as e:  # no images, or a bad --model
        raise fail(str(e)) from None


def calibrate_cmd(
    images_dir: Annotated[
        Path, typer.Argument(help="folder of board photographs (one camera, one image size)")
    ],
    pattern: Annotated[
        str,
        typer.Option(
            metavar="COLSxROWS",
            help="chessboard: inner corners (e.g. 9x6; the Bouguet set: 13x12); ChArUco: squares",
        ),
    ],
    square: BoardSide,
    out: Annotated[Path, typer.Option(help="calibration file to write (camera.yaml)")],
    charuco: CharucoFlag = False,
    marker: MarkerOption = None,
    dictionary: DictionaryOption = "DICT_4X4_50",
    legacy: LegacyFlag = False,
    report: Annotated[Path | None, typer.Option(help="folder for calibration_report.json and .png")] = None,
    fmt: Annotated[
        str, typer.Option("--format", help="opencv (FileStorage YAML) or ros (camera_info)")
    ] = "opencv",
    model: Annotated[
        str, typer.Option(help="'auto' (choose by held-out error) or a candidate, e.g. plumb_bob")
    ] = "auto",
    folds: Annotated[int, typer.Option(min=2, help="K of the K-fold held-out model selection")] = 5,
    min_views: Annotated[int, typer.Option(min=3, help="fewest usable views to calibrate with")] = 4,
    camera_name: Annotated[str, typer.Option(help="camera name stored in the file")] = "doorloc",
    optics: OpticsFlag = None,
) -> None:
    """Calibrate a camera from photographs of a chessboard or ChArUco board.

    With a chessboard it also measures the camera's response on the squares' edges (written to the
    file as response_gamma +- response_gamma_sigma, and printed as the cell-file lines it allows),
    and the camera's photometric model (a shoulder or a pedestal in its response, its point spread,
    what its edges keep held out), which locate then uses in place of the doubts it grants a camera
    nobody measured (--no-optics: not measured).
    Images without a board, unreadable files and images of another size are skipped with a
    reason; the calibration goes ahead if enough views remain. Exit codes: 0 done, 2 bad
    arguments or input, 3 too few usable views (nothing written).
    """
    from doorloc.calib.io import save_calibration
    from doorloc.calib.report import write_report

    if fmt not in ("opencv", "ros"):
        raise fail(f"--format must be opencv or ros, got {fmt!r}")
    if optics and charuco:
        raise fail("--optics reads a chessboard's square edges; a ChArUco board's are broken by its markers")
    board = _board_or_fail(pattern, square, charuco, marker, dictionary, legacy)
    done = _calibrated(
        images_dir, board, model, folds, min_views, camera_name, not charuco and optics is not False
    )
    _echo_warnings(done)
    save_calibration(done.calibration, out, fmt)
    if report is not None:
        d = done.outcome.detected
        write_report(report, done.outcome.result, d.scan, board, d.background)
    _echo_calibration(done.outcome, out, fmt)
    _echo_response(done.response, done.calibration.stored_bits)
    if not charuco:
        _echo_optics(done.optics, images_dir, pattern, square, out)


def calibrate_cell_cmd(
    image: Annotated[Path, typer.Argument(help="one image of the board lying on the hinge-face plane")],
    cell: Annotated[Path, typer.Option(help="cell file with the calibrated camera (cell.yaml)")],
    pattern: Annotated[
        str, typer.Option(metavar="COLSxROWS", help="chessboard inner corners; ChArUco: squares")
    ],
    square: BoardSide,
    board_origin: Annotated[
        tuple[float, float, float],
        typer.Option(
            metavar="X Y Z",
            help="cell position (mm) of the board origin: chessboard corner 0 = the inner corner seen top-left; "
            "ChArUco corner id 0",
        ),
    ],
    out: Annotated[Path, typer.Option(help="cell file to write (may be the same as --cell)")],
    board_x_axis: Annotated[
        Vec3, typer.Option(metavar="X Y Z", help="cell direction of the board's rows (image-right: +X)")
    ] = (1.0, 0.0, 0.0),
    board_y_axis: Annotated[
        Vec3, typer.Option(metavar="X Y Z", help="cell direction of the board's columns (image-down: -Z)")
    ] = (0.0, 0.0, -1.0),
    charuco: CharucoFlag = False,
    marker: MarkerOption = None,
    dictionary: DictionaryOption = "DICT_4X4_50",
    legacy: LegacyFlag = False,
    max_rms: Annotated[float, typer.Option(help="refuse (exit 1, nothing written) above this RMS, px")] = 1.0,
) -> None:
    """Camera extrinsics from one image of a board at a known place in the cell -> cell.yaml.

    Prints the reprojection error and the mm per pixel at the reference corner. Exit codes:
    0 written, 1 refused (no board, or a poor fit), 2 bad arguments or files.
    """
    from doorloc.app.services import PlacementRefused, place_camera
    from doorloc.cell import CellFileError
    from doorloc.fileio import atomic_write_text

    board = _board_or_fail(pattern, square, charuco, marker, dictionary, legacy)
    axes = (board_origin, board_x_axis, board_y_axis)
    try:
        placed = place_camera(
            cell, image, board, *axes, board_label=pattern, out_path=out, max_rms_px=max_rms
        )
    except PlacementRefused as e:
        raise fail(str(e), EXIT_REFUSED) from None
    except (ValueError, CellFileError) as e:
        raise fail(str(e)) from None
    atomic_write_text(out, placed.cell_yaml)
    _echo_placement(out, placed, cell)


def _echo_placement(out: Path, placed: CameraPlacement, cell_path: Path) -> None:
    """What ``doorloc calibrate-cell`` prints after writing: the extrinsics, the fit, the scale."""
    res = placed.fit
    typer.echo(
        f"wrote {out}: rvec {[round(float(v), 6) for v in res.extrinsics.rvec]} "
        f"tvec_mm {[round(float(v), 3) for v in res.extrinsics.tvec_mm]}"
    )
    typer.echo(
        f"board RMS {res.rms_px:.3f} px (max {res.max_residual_px:.3f} px, {res.n_corners} corners); "
        f"reference corner at pixel ({res.reference_corner_px[0]:.1f}, {res.reference_corner_px[1]:.1f}), "
        f"{res.scale_mm_per_px:.4f} mm/px; reference corner uncertainty "
        f"{res.reference_corner_sigma_px * res.scale_mm_per_px:.4f} mm (1 sigma, intrinsics exact)"
    )
    _warn_beyond_valid_radius(placed.camera, [placed.corners_px, res.reference_corner_px], cell_path)


def validity_cmd(
    path: Annotated[Path, typer.Argument(help="a calibration file (OpenCV or ROS YAML) or a cell file")],
    as_json: Annotated[bool, typer.Option("--json", help="print the validity report as JSON")] = False,
) -> None:
    """Where a camera model can be trusted: fold-over radius, observed radius, the image corners.

    Exit code 0 when the distortion model is one-to-one over the whole image, 1 when it folds
    over inside the image (unusable beyond the fold radius), 2 for an unreadable file.
    """
    from doorloc.calib.camera import distortion_validity
    from doorloc.calib.io import CalibrationFileError, load_calibration
    from doorloc.cell import CellFileError, load_cell

    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise fail(f"cannot read {path}: {getattr(e, 'strerror', None) or e}") from None
    try:
        # A cell file has a top-level 'camera:' mapping; a calibration file has 'camera_matrix'.
        if re.search(r"^camera:", text, flags=re.MULTILINE):
            camera = load_cell(path).camera
        else:
            camera = load_calibration(path).camera
    except (CalibrationFileError, CellFileError) as e:
        raise fail(str(e)) from None
    v = distortion_validity(camera)
    if as_json:
        typer.echo(json.dumps({"file": str(path), **v.to_dict()}, indent=2))
    else:
        typer.echo("\n".join(_validity_lines(path, camera, v)))
        for w in v.warnings:
            typer.echo(f"warning: {w}", err=True)
    if not v.corners_inside_fold:
        raise typer.Exit(EXIT_REFUSED)


def _validity_lines(path: Path, camera: CameraModel, v: DistortionValidity) -> list[str]:
    """The validity report as lines for a person."""
    lines = [
        f"{path}: {camera.image_size[0]}x{camera.image_size[1]}, distortion "
        f"[{', '.join(f'{c:.6g}' for c in camera.dist_coeffs)}]"
    ]
    if v.fold_radius_px is None:
        lines.append("fold-over radius: none (the distortion is one-to-one out to three image diagonals)")
    else:
        lines.append(
            f"fold-over radius: {v.fold_radius_px:.1f} px from the principal point "
            f"(image corners at {v.corner_radius_px:.1f} px)"
        )
    obs = "unknown" if v.observed_radius_px is None else f"{v.observed_radius_px:.1f} px"
    valid = "unknown" if v.valid_radius_px is None else f"{v.valid_radius_px:.1f} px"
    lines.append(f"observed radius: {obs}; valid radius: {valid}")
    for c in v.corner_report:
        angle = (
            "no ray (beyond the fold)"
            if c["field_angle_deg"] is None
            else f"field angle {c['field_angle_deg']:.1f} deg"
        )
        land = c["ideal_ray_lands_at_px"]
        lines.append(
            f"  {c['corner']:12s} pixel ({c['pixel'][0]:.1f}, {c['pixel'][1]:.1f}): "
            f"{'undistortable' if c['undistortable'] else 'NOT undistortable'}, {angle}; the ray a "
            f"pinhole sees there is sent to ({round(land[0])}, {round(land[1])}), "
            f"{c['distortion_shift_px']:.0f} px away"
        )
    if not v.corners_inside_fold:
        lines.append(
            f"UNUSABLE beyond {v.fold_radius_px:.0f} px from the principal point: the model folds over inside the image"
        )
    return lines


def register(app: typer.Typer) -> None:
    """Add this area's subcommands to the root app."""
    app.command("calibrate")(calibrate_cmd)
    app.command("calibrate-cell")(calibrate_cell_cmd)
    app.command("validity")(validity_cmd)


__all__ = ["register", "parse_pattern", "EXIT_USAGE"]

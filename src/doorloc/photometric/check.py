"""The model check on photographs of a board: measure, fit, choose by held-out photographs, report.

:func:`check_boards` is the one call behind ``doorloc check-model --boards`` (the shared specification's
section 8b); its result holds every figure of ``report.json``. Steps:

1. find the board in each photograph (:mod:`doorloc.calib.detect`); the calibration is the one given or,
   without one, calibrated from the same photographs (:mod:`doorloc.calib.folder`);
2. place every square edge with the plain model and measure its offset from the board's line
   (:mod:`~doorloc.photometric.board_edges`);
3. choose the edge-moving causes by photographs held out (:mod:`~doorloc.photometric.fit`), then the profile
   causes: the point spread's halo by held-out profile misfit, an interlaced camera's fields out of register
   by each photograph's edges held out (:func:`field_offsets`; at least :data:`FIELD_OFFSET_MIN_PX`), the
   blur's field and direction terms by held-out edge blurs (:mod:`~doorloc.photometric.blur`);
4. each photograph's figures with the plain model and with the model fitted without its fold;
5. each photograph's rendered twin (:mod:`~doorloc.photometric.twin`), whose misfit is what the profile misfit
   is judged against (:meth:`BoardCheck.profile_over_twin`).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from doorloc.calib.calibrate import View
from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard, stored_bits_of, stored_grey_8bit
from doorloc.calib.folder import (
    CalibrationError,
    CalibrationInputError,
    DetectedViews,
    LoadedImage,
    detect_views,
    read_folder,
)
from doorloc.calib.io import CalibrationFile
from doorloc.photometric.blur import BlurTerms, EdgeBlurs, blur_terms
from doorloc.photometric.board_edges import BoardEdges, EdgeSettings, measure_board_edges
from doorloc.photometric.catalogue import CAUSES_BY_NAME, EDGE_CAUSES, PROFILE_CAUSES, keep_sigmas
from doorloc.photometric.fit import (
    Photograph,
    Selection,
    direction_noise_floor_px,
    folds_by_photograph,
    noise_floor_px,
    select_causes,
    transition_centres_px,
)
from doorloc.photometric.model import PLAIN, PhotometricModel
from doorloc.photometric.profiles import (
    GAP_TO_PLACE_GREY,
    EdgeProfiles,
    FieldFlip,
    FieldOffset,
    ResidualProfile,
    camera_or_print,
    field_flip,
    fit_field_offset,
    fit_profiles,
    gap_place_px,
    mean_residual_profile,
)
from doorloc.photometric.twin import ProfileTwin, profile_twins, read_jpeg_quality
from doorloc.sim.boards import Checkerboard

__all__ = [
    "BoardCheckError",
    "BoardCheckOptions",
    "BoardCheck",
    "PhotographResult",
    "MeasuredBoards",
    "check_boards",
    "check_photographs",
    "field_offsets",
    "grid_choice",
    "FieldOffsets",
    "measure_boards",
    "measure_detected",
    "response_measured_to",
]

#: fewest photographs with the whole board a check is attempted with (one held out, two to fit)
MIN_PHOTOGRAPHS = 3
#: the least RMS over photographs of their interlaced fields' offsets (px) that names the cause, beside the
#: held-out gain's significance: an offset of a few hundredths of a pixel reshapes no profile that matters, and
#: JPEG's blocks leave such readings (rendered boards without fields, through JPEG of quality 20-75, read
#: 0.015-0.034 px on the rows :data:`~doorloc.photometric.profiles.FIELD_READ_ROWS`; read on every row they had
#: passed the significance test at 0.02-0.07 px); Bouguet's camera reads 0.2 px
FIELD_OFFSET_MIN_PX = 0.03
#: halo fractions tried for the point spread's tail (``psf_tail``), with its scale ``psf_tail_px``
TAIL_GRID = ((0.02, 3.0), (0.05, 3.0), (0.1, 3.0), (0.05, 6.0), (0.1, 6.0))


@dataclass(frozen=True)
class FieldOffsets:
    """What the photographs say of an interlaced camera's fields (:func:`field_offsets`): per photograph its
    offset from all its edges (``own``) and its profile misfit (grey levels, RMS over its windows) with each
    half of its edges read through the other half's offset (``heldout_rms``); the mean squared misfit those
    take off, paired over photographs, and its standard error (``gain``, grey levels^2)."""

    own: list[FieldOffset]
    heldout_rms: np.ndarray
    gain: tuple[float, float]

    def _read(self) -> list[FieldOffset]:
        return [o for o in self.own if np.isfinite(o.u_px)]

    def _read_vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """The offsets read (n, 2: u, v px) and their standard errors (n, 2)."""
        read = self._read()
        return np.array([o.vector for o in read]), np.array([(o.sigma_u_px, o.sigma_v_px) for o in read])

    @property
    def rms_px(self) -> float:
        """RMS over photographs of their offsets' length, px (0 where none was read)."""
        f = self._read_vectors()[0]
        return float(np.sqrt(np.mean(np.sum(f**2, axis=1)))) if f.size else 0.0

    def mean_and_scatter(self) -> tuple[np.ndarray, np.ndarray, float]:
        """The offset's mean over photographs (u, v px), its standard error, and the photographs' scatter about
        it (px, RMS per component, their own standard errors taken off in quadrature)."""
        f, se = self._read_vectors()
        if f.shape[0] < 2:
            return np.zeros(2), np.full(2, np.nan), 0.0
        return f.mean(axis=0), f.std(axis=0, ddof=1) / np.sqrt(f.shape[0]), _scatter(f, se)

    def scatter_sigma(self) -> float:
        """The 1-sigma of :meth:`mean_and_scatter`'s scatter (px): the delete-one jackknife over the
        photographs read (NaN under three)."""
        f, se = self._read_vectors()
        n = f.shape[0]
        if n < 3:
            return float("nan")
        each = np.array([_scatter(np.delete(f, i, axis=0), np.delete(se, i, axis=0)) for i in range(n)])
        return float(np.sqrt((n - 1) / n * np.sum((each - each.mean()) ** 2)))


def _scatter(f: np.ndarray, se: np.ndarray) -> float:
    """The scatter of offsets ``f`` (n, 2) about their mean, px (RMS per component, their standard errors
    ``se`` (n, 2) taken off in quadrature; 0 where those hold it all)."""
    spread = float(np.mean((f - f.mean(axis=0)) ** 2) - np.mean(se**2))
    return float(np.sqrt(max(spread, 0.0)))


def field_offsets(
    photos: list[Photograph],
    models: list[PhotometricModel],
    keep: list[np.ndarray],
    shifts: list[np.ndarray],
) -> FieldOffsets:
    """Each photograph's interlaced fields' offset (:func:`~doorloc.photometric.profiles.fit_field_offset`,
    with its fold's model ``models[i]``, its scan lines ``keep[i]`` and its edges' centres ``shifts[i]``), and
    the evidence for it held out within the photograph: its edges split in two interleaved halves, each half's
    profiles fitted with the offset the other half gives against with none. The offset is one photograph's
    (motion between the fields' exposures is), so it is held out by edges, as a blur or a level is measured
    on its own edge, not predicted from other photographs."""
    own, rms, gains = [], [], []
    for p, m, k, sh in zip(photos, models, keep, shifts, strict=True):
        e = p.edges
        own.append(fit_field_offset(e, m, k, sh))
        half = e.windows.edge % 2 == 0
        sq0 = sq1 = n = 0.0
        for part, other in ((k & half, k & ~half), (k & ~half, k & half)):
            f_other = fit_field_offset(e, m, other, sh).vector
            r0 = fit_profiles(e, m, part, sh).residual
            r1 = fit_profiles(e, m, part, sh, f_other).residual
            ok = np.isfinite(r0) & np.isfinite(r1)
            sq0 += float(np.sum(r0[ok] ** 2))
            sq1 += float(np.sum(r1[ok] ** 2))
            n += float(ok.sum())
        rms.append(np.sqrt(sq1 / n) if n else np.nan)
        gains.append((sq0 - sq1) / n if n else np.nan)
    g = np.asarray(gains, float)
    g = g[np.isfinite(g)]
    gain = (float(g.mean()), float(g.std(ddof=1) / np.sqrt(g.size))) if g.size >= 2 else (0.0, np.inf)
    return FieldOffsets(own, np.asarray(rms, float), gain)


class BoardCheckError(ValueError):
    """Input the check cannot use (no folder, no images, too few photographs showing the whole board);
    the message says what to do."""


@dataclass(frozen=True)
class BoardCheckOptions:
    """``folds``: photographs are held out in this many folds (>= the number of photographs: one at a time);
    ``settings``: how edges are placed."""

    folds: int = 5
    settings: EdgeSettings = EdgeSettings()


@dataclass(frozen=True)
class PhotographResult:
    """One photograph's figures (px, grey levels)."""

    image: str
    heldout: bool
    n_edges: int
    offset_before_px: float
    offset_after_px: float
    noise_px: float
    profile_rms_before: float
    profile_rms_after: float
    noise_grey: float
    noise_rms_grey: float
    edges: BoardEdges
    profiles_before: EdgeProfiles
    profiles_after: EdgeProfiles


@dataclass(frozen=True)
class BoardCheck:
    """Everything the check found (``report.json``'s figures and what the plots need)."""

    causes: list[str]
    model: PhotometricModel
    parameters: dict[str, dict[str, dict[str, float]]]
    photographs: list[PhotographResult]
    selection: Selection
    blur: BlurTerms
    tail_gain: tuple[float, float]
    camera: CameraModel | None
    calibration_source: str
    alternatives: dict[str, list[str]] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    #: each photograph's interlaced fields' offset and the held-out evidence for it (every check reads it)
    fields: FieldOffsets | None = None
    #: each photograph's rendered twin (:mod:`~doorloc.photometric.twin`), in the order of ``photographs``
    #: (None where it has none)
    twins: list[ProfileTwin | None] = field(default_factory=list)
    #: the bits the camera stores its levels at in its 16-bit photographs, read with them (None: 8-bit, or
    #: all 16), which the extended calibration states (``stored_bits``)
    stored_bits: int | None = None

    def heldout_rms(self, attr: str) -> dict[str, float]:
        h = [p for p in self.photographs if p.heldout]

        def rms(v: list[float]) -> float:
            a = np.asarray(v, float)
            a = a[np.isfinite(a)]
            return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")

        return {
            "before": rms([getattr(p, f"{attr}_before" + ("_px" if attr == "offset" else "")) for p in h]),
            "after": rms([getattr(p, f"{attr}_after" + ("_px" if attr == "offset" else "")) for p in h]),
        }

    @functools.cached_property
    def residual_profiles(self) -> tuple[ResidualProfile, ResidualProfile]:
        """The mean residual profiles (:func:`~doorloc.photometric.profiles.mean_residual_profile`) of the
        plain model's and the extended model's fits over every photograph (made once: the plot, report.json
        and report.md each read them)."""
        return (
            mean_residual_profile([p.profiles_before for p in self.photographs]),
            mean_residual_profile([p.profiles_after for p in self.photographs]),
        )

    @functools.cached_property
    def gap_source(self) -> tuple[str | None, np.ndarray, np.ndarray]:
        """Whether the extended model's gap between the rows' and the columns' profiles
        (:meth:`ResidualProfile.direction_gap`) is the camera's or the print's
        (:func:`~doorloc.photometric.profiles.camera_or_print`, None where not told), from where it lies in
        each photograph (px from the edge, :func:`~doorloc.photometric.profiles.gap_place_px`) against its
        board's scale (median px per mm): the verdict, the places and the scales. None and NaN places where
        the gap is under :data:`~doorloc.photometric.profiles.GAP_TO_PLACE_GREY`."""
        gap, at = self.residual_profiles[1].direction_gap()
        scales = np.array([float(np.median(p.edges.px_per_mm)) for p in self.photographs])
        if not abs(gap) >= GAP_TO_PLACE_GREY:
            return None, np.full(scales.size, np.nan), scales
        places = np.array(
            [
                gap_place_px(mean_residual_profile([p.profiles_after]), at, np.sign(gap))
                for p in self.photographs
            ]
        )
        return camera_or_print(places, scales), places, scales

    @functools.cached_property
    def field_flip(self) -> FieldFlip | None:
        """The extended model's residual profiles in the outer field, edges facing out and in
        (:func:`~doorloc.photometric.profiles.field_flip`, about the principal point); None without a
        camera."""
        if self.camera is None:
            return None
        k = self.camera.camera_matrix
        half = 0.5 * float(np.hypot(*self.camera.image_size))
        return field_flip([(p.edges, p.profiles_after) for p in self.photographs], (k[0, 2], k[1, 2]), half)

    def profile_over_twin(self) -> dict[str, float]:
        """The held-out profile misfit (RMS over photographs, plain model and extended) over the misfit the
        photographs' twins leave (RMS over the same photographs): 1 = the profiles are drawn up to what the
        noise and the compression leave; NaN without twins."""
        pairs = [
            (p, t) for p, t in zip(self.photographs, self.twins, strict=False) if p.heldout and t is not None
        ]
        twin = np.array([t.misfit for _, t in pairs], float)
        ok = np.isfinite(twin)
        if not ok.any():
            return {"before": float("nan"), "after": float("nan")}
        ref = float(np.sqrt(np.mean(twin[ok] ** 2)))

        def rms(v: list[float]) -> float:
            a = np.asarray(v, float)[ok]
            a = a[np.isfinite(a)]
            return float(np.sqrt(np.mean(a**2))) / ref if a.size else float("nan")

        return {
            "before": rms([p.profile_rms_before for p, _ in pairs]),
            "after": rms([p.profile_rms_after for p, _ in pairs]),
        }

    @property
    def noise_grey(self) -> float:
        """Median over photographs of each one's median plateau spread (grey levels)."""
        return float(np.median([p.noise_grey for p in self.photographs]))

    @property
    def noise_rms_grey(self) -> float:
        """RMS over photographs of each one's plateau spread RMS over its windows (grey levels): the noise a
        profile misfit is compared with (:meth:`~doorloc.photometric.board_edges.BoardEdges.plateau_spread_rms`)."""
        v = np.asarray([p.noise_rms_grey for p in self.photographs], float)
        v = v[np.isfinite(v)]
        return float(np.sqrt(np.mean(v**2))) if v.size else float("nan")

    @property
    def offset_standard_error_px(self) -> float:
        """RMS over photographs of each one's median offset's standard error (what noise alone leaves), px."""
        return float(np.sqrt(np.nanmean([p.noise_px**2 for p in self.photographs])))


@dataclass(frozen=True)
class MeasuredBoards:
    """A folder of board photographs measured with the plain model: the photographs whose whole board was
    found, the camera they were measured through and where it came from, and why others were skipped."""

    photographs: list[Photograph]
    camera: CameraModel
    camera_source: str
    skipped: list[str]
    #: the bits the camera stores its levels at in 16-bit photographs, which they were read with (None: 8-bit
    #: photographs, or all 16 bits; :func:`doorloc.calib.detect.stored_bits_of`)
    stored_bits: int | None = None


def measure_boards(
    images_dir: str | os.PathLike,
    board: Chessboard,
    calibration: CalibrationFile | None = None,
    settings: EdgeSettings = EdgeSettings(),
    progress: Callable[[str], None] | None = None,
) -> MeasuredBoards:
    """Steps 1 and 2 of the check: read the photographs in ``images_dir``, find ``board``, calibrate if no
    ``calibration`` is given, and place every square edge with the plain model, 16-bit photographs read at
    the depth the calibration states (``stored_bits``) or their levels show
    (:func:`doorloc.calib.detect.stored_bits_of`). Raises :class:`BoardCheckError` for input it cannot use."""
    from doorloc.calib.folder import calibrate_detected

    say = progress or (lambda _m: None)
    try:
        images = read_folder(images_dir)
    except CalibrationInputError as e:
        raise BoardCheckError(str(e)) from None
    detected = detect_views(images, board)
    full, skipped = _whole_board_views(detected, board, images_dir, len(images))
    if calibration is None:
        say(f"no calibration given: calibrating from the {len(detected.views)} photographs")
        try:
            camera = calibrate_detected(detected).result.camera
        except CalibrationError as e:
            raise BoardCheckError(
                f"cannot calibrate from these photographs ({e}); give --calibration"
            ) from None
        source = "calibrated from the same photographs"
    else:
        camera = calibration.camera
        source = "given"
    if detected.scan.image_size is not None and tuple(detected.scan.image_size) != tuple(camera.image_size):
        raise BoardCheckError(
            f"the photographs are {detected.scan.image_size[0]}x{detected.scan.image_size[1]} px but the "
            f"calibration is for {camera.image_size[0]}x{camera.image_size[1]} px"
        )
    bits = calibration.stored_bits if calibration is not None else None
    if bits is None:
        bits = stored_bits_of(im for _, im, _ in images)
    return _measured(images, full, skipped, board, camera, source, images_dir, settings, progress, bits)


def _whole_board_views(
    detected: DetectedViews, board: Chessboard, images_dir: str | os.PathLike, n_images: int
) -> tuple[list[View], list[str]]:
    """The views that show the whole board, and why the others were skipped; raises
    :class:`BoardCheckError` where fewer than :data:`MIN_PHOTOGRAPHS` do."""
    full = [v for v in detected.views if v.n == board.n_corners]
    skipped = [f"{s.name}: {s.reason}" for s in detected.skipped] + [
        f"{v.name}: only part of the board is seen" for v in detected.views if v.n != board.n_corners
    ]
    if len(full) < MIN_PHOTOGRAPHS:
        raise BoardCheckError(
            f"only {len(full)} of {n_images} images in {images_dir} show the whole {board.cols}x{board.rows} "
            f"board; the check needs at least {MIN_PHOTOGRAPHS} (is --pattern the inner corners, COLSxROWS?)"
        )
    return full, skipped


def measure_detected(
    images: list[LoadedImage],
    detected: DetectedViews,
    board: Chessboard,
    camera: CameraModel,
    camera_source: str,
    images_dir: str | os.PathLike,
    settings: EdgeSettings = EdgeSettings(),
    progress: Callable[[str], None] | None = None,
    stored_bits: int | None = None,
) -> MeasuredBoards:
    """Step 2 of the check on photographs already read (``images``, from ``images_dir``) and searched for
    ``board`` (``detected``), as a calibration leaves them: every square edge of the views that show the
    whole board placed with the plain model through ``camera``, 16-bit photographs read as storing
    ``stored_bits`` (None: all 16). Raises :class:`BoardCheckError` where too few photographs can be used."""
    full, skipped = _whole_board_views(detected, board, images_dir, len(images))
    return _measured(
        images, full, skipped, board, camera, camera_source, images_dir, settings, progress, stored_bits
    )


def _measured(
    images: list[LoadedImage],
    full: list[View],
    skipped: list[str],
    board: Chessboard,
    camera: CameraModel,
    camera_source: str,
    images_dir: str | os.PathLike,
    settings: EdgeSettings,
    progress: Callable[[str], None] | None,
    stored_bits: int | None = None,
) -> MeasuredBoards:
    """:func:`measure_detected` on its whole-board views ``full`` (``skipped``: why the others were)."""
    by_name = {name: im for name, im, _ in images if im is not None}
    photos = []
    for v in full:
        gray = stored_grey_8bit(by_name[v.name], stored_bits)
        corners = v.image_points[np.argsort(v.ids)]
        edges = measure_board_edges(
            gray,
            corners,
            board.cols,
            board.rows,
            board.square_mm,
            camera,
            image=v.name,
            settings=settings,
        )
        if np.isfinite(edges.offset_px).sum() == 0:
            skipped.append(f"{v.name}: squares too small to read an edge on")
            continue
        quality = read_jpeg_quality(Path(images_dir) / v.name)
        photos.append(Photograph(gray, edges, settings, corners, quality))
    if len(photos) < MIN_PHOTOGRAPHS:
        raise BoardCheckError(
            f"only {len(photos)} photographs have squares large enough to read edges on "
            f"(the edge windows need squares of about {(settings.half + settings.plateau) / 0.3:.0f} px)"
        )
    if progress:
        progress(f"{len(photos)} photographs, {sum(p.edges.n_edges for p in photos)} edges")
    return MeasuredBoards(photos, camera, camera_source, skipped, stored_bits)


def check_boards(
    images_dir: str | os.PathLike,
    board: Chessboard,
    calibration: CalibrationFile | None = None,
    options: BoardCheckOptions = BoardCheckOptions(),
    progress: Callable[[str], None] | None = None,
) -> BoardCheck:
    """:func:`measure_boards`, then :func:`check_photographs`. Raises :class:`BoardCheckError` for input it
    cannot use."""
    measured = measure_boards(images_dir, board, calibration, options.settings, progress)
    result = check_photographs(measured.photographs, options, progress)
    if progress:
        progress("rendering each photograph's twin (its pose, levels, noise and compression)")
    own = (
        [f.vector for f in result.fields.own]
        if result.fields is not None and result.model.interlaced
        else None
    )
    twins = profile_twins(
        measured.photographs,
        measured.camera,
        Checkerboard(board.cols, board.rows, board.square_mm),
        result.model,
        own,
    )
    return BoardCheck(
        result.causes,
        result.model,
        result.parameters,
        result.photographs,
        result.selection,
        result.blur,
        result.tail_gain,
        measured.camera,
        measured.camera_source,
        result.alternatives,
        measured.skipped,
        result.fields,
        twins,
        measured.stored_bits,
    )


def grid_choice(value: float, per_fold: np.ndarray, grid: Sequence[float]) -> dict[str, float]:
    """A parameter chosen from ``grid``'s values (``value`` on all photographs, ``per_fold`` with each fold
    held out) as the report states it: its 1-sigma the delete-a-fold jackknife of the folds' choices, as
    the edge causes' is (:func:`doorloc.photometric.fit.held_out`), and no less than half the step to the
    nearest other value tried (where every fold picks the same value, the grid's resolution is what is known
    of it, not a zero); ``at_bound`` where it is the grid's least or largest value (the data may ask for
    more than was tried)."""
    k = per_fold.size
    jackknife = math.sqrt((k - 1) / k * float(((per_fold - per_fold.mean()) ** 2).sum())) if k > 1 else 0.0
    others = [abs(g - value) for g in set(grid) if g != value]
    resolution = 0.5 * min(others) if others else math.nan
    return {
        "value": value,
        "sigma": max(jackknife, resolution),
        "at_bound": float(value in (min(grid), max(grid))),
    }


def check_photographs(
    photos: list[Photograph],
    options: BoardCheckOptions = BoardCheckOptions(),
    progress: Callable[[str], None] | None = None,
) -> BoardCheck:
    """The check on measured photographs (module docstring, steps 3 and 4); ``camera`` is left unset (None)."""
    folds = folds_by_photograph(len(photos), options.folds)
    sel = select_causes(photos, EDGE_CAUSES, folds=options.folds, progress=progress)
    model = sel.fit.model
    fold_models = [f.model for f in sel.heldout.fits] if sel.causes else [PLAIN] * len(photos)
    # the point spread's halo: held-out profile misfit with the halo fitted on the other folds
    keep = [np.isfinite(p.edges.offset_px) for p in photos]

    shifts = [transition_centres_px(p, m) for p, m in zip(photos, fold_models, strict=True)]
    plain_shifts = [transition_centres_px(p, PLAIN) for p in photos]

    def misfit(i: int, m: PhotometricModel) -> float:
        return fit_profiles(photos[i].edges, m, keep[i], shifts[i]).rms_over_windows()

    base = np.array([misfit(i, fold_models[i]) for i in range(len(photos))])
    # each photograph's misfit with each halo, under the model its fold fitted (reused by every fold)
    with_tail = np.array(
        [
            [misfit(i, fold_models[i].with_values(psf_tail=t, psf_tail_px=b)) for t, b in TAIL_GRID]
            for i in range(len(photos))
        ]
    )
    tail_choice: dict[int, tuple[float, float]] = {}
    trial = np.empty(len(photos))
    for f in np.unique(folds).tolist():
        train = folds != f
        tail_choice[int(f)] = TAIL_GRID[int(np.argmin((with_tail[train] ** 2).mean(0)))]
        held = np.flatnonzero(~train)
        trial[held] = with_tail[held, TAIL_GRID.index(tail_choice[int(f)])]
    d = base**2 - trial**2
    tail_gain = (float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size)))
    causes = list(sel.causes)
    parameters: dict[str, dict[str, dict[str, float]]] = {}
    for name in CAUSES_BY_NAME:  # in the catalogue's order
        if name in causes:
            c = sel.cause(name)
            parameters[c.name] = {
                n: {
                    "value": float(getattr(model, n)),
                    "sigma": float(sel.heldout.sigma.get(n, float("nan"))),
                    # a value on its range's end: the data ask for more than this form of the cause allows
                    "at_bound": float(min(abs(getattr(model, n) - lo), abs(getattr(model, n) - hi)) < 1e-3),
                }
                for n, lo, hi in zip(c.parameters, c.lower, c.upper, strict=True)
            }
    # the halo and the blur's two terms are the profile causes tried on every check
    if tail_gain[0] > keep_sigmas(len(PROFILE_CAUSES)) * tail_gain[1]:
        scores_all = [
            np.mean(
                [misfit(i, model.with_values(psf_tail=t, psf_tail_px=b)) ** 2 for i in range(len(photos))]
            )
            for t, b in TAIL_GRID
        ]
        t, b = TAIL_GRID[int(np.argmin(scores_all))]
        model = model.with_values(psf_tail=t, psf_tail_px=b)
        fold_models = [
            m.with_values(psf_tail=tail_choice[int(f)][0], psf_tail_px=tail_choice[int(f)][1])
            for m, f in zip(fold_models, folds, strict=True)
        ]
        causes.append("psf_tail")
        per_fold = np.array([tail_choice[int(f)] for f in np.unique(folds)])
        parameters["psf_tail"] = {
            name: grid_choice(value, per_fold[:, j], [g[j] for g in TAIL_GRID])
            for j, (name, value) in enumerate((("psf_tail", t), ("psf_tail_px", b)))
        }
    # an interlaced camera's fields out of register: each photograph's own offset, held out by its edges
    fields = field_offsets(photos, fold_models, keep, shifts)
    interlaced = (
        fields.gain[0] > keep_sigmas(len(PROFILE_CAUSES)) * fields.gain[1]
        and fields.rms_px >= FIELD_OFFSET_MIN_PX
    )
    if interlaced:
        mean, se, scatter = fields.mean_and_scatter()
        model = model.with_values(
            field_offset_u_px=float(mean[0]),
            field_offset_v_px=float(mean[1]),
            field_offset_scatter_px=scatter,
        )
        causes.append("interlaced_fields")
        parameters["interlaced_fields"] = {
            "field_offset_u_px": {"value": float(mean[0]), "sigma": float(se[0])},
            "field_offset_v_px": {"value": float(mean[1]), "sigma": float(se[1])},
            "field_offset_scatter_px": {"value": scatter, "sigma": fields.scatter_sigma()},
        }
    # profiles before and after, and the blurs they give
    results = []
    blurs = []
    for i, p in enumerate(photos):
        before = fit_profiles(p.edges, PLAIN, keep[i], plain_shifts[i])
        own = fields.own[i].vector if interlaced else (0.0, 0.0)
        after = fit_profiles(p.edges, fold_models[i], keep[i], shifts[i], own)
        # (the photograph's misfit after: with its edges' halves read through each other's field offset)
        rms_after = float(fields.heldout_rms[i]) if interlaced else after.rms_over_windows()
        blurs.append(EdgeBlurs(after.blur_px, p.edges.mid_px, p.edges.normal, p.edges.image_size))
        noise = p.edges.noise[np.isfinite(p.edges.noise)]
        results.append(
            PhotographResult(
                p.name,
                True,
                p.edges.n_edges,
                float(sel.plain_px[i]),
                float(sel.heldout.offsets_px[i]) if sel.causes else float(sel.plain_px[i]),
                noise_floor_px(p),
                before.rms_over_windows(),
                rms_after,
                float(np.median(noise)) if noise.size else float("nan"),
                p.edges.plateau_spread_rms(p.settings.plateau, keep[i]),
                p.edges,
                before,
                after,
            )
        )
    bt = blur_terms(blurs, folds)
    for name in bt.causes:
        causes.append(name)
        parameters[name] = {name: {"value": bt.values[name], "sigma": bt.sigma[name]}}
        model = model.with_values(**{name: bt.values[name]})
    heldout_after = np.array([r.offset_after_px for r in results])
    floor = float(np.sqrt(np.nanmean([r.noise_px**2 for r in results])))
    rms_after = float(np.sqrt(np.nanmean(heldout_after**2)))
    if rms_after > max(0.03, 1.5 * floor) and rms_after > 2.0 * floor:
        causes.append("unexplained")
    # what the model leaves on these photographs' edges, held out: locate's measured doubt of every edge. A
    # door's edge faces one way, so the figure is the larger of the photographs' medians and their medians by
    # edge direction (less the noise of the latter: a quarter of the edges each), which a bias that changes
    # sign with the direction from photograph to photograph leaves and the median over all directions hides
    edge_px = _edge_residual_px(rms_after, sel.heldout.by_direction_px, photos)
    if np.isfinite(edge_px):
        model = model.with_values(residual_edge_px=min(edge_px, 5.0))
    model = model.with_values(response_measured_to=response_measured_to(photos, model.black_level))
    return BoardCheck(
        causes, model, parameters, results, sel, bt, tail_gain, None, "", sel.alternatives, fields=fields
    )


def response_measured_to(photos: list[Photograph], black_level: float) -> float:
    """The level (fraction of full scale above the pedestal ``black_level``) up to which ``photos`` read the
    camera's response: the 90th percentile of their edges' bright plateaus. A shoulder from there would bend
    a tenth of their edges or more, which the check's held-out fit sees; one that starts higher, fewer."""
    b = np.concatenate([p.edges.bright for p in photos]) / 255.0
    b = b[np.isfinite(b)]
    if not b.size:
        return 1.0
    top = (float(np.percentile(b, 90)) - black_level) / (1.0 - black_level)
    return float(np.clip(top, 0.05, 1.0))


def _edge_residual_px(median_rms_px: float, by_direction_px: np.ndarray, photos: list[Photograph]) -> float:
    """What the model leaves on one edge of this camera, px: the held-out RMS of the photographs' medians
    (``median_rms_px``) or, where larger, the RMS of their medians by edge direction (``by_direction_px``,
    photographs x 4) with those medians' own noise taken off in quadrature; NaN where neither is finite."""
    by_dir = np.asarray(by_direction_px, float)
    noise = np.array([direction_noise_floor_px(p) for p in photos])
    ok = np.isfinite(by_dir) & np.isfinite(noise)
    directional = (
        np.sqrt(max(np.mean(by_dir[ok] ** 2) - np.mean(noise[ok] ** 2), 0.0)) if ok.any() else np.nan
    )
    both = np.array([median_rms_px, directional], float)
    return float(np.max(both[np.isfinite(both)])) if np.isfinite(both).any() else float("nan")

"""Fit the edge-moving causes of the catalogue to a set of board photographs and choose among them by
photographs held out.

The practice follows camera calibration's (mrcal's cross-validation, doorloc's own calibrate): a cause is
kept only if the model fitted *without* a photograph places that photograph's edges better, paired over
photographs. The reference is the board: an edge's offset from the line between its two inner corners.
The corners never place an edge: the model only chooses the table through which the area estimator reads
the pixels and the board-length shift of the print; the edge is then placed from the pixels alone.

Residuals: per edge, the mean offset over its scan lines (samples the plain estimate calls outliers,
beyond 4 robust sigmas of their edge's median, are left out once for all fits, so the sum stays smooth in
the parameters), each photograph weighted equally. Parameter 1-sigma: the jackknife over photographs
(the leave-one-out fits that give the held-out figures), which carries the scatter between photographs that
a Jacobian-based sigma of correlated scan lines would not.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares

from doorloc.photometric.board_edges import BoardEdges, EdgeSettings, darkest_plateau, per_edge_median
from doorloc.photometric.catalogue import (
    CAUSES_BY_NAME,
    EDGE_CAUSES,
    KEEP_SIGMAS,
    REFINE_KEEP_SIGMAS,
    REFINED_FORMS,
    TONE_CAUSE,
    TONE_KEEP_SIGMAS,
    Cause,
    keep_sigmas,
)
from doorloc.photometric.clipping import (
    censored_blur_px,
    censored_offsets_px,
    clip_candidates,
    clipped_lines,
    near_clip_edges,
    unclipped_blur_px,
    unclipped_contrast,
    white_starts,
)
from doorloc.photometric.model import CLIPPED_CONTRAST_MAX, PLAIN, PhotometricModel
from doorloc.photometric.profiles import fit_profiles
from doorloc.vision.edges import AreaEdgeReader

__all__ = [
    "Photograph",
    "CauseFit",
    "Selection",
    "place_edges",
    "fit_causes",
    "held_out",
    "select_causes",
    "noise_floor_px",
    "direction_noise_floor_px",
    "folds_by_photograph",
    "photo_median",
    "transition_centres_px",
    "HeldOut",
]

#: a cause that halves a held-out bias this many times the noise's standard error is kept too
BIAS_OVER_NOISE = 5.0
#: candidates within this many standard errors of the best at a step cannot be told apart from it
TIE_SIGMAS = 1.0


@dataclass(frozen=True)
class Photograph:
    """A board photograph's pixels and its measured edges (plain model); ``corners_px`` (cols*rows, 2) its
    board's inner corners as found (image px; None where not kept) and ``jpeg_quality`` the compression its
    file says (0: none or unknown), which its rendered twin takes (:mod:`doorloc.photometric.twin`)."""

    gray: np.ndarray
    edges: BoardEdges
    settings: EdgeSettings = EdgeSettings()
    corners_px: np.ndarray | None = None
    jpeg_quality: int = 0

    @property
    def name(self) -> str:
        return self.edges.image

    @cached_property
    def _area_readers(self) -> list[tuple[np.ndarray, AreaEdgeReader, np.ndarray, np.ndarray, np.ndarray]]:
        # per scan direction: its lines, the area estimator prepared on them, their true edges and the
        # signs and cosines that turn a place along the scan into an offset along the normal
        # (:func:`place_edges` reads them through every model a fit tries)
        w, s = self.edges.windows, self.settings
        out = []
        for is_col in (True, False):
            sel = np.flatnonzero(w.axis == is_col)
            if sel.size:
                scan, true_along = w.scan[sel], w.true_along[sel]
                reader = AreaEdgeReader(
                    self.gray, "col" if is_col else "row", scan, true_along, s.half, s.plateau
                )
                out.append((sel, reader, true_along, w.cos[sel], w.bright_sign[sel]))
        return out

    @cached_property
    def _line_normals_and_scales(self) -> tuple[np.ndarray, np.ndarray]:
        # each scan line's edge's normal towards its bright side (image px; N, 2) and the board's scale
        # across it (px per mm; N,)
        e = self.edges
        return e.normal[e.windows.edge], e.px_per_mm[e.windows.edge]

    @cached_property
    def edge_blur_px(self) -> np.ndarray:
        """Each edge's blur (Gaussian sigma of the optics, px) from its profile under the plain model (E,)."""
        return fit_profiles(self.edges, PLAIN, np.isfinite(self.edges.offset_px)).blur_px

    def unclipped_blur_px(self, clip_level: float) -> float:
        """The camera's blur (px) measured on the edges whose bright plateau stays below the band under a
        clip at ``clip_level`` (:func:`~doorloc.photometric.clipping.near_clip_edges`); NaN where too few do."""
        return unclipped_blur_px(self.edge_blur_px, near_clip_edges(self.edges, clip_level))

    def camera_blur_px(self, model: PhotometricModel) -> float:
        """The blur (px) the clipped edges are read with: the photograph's own unclipped edges', else the
        one its clipped edges' censored fits read with their true step known
        (:func:`~doorloc.photometric.clipping.censored_blur_px`), else the model's ``clipped_blur_px``, else
        all its edges'.

        A clipped edge's own profile reads too sharp (its top flattens early: 0.68-0.79 px against 0.9-0.96
        on OpenCV's photographs), and a censored fit with the step free trades a wider blur against a taller
        step (1.0-1.3 px): neither is used."""
        blur = self.unclipped_blur_px(model.clip_level)
        if np.isfinite(blur):
            return blur
        contrast = self.camera_contrast(model)
        if np.isfinite(contrast):
            key = (
                model.gamma,
                model.black_level,
                model.shoulder,
                model.white_level,
                model.curvature,
                *model.tone,
                model.clip_level,
                contrast,
            )
            if key not in self._censored_blur:
                lines = np.flatnonzero(
                    clipped_lines(self.edges, model.clip_level) & np.isfinite(self.edges.offset_px)
                )
                self._censored_blur[key] = censored_blur_px(self.edges, lines, contrast, model)
            blur = self._censored_blur[key]
            if np.isfinite(blur):
                return blur
        if model.clipped_blur_px > 0:
            return model.clipped_blur_px
        b = self.edge_blur_px
        return float(np.nanmedian(b)) if np.isfinite(b).any() else 1.0

    @cached_property
    def _censored_blur(self) -> dict[tuple[float, ...], float]:
        # the clipped edges' blur under each response, clip and contrast asked for (a fit's many calls
        # ask for the same few)
        return {}

    def unclipped_contrast(self, model: PhotometricModel) -> float:
        """The board's contrast (light square's light over dark square's, in ``model``'s linear light) on the
        edges whose bright plateau stays below the band under ``model``'s clip; NaN where too few do."""
        return unclipped_contrast(self.edges, model, near_clip_edges(self.edges, model.clip_level))

    def camera_contrast(self, model: PhotometricModel) -> float:
        """The contrast the clipped edges' true steps are read with: the photograph's own unclipped edges',
        else the model's ``clipped_contrast``, else NaN (the step is then the clipped one: no correction)."""
        c = self.unclipped_contrast(model)
        if np.isfinite(c):
            return c
        return model.clipped_contrast if model.clipped_contrast > 1 else float("nan")


def place_edges(photo: Photograph, model: PhotometricModel) -> np.ndarray:
    """Offsets (px, + towards bright) of the edges placed with ``model``: the area estimator reads the pixels
    through the model's response (scan lines whose bright square the model's clip level reaches are placed
    by the censored fit of :mod:`doorloc.photometric.clipping` instead), then the print's board-length shift
    and the point spread's asymmetric shift along each edge's normal are taken off (N,)."""
    lut = None if model.linear_response else model.linearizing_lut()
    out = np.full(photo.edges.windows.edge.size, np.nan)
    for sel, reader, true_along, cos, bright_sign in photo._area_readers:
        along, valid = reader.along(lut)
        out[sel] = np.where(valid, (along - true_along) * cos * bright_sign, np.nan)
    if model.clips:
        lines = np.flatnonzero(clipped_lines(photo.edges, model.clip_level) & np.isfinite(out))
        out[lines] = censored_offsets_px(
            photo.edges, lines, photo.camera_blur_px(model), photo.camera_contrast(model), model
        )
    n, px_per_mm = photo._line_normals_and_scales
    asym = model.edge_shift_u_px * n[:, 0] + model.edge_shift_v_px * n[:, 1]
    return out - model.print_spread_mm * px_per_mm - asym


def transition_centres_px(photo: Photograph, model: PhotometricModel) -> np.ndarray:
    """Each edge's transition centre as ``model`` places it, px from the true edge along its normal (+ towards
    bright; E,): the median of :func:`place_edges` over its scan lines with the print's and the point spread's
    shifts put back (where a profile fit centres the edge's transition, so that its misfit measures the
    profile's shape and not the edge's position)."""
    e = photo.edges
    n = e.normal[e.windows.edge]
    asym = model.edge_shift_u_px * n[:, 0] + model.edge_shift_v_px * n[:, 1]
    o = place_edges(photo, model) + model.print_spread_mm * e.px_per_mm[e.windows.edge] + asym
    return per_edge_median(e.windows.edge, o, e.n_edges)


def photo_median(photo: Photograph, model: PhotometricModel) -> float:
    """The photograph's median offset over all its edges' scan lines with ``model``, px."""
    o = place_edges(photo, model)
    ok = np.isfinite(o)
    return float(np.median(o[ok])) if ok.any() else float("nan")


def _quadrant(normal: np.ndarray) -> np.ndarray:
    """Which way each normal (N, 2) faces: 0 +u, 1 +v, 2 -u, 3 -v (N,)."""
    return np.round(np.arctan2(normal[:, 1], normal[:, 0]) / (np.pi / 2)).astype(int) % 4


def _median_standard_error(x: np.ndarray) -> float:
    """Standard error of the median of ``x`` from its scatter (MAD), NaN for fewer than three values."""
    if x.size < 3:
        return float("nan")
    mad = 1.4826 * np.median(np.abs(x - np.median(x)))
    return float(1.2533 * mad / np.sqrt(x.size))


def direction_medians(photo: Photograph, model: PhotometricModel) -> np.ndarray:
    """The photograph's median offset over the edges whose bright side faces each way (+u, +v, -u, -v), px (4,).

    What causes are chosen by: a bias that depends on the edge's direction cancels in the photograph's
    median over all edges when the directions are balanced, but not in these four.
    """
    o = place_edges(photo, model)
    quadrant = _quadrant(photo.edges.normal[photo.edges.windows.edge])
    out = np.full(4, np.nan)
    for q in range(4):
        ok = (quadrant == q) & np.isfinite(o)
        if ok.sum() >= 10:
            out[q] = np.median(o[ok])
    return out


def direction_noise_floor_px(photo: Photograph) -> np.ndarray:
    """Standard error of each of :func:`direction_medians`' four medians from the scatter between the edges of
    that direction, px (4,; NaN where fewer than three edges face that way)."""
    e = photo.edges.edge_offsets_px()
    quadrant = _quadrant(photo.edges.normal)
    return np.array([_median_standard_error(e[(quadrant == q) & np.isfinite(e)]) for q in range(4)])


def noise_floor_px(photo: Photograph) -> float:
    """Standard error of a photograph's median offset from the scatter between its edges, px."""
    e = photo.edges.edge_offsets_px()
    return _median_standard_error(e[np.isfinite(e)])


def _inliers(photo: Photograph) -> np.ndarray:
    o = photo.edges.offset_px
    med = photo.edges.edge_offsets_px()[photo.edges.windows.edge]
    dev = np.abs(o - med)
    ok = np.isfinite(dev)
    s = 1.4826 * np.median(dev[ok]) if ok.any() else 0.0
    return ok & (dev <= 4.0 * max(s, 0.02))


@dataclass(frozen=True)
class CauseFit:
    """The model fitted for a set of causes on some photographs: its values and the training cost."""

    causes: tuple[str, ...]
    names: tuple[str, ...]
    values: tuple[float, ...]
    model: PhotometricModel
    cost: float


def _free(causes: Sequence[Cause]) -> tuple[list[str], list[float], list[float], list[float]]:
    """The parameters ``causes`` free, each once (its first cause's start and bounds): names, starts, lows,
    highs."""
    seen: dict[str, tuple[float, float, float]] = {}
    for c in causes:
        for n, s, a, b in zip(c.parameters, c.start, c.lower, c.upper, strict=True):
            seen.setdefault(n, (s, a, b))
    x0, lo, hi = (list(v) for v in zip(*seen.values(), strict=True)) if seen else ([], [], [])
    return list(seen), x0, lo, hi


#: the robust loss's scale on an edge's mean offset (px): offsets beyond it count less than squared
LOSS_SCALE_PX = 0.02
#: the price of a response held flat over stored levels (px per ln of grey it is flat over, one residual
#: beside the edges'): no camera stores levels that carry no light
#: (``PhotometricModel.flat_response_ln_grey``, ``pedestal_over_darks_ln_grey``)
FLAT_RESPONSE_PX = 10.0


def set_blur_px(photos: Sequence[Photograph], clip_level: float) -> float:
    """The median over ``photos`` of each one's blur on its edges a clip at ``clip_level`` leaves unclipped,
    px (0 where none has enough)."""
    b = np.array([p.unclipped_blur_px(clip_level) for p in photos])
    return float(np.median(b[np.isfinite(b)])) if np.isfinite(b).any() else 0.0


def set_contrast(photos: Sequence[Photograph], model: PhotometricModel) -> float:
    """The median over ``photos`` of each one's board contrast on the edges ``model``'s clip leaves
    unclipped (0 where none has enough)."""
    c = np.array([p.unclipped_contrast(model) for p in photos])
    return float(np.median(c[np.isfinite(c)])) if np.isfinite(c).any() else 0.0


def with_clip_references(photos: Sequence[Photograph], model: PhotometricModel) -> PhotometricModel:
    """``model`` with the blur and contrast a photograph with too few unclipped edges reads its clipped
    edges with (``clipped_blur_px``, ``clipped_contrast``), measured on ``photos``; unchanged without a clip."""
    if not model.clips:
        return model
    # Read through a response far from the camera's (a power law of 4 for a linear camera, as a fit's search
    # may try), a board's contrast can exceed what a model holds (1:52000 measured): held at the most it
    # holds, so the trial is costed (and loses) instead of ending the check; a contrast of 1 or less
    # (a response that falls) is none
    contrast = set_contrast(photos, model)
    contrast = min(contrast, CLIPPED_CONTRAST_MAX) if contrast > 1.0 else 0.0
    return model.with_values(clipped_blur_px=set_blur_px(photos, model.clip_level), clipped_contrast=contrast)


def fit_causes(
    photos: Sequence[Photograph], causes: Sequence[Cause], base: PhotometricModel = PLAIN
) -> CauseFit:
    """Least-squares fit of the parameters ``causes`` free, on ``photos`` (module docstring).

    A clip level is not a smooth parameter (a scan line is clipped or not): it is chosen among the levels
    where the photographs' bright plateaus lie (:func:`~doorloc.photometric.clipping.clip_candidates`) by the
    same robust cost, alone (the highest of equal cost), with the blur and board contrast of these photographs' unclipped edges for those
    with none (``clipped_blur_px``, ``clipped_contrast``: :func:`with_clip_references`, measured again
    through every response tried); the other parameters are then fitted at that level.
    Causes read on the photographs' medians (the free tone curve) are fitted after the others, to those
    medians, the others' values held (:func:`_fit_on_medians`).
    """
    on_medians = [c for c in causes if c.on_medians]
    if on_medians:
        edge_fit = fit_causes(photos, [c for c in causes if not c.on_medians], base)
        return _fit_on_medians(photos, on_medians, edge_fit, tuple(c.name for c in causes))
    names, x0, lo, hi = _free(causes)
    if not names:
        return CauseFit((), (), (), base, float("nan"))
    masks = [_inliers(p) for p in photos]
    edges = [p.edges.windows.edge for p in photos]
    n_e = [p.edges.n_edges for p in photos]
    # the edges with inlier samples: a fixed set, so the residual vector keeps its length
    used = [np.bincount(e[m], minlength=ne) > 0 for e, m, ne in zip(edges, masks, n_e, strict=True)]
    darkest = darkest_plateau([p.edges for p in photos])

    def residuals_of(m: PhotometricModel) -> np.ndarray:
        out = []
        for p, mk, e, ne, has in zip(photos, masks, edges, n_e, used, strict=True):
            o = place_edges(p, m)
            ok = mk & np.isfinite(o)
            s = np.bincount(e[ok], o[ok], minlength=ne)
            c = np.bincount(e[ok], minlength=ne)
            out.append(np.where(c > 0, s / np.maximum(c, 1), 0.0)[has] / np.sqrt(max(has.sum(), 1)))
        flat = m.flat_response_ln_grey() + m.pedestal_over_darks_ln_grey(darkest)
        return np.concatenate([*out, [FLAT_RESPONSE_PX * flat]])

    def robust_cost(r: np.ndarray) -> float:
        # least_squares' soft_l1 cost, so a fixed model's cost compares with a fitted one's
        z = (r / LOSS_SCALE_PX) ** 2
        return float(0.5 * LOSS_SCALE_PX**2 * np.sum(2.0 * (np.sqrt(1.0 + z) - 1.0)))

    clip_free = "clip_level" in names
    if clip_free:
        i = names.index("clip_level")
        levels = clip_candidates(np.concatenate([p.edges.bright for p in photos]))
        trial = [with_clip_references(photos, base.with_values(clip_level=float(c))) for c in levels]
        costs = np.array([robust_cost(residuals_of(m)) for m in trial])
        # levels that flag the same lines cost the same: the highest of them, the least the data ask for
        # (where no photograph here is clipped, a clip above all their plateaus)
        tied = np.flatnonzero(costs <= costs.min() * (1.0 + 1e-9) + 1e-15)
        base = trial[int(tied[-1])]
        cost_clip = float(costs.min())
        del names[i], x0[i], lo[i], hi[i]
        if not names:
            return CauseFit(
                tuple(c.name for c in causes), ("clip_level",), (base.clip_level,), base, cost_clip
            )

    def model_at(x: np.ndarray) -> PhotometricModel:
        return with_clip_references(photos, base.with_values(**dict(zip(names, map(float, x), strict=True))))

    def residuals(x: np.ndarray) -> np.ndarray:
        return residuals_of(model_at(x))

    # two starts: the cause's own and the base model's values (a curve that bends the other way from the
    # cause's start is found from the plain model); the lower cost wins
    starts = [np.asarray(x0, float), np.clip([float(getattr(base, n)) for n in names], lo, hi)]
    if "white_level" in names and "shoulder" in names:
        # a shoulder above every plateau moves no edge (no gradient to follow): the cause's start is the
        # least costly of knees and white levels placed at the plateaus these photographs have
        iw, ik = names.index("white_level"), names.index("shoulder")
        grid = []
        for k, w in white_starts(np.concatenate([p.edges.bright for p in photos])):
            x = starts[0].copy()
            x[iw], x[ik] = w, k
            grid.append(np.clip(x, lo, hi))
        starts[0] = min(grid, key=lambda x: robust_cost(residuals(x)))
    if np.allclose(starts[0], starts[1]):
        starts = starts[:1]
    res = min(
        (
            least_squares(
                residuals,
                x,
                bounds=(lo, hi),
                loss="soft_l1",
                f_scale=LOSS_SCALE_PX,
                diff_step=1e-3,
                x_scale="jac",
            )
            for x in starts
        ),
        key=lambda r: float(r.cost),
    )
    model = model_at(res.x)
    if clip_free:
        names, values = ["clip_level", *names], [base.clip_level, *map(float, res.x)]
    else:
        values = [float(v) for v in res.x]
    return CauseFit(tuple(c.name for c in causes), tuple(names), tuple(values), model, float(res.cost))


#: the free tone curve's ridge (px of one photograph's median per ln light): a bend the photographs do not hold
#: (a knot no edge's level comes near) stays near none
MEDIANS_RIDGE_PX = 0.1
#: the central differences' step for the medians' Jacobian (in each parameter's unit: ln light for the tone)
MEDIANS_STEP = 0.05


def _fit_on_medians(
    photos: Sequence[Photograph], causes: Sequence[Cause], edge_fit: CauseFit, all_causes: tuple[str, ...]
) -> CauseFit:
    """``causes`` (:attr:`~doorloc.photometric.catalogue.Cause.on_medians`) fitted to the photographs' median
    offsets, the edge fit's values held: two Gauss-Newton steps from none, with a ridge
    (``MEDIANS_RIDGE_PX``) and central differences over ``MEDIANS_STEP``; one CauseFit of both.

    Written out rather than scipy's ``least_squares``: a photograph's median is piecewise constant at that
    solver's small steps (a median of finitely many offsets), and from none it stopped at none on one fold
    of five, while on the same photographs measured twice (3e-13 px apart) it ended 0.026 and 0.042 px held
    out; these steps end 0.023 px on both. The medians follow a bend of a tenth of ln light nearly linearly,
    which two steps reach."""
    names, _, lo, hi = _free(causes)
    k = len(names)

    def model_at(x: np.ndarray) -> PhotometricModel:
        return edge_fit.model.with_values(**dict(zip(names, map(float, x), strict=True)))

    def medians(x: np.ndarray) -> np.ndarray:
        m = model_at(x)
        return np.array([photo_median(p, m) for p in photos])

    x = np.zeros(k)
    for _ in range(2):
        r = medians(x)
        jac = np.stack(
            [
                (medians(x + MEDIANS_STEP * e) - medians(x - MEDIANS_STEP * e)) / (2 * MEDIANS_STEP)
                for e in np.eye(k)
            ],
            axis=1,
        )
        ok = np.isfinite(r) & np.isfinite(jac).all(axis=1)
        a = jac[ok].T @ jac[ok] + MEDIANS_RIDGE_PX**2 * np.eye(k)
        x = np.clip(x + np.linalg.solve(a, -(jac[ok].T @ r[ok] + MEDIANS_RIDGE_PX**2 * x)), lo, hi)
    r = medians(x)
    return CauseFit(
        all_causes,
        (*edge_fit.names, *names),
        (*edge_fit.values, *map(float, x)),
        model_at(x),
        float(0.5 * np.nansum(r**2)),
    )


@dataclass(frozen=True)
class HeldOut:
    """Leave-one-photograph-out results of one cause set: each photograph's median offset with the model
    fitted without it (px), the fits, and the jackknife 1-sigma of each parameter."""

    causes: tuple[str, ...]
    offsets_px: np.ndarray
    fits: list[CauseFit]
    sigma: dict[str, float]
    by_direction_px: np.ndarray  # (n, 4): :func:`direction_medians` of each photograph, held out

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.nanmean(self.offsets_px**2)))

    @property
    def score_px(self) -> float:
        """RMS over photographs and the four edge directions of the held-out median offsets, px."""
        return float(np.sqrt(np.nanmean(self.by_direction_px**2)))


def folds_by_photograph(n: int, k: int) -> np.ndarray:
    """Fold of each of ``n`` photographs (in their order: neighbours in a sequence go to different folds);
    ``k >= n`` is leave-one-out."""
    return np.arange(n) % max(1, min(k, n))


def held_out(
    photos: Sequence[Photograph], causes: Sequence[Cause], folds: np.ndarray, base: PhotometricModel = PLAIN
) -> HeldOut:
    """Each photograph's median offset placed with the model fitted without its fold of photographs.

    ``fits[i]`` is the model photograph ``i`` was placed with; the 1-sigma is the delete-a-fold jackknife.
    """
    n = len(photos)
    offs = np.full(n, np.nan)
    by_dir = np.full((n, 4), np.nan)
    fits: list[CauseFit] = [CauseFit((), (), (), base, float("nan"))] * n
    per_fold = []
    for f_id in np.unique(folds):
        f = fit_causes([p for j, p in enumerate(photos) if folds[j] != f_id], causes, base)
        per_fold.append(f)
        for i in np.flatnonzero(folds == f_id).tolist():
            fits[i] = f
            offs[i] = photo_median(photos[i], f.model)
            by_dir[i] = direction_medians(photos[i], f.model)
    sigma: dict[str, float] = {}
    k = len(per_fold)
    if k > 1 and per_fold[0].names:
        v = np.array([f.values for f in per_fold])
        sd = np.sqrt((k - 1) / k * ((v - v.mean(0)) ** 2).sum(0))
        sigma = dict(zip(per_fold[0].names, map(float, sd), strict=True))
    return HeldOut(tuple(c.name for c in causes), offs, fits, sigma, by_dir)


@dataclass(frozen=True)
class Selection:
    """What the held-out comparison chose.

    ``causes``: the kept causes in the order they were added; ``final``: its fit on all photographs and its
    held-out results; ``plain_px``: each photograph's median offset with the plain model; ``steps``: per step,
    each candidate's held-out RMS (px); ``alternatives``: causes the data cannot tell apart from a kept one
    (``{kept: [others]}``); ``not_tried``: causes the photographs are too few to measure, and why; ``refined``:
    causes kept in their richer form (:data:`~doorloc.photometric.catalogue.REFINED_FORMS`).
    """

    causes: tuple[str, ...]
    fit: CauseFit
    heldout: HeldOut
    plain_px: np.ndarray
    steps: list[dict[str, float]] = field(default_factory=list)
    alternatives: dict[str, list[str]] = field(default_factory=dict)
    not_tried: dict[str, str] = field(default_factory=dict)
    refined: tuple[str, ...] = ()

    def cause(self, name: str) -> Cause:
        """The named cause in the form it was kept (its richer form where that was kept)."""
        return REFINED_FORMS[name] if name in self.refined else CAUSES_BY_NAME[name]


def _gain_z(before: np.ndarray, after: np.ndarray) -> tuple[float, float]:
    """Mean paired reduction of squared offsets (per photograph: the mean over its edge directions) and its
    standard error."""

    def per_photo(x: np.ndarray) -> np.ndarray:
        sq = np.where(np.isfinite(x), x**2, 0.0)
        n = np.isfinite(x).sum(axis=1)
        return np.where(n > 0, sq.sum(axis=1) / np.maximum(n, 1), np.nan)

    d = per_photo(before) - per_photo(after)
    d = d[np.isfinite(d)]
    if d.size < 2:
        return 0.0, float("inf")
    return float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size))


def select_causes(
    photos: Sequence[Photograph],
    catalogue: Sequence[Cause] = EDGE_CAUSES,
    folds: int = 5,
    progress: Callable[[str], None] | None = None,
    tried_last: Cause | None = TONE_CAUSE,
) -> Selection:
    """Forward selection by held-out photographs: add the cause that lowers the held-out offsets most (each
    photograph's medians by edge direction, :func:`direction_medians`), while the lowering is significant
    (paired over photographs, by :func:`~doorloc.photometric.catalogue.keep_sigmas` of the candidates tried at
    the step: a control's best candidate must not pass by the luck of the draw); of the candidates within
    ``TIE_SIGMAS`` of it, one that frees a part of its parameters is named in its place. Then each named
    cause's richer form (:data:`~doorloc.photometric.catalogue.REFINED_FORMS`) in its place, kept where it
    lowers them by ``REFINE_KEEP_SIGMAS`` standard errors. Then ``tried_last`` (the free tone curve), where
    there are twice as many photographs as it has parameters, kept where it lowers the photographs' medians
    by ``TONE_KEEP_SIGMAS`` standard errors without making those by direction significantly worse."""
    plain = np.array([photo_median(p, PLAIN) for p in photos])
    plain_dir = np.array([direction_medians(p, PLAIN) for p in photos])
    floor = float(np.sqrt(np.nanmean([noise_floor_px(p) ** 2 for p in photos])))
    fold_of = folds_by_photograph(len(photos), folds)
    current: list[Cause] = []
    cur_off = plain_dir
    cur_ho: HeldOut | None = None
    steps: list[dict[str, float]] = []
    alternatives: dict[str, list[str]] = {}
    remaining = list(catalogue)
    while remaining:
        trials = {c.name: held_out(photos, [*current, c], fold_of) for c in remaining}
        steps.append({k: v.score_px for k, v in trials.items()})
        if progress:
            progress(
                "held-out RMS by edge direction with "
                + ", ".join(f"+{k} {v.score_px:.3f}" for k, v in trials.items())
                + " px"
            )
        best = min(trials, key=lambda k: trials[k].score_px)
        gain, se = _gain_z(cur_off, trials[best].by_direction_px)
        before = float(np.sqrt(np.nanmean(cur_off**2)))
        # significant paired over photographs, or (few photographs, the bias on some only) a bias well above
        # the noise at least halved
        halved = trials[best].score_px < 0.5 * before and before > BIAS_OVER_NOISE * floor
        if not (gain > keep_sigmas(len(trials)) * se or halved):
            break
        ties = []
        for k, v in trials.items():
            if k == best:
                continue
            g, s = _gain_z(v.by_direction_px, trials[best].by_direction_px)
            g0, s0 = _gain_z(cur_off, v.by_direction_px)
            if g <= TIE_SIGMAS * s and g0 > KEEP_SIGMAS * s0:
                ties.append(k)
        cause = next(c for c in remaining if c.name == best)
        # the one-standard-error rule between nested forms: a tie that frees a part of the best's parameters
        # names the effect as well with fewer (a power law is a curved response of zero curvature)
        simpler = [c for c in remaining if c.name in ties and set(c.parameters) < set(cause.parameters)]
        if simpler:
            cause = min(simpler, key=lambda c: (len(c.parameters), trials[c.name].score_px))
            ties, best = [k for k in ties if k != cause.name] + [best], cause.name
        current.append(cause)
        remaining.remove(cause)
        if ties:
            alternatives[best] = ties
        cur_off, cur_ho = trials[best].by_direction_px, trials[best]
    refined: list[str] = []
    for i, cause in enumerate(current):
        richer = REFINED_FORMS.get(cause.name)
        if richer is None:
            continue
        trial = held_out(photos, [*current[:i], richer, *current[i + 1 :]], fold_of)
        steps.append({f"{cause.name} ({', '.join(richer.parameters)})": trial.score_px})
        gain, se = _gain_z(cur_off, trial.by_direction_px)
        if gain > REFINE_KEEP_SIGMAS * se:
            current[i] = richer
            refined.append(cause.name)
            cur_off, cur_ho = trial.by_direction_px, trial
    # a free curve is read on the photographs' medians, one number each: it needs twice its parameters
    not_tried: dict[str, str] = {}
    if tried_last is not None and len(photos) < 2 * len(tried_last.parameters):
        not_tried[tried_last.name] = (
            f"it is read on each photograph's median offset and needs {2 * len(tried_last.parameters)} "
            f"photographs, {len(photos)} given; 16 or more at different exposures measure it"
        )
    elif tried_last is not None:
        trial = held_out(photos, [*current, tried_last], fold_of)
        steps.append({tried_last.name: trial.score_px})
        if progress:
            progress(
                f"held-out RMS by edge direction with +{tried_last.name} {trial.score_px:.3f} px, of the "
                f"photographs' medians {trial.rms_px:.3f} px"
            )
        # A response moves the edges of every direction alike: its gain is read on each photograph's median over
        # all its edges, where a bias by direction that no cause explains does not drown it (on Bouguet's set,
        # +-0.3 px by direction against a tone's 0.04 px on the medians); the figure by direction must not get
        # significantly worse (the tone moves sharp and blurred edges by different amounts, so it need not
        # fall there).
        medians = (cur_ho.offsets_px if cur_ho is not None else plain)[:, None]
        gain, se = _gain_z(medians, trial.offsets_px[:, None])
        gain_dir, se_dir = _gain_z(cur_off, trial.by_direction_px)
        if gain > TONE_KEEP_SIGMAS * se and gain_dir > -KEEP_SIGMAS * se_dir:
            current.append(tried_last)
            cur_off, cur_ho = trial.by_direction_px, trial
    final = fit_causes(photos, current)
    if cur_ho is None:
        cur_ho = HeldOut((), plain, [], {}, plain_dir)
    return Selection(
        tuple(c.name for c in current), final, cur_ho, plain, steps, alternatives, not_tried, tuple(refined)
    )

"""Edge profiles: each edge's blur and levels fitted across its scan lines, and how well a photometric model
reproduces the measured grey levels.

The model of one scan line's window: the pixel's stored grey is the response applied to linear light
``La + (Lb - La) E(d)``, ``d`` the pixel centre's distance from the true edge along the normal (+ towards
bright, px) moved by the print's spread, and ``E`` the edge spread function: a Gaussian of the edge's blur
combined with the pixel's footprint (its projection on the normal has variance 1/12 px^2 at every angle),
optionally with an exponential halo (``psf_tail``). Per edge, the blur and both linear levels are free; the
levels are solved by linear least squares in linear light for each blur on a grid, and the blur with the
least grey-level misfit is kept (a grid, not a solver: one vectorised pass over all edges of a photograph).

An interlaced camera's fields out of register (``field_offset_px``, one photograph's: the even image rows
sample the scene half of it away, the odd rows half of it the other way) move each sample's distance from
the edge by half the offset's projection on the edge's normal, with the sample's field's sign.
:func:`fit_field_offset` measures a photograph's offset from its profiles: each edge's residual against the
profile's slope, alternating with the field, gives the offset along its normal, and the edges' normals
together the vector.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from doorloc.photometric.board_edges import BoardEdges
from doorloc.photometric.model import PhotometricModel

__all__ = [
    "EdgeProfiles",
    "FIELD_READ_ROWS",
    "FieldOffset",
    "RESIDUAL_PROFILE_BINS_PX",
    "ResidualProfile",
    "fit_profiles",
    "fit_field_offset",
    "edge_spread",
    "parabola_vertex_step",
    "mean_residual_profile",
    "GAP_TO_PLACE_GREY",
    "gap_place_px",
    "FieldFlip",
    "field_flip",
    "FIELD_FLIP_SECTORS",
    "camera_or_print",
]

#: the blur grid searched (Gaussian sigma of the optics, px); the least misfit is refined by a parabola
BLUR_GRID_PX = np.round(np.arange(0.2, 3.51, 0.1), 3)


def edge_spread(d: np.ndarray, blur_px: np.ndarray | float, model: PhotometricModel) -> np.ndarray:
    """Fraction of the step reached at signed distance ``d`` (px) from the edge, for Gaussian optics of
    ``blur_px`` over a pixel footprint, with the model's halo (exponential, mean free path ``psf_tail_px``)."""
    s = np.sqrt(np.asarray(blur_px, float) ** 2 + 1.0 / 12.0)
    core = ndtr(d / s)
    if model.psf_tail <= 0:
        return core
    b = model.psf_tail_px
    lap = np.where(d < 0, 0.5 * np.exp(np.minimum(d, 0) / b), 1.0 - 0.5 * np.exp(-np.maximum(d, 0) / b))
    return (1.0 - model.psf_tail) * core + model.psf_tail * lap


@dataclass(frozen=True)
class EdgeProfiles:
    """Per edge (E,): ``blur_px`` (Gaussian sigma of the optics), ``dark``, ``bright`` (linear light, 0-1 of
    full scale), ``rms`` (grey levels, the misfit over its windows), ``n`` (samples). ``residual`` (N, L) grey,
    data minus model, for each scan line's window; ``distance`` (N, L) px from the true edge; ``along_rows``
    (N,) whether the scan line runs along an image row (the edge is nearer vertical than horizontal);
    ``edge`` (N,) each scan line's edge (None where not known)."""

    blur_px: np.ndarray
    dark: np.ndarray
    bright: np.ndarray
    rms: np.ndarray
    n: np.ndarray
    residual: np.ndarray
    distance: np.ndarray
    along_rows: np.ndarray
    edge: np.ndarray | None = None

    def rms_over_windows(self) -> float:
        """RMS misfit over every window sample of the photograph, grey levels."""
        r = self.residual[np.isfinite(self.residual)]
        return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def parabola_vertex_step(
    s0: np.ndarray | float, s1: np.ndarray | float, s2: np.ndarray | float, limit: float = 1.0
) -> np.ndarray:
    """The step, in units of their spacing, from the middle of three equally spaced values ``s0, s1, s2`` to
    the vertex of the parabola through them where it opens upwards (a least), held within ``limit``; 0 where
    it does not open upwards or a value is not finite."""
    s0, s1, s2 = np.asarray(s0, float), np.asarray(s1, float), np.asarray(s2, float)
    den = s0 - 2.0 * s1 + s2
    with np.errstate(divide="ignore", invalid="ignore"):
        step = 0.5 * (s0 - s2) / den
        return np.where(np.isfinite(step) & (den > 0), np.clip(step, -limit, limit), 0.0)


def fit_profiles(
    edges: BoardEdges,
    model: PhotometricModel,
    keep: np.ndarray | None = None,
    edge_shift_px: np.ndarray | None = None,
    field_offset_px: tuple[float, float] = (0.0, 0.0),
) -> EdgeProfiles:
    """Fit each edge's blur and levels under ``model`` (module docstring); ``keep`` (N,) selects scan lines.
    ``field_offset_px``: the photograph's interlaced fields' offset (u, v image px; module docstring).

    ``edge_shift_px`` (E,): where each edge's transition is centred, px from the true edge along the normal
    (+ towards bright): the model's own placement, so that the misfit measures the profile's shape and not
    the edge's position (which the offsets measure). None: the true edge moved by the print's spread.
    """
    w = edges.windows if keep is None else edges.windows.subset(keep)
    g = w.grey / 255.0
    y = model.light_from_grey(g)
    if edge_shift_px is None:
        d = w.distance_px() - model.print_spread_mm * edges.px_per_mm[w.edge][:, None]
    else:
        d = w.distance_px() - np.nan_to_num(np.asarray(edge_shift_px, float))[w.edge][:, None]
    if field_offset_px[0] or field_offset_px[1]:
        n = edges.normal[w.edge]
        along_normal = field_offset_px[0] * n[:, 0] + field_offset_px[1] * n[:, 1]
        d = d + 0.5 * w.field_sign() * along_normal[:, None]
    e = np.repeat(w.edge, g.shape[1])
    n_e = edges.n_edges
    cnt = np.bincount(e, minlength=n_e).astype(float)
    # a sample stored at the clip holds no light beyond it: the levels are fitted on the others (censored),
    # and every sample is drawn clipped (fitted with the clip's light as its own, an edge's bright level read
    # low and its profile drawn 2-3 times worse than the plain model's on rendered clipped boards)
    wt = (g < model.clip_level - 0.5 / 255.0).ravel().astype(float) if model.clips else np.ones(g.size)
    cnt_w = np.bincount(e, wt, minlength=n_e)
    sy = np.bincount(e, wt * y.ravel(), minlength=n_e)
    table = model.response_table()
    top = model.clip_level if model.clips else np.inf

    def levels_and_misfit(blur: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        E = edge_spread(d, blur, model).ravel()
        se = np.bincount(e, wt * E, minlength=n_e)
        see = np.bincount(e, wt * E * E, minlength=n_e)
        sey = np.bincount(e, wt * E * y.ravel(), minlength=n_e)
        # y = a + c E: normal equations per edge
        det = cnt_w * see - se * se
        with np.errstate(divide="ignore", invalid="ignore"):
            c = (cnt_w * sey - se * sy) / det
            a = (sy - c * se) / cnt_w
        L = a[e] + c[e] * E
        pred = np.minimum(L if model.linear_response else np.interp(np.clip(L, 0.0, None), *table), top)
        return a, a + c, np.bincount(e, (pred - g.ravel()) ** 2, minlength=n_e)

    # (float: bincount gives integers where a photograph has no edge at all)
    sse_grid = np.array([levels_and_misfit(sigma)[2] for sigma in BLUR_GRID_PX], dtype=float)  # (S, E)
    sse_grid[~np.isfinite(sse_grid)] = np.inf
    k = np.argmin(sse_grid, axis=0)
    kk = np.clip(k, 1, BLUR_GRID_PX.size - 2)
    cols = np.arange(n_e)
    s0, s1, s2 = sse_grid[kk - 1, cols], sse_grid[kk, cols], sse_grid[kk + 1, cols]
    step = np.where(k == kk, parabola_vertex_step(s0, s1, s2), 0.0)
    out_blur = np.interp(k + step, np.arange(BLUR_GRID_PX.size), BLUR_GRID_PX)
    out_blur[cnt == 0] = np.nan
    out_a, out_b, _ = levels_and_misfit(np.where(np.isfinite(out_blur), out_blur, 1.0)[w.edge][:, None])
    out_a[cnt == 0] = np.nan
    out_b[cnt == 0] = np.nan
    E = edge_spread(d, out_blur[w.edge][:, None], model)
    L = out_a[w.edge][:, None] + (out_b - out_a)[w.edge][:, None] * E
    pred = np.minimum(L, top) if model.linear_response else model.grey_from_light(L)
    resid = (g - pred) * 255.0
    rms = np.sqrt(np.bincount(e, resid.ravel() ** 2, minlength=n_e) / np.maximum(cnt, 1))
    return EdgeProfiles(out_blur, out_a, out_b, rms, cnt, resid, d, ~w.axis, w.edge)


#: the distances (px from the true edge, + towards bright) over which :func:`mean_residual_profile` averages
RESIDUAL_PROFILE_BINS_PX = np.arange(-7.5, 7.6, 0.5)
#: the fewest samples a distance's mean is read from (fewer: NaN)
RESIDUAL_PROFILE_MIN_SAMPLES = 50


def _largest(gap: np.ndarray, distance_px: np.ndarray) -> tuple[float, float]:
    """The value of ``gap`` largest in size and its distance; NaN and NaN where none is finite."""
    ok = np.isfinite(gap)
    if not ok.any():
        return float("nan"), float("nan")
    k = int(np.argmax(np.where(ok, np.abs(gap), -1.0)))
    return float(gap[k]), float(distance_px[k])


@dataclass(frozen=True)
class ResidualProfile:
    """The mean residual (grey levels, photograph minus model) against the distance from the true edge
    (``distance_px``, the bins' centres, + towards bright): over every scan line (``all``), and over those
    along the image rows (``along_rows``: edges nearer vertical) and along the columns (``along_columns``)
    apart. Optics and a response draw an edge the same whichever way it runs (up to the blur the profile fit
    takes per edge); a camera's scan lines do not (an analogue line's filter or sharpening acts along the rows
    only), nor may the board's print, which a printer lays differently across and along its paper's travel
    (Bouguet's photographs dip a tenth of the step below their dark squares 2-3 px from the edges across
    the rows, median 7.7 %, and not across the columns, 0.6 %; its board's rows run the same way in every
    photograph, :meth:`~doorloc.photometric.board_edges.BoardEdges.board_turned`). NaN where fewer than
    ``RESIDUAL_PROFILE_MIN_SAMPLES`` samples fall at a distance."""

    distance_px: np.ndarray
    all: np.ndarray
    along_rows: np.ndarray
    along_columns: np.ndarray

    def direction_gap(self) -> tuple[float, float]:
        """The largest difference (grey levels, rows less columns, by size) between the two directions' means
        and the distance (px) where it lies; NaN and NaN where no distance holds both."""
        return _largest(self.along_rows - self.along_columns, self.distance_px)


#: the least gap (grey levels) between the rows' and the columns' mean residual whose place is read
GAP_TO_PLACE_GREY = 2.0
#: how far (px) one photograph's gap is sought from where all photographs' together lies
GAP_PLACE_REACH_PX = 1.5
#: the least ratio of the largest board scale (px per mm) to the smallest over which a gap's place fixed in
#: pixels (the camera's) is told from one fixed on the board (the print's)
SCALE_RATIO_TO_TELL = 1.25
#: the F-test's level at which the place's other constant is rejected, and the one it must keep its own at
PLACE_REJECT_P = 0.001
PLACE_KEEP_P = 0.01


def gap_place_px(profile: ResidualProfile, near_px: float, sign: float) -> float:
    """Where ``profile``'s rows-less-columns gap (:meth:`ResidualProfile.direction_gap`) of the sign ``sign``
    is largest within :data:`GAP_PLACE_REACH_PX` of ``near_px``, px from the edge: the bin's centre moved to
    the vertex of the parabola through it and its neighbours. NaN where no bin there holds both directions."""
    gap = sign * (profile.along_rows - profile.along_columns)
    x = profile.distance_px
    near = np.abs(x - near_px) <= GAP_PLACE_REACH_PX
    ok = near & np.isfinite(gap)
    if not ok.any():
        return float("nan")
    k = int(np.argmax(np.where(ok, gap, -np.inf)))
    if not 0 < k < x.size - 1:
        return float(x[k])
    # the largest value: the least of the values turned over
    step = float(parabola_vertex_step(-gap[k - 1], -gap[k], -gap[k + 1], 0.5))
    return float(x[k] + step * (x[1] - x[0]))


def camera_or_print(places_px: np.ndarray, px_per_mm: np.ndarray) -> str | None:
    """Whether a gap between the two directions' profiles is the camera's or the print's, from where it lies
    in photographs of the board at different scales (``places_px`` (P,) px from the edge,
    :func:`gap_place_px`; ``px_per_mm`` (P,) each photograph's board scale): ``"camera"`` where its place is
    one distance in pixels (a scan line's filter), ``"print"`` where it is one distance on the board (the
    place in pixels in proportion to the scale). Each is the line ``place = a + b scale`` with one term
    held at 0 (``b`` for the camera, ``a`` for the print); one is told where an F-test against the free line
    rejects the other at :data:`PLACE_REJECT_P` and keeps it at :data:`PLACE_KEEP_P`. None where fewer than
    four photographs place it, their scales differ by less than :data:`SCALE_RATIO_TO_TELL`, or the test
    tells neither (the places' scatter hides the difference)."""
    from scipy.stats import f as f_dist  # (slow to import, and only the report asks, once a check)

    p, s = np.asarray(places_px, float), np.asarray(px_per_mm, float)
    ok = np.isfinite(p) & np.isfinite(s) & (s > 0)
    p, s = p[ok], s[ok]
    if p.size < 4 or s.max() < SCALE_RATIO_TO_TELL * s.min():
        return None
    design = np.stack([np.ones_like(s), s], axis=1)
    free = float(np.sum((p - design @ np.linalg.lstsq(design, p, rcond=None)[0]) ** 2))
    dof = p.size - 2
    variance = max(free / dof, 1e-12 * max(float(np.mean(p * p)), 1e-12))

    def p_value(held: float) -> float:
        return float(f_dist.sf(max(held - free, 0.0) / variance, 1, dof))

    on_camera = p_value(float(np.sum((p - p.mean()) ** 2)))
    on_board = p_value(float(np.sum((p - s * (np.sum(p * s) / np.sum(s * s))) ** 2)))
    if on_board < PLACE_REJECT_P and on_camera >= PLACE_KEEP_P:
        return "camera"
    if on_camera < PLACE_REJECT_P and on_board >= PLACE_KEEP_P:
        return "print"
    return None


#: the part of the field (fraction of the half-diagonal from the centre) whose edges :func:`field_flip` reads
FIELD_FLIP_OUTER = 0.5


@dataclass(frozen=True)
class FieldFlip:
    """The mean residual (grey levels) of the edges in the outer field (beyond :data:`FIELD_FLIP_OUTER` of
    the half-diagonal) whose bright side faces away from the image centre less that of those facing it
    whose normals point the same way in the image (:func:`field_flip`), against the distance from the true
    edge (``distance_px``). Optics that are the same at every point of the field draw both alike; a point
    spread whose asymmetry follows the radius (coma, a lens tilted on its sensor) draws them as mirror
    images: it moves no edge against its corners (both move by the spread's centroid) but shapes every
    profile. NaN where fewer than ``RESIDUAL_PROFILE_MIN_SAMPLES`` samples fall at a distance."""

    distance_px: np.ndarray
    outward_less_inward: np.ndarray

    def largest(self) -> tuple[float, float]:
        """The largest difference (grey levels, outward less inward, by size) and the distance (px) where it
        lies; NaN and NaN where no distance holds both."""
        return _largest(self.outward_less_inward, self.distance_px)


#: the sectors of the edge normal's direction within which :func:`field_flip` sets edges facing out against
#: edges facing in
FIELD_FLIP_SECTORS = 8


def field_flip(
    parts: Sequence[tuple[BoardEdges, EdgeProfiles]], centre_px: tuple[float, float], half_diagonal_px: float
) -> FieldFlip:
    """The :class:`FieldFlip` of several photographs' fitted profiles (each with its edges; profiles without
    ``edge`` are passed over), about the image point ``centre_px`` (the principal point).

    Edges facing out are set against edges facing in whose normals point the same way in the image (within
    one of :data:`FIELD_FLIP_SECTORS` sectors; such edges lie on opposite sides of the centre): an
    asymmetry fixed in the image (a ghost a fixed vector away, which the catalogue's ``psf_asymmetry``
    names) draws those alike and cancels; one along the radius does not. At each distance the sectors'
    differences are averaged, each weighted by the fewer of its two counts. (Set apart without the sectors, the hidden bench's ghosts on boards that fill
    one side of the field more than the other read 8-12 grey levels.)"""
    d_all, r_all, key_all = [np.empty(0)], [np.empty(0)], [np.empty(0, int)]
    for edges, prof in parts:
        if prof.edge is None:
            continue
        radial = edges.mid_px[prof.edge] - np.asarray(centre_px, float)
        outer = np.hypot(radial[:, 0], radial[:, 1]) > FIELD_FLIP_OUTER * half_diagonal_px
        n = edges.normal[prof.edge]
        sector = np.floor((np.arctan2(n[:, 1], n[:, 0]) + np.pi) / (2 * np.pi) * FIELD_FLIP_SECTORS)
        key = 2 * np.clip(sector.astype(int), 0, FIELD_FLIP_SECTORS - 1) + (np.sum(n * radial, axis=1) > 0)
        d_all.append(prof.distance[outer].ravel())
        r_all.append(prof.residual[outer].ravel())
        key_all.append(np.repeat(key[outer], prof.residual.shape[1]))
    d, r, key = np.concatenate(d_all), np.concatenate(r_all), np.concatenate(key_all)
    bins = RESIDUAL_PROFILE_BINS_PX
    ok = np.isfinite(d) & np.isfinite(r) & (d >= bins[0]) & (d < bins[-1])
    nb = bins.size - 1
    at = (np.digitize(d[ok], bins) - 1) * 2 * FIELD_FLIP_SECTORS + key[ok]
    size = nb * 2 * FIELD_FLIP_SECTORS
    cnt = np.bincount(at, minlength=size).reshape(nb, FIELD_FLIP_SECTORS, 2).astype(float)
    mean = np.bincount(at, r[ok], minlength=size).reshape(nb, FIELD_FLIP_SECTORS, 2) / np.maximum(cnt, 1)
    weight = np.minimum(cnt[..., 0], cnt[..., 1])
    total = weight.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = np.sum(weight * (mean[..., 1] - mean[..., 0]), axis=1) / total
    diff = np.where(total >= RESIDUAL_PROFILE_MIN_SAMPLES, diff, np.nan)
    return FieldFlip(0.5 * (bins[1:] + bins[:-1]), diff)


def mean_residual_profile(profiles: Sequence[EdgeProfiles]) -> ResidualProfile:
    """The mean residual profile of several photographs' fitted profiles (:class:`ResidualProfile`)."""
    parts = list(profiles)
    d = np.concatenate([np.empty(0)] + [p.distance.ravel() for p in parts])
    r = np.concatenate([np.empty(0)] + [p.residual.ravel() for p in parts])
    rows = np.concatenate([np.empty(0, bool)] + [np.repeat(p.along_rows, p.residual.shape[1]) for p in parts])
    centres, (every, along_rows, along_columns) = _binned_means(d, r, [np.ones(r.size, bool), rows, ~rows])
    return ResidualProfile(centres, every, along_rows, along_columns)


def _binned_means(
    d: np.ndarray, r: np.ndarray, groups: Sequence[np.ndarray]
) -> tuple[np.ndarray, list[np.ndarray]]:
    """The bins' centres of :data:`RESIDUAL_PROFILE_BINS_PX` and, for each of ``groups`` (boolean masks over
    the samples), the mean residual ``r`` of its samples at distance ``d`` in each bin (NaN under
    ``RESIDUAL_PROFILE_MIN_SAMPLES``)."""
    bins = RESIDUAL_PROFILE_BINS_PX
    ok = np.isfinite(d) & np.isfinite(r) & (d >= bins[0]) & (d < bins[-1])
    at = np.digitize(d[ok], bins) - 1

    def mean(sel: np.ndarray) -> np.ndarray:
        n = np.bincount(at[sel], minlength=bins.size - 1)
        s = np.bincount(at[sel], r[ok][sel], minlength=bins.size - 1)
        return np.where(n >= RESIDUAL_PROFILE_MIN_SAMPLES, s / np.maximum(n, 1), np.nan)

    return 0.5 * (bins[1:] + bins[:-1]), [mean(np.asarray(g)[ok]) for g in groups]


@dataclass(frozen=True)
class FieldOffset:
    """One photograph's interlaced fields' offset as its profiles give it: ``u_px``, ``v_px`` (the even rows'
    displacement less the odd rows', image px) and their 1-sigma from the scatter of the edges' readings about
    the fitted vector (``sigma_u_px``, ``sigma_v_px``); ``n_edges`` read (NaN and 0 where fewer than 4)."""

    u_px: float
    v_px: float
    sigma_u_px: float
    sigma_v_px: float
    n_edges: int

    @property
    def vector(self) -> tuple[float, float]:
        return (self.u_px, self.v_px) if np.isfinite(self.u_px) else (0.0, 0.0)


#: the image rows, modulo 8, whose samples read a photograph's field offset: JPEG's 8 x 8 blocks start on rows
#: divisible by 8, and their quantisation bends the rows beside a block's border (0, 1, 6, 7) as a field offset
#: would (rendered boards without fields, through JPEG of quality 20-50: 0.05-0.10 px read on those rows, about
#: 0.01 on rows 2-5), while fields out of register read alike on every row (0.145-0.154 px on each pair of rows
#: for 0.15); the offset, once read, is applied to every row
FIELD_READ_ROWS = (2, 3, 4, 5)
#: the step of the profile's slope's central difference, px
_SLOPE_STEP_PX = 0.05
#: Gauss-Newton passes of :func:`fit_field_offset` (the profiles' blurs and levels fitted again in each)
_FIELD_PASSES = 3


def _profile_slope(prof: EdgeProfiles, edge: np.ndarray, model: PhotometricModel) -> np.ndarray:
    """The fitted profiles' slope (grey levels per px along the normal) at each window sample (N, L);
    ``edge`` (N,) each scan line's edge."""
    blur, dark, bright = prof.blur_px[edge][:, None], prof.dark[edge][:, None], prof.bright[edge][:, None]

    def grey(d: np.ndarray) -> np.ndarray:
        light = dark + (bright - dark) * edge_spread(d, blur, model)
        return (light if model.linear_response else model.grey_from_light(light)) * 255.0

    return (grey(prof.distance + _SLOPE_STEP_PX) - grey(prof.distance - _SLOPE_STEP_PX)) / (
        2.0 * _SLOPE_STEP_PX
    )


def fit_field_offset(
    edges: BoardEdges,
    model: PhotometricModel,
    keep: np.ndarray,
    edge_shift_px: np.ndarray | None = None,
) -> FieldOffset:
    """The photograph's interlaced fields' offset from the scan lines ``keep`` (module docstring), read on the
    samples of the rows :data:`FIELD_READ_ROWS` (modulo 8), away from JPEG's block borders.

    Each pass fits the profiles at the offset so far and linearises the model in it: a sample of field sign
    ``s`` moves by ``s (f . n) / 2`` along its edge's normal ``n``, so its residual is the profile's slope
    times that; each edge's offset along its normal is the slope-weighted regression of its residuals on
    ``s slope / 2``, and the vector ``f`` the weighted least-squares fit of the edges' readings to their
    normals, its 1-sigma from their scatter about it (which the noise of one edge's neighbouring pixels,
    correlated through the blur and the level fit, would understate if taken sample by sample)."""
    f = np.zeros(2)
    cov = np.full((2, 2), np.nan)
    n_read = 0
    w = edges.windows.subset(keep)
    sign = w.field_sign() * np.isin(w.image_rows() % 8, FIELD_READ_ROWS)
    for _ in range(_FIELD_PASSES):
        prof = fit_profiles(edges, model, keep, edge_shift_px, (float(f[0]), float(f[1])))
        slope = _profile_slope(prof, w.edge, model)
        a = 0.5 * sign * slope
        r = prof.residual
        ok = np.isfinite(a) & np.isfinite(r)
        e = np.broadcast_to(w.edge[:, None], a.shape)[ok]
        saa = np.bincount(e, a[ok] ** 2, minlength=edges.n_edges)
        sar = np.bincount(e, a[ok] * r[ok], minlength=edges.n_edges)
        read = saa > 0
        n_read = int(read.sum())
        if n_read < 4:
            return FieldOffset(np.nan, np.nan, np.nan, np.nan, n_read)
        along = sar[read] / saa[read]  # each edge's offset along its normal (the increment to f's projection)
        N = edges.normal[read]
        W = saa[read]
        A = N.T @ (W[:, None] * N)
        step = np.linalg.solve(A, N.T @ (W * along))
        chi = W * (along - N @ step) ** 2
        cov = np.linalg.inv(A) * float(chi.sum()) / max(n_read - 2, 1)
        f = f + step
        if np.all(np.abs(step) < 1e-4):
            break
    return FieldOffset(float(f[0]), float(f[1]), float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1])), n_read)

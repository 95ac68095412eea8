"""The blurred step on the pixel grid, and the edge reader that fits it on each scan line.

A straight edge blurred by a Gaussian (the optics) and integrated over each pixel (the sensor) gives a
profile ``A + (B - A) C(k; e, sigma)`` across it: :func:`pixel_step` forms ``C`` and its derivatives
(compiled, the Gaussian terms only near the edge), :func:`step_fit` fits the edge with free levels per
scan line, and :func:`refine_step_fit` is the reader that refines area-estimator points so (the ``step_fit``
edge model of :mod:`doorloc.vision.edge_models`). :func:`face_slope_step_fit` lets the door's face change
linearly with the distance from the edge (a flank of wood grain that runs along it), blurred with the step,
and :func:`refine_face_slope_fit` is the reader that refines points so, the blur found in the profiles. The
far-face fit (:mod:`doorloc.vision.far_face`) and the texture term (:mod:`doorloc.vision.texture`) use the
same pixel model.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import kernel, pairwise_sum
from doorloc.vision.sampling import gather_profiles, normal_cdf_pdf, oriented

__all__ = [
    "FACE_SLOPE_MAX_MOVE_PX",
    "STEP_FIT_MIN_BLUR_PX",
    "STEP_TAIL_SIGMAS",
    "FaceSloped",
    "face_slope_step_fit",
    "pixel_step",
    "refine_face_slope_fit",
    "refine_step_fit",
    "step_fit",
]


#: beyond this many blur sigmas from an edge a blurred step is 0 or 1 to within 1e-23 (Phi(-10) = 7.6e-24),
#: far below the rounding of the grey levels it is added to: :func:`pixel_step` takes the exact limits there
STEP_TAIL_SIGMAS = 10.0

#: how far the sloped fit may move a point from its area estimate, px (the flank of a strong grain's
#: stripe moved a door's reference arris's area estimates 0.8-1.6 px)
FACE_SLOPE_MAX_MOVE_PX = 2.0
#: the blurs the sloped fit tries, times the one the flat transition widths read (which texture only
#: widens), in steps of a quarter in the log
FACE_SLOPE_BLUR_STEPS = (0.4, 0.5, 0.63, 0.79, 1.0, 1.26)
#: scan lines the blur is searched on, at most
FACE_SLOPE_BLUR_ROWS = 160
#: a scan line's sloped fit stops at a step shorter than this, px: on the realistic frames of
#: ``bench/bench_speed.py --seed 1`` (2026-12-05) seven scan lines in ten took one before the eighth step
#: (the second fit of a line starts where the first ended), and stopping there took 36 % off the fit's
#: time, 15-25 % off a textured frame's locate; the steps left would have moved a point by 2e-11 px at
#: most there (its misfit by 2e-12 of itself), far below the 1e-6 mm the answers are held to
FACE_SLOPE_CONVERGED_PX = 1e-10
#: the final pass fits a blurred step (LocateConfig.step_fit) only above this optical blur, px, and the
#: sloped fit tries no blur below it: the blurred step's shape then depends on the pixel's phase
STEP_FIT_MIN_BLUR_PX = 0.5


def _step_pixel_values_warm_up(k) -> None:
    k(np.arange(7.0) - 3.5, np.array([0.2, -0.4]), 0.1, STEP_TAIL_SIGMAS)
    k(np.arange(7.0) - 3.5, np.array([0.2, np.nan]), 2.0, STEP_TAIL_SIGMAS)


@kernel(_step_pixel_values_warm_up)
def _step_pixel_values(bounds, e, sigma, tail_sigmas):
    """The pixel values ``C``, ``-dC/de`` and ``dC/dsigma`` (N, M) of :func:`pixel_step`, and whether the
    Gaussian terms were evaluated near the edges only (within ``tail_sigmas`` blur sigmas).

    Near each edge: ``Phi(y / sigma)``, ``phi(y / sigma)`` and the integral of ``Phi`` over ``y``,
    ``y Phi + sigma phi``, on a window of ``K`` boundaries per row (from the first within the tail cut,
    moved left at the far end; ``K`` the widest row's count plus one); everywhere where ``2 K`` reaches the
    boundary count or an edge is not finite.
    """
    N, n_b = e.size, bounds.size
    cut = tail_sigmas * sigma
    lo = np.searchsorted(bounds, e - cut, side="left")
    hi = np.searchsorted(bounds, e + cut, side="right")
    K = 1
    finite = True
    for i in range(N):
        K = max(K, hi[i] - lo[i] + 1)
        finite = finite and np.isfinite(e[i])
    windowed = 2 * K < n_b and finite
    C = np.empty((N, n_b - 1))
    g = np.empty((N, n_b - 1))
    h = np.empty((N, n_b - 1))
    inv = 1.0 / sigma
    G = np.empty(n_b)
    P = np.empty(n_b)
    p = np.empty(n_b)
    for i in range(N):
        j0, j1 = (min(lo[i], n_b - K), min(lo[i], n_b - K) + K) if windowed else (0, n_b)
        for j in range(n_b):
            y = bounds[j] - e[i]
            if j0 <= j < j1:
                P[j], p[j] = normal_cdf_pdf(y * inv)
                G[j] = y * P[j] + sigma * p[j]
            else:
                P[j] = 1.0 if y > 0.0 else 0.0
                p[j] = 0.0
                G[j] = max(y, 0.0)
        for j in range(n_b - 1):
            C[i, j] = G[j + 1] - G[j]
            g[i, j] = P[j + 1] - P[j]
            h[i, j] = p[j + 1] - p[j]
    return C, g, h, windowed


def pixel_step(bounds: np.ndarray, e: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit steps at ``e`` (N,), blurred by a Gaussian ``sigma`` and integrated over pixels (compiled:
    :func:`_step_pixel_values`).

    ``bounds`` (M + 1,) are the pixel boundaries, ascending (pixel ``i`` spans ``bounds[i]..bounds[i + 1]``).
    Returns, each (N, M), the pixel values ``C``, ``-dC/de`` (``g``) and ``dC/dsigma`` (``h``). The Gaussian
    terms (``Phi``, ``exp``: most of the cost) are evaluated only on the boundaries within
    :data:`STEP_TAIL_SIGMAS` blur sigmas of each edge; beyond them the step's exact limits (``Phi`` 0 or 1,
    ``phi`` 0, its integral 0 or ``y``) stand in, which differ from the full evaluation by less than 1e-22.
    A narrow blur (rendered and most real frames: sigma < 0.2 px) thus costs a few boundaries per scan line
    instead of the whole window.
    """
    C, g, h, _ = _step_pixel_values(
        np.ascontiguousarray(bounds, np.float64),
        np.ascontiguousarray(e, np.float64),
        float(sigma),
        STEP_TAIL_SIGMAS,
    )
    return C, g, h


def step_fit(
    vals: np.ndarray, e: np.ndarray, bounds: np.ndarray, sigma: float, n_iter: int = 4
) -> np.ndarray:
    """Edge positions (N,) that make ``A + (B - A) C(k; e, sigma)`` fit each profile row of ``vals`` best.

    ``C`` is a Gaussian-blurred unit step integrated over each pixel (:func:`pixel_step`), ``bounds`` the
    pixel boundaries in the coordinates of ``e``. Per row, ``A`` and ``B`` are solved linearly for the
    current edge and the edge takes a Gauss-Newton step (clipped to half a pixel) - a variable-projection
    fit with three unknowns per scan line (compiled: :func:`_step_fit_rows`).
    """
    return _step_fit_rows(
        np.ascontiguousarray(vals, np.float64),
        np.array(e, np.float64),
        np.ascontiguousarray(bounds, np.float64),
        float(sigma),
        n_iter,
    )


def _step_fit_warm_up(k) -> None:
    k(np.full((2, 6), 0.5), np.zeros(2), np.arange(7.0) - 3.5, 0.5, 2)


@kernel(_step_fit_warm_up)
def _step_fit_rows(vals, e, bounds, sigma, n_iter):
    """:func:`step_fit`'s iterations (``e`` updated in place and returned): each row's sums in numpy's
    order (written with numpy, 7 row sums and a dozen array operations per iteration took 2-3 ms of a
    textured frame's step fits).

    The edge's step divides by its Jacobian less the part of it the two levels take up (variable
    projection; as :func:`_face_slope_fit_rows`): the levels move with the edge, and a step over the
    Jacobian alone fell short of the minimum by a third of the distance at every iteration: on the
    realistic frames of ``bench/bench_speed.py`` six such steps left the scan lines 8.3e-5 px (RMS) from
    their minimum, four steps so projected 6.7e-5 px, at two thirds of the cost."""
    N, M = vals.shape
    t = np.empty((9, M))
    for _ in range(n_iter):
        C, g, _, _ = _step_pixel_values(bounds, e, sigma, STEP_TAIL_SIGMAS)
        for i in range(N):
            for k in range(M):
                x0 = 1.0 - C[i, k]
                t[0, k] = x0 * x0
                t[1, k] = x0 * C[i, k]
                t[2, k] = C[i, k] * C[i, k]
                t[3, k] = x0 * vals[i, k]
                t[4, k] = C[i, k] * vals[i, k]
            s00, s01, s11 = pairwise_sum(t[0], 0, M), pairwise_sum(t[1], 0, M), pairwise_sum(t[2], 0, M)
            b0, b1 = pairwise_sum(t[3], 0, M), pairwise_sum(t[4], 0, M)
            det = s00 * s11 - s01 * s01
            A = (s11 * b0 - s01 * b1) / det
            B = (s00 * b1 - s01 * b0) / det
            for k in range(M):
                r = vals[i, k] - (A * (1.0 - C[i, k]) + B * C[i, k])
                J = (B - A) * g[i, k]  # -dm/de (g = -dC/de)
                t[5, k] = J * r
                t[6, k] = J * J
                t[7, k] = (1.0 - C[i, k]) * J
                t[8, k] = C[i, k] * J
            jj = pairwise_sum(t[6], 0, M)
            u0, u1 = pairwise_sum(t[7], 0, M), pairwise_sum(t[8], 0, M)
            taken = (s11 * u0 * u0 - 2.0 * s01 * u0 * u1 + s00 * u1 * u1) / det
            den = jj - taken if jj - taken > 1e-9 * jj else jj
            de = -pairwise_sum(t[5], 0, M) / den
            e[i] = e[i] + (min(max(de, -0.5), 0.5) if np.isfinite(de) else 0.0)
    return e


def _face_slope_fit_warm_up(k) -> None:
    k(np.full((2, 9), 0.5), np.zeros(2), np.arange(10.0) - 4.5, 0.8, 2, np.zeros(2))


@kernel(_face_slope_fit_warm_up)
def _face_slope_fit_rows(vals, e, bounds, sigma, n_iter, misfit):
    """:func:`face_slope_step_fit`'s iterations, the face at increasing coordinates (``e`` updated in place
    and returned; ``misfit`` (N,) takes each row's sum of squared residuals at its last iteration).

    The face's light ``B + s (y - e)`` beyond the edge, blurred by the Gaussian and integrated over each
    pixel, is ``B C + s D``: ``C`` the pixel's integral of ``Phi``, ``D`` of its integral
    ``G(y) = y Phi + sigma phi`` (``H(y) = (y^2 + sigma^2) Phi / 2 + y sigma phi / 2`` at the pixel's
    boundaries); ``-dC/de`` is the pixel's ``Phi`` difference and ``-dD/de`` is ``C``. The whole row is
    evaluated (its window is a few blur widths). A row stops once its step is under
    :data:`FACE_SLOPE_CONVERGED_PX` (``misfit`` then that iteration's)."""
    N, M = vals.shape
    nb = bounds.size
    P = np.empty(nb)
    G = np.empty(nb)
    H = np.empty(nb)
    C = np.empty(M)
    g = np.empty(M)
    D = np.empty(M)
    for i in range(N):
        for _ in range(n_iter):
            for j in range(nb):
                y = bounds[j] - e[i]
                Pj, pj = normal_cdf_pdf(y / sigma)
                P[j] = Pj
                G[j] = y * Pj + sigma * pj
                H[j] = 0.5 * (y * y + sigma * sigma) * Pj + 0.5 * y * sigma * pj
            # the normal equations of the levels (A, B, s) on the columns (1 - C, C, D)
            a00 = a01 = a02 = a11 = a12 = a22 = b0 = b1 = b2 = 0.0
            for k in range(M):
                C[k] = G[k + 1] - G[k]
                g[k] = P[k + 1] - P[k]
                D[k] = H[k + 1] - H[k]
                x0, x1, x2, v = 1.0 - C[k], C[k], D[k], vals[i, k]
                a00 += x0 * x0
                a01 += x0 * x1
                a02 += x0 * x2
                a11 += x1 * x1
                a12 += x1 * x2
                a22 += x2 * x2
                b0 += x0 * v
                b1 += x1 * v
                b2 += x2 * v
            c00 = a11 * a22 - a12 * a12
            c01 = a02 * a12 - a01 * a22
            c02 = a01 * a12 - a02 * a11
            det = a00 * c00 + a01 * c01 + a02 * c02
            c11, c12, c22 = a00 * a22 - a02 * a02, a02 * a01 - a00 * a12, a00 * a11 - a01 * a01
            A = (c00 * b0 + c01 * b1 + c02 * b2) / det
            B = (c01 * b0 + c11 * b1 + c12 * b2) / det
            S = (c02 * b0 + c12 * b1 + c22 * b2) / det
            jr = jj = t0 = t1 = t2 = rr = 0.0
            for k in range(M):
                r = vals[i, k] - (A * (1.0 - C[k]) + B * C[k] + S * D[k])
                J = (B - A) * g[k] + S * C[k]  # -dm/de
                rr += r * r
                jr += J * r
                jj += J * J
                t0 += (1.0 - C[k]) * J
                t1 += C[k] * J
                t2 += D[k] * J
            # the edge's Jacobian less its part the levels take up (variable projection: the residual is
            # already orthogonal to the levels' columns, so only the step's denominator changes)
            taken = (
                t0 * (c00 * t0 + c01 * t1 + c02 * t2)
                + t1 * (c01 * t0 + c11 * t1 + c12 * t2)
                + t2 * (c02 * t0 + c12 * t1 + c22 * t2)
            ) / det
            de = -jr / (jj - taken) if jj - taken > 1e-9 * jj else -jr / jj
            step = min(max(de, -0.5), 0.5) if np.isfinite(de) else 0.0
            e[i] = e[i] + step
            misfit[i] = rr
            if abs(step) < FACE_SLOPE_CONVERGED_PX:
                break
    return e


def face_slope_step_fit(
    vals: np.ndarray,
    e: np.ndarray,
    bounds: np.ndarray,
    sigma: float,
    face_side: int,
    n_iter: int = 8,
    misfit: np.ndarray | None = None,
) -> np.ndarray:
    """Edge positions (N,) that make ``A (1 - C) + B C + s D`` fit each profile row of ``vals`` best: the
    blurred step of :func:`step_fit` with the face's light changing linearly with the distance from the edge
    (``s`` per px) on the side ``face_side`` (+1: increasing coordinates), blurred with it.

    Wood grain that runs along an edge is the same on every scan line at the same distance from it; where a
    flank of it lies beside the edge the face's level near the transition is not its level a few pixels
    out, and a step with flat levels puts the edge where the mean of the two lies (the surfaces bench's
    strong grain: its reference arris 0.3-0.8 px off on a door in ten). A face that changes linearly is
    told apart from the step by the blur's shape (``sigma`` known); the background side stays flat (a
    slope there would trade with the step's level). Four unknowns per scan line, ``A``, ``B``, ``s`` solved
    linearly for the current edge and the edge taking Gauss-Newton steps clipped to half a pixel (compiled:
    :func:`_face_slope_fit_rows`). ``misfit`` (N,), where given, takes each row's sum of squared residuals.
    """
    vals = np.asarray(vals, np.float64)
    bounds = np.asarray(bounds, np.float64)
    e = np.array(e, np.float64)
    if vals.ndim != 2 or bounds.shape != (vals.shape[1] + 1,) or e.shape != (vals.shape[0],):
        # (the compiled loop does not check its indices)
        raise ValueError(
            f"face_slope_step_fit: rows {vals.shape}, bounds {bounds.shape} and edges {e.shape} do not agree: "
            "(N, M) rows need M + 1 pixel bounds and N edges"
        )
    if face_side < 0:  # (mirrored: the face at increasing coordinates)
        vals, bounds, e = vals[:, ::-1], -bounds[::-1], -e
    rss = misfit if misfit is not None else np.empty(e.size)
    out = _face_slope_fit_rows(
        np.ascontiguousarray(vals), e, np.ascontiguousarray(bounds), float(sigma), n_iter, rss
    )
    return out if face_side > 0 else -out


def refine_step_fit(
    plane: np.ndarray, samples: EdgeSamples, half: int, blur_px: float, lut: np.ndarray | None = None
) -> EdgeSamples:
    """Refine area-estimator edge points by fitting a blurred step with free levels on each scan line.

    The area estimator takes the two grey levels from plateaus beyond its window and assumes they hold
    under the transition; texture along the edge (wood grain) breaks that by the difference between the
    texture under the window and at the plateaus. Fitting ``A + (B - A) C(k; e, blur)`` to the window itself
    (``half + 1`` px each side, ``A`` and ``B`` free per scan line) takes both levels from right beside
    the transition instead, and weighs the pixels by how much they say about the edge (the steep part):
    on the bench's wood-grain set it halves the area estimator's error, and on clean steps it is
    as exact. ``blur_px`` (Gaussian sigma, px, without the pixel) only shapes the model: a symmetric
    misfit of it does not move a symmetric edge. Points that the fit moves by more than a pixel, or not
    to a finite value, keep the area estimate.
    """
    ok = samples.valid & np.isfinite(samples.along)
    if not np.any(ok) or not np.isfinite(blur_px):
        return samples
    P = oriented(plane, samples.axis)
    a0 = samples.along[ok]
    c0 = np.round(a0).astype(int)
    h = half + 1
    vals, inside = gather_profiles(P, samples.scan[ok], c0 - h, 2 * h + 1, lut=lut)
    bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
    e = step_fit(vals, a0 - c0, bounds, max(float(blur_px), 0.05))
    fitted = c0 + e
    keep = inside.all(axis=1) & np.isfinite(fitted) & (np.abs(fitted - a0) <= 1.0)
    along = samples.along.copy()
    along[np.flatnonzero(ok)[keep]] = fitted[keep]
    return replace(samples, along=along)


@dataclass(frozen=True)
class FaceSloped:
    """Edge points read with the face's level sloped (:func:`refine_face_slope_fit`), and the blur that fits
    their profiles best (px, Gaussian sigma without the pixel)."""

    samples: EdgeSamples
    blur_px: float


def refine_face_slope_fit(
    plane: np.ndarray,
    samples: EdgeSamples,
    half: int,
    blur_px: float,
    face_side: int,
    lut: np.ndarray | None = None,
    search_blur: bool = True,
) -> FaceSloped:
    """Refine area-estimator edge points by the blurred step with the face's level sloped
    (:func:`face_slope_step_fit`; the face on the side ``face_side``, +1 at increasing ``along``), on a
    window of ``half + 1`` px each side of the point (as :func:`refine_step_fit`).

    With ``search_blur`` the blur comes from the profiles themselves (:func:`_face_slope_blur`, from
    ``blur_px`` down; else ``blur_px`` is used as it is): texture beside an edge widens
    its transition, so a width read with flat levels is not the lens's blur (a strong grain's door with a
    1.0 px blur read 2.15 on its bottom end, and its arrises read sloped with that blur lay 0.6 px off).
    The window is centred on the area estimate first, then on the fitted edge and fitted again: the face
    is a line only near the edge, and a window placed off it reads another stretch of the stripe (0.14 px
    on a door whose area estimates lay 0.57 px off). Points that move by more than
    ``FACE_SLOPE_MAX_MOVE_PX``, or not to a finite value, keep the area estimate.
    """
    # why many parameters: the edge's window as the flat step fit reads it, and the side of the face
    ok = samples.valid & np.isfinite(samples.along)
    if not np.any(ok) or not np.isfinite(blur_px):
        return FaceSloped(samples, float("nan"))
    P = oriented(plane, samples.axis)
    a0 = samples.along[ok]
    bounds = np.arange(-half - 1, half + 3, dtype=np.float64) - 0.5
    c0 = np.round(a0).astype(int)
    vals, inside = gather_profiles(P, samples.scan[ok], c0 - half - 1, 2 * half + 3, lut=lut)
    rows_in = inside.all(axis=1)
    sigma = (
        _face_slope_blur(vals[rows_in], (a0 - c0)[rows_in], bounds, float(blur_px), face_side)
        if search_blur
        else float(blur_px)
    )
    fitted = c0 + face_slope_step_fit(vals, a0 - c0, bounds, sigma, face_side)
    # (centred again on the fitted edge, where it moved a pixel or less; else where it was)
    c1 = np.where(np.abs(fitted - a0) <= 1.0, np.round(fitted), c0).astype(int)
    vals, inside = gather_profiles(P, samples.scan[ok], c1 - half - 1, 2 * half + 3, lut=lut)
    fitted = c1 + face_slope_step_fit(vals, fitted - c1, bounds, sigma, face_side)
    keep = inside.all(axis=1) & np.isfinite(fitted) & (np.abs(fitted - a0) <= FACE_SLOPE_MAX_MOVE_PX)
    along = samples.along.copy()
    along[np.flatnonzero(ok)[keep]] = fitted[keep]
    return FaceSloped(replace(samples, along=along), sigma)


def _face_slope_blur(
    vals: np.ndarray, e0: np.ndarray, bounds: np.ndarray, blur_px: float, face_side: int
) -> float:
    """The blur (px) with which the sloped step fits the rows ``vals`` best: the median of their squared
    residuals over :data:`FACE_SLOPE_BLUR_STEPS` times ``blur_px`` (no less than ``STEP_FIT_MIN_BLUR_PX``),
    refined by a parabola in the log of the blur through the best and its neighbours; ``blur_px`` where
    fewer than 8 rows are given. Up to :data:`FACE_SLOPE_BLUR_ROWS` rows, evenly spread, are used."""
    if len(vals) < 8:
        return blur_px
    rows = np.unique(np.linspace(0, len(vals) - 1, min(len(vals), FACE_SLOPE_BLUR_ROWS)).astype(int))
    vals, e0 = vals[rows], e0[rows]
    sigmas = np.unique(np.maximum(blur_px * np.asarray(FACE_SLOPE_BLUR_STEPS), STEP_FIT_MIN_BLUR_PX))
    misfit = np.empty(rows.size)
    cost = []
    for s in sigmas:
        face_slope_step_fit(vals, e0, bounds, float(s), face_side, misfit=misfit)
        cost.append(float(np.median(misfit)))
    i = int(np.argmin(cost))
    if 0 < i < sigmas.size - 1:
        x, y = np.log(sigmas[i - 1 : i + 2]), np.asarray(cost[i - 1 : i + 2])
        a, b, _ = np.polyfit(x, y, 2)  # (through the three points)
        if a > 0:
            return float(np.exp(np.clip(-b / (2.0 * a), x[0], x[2])))
    return float(sigmas[i])

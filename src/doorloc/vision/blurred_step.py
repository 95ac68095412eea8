"""The blurred step on the pixel grid, and the edge reader that fits it on each scan line.

A straight edge blurred by a Gaussian (the optics) and integrated over each pixel (the sensor) gives a
profile ``A + (B - A) C(k; e, sigma)`` across it: :func:`pixel_step` forms ``C`` and its derivatives
(compiled, the Gaussian terms only near the edge), :func:`step_fit` fits the edge with free levels per
scan line, and :func:`refine_step_fit` is the reader that refines area-estimator points so (the ``step_fit``
edge model of :mod:`doorloc.vision.edge_models`). The far-face fit (:mod:`doorloc.vision.far_face`) and the
texture term (:mod:`doorloc.vision.texture`) use the same pixel model.
"""

from __future__ import annotations

import numpy as np

from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import kernel, pairwise_sum
from doorloc.vision.sampling import gather_profiles, normal_cdf_pdf, oriented

__all__ = ["STEP_TAIL_SIGMAS", "pixel_step", "refine_step_fit", "step_fit"]


#: beyond this many blur sigmas from an edge a blurred step is 0 or 1 to within 1e-23 (Phi(-10) = 7.6e-24),
#: far below the rounding of the grey levels it is added to: :func:`pixel_step` takes the exact limits there
STEP_TAIL_SIGMAS = 10.0


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
    vals: np.ndarray, e: np.ndarray, bounds: np.ndarray, sigma: float, n_iter: int = 6
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
    textured frame's step fits)."""
    N, M = vals.shape
    t = np.empty((7, M))
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
            de = -pairwise_sum(t[5], 0, M) / pairwise_sum(t[6], 0, M)
            e[i] = e[i] + (min(max(de, -0.5), 0.5) if np.isfinite(de) else 0.0)
    return e


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
    return EdgeSamples(
        samples.axis,
        samples.scan,
        along,
        samples.step,
        samples.noise,
        samples.width,
        samples.bright,
        samples.valid,
    )

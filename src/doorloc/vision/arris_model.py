"""The virtual sharp corner behind a chamfered or rounded arris.

An arris of size ``a`` shows as a strip between the background and the hinge face. Its outer border is
the chamfer's far edge, or on a rounding the silhouette where the view ray grazes the cylinder; its inner
border the tangent line on the hinge face. Both are straight lines whose places follow from the
geometry (:class:`doorloc.arris.ArrisSection`); the strip's brightness does not: it depends on the light,
the wood and the camera's response. Where an edge estimator that assumes a plain step puts the edge inside
the strip depends on that brightness, so locate measures it:

1. :func:`arris_geometry` (:mod:`doorloc.vision.arris_geometry`): from the current pose, each arris's
   cross-section seen from the camera: the outer border's place on the outline plane (``y = a``; inwards
   from the sharp corner's line, mm), the inner border's, and the map from the fraction of the strip's image width to the surface angle ``theta``;
2. :func:`fit_strip_profile`: the strip's shading, fitted to the profiles of many scan lines at once
   (linear light, each normalised by its own two plateaus): background | strip | hinge face, blurred by a
   Gaussian and integrated over the pixels, with the outer border's offset and the blur free, and the strip
   a chamfer's constant level or a rounding's shading (free and piecewise linear, or a Lambert arc where
   that fits about as well; the two weighed where they disagree; where the arc fits worse, its deficit
   under the light fitted to it is a prior on the free shading's, as wide as the two disagree). What it
   returns is the strip's *deficit*: the fraction of its width by which the area of the strip falls short
   of the hinge face, the mean of its posterior along the valley where the border's offset and the
   strip's level trade off;
3. :func:`arris_edges`: per scan line the area estimator (blur-free: it only uses areas) with that deficit,
   ``e = K - S / D - w * deficit``, which puts every edge point on the outer border, then refined by
   fitting the strip's fitted shape to the line with its two levels free (:func:`_line_borders`: the
   area estimate takes in the face's texture beside the strip, the shape fit hardly); the caller moves
   it to the sharp corner's line by the geometry.

What the deficit leaves in doubt (the posterior's standard deviation, widened by the blur model's doubt)
is reported per line as ``arris_correction_sigma_mm`` for the uncertainty budget.

Cost: the profiles are binned by the outer border's sub-pixel phase (``_PHASE_BINS`` rows instead of one
per scan line), the levels are solved linearly inside every evaluation (variable projection) with closed
form derivatives of the pixel integrals in the offset and the blur, and grids of offsets are evaluated as
one batch: a few ms per edge (it was ~60-90 ms with numerical Jacobians and one design per evaluation).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from doorloc.vision.arris_geometry import ArrisGeometry, arris_geometry
from doorloc.vision.edges import DITHERING_NOISE_LEVELS, STEP_TAIL_SIGMAS, EdgeSamples
from doorloc.vision.jit import kernel, pairwise_sum
from doorloc.vision.sampling import Axis, gather_profiles, normal_cdf_pdf, oriented

__all__ = ["ArrisGeometry", "StripFit", "arris_geometry", "deficit_prior", "fit_strip_profile", "arris_edges"]

#: sub-intervals of a rounding's strip (uniform in image width) over which its shading is taken constant in
#: the fit, at most
_STRIP_CELLS = 16
#: narrowest part of a rounding's strip whose shading level the fit leaves free, px
_PART_PX = 1.5
#: sub-pixel phases of the outer border over which the fit bins its profiles
_PHASE_BINS = 8
#: Lambert shadings (of the 41 lights tried) refined at their best place against a rounding's free shading
_SHADINGS_REFINED = 4
#: scan lines the shading fit uses at most (spread evenly over the edge)
_FIT_LINES = 40
#: plausible error of the Gaussian blur model, px (sets the model's doubt in the strip's deficit)
BLUR_DOUBT = 0.1
#: least doubt in the deficit of a rounding's Lambert shading under the light fitted to it (a real finish is
#: no exact Lambertian, nor its light one direction): 0.03 of the strip's width
LIT_DEFICIT_FLOOR = 0.03
#: prior of the deficit where the two plateaus' radiances cannot say more (no contrast): a strip somewhere
#: between the background and the hinge face
PRIOR_DEFICIT, PRIOR_SIGMA = 0.5, 0.5
#: prior of the strip's mean radiance over the hinge face's (linear light): mean and standard deviation.
#: From physics, not fitted to any rendered set: the strip is the same wood turned away from the camera by
#: 0-90 deg. Under light from anywhere in front of the door a Lambertian surface turned by theta gets about
#: (1 + cos theta) / 2 of what the face gets: a 45 deg chamfer 0.85, a rounding (cos theta averaged over
#: its image width, uniform in sin theta) 0.89. A light from one side brightens one arris and darkens the
#: other; sanding and end grain move the albedo by some tens of per cent: +-0.45 (a grazing light can make
#: a chamfer facing it glint at twice the face, arris bench seed 1092: the prior's tail, where a strip
#: narrower than the blur is then misplaced by 2.7 sigma). It is what places the edge where the profiles
#: cannot split a strip's area into its width and its level (a strip narrower than the blur): the neutral
#: "between background and face" (0.5 +- 0.5 of the contrast) put the edge a quarter of such a strip's
#: width outwards on average (arris bench, arrises of 0-0.3 mm: thickness +0.047 mm mean over 12
#: chamfers) and, on a door darker than its background, assumed a strip brighter than the face.
STRIP_RADIANCE, STRIP_RADIANCE_SIGMA = 0.9, 0.45
#: prior of each strip cell's relative level ``(strip - background) / (face - background)``: about the
#: middle, within a wide range (a strip in shadow is a little darker than the background, a lit one
#: brighter than the face). Weak beside what the profiles say of a strip a pixel wide or more; on a strip
#: much narrower than a pixel it is what keeps the levels finite (module docstring of _StripProblem)
PRIOR_LEVEL, PRIOR_LEVEL_SIGMA = 0.5, 1.0


def deficit_prior(face: float, background: float) -> tuple[float, float]:
    """The strip's deficit a priori, mean and standard deviation, from the plateaus' levels.

    ``face`` and ``background`` are in linear light (zero at black). A strip of radiance ``rho`` times the
    face's has the deficit ``(1 - rho) face / (face - background)``; ``rho`` is ``STRIP_RADIANCE +-
    STRIP_RADIANCE_SIGMA``. Without a usable contrast (or a face at black) the neutral ``PRIOR_DEFICIT +-
    PRIOR_SIGMA``.

    >>> [round(v, 3) for v in deficit_prior(200.0, 20.0)]  # a bright face on a dark background
    [0.111, 0.5]
    >>> [round(v, 3) for v in deficit_prior(100.0, 200.0)]  # a door darker than its background
    [-0.1, 0.45]
    >>> deficit_prior(0.0, 0.0)  # no contrast: the neutral prior
    (0.5, 0.5)
    """
    contrast = face - background
    if not (math.isfinite(face) and math.isfinite(background)) or face <= 0 or abs(contrast) < 1e-6 * face:
        return PRIOR_DEFICIT, PRIOR_SIGMA
    k = face / contrast
    return (1.0 - STRIP_RADIANCE) * k, STRIP_RADIANCE_SIGMA * abs(k)


@dataclass(frozen=True)
class StripFit:
    """The strip's shading fitted over many scan lines (:func:`fit_strip_profile`).

    Attributes
    ----------
    deficit : float
        ``1/w`` times the integral over the strip of ``(face - strip) / (face - background)``: 0 for a strip as
        bright as the hinge face (the edge is the outer border), 1 for one as dark as the background.
    deficit_sigma : float
        Its standard deviation: the posterior's along the valley where the border's offset and the strip's
        level trade off (:func:`fit_strip_profile`), widened by the blur model's doubt.
    offset_px : float
        Outer border's offset from where the pose put it, px (along the mirrored scan, towards the door).
    blur_px : float
        Gaussian blur sigma that fits best, px.
    misfit : float
        Residual RMS of the fit over the plateaus' noise (about 1 when the model explains the profiles).
    levels : ndarray
        The strip's relative level ``(strip - background) / (face - background)`` on ``_STRIP_CELLS`` cells.
    model : ndarray (N, P)
        The fitted profiles (noise-free), for the profiles that went into the fit.
    border : ndarray (N,)
        Their fitted outer border (coordinates of ``x``), px.
    model_deficit : float
        The deficit of the fitted profiles ``model`` (the best fit's, where ``deficit`` is the posterior
        mean along the valley).
    deficit_at_blur : callable or None
        ``blur_px -> deficit``: the deficit of the best fit with the blur held at another value (the
        border's offset searched again over the fit's range), for the caller's check of the blur against
        the image's other strips (one lens, one blur).
    """

    deficit: float
    deficit_sigma: float
    offset_px: float
    blur_px: float
    misfit: float
    levels: np.ndarray
    model: np.ndarray
    border: np.ndarray
    model_deficit: float
    deficit_at_blur: Callable[[float], float] | None = field(default=None, compare=False, repr=False)


def _pixel_terms(
    edges: np.ndarray, bounds: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each pixel's integral of a blurred unit level beyond each boundary, and its derivatives.

    ``edges`` (P+1,) the pixel borders, ascending; ``bounds`` (B, R, J) the boundaries of each candidate
    ``B`` and row ``R``; ``sigma`` (B,) the Gaussian blur. With ``G(y) = y Phi(y / s) + s phi(y / s)`` (the
    integral of the Gaussian CDF) the pixel between borders ``e0, e1`` sees ``G(e1 - b) - G(e0 - b)`` of the
    level beyond ``b``; ``dG/db = -Phi`` and ``dG/ds = phi`` are closed form. Returns ``prim``,
    ``d prim / d b`` and ``d prim / d s``, each (B, R, P, J) (compiled: :func:`_pixel_terms_compiled`).
    """
    sigma = np.asarray(sigma, np.float64).reshape(-1)
    n_b = max(bounds.shape[0], sigma.size)  # (the candidates broadcast, as in the array formula)
    if bounds.shape[0] != n_b:
        bounds = np.broadcast_to(bounds, (n_b, *bounds.shape[1:]))
    if sigma.size != n_b:
        sigma = np.broadcast_to(sigma, (n_b,))
    return _pixel_terms_compiled(
        np.ascontiguousarray(edges, np.float64),
        np.ascontiguousarray(bounds, np.float64),
        np.ascontiguousarray(sigma),
        STEP_TAIL_SIGMAS,
    )


def _pixel_terms_warm_up(k) -> None:
    k(np.arange(12.0) - 5.5, np.array([[[-0.3, 0.6]], [[0.1, 1.2]]]), np.array([0.4, 1.1]), STEP_TAIL_SIGMAS)


@kernel(_pixel_terms_warm_up)
def _pixel_terms_compiled(edges, bounds, sigma, tail_sigmas):
    """:func:`_pixel_terms`, compiled. The Gaussian terms (most of the cost: the strip fit evaluates them
    for every candidate, bin and cell boundary at every pixel border, 20-40 ms of an arris frame as array
    code) only at the borders within ``tail_sigmas`` blur sigmas of each boundary; beyond them the exact
    limits (``Phi`` 0 or 1, ``phi`` 0, ``G`` 0 or ``y``), as :func:`doorloc.vision.edges._pixel_step`:
    they differ from the full evaluation by less than 1e-22. ``Phi`` and ``phi`` are
    :func:`doorloc.vision.edges._normal_cdf_pdf` (within 2e-14 of scipy's ndtr, relative)."""
    n_b, n_r, n_j = bounds.shape
    n_e = edges.size
    prim = np.empty((n_b, n_r, n_e - 1, n_j))
    d_b = np.empty((n_b, n_r, n_e - 1, n_j))
    d_s = np.empty((n_b, n_r, n_e - 1, n_j))
    _pixel_terms_fill(edges, bounds, sigma, tail_sigmas, prim, d_b, d_s)
    return prim, d_b, d_s


@kernel(inline=True)
def _pixel_terms_fill(edges, bounds, sigma, tail_sigmas, prim, d_b, d_s):
    """:func:`_pixel_terms_compiled`'s terms written into ``prim``, ``d_b``, ``d_s`` (B, R, P, J)."""
    n_b, n_r, n_j = bounds.shape
    n_e = edges.size
    G = np.empty(n_e)
    C = np.empty(n_e)
    D = np.empty(n_e)
    for b in range(n_b):
        s = sigma[b]
        cut = tail_sigmas * s
        for r in range(n_r):
            for j in range(n_j):
                at = bounds[b, r, j]
                lo = np.searchsorted(edges, at - cut, side="left")
                hi = np.searchsorted(edges, at + cut, side="right")
                for p in range(n_e):
                    y = edges[p] - at
                    if lo <= p < hi and math.isfinite(y):
                        C[p], D[p] = normal_cdf_pdf(y / s)
                        G[p] = y * C[p] + s * D[p]
                    elif y != y:  # a NaN boundary: NaN terms, as the array code gave
                        C[p] = D[p] = G[p] = np.nan
                    else:
                        C[p] = 1.0 if y > 0.0 else 0.0
                        D[p] = 0.0
                        G[p] = max(y, 0.0)
                for p in range(n_e - 1):
                    prim[b, r, p, j] = G[p + 1] - G[p]
                    d_b[b, r, p, j] = C[p] - C[p + 1]
                    d_s[b, r, p, j] = D[p + 1] - D[p]


def _strip_basis(geom: ArrisGeometry, n_cells: int, terminator: float | None, lit_below: bool) -> np.ndarray:
    """A rounding's Lambert shading basis on the strip cells, shape (C, k): ``1, cos, sin`` of ``theta`` (a
    light whose terminator lies off the arc), or ``1, max(0, +-sin(theta - terminator))``."""
    # cell means over 8 sub-samples: near the silhouette theta changes fast across one cell
    tau = (np.arange(n_cells)[:, None] + (np.arange(8)[None, :] + 0.5) / 8) / n_cells
    th = geom.theta_at(tau)
    if terminator is None:
        return np.stack([np.ones(n_cells), np.cos(th).mean(axis=1), np.sin(th).mean(axis=1)], axis=1)
    s = np.sin(th - terminator) * (-1.0 if lit_below else 1.0)
    return np.stack([np.ones(n_cells), np.maximum(s, 0.0).mean(axis=1)], axis=1)


def _mix(basis: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """The map from the boundary terms ``prim`` (J = C + 1) to the design's columns, and its constant.

    Background ``1 - prim_0``, face ``prim_C``, shading basis (C, k) over the cells ``prim_j - prim_j+1``.
    """
    k = basis.shape[1]
    M = np.zeros((n_cells + 1, 2 + k))
    M[0, 0] = -1.0
    M[n_cells, 1] = 1.0
    M[:n_cells, 2:] += basis
    M[1:, 2:] -= basis
    const = np.zeros(2 + k)
    const[0] = 1.0
    return M, const


@dataclass(frozen=True)
class _Eval:
    """The strip model at a batch of (offset, blur) candidates, its levels solved linearly."""

    chi2: np.ndarray  # (B,) weighted residual sum of squares
    coef: np.ndarray  # (B, m) background, face, shading coefficients
    deficit: np.ndarray  # (B,)
    grad: np.ndarray | None  # (B, 2) d chi2 / d (offset, blur), variable projection
    hess: np.ndarray | None  # (B, 2, 2) its Gauss-Newton Hessian


@kernel(inline=True)
def _lu_solve(N, R):
    """Solve ``N X = R`` in place (``N`` (m, m) becomes its LU factors with partial pivoting, ``R`` (m, k)
    becomes ``X``): Gaussian elimination as LAPACK's getrf/getrs, for the strip's few unknowns (numba's
    np.linalg.solve copies and calls LAPACK per system: most of the time at this size)."""
    m = N.shape[0]
    for k in range(m):
        p = k
        for i in range(k + 1, m):
            if abs(N[i, k]) > abs(N[p, k]):
                p = i
        if p != k:
            for j in range(m):
                N[k, j], N[p, j] = N[p, j], N[k, j]
            for j in range(R.shape[1]):
                R[k, j], R[p, j] = R[p, j], R[k, j]
        inv = 1.0 / N[k, k]
        for i in range(k + 1, m):
            N[i, k] *= inv
            for j in range(k + 1, m):
                N[i, j] -= N[i, k] * N[k, j]
            for j in range(R.shape[1]):
                R[i, j] -= N[i, k] * R[k, j]
    for j in range(R.shape[1]):
        for k in range(m - 1, -1, -1):
            acc = R[k, j]
            for i in range(k + 1, m):
                acc -= N[k, i] * R[i, j]
            R[k, j] = acc / N[k, k]


def _strip_solve_warm_up(k) -> None:
    for m in (1, 3):
        basis = np.ones((2, m))
        M, const = _mix(basis, 2)
        prim = np.random.default_rng(0).uniform(size=(2, 3, 5, 3))
        P = np.concatenate([np.full((2, 1), -0.5), np.full((2, 1), -0.5), basis], axis=1)
        for jac in (False, True):
            k(prim, prim, prim, M, const, np.ones(15), np.ones(15), P, basis, jac)


@kernel(_strip_solve_warm_up, reassociate=True)
def _strip_solve(prim, d_b, d_s, M, const, y, w, P, basis, jac):
    """:meth:`_StripProblem.solve`, compiled: for each candidate ``b`` the design ``A = prim[b] M + const``
    (``n = R * P`` rows), the normal equations ``A'WA + P'P + 1e-12 I`` with the levels' prior rows ``P``,
    the coefficients, ``chi2``, the deficit, and with ``jac`` the variable projection's gradient and
    Gauss-Newton Hessian by (offset, blur). The array code's formulas; its matrix products summed in
    vector lanes (``reassociate``) instead of BLAS's blocks: the same numbers to rounding, and the
    coefficients, of ill-conditioned normal equations, to ~1e-9 relative. (As array code, ~20 array
    operations per call on a few hundred rows: 0.3 ms a call, a third of an arris frame.)
    """
    n_b, n_r, n_p, n_j = prim.shape
    n = n_r * n_p
    m = M.shape[1]
    n_c = P.shape[0]
    chi2 = np.empty(n_b)
    coef = np.empty((n_b, m))
    deficit = np.empty(n_b)
    grad = np.zeros((n_b, 2))
    hess = np.zeros((n_b, 2, 2))
    PtP = np.zeros((m, m))
    for c in range(m):
        for e in range(m):
            for k in range(n_c):
                PtP[c, e] += P[k, c] * P[k, e]
    At = np.empty((m, n))  # the design, one row per column of A (the sums below run along rows)
    Aw = np.empty((m, n))  # ... times the weights
    Jm = np.empty((2, n))
    f = np.empty(n)
    fp = np.empty(n_c)
    N = np.empty((m, m))
    N0 = np.empty((m, m))
    R = np.empty((m, 1))
    R2 = np.empty((m, 2))
    v = np.empty(n_j)
    for b in range(n_b):
        pb = prim[b].reshape(n, n_j)
        for c in range(m):
            for i in range(n):
                acc = 0.0
                for j in range(n_j):
                    acc += pb[i, j] * M[j, c]
                At[c, i] = acc + const[c]
                Aw[c, i] = At[c, i] * w[i]
        for c in range(m):
            for e in range(c, m):
                acc = 0.0
                for i in range(n):
                    acc += Aw[c, i] * At[e, i]
                N[c, e] = N[e, c] = (acc + PtP[c, e]) + (1e-12 if c == e else 0.0)
            acc = 0.0
            for i in range(n):
                acc += Aw[c, i] * y[i]
            R[c, 0] = acc
        N0[:, :] = N
        _lu_solve(N, R)
        x = R[:, 0]
        coef[b] = x
        f[:] = 0.0
        for c in range(m):
            for i in range(n):
                f[i] += At[c, i] * x[c]
        c2 = 0.0
        for i in range(n):
            f[i] -= y[i]
            c2 += f[i] * f[i] * w[i]
        for k in range(n_c):
            acc = 0.0
            for c in range(m):
                acc += P[k, c] * x[c]
            fp[k] = acc
            c2 += acc * acc
        chi2[b] = c2
        c0, cb = x[0], x[1]
        dsum = 0.0
        for k in range(n_c):
            lev = 0.0
            for q in range(m - 2):
                lev += basis[k, q] * x[2 + q]
            dsum += 1.0 - (lev - c0) / (cb - c0)
        deficit[b] = dsum / n_c
        if not jac:
            continue
        # variable projection (Kaufman): d f / d theta = (I - A A+) (dA / d theta) coef, where
        # (dA / d theta) coef = (d prim / d theta) (M coef)
        for j in range(n_j):
            acc = 0.0
            for c in range(m):
                acc += M[j, c] * x[c]
            v[j] = acc
        db, ds = d_b[b].reshape(n, n_j), d_s[b].reshape(n, n_j)
        for i in range(n):
            a0 = 0.0
            a1 = 0.0
            for j in range(n_j):
                a0 += db[i, j] * v[j]
                a1 += ds[i, j] * v[j]
            Jm[0, i] = a0
            Jm[1, i] = a1
        for c in range(m):
            for t in range(2):
                acc = 0.0
                for i in range(n):
                    acc += Aw[c, i] * Jm[t, i]
                R2[c, t] = acc
        _lu_solve(N0, R2)  # d coef / d (offset, blur), (m, 2)
        for c in range(m):
            for t in range(2):
                for i in range(n):
                    Jm[t, i] -= At[c, i] * R2[c, t]
        g0 = g1 = h00 = h01 = h11 = 0.0
        for i in range(n):
            j0, j1 = Jm[0, i] * w[i], Jm[1, i] * w[i]
            g0 += j0 * f[i]
            g1 += j1 * f[i]
            h00 += j0 * Jm[0, i]
            h01 += j0 * Jm[1, i]
            h11 += j1 * Jm[1, i]
        # the prior rows do not move with the offset or the blur: only through the coefficients
        for k in range(n_c):
            p0 = p1 = 0.0
            for c in range(m):
                p0 -= P[k, c] * R2[c, 0]
                p1 -= P[k, c] * R2[c, 1]
            g0 += p0 * fp[k]
            g1 += p1 * fp[k]
            h00 += p0 * p0
            h01 += p0 * p1
            h11 += p1 * p1
        grad[b, 0], grad[b, 1] = 2.0 * g0, 2.0 * g1
        hess[b, 0, 0], hess[b, 1, 1] = 2.0 * h00, 2.0 * h11
        hess[b, 0, 1] = hess[b, 1, 0] = 2.0 * h01
    return chi2, coef, deficit, grad, hess


def _strip_evaluate_warm_up(k) -> None:
    edges = np.arange(13.0) - 0.5
    for m in (1, 3):
        basis = np.ones((2, m))
        M, const = _mix(basis, 2)
        P = np.concatenate([np.full((2, 1), -0.5), np.full((2, 1), -0.5), basis], axis=1)
        v = np.array([4.0, 5.0, 6.0])
        for jac in (False, True):
            k(
                edges,
                v,
                v,
                np.linspace(0, 1, 3),
                v,
                v,
                STEP_TAIL_SIGMAS,
                M,
                const,
                np.ones(36),
                np.ones(36),
                P,
                basis,
                jac,
            )


@kernel(_strip_evaluate_warm_up)
def _strip_evaluate(edges, outer, width, frac, delta, sigma, tail_sigmas, M, const, y, w, P, basis, jac):
    """:meth:`_StripProblem.evaluate`: for each candidate ``b`` (offset ``delta[b]``, blur ``sigma[b]``)
    the strip's pixel terms (:func:`_pixel_terms_fill`, its boundaries ``outer + delta[b] + width frac``)
    and their solve (:func:`_strip_solve`), one candidate at a time: the same numbers as the two kernels
    over all candidates, without their (B, R, P, J) arrays (three of them written and read again per
    call, a few hundred kB: most of an arris frame's time in the strip fit went to them)."""
    n_b, n_r, n_j = delta.size, outer.size, frac.size
    n_p = edges.size - 1
    m = M.shape[1]
    bounds = np.empty((1, n_r, n_j))
    sig = np.empty(1)
    prim = np.empty((1, n_r, n_p, n_j))
    d_b = np.empty((1, n_r, n_p, n_j))
    d_s = np.empty((1, n_r, n_p, n_j))
    chi2 = np.empty(n_b)
    coef = np.empty((n_b, m))
    deficit = np.empty(n_b)
    grad = np.zeros((n_b, 2))
    hess = np.zeros((n_b, 2, 2))
    for b in range(n_b):
        for r in range(n_r):
            for j in range(n_j):
                bounds[0, r, j] = (outer[r] + delta[b]) + width[r] * frac[j]
        sig[0] = sigma[b]
        _pixel_terms_fill(edges, bounds, sig, tail_sigmas, prim, d_b, d_s)
        c2, cf, df, gr, hs = _strip_solve(prim, d_b, d_s, M, const, y, w, P, basis, jac)
        chi2[b] = c2[0]
        coef[b] = cf[0]
        deficit[b] = df[0]
        grad[b] = gr[0]
        hess[b] = hs[0]
    return chi2, coef, deficit, grad, hess


def _bin_means_warm_up(k) -> None:
    k(np.ones((5, 4)), np.arange(5.0), np.ones(5), np.array([0, 2, 2, 0, 1]), np.array([0, 1, 2]))


@kernel(_bin_means_warm_up)
def _bin_means(r, outer, width, k, used):
    """Per phase bin ``used[b]`` of the profiles (``k`` (N,) each profile's bin): the count, and the means
    of the profiles ``r`` (N, P), their outer borders and widths, as numpy's ``mean`` over ``k == b``
    gives them bit for bit (the rows added in order, a single column's and the borders' and widths' sums
    pairwise). Compiled:
    four list comprehensions of masks and means over the bins took a quarter of a millisecond a fit."""
    n, n_p = r.shape
    n_b = used.size
    count = np.zeros(n_b)
    y = np.zeros((n_b, n_p))
    outer_mean = np.empty(n_b)
    width_mean = np.empty(n_b)
    buf_o = np.empty(n)
    buf_w = np.empty(n)
    buf_r = np.empty(n)
    for b in range(n_b):
        m = 0
        for i in range(n):
            if k[i] == used[b]:
                for p in range(n_p):
                    y[b, p] += r[i, p]
                buf_o[m] = outer[i]
                buf_w[m] = width[i]
                buf_r[m] = r[i, 0]
                m += 1
        count[b] = m
        if n_p == 1:  # a single column is contiguous: numpy sums it pairwise too
            y[b, 0] = pairwise_sum(buf_r, 0, m)
        for p in range(n_p):
            y[b, p] /= m
        outer_mean[b] = pairwise_sum(buf_o, 0, m) / m
        width_mean[b] = pairwise_sum(buf_w, 0, m) / m
    return count, y, outer_mean, width_mean


class _StripProblem:
    """The strip model on profiles binned by the outer border's sub-pixel phase (:func:`fit_strip_profile`).

    Profiles whose outer border lies at about the same phase look alike; their mean, weighted by their
    number, carries the same information for the model as the profiles themselves (up to the phase's
    spread in a bin) at a fraction of the cost.

    Each cell's level has a weak prior (``PRIOR_LEVEL`` +- ``PRIOR_LEVEL_SIGMA``, in units of the
    profiles' ``noise``): rows ``[p - 1, -p, basis_j] / (PRIOR_LEVEL_SIGMA / noise)`` (``p = PRIOR_LEVEL``)
    appended to the linear system, which is ``(level_j - p) (face - background)`` exactly. Without it, a strip much
    narrower than a pixel (an arris of a few hundredths of a millimetre) leaves its levels free to grow
    without bound in alternating signs: a strip of +-2000 levels a thirtieth of a pixel wide acts as the
    derivative of the step and shifts the edge by a pixel at no cost (0.09 mm at 8 sigma on the arris
    bench, seed 1519).
    """

    def __init__(
        self,
        r: np.ndarray,
        x: np.ndarray,
        outer: np.ndarray,
        width: np.ndarray,
        n_cells: int,
        bins: int,
        noise: float,
        shared: float = 0.0,
    ) -> None:
        lo, hi = float(outer.min()), float(outer.max())
        k = np.minimum(((outer - lo) / max(hi - lo, 1e-9) * bins).astype(int), bins - 1)
        self.count, self.y, self.outer, self.width = _bin_means(  # (R,), (R, P), (R,), (R,)
            np.ascontiguousarray(r, np.float64),
            np.ascontiguousarray(outer, np.float64),
            np.ascontiguousarray(width, np.float64),
            k,
            np.unique(k),
        )
        self.edges = np.concatenate([x[:1] - 0.5, x + 0.5])
        self.n_cells = n_cells
        self.frac = np.arange(n_cells + 1) / n_cells
        # row weights of the flattened (R * P) system, in units of the profiles' noise: a bin's mean has the
        # noise over its count, and ``shared`` (the rounding of an image whose noise does not dither it:
        # every profile of a bin, at about the same phase, rounded alike) that no count averages down
        eff = self.count / (1.0 + self.count * shared / max(noise, 1e-6) ** 2)
        self.w = np.repeat(eff, r.shape[1])
        self.prior_weight = (max(noise, 1e-6) / PRIOR_LEVEL_SIGMA) ** 2
        self.y_flat = self.y.ravel()
        self._basis_terms: dict[tuple[tuple[int, ...], bytes], tuple[np.ndarray, ...]] = {}

    def evaluate(self, delta: np.ndarray, sigma: np.ndarray, basis: np.ndarray, jac: bool = False) -> _Eval:
        """:meth:`solve` of :meth:`pixel_terms` at a batch of (offset, blur) candidates (compiled, one
        candidate at a time: :func:`_strip_evaluate`)."""
        delta = np.atleast_1d(np.asarray(delta, float))
        sigma = np.maximum(np.atleast_1d(np.asarray(sigma, float)), 0.05)
        n_b = max(delta.size, sigma.size)  # (the candidates broadcast, as in pixel_terms)
        M, const, P, basis_c = self._basis_terms_of(basis)
        chi2, coef, deficit, grad, hess = _strip_evaluate(
            self.edges,
            self.outer,
            self.width,
            self.frac,
            np.ascontiguousarray(np.broadcast_to(delta, (n_b,))),
            np.ascontiguousarray(np.broadcast_to(sigma, (n_b,))),
            STEP_TAIL_SIGMAS,
            M,
            const,
            self.y_flat,
            self.w,
            P,
            basis_c,
            jac,
        )
        return _Eval(chi2, coef, deficit, grad if jac else None, hess if jac else None)

    def _basis_terms_of(self, basis: np.ndarray) -> tuple[np.ndarray, ...]:
        """A shading basis's mix (:func:`_mix`), its levels' prior rows and the basis itself, contiguous:
        a fit solves for a few bases ~20 times each, so they are kept by value."""
        key = (basis.shape, basis.tobytes())
        got = self._basis_terms.get(key)
        if got is None:
            M, const = _mix(basis, self.n_cells)
            # the levels' prior (class docstring): rows P, target 0, the same for every candidate
            C = basis.shape[0]
            P = np.concatenate(
                [np.full((C, 1), PRIOR_LEVEL - 1.0), np.full((C, 1), -PRIOR_LEVEL), basis], axis=1
            ) * math.sqrt(self.prior_weight)
            got = self._basis_terms[key] = (M, const, P, np.ascontiguousarray(basis, np.float64))
        return got

    def pixel_terms(self, delta: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`_pixel_terms` of the strip's boundaries at a batch of (offset, blur) candidates: what
        :meth:`solve` needs for any shading basis."""
        delta = np.atleast_1d(np.asarray(delta, float))
        sigma = np.maximum(np.atleast_1d(np.asarray(sigma, float)), 0.05)
        bounds = (self.outer[None, :, None] + delta[:, None, None]) + self.width[None, :, None] * self.frac
        return _pixel_terms(self.edges, bounds, sigma)

    def solve(
        self, terms: tuple[np.ndarray, np.ndarray, np.ndarray], basis: np.ndarray, jac: bool = False
    ) -> _Eval:
        """The levels solved linearly for one shading basis, given :meth:`pixel_terms` (compiled:
        :func:`_strip_solve`)."""
        prim, d_b, d_s = terms
        M, const, P, basis_c = self._basis_terms_of(basis)
        chi2, coef, deficit, grad, hess = _strip_solve(
            prim, d_b, d_s, M, const, self.y_flat, self.w, P, basis_c, jac
        )
        return _Eval(chi2, coef, deficit, grad if jac else None, hess if jac else None)

    def chi2_many(
        self, terms: tuple[np.ndarray, np.ndarray, np.ndarray], bases: list[np.ndarray]
    ) -> np.ndarray:
        """:meth:`solve`'s misfit for many shading bases at once, shape (bases, candidates).

        Every basis is a linear map ``T`` of the free cell levels (background, face, one level per cell):
        the normal equations of the cells, ``G = A'WA + P'P`` and ``h = A'Wy``, are formed once and each
        basis's are ``T'GT`` and ``T'h``; at the solution the misfit is ``y'Wy - coef . T'h``. (One
        :meth:`solve` per basis cost ~20 ms a fit over the 41 lights tried.)
        """
        prim = terms[0]
        C = self.n_cells
        Mc, const = _mix(np.eye(C), C)
        B = prim.shape[0]
        A = (prim @ Mc + const).reshape(B, -1, Mc.shape[1])  # (B, n, C + 2)
        y = self.y.ravel()
        AwT = A.transpose(0, 2, 1) * self.w
        Pc = np.concatenate(
            [np.full((C, 1), PRIOR_LEVEL - 1.0), np.full((C, 1), -PRIOR_LEVEL), np.eye(C)], axis=1
        )
        G = AwT @ A + self.prior_weight * (Pc.T @ Pc)  # (B, C + 2, C + 2)
        h = AwT @ y  # (B, C + 2)
        yy = float((y * y) @ self.w)
        out = np.empty((len(bases), B))
        for i, basis in enumerate(bases):
            T = np.zeros((C + 2, 2 + basis.shape[1]))
            T[0, 0] = T[1, 1] = 1.0
            T[2:, 2:] = basis
            N = T.T @ G @ T + 1e-12 * np.eye(T.shape[1])
            rhs = h @ T
            coef = np.linalg.solve(N, rhs[..., None])[..., 0]
            out[i] = yy - np.sum(coef * rhs, axis=1)
        return out

    def refine(
        self, delta: float, sigma: float, basis: np.ndarray, n_iter: int = 12
    ) -> tuple[float, float, _Eval]:
        """Gauss-Newton (variable projection, analytic Jacobian) on the offset and the blur."""
        p = np.array([delta, sigma])
        ev = self.evaluate(p[:1], p[1:], basis, jac=True)
        lam = 1e-3
        for _ in range(n_iter):
            assert ev.grad is not None and ev.hess is not None
            H = ev.hess[0] + lam * np.diag(np.diag(ev.hess[0]) + 1e-12)
            step = -np.linalg.solve(H, ev.grad[0])
            step = np.clip(step, [-0.5, -0.3], [0.5, 0.3])
            q = p + step
            q[1] = max(q[1], 0.1)
            ev1 = self.evaluate(q[:1], q[1:], basis, jac=True)
            if ev1.chi2[0] <= ev.chi2[0]:
                done = ev.chi2[0] - ev1.chi2[0] < 1e-9 * max(ev.chi2[0], 1e-300) or np.all(
                    np.abs(step) < 1e-5
                )
                p, ev, lam = q, ev1, lam * 0.3
                if done:
                    break
            else:
                lam *= 10.0
                if lam > 1e6:
                    break
        return float(p[0]), float(p[1]), ev

    def offset_at_blur(self, delta: np.ndarray, sigma: np.ndarray, basis: np.ndarray, n_iter: int) -> _Eval:
        """The model with the offset refitted at a held blur (Newton steps on the offset alone, every
        candidate at once, from ``delta``)."""
        d = np.asarray(delta, float)
        for _ in range(n_iter):
            e = self.evaluate(d, sigma, basis, jac=True)
            assert e.grad is not None and e.hess is not None
            d = d - np.clip(e.grad[:, 0] / np.maximum(e.hess[:, 0, 0], 1e-300), -0.5, 0.5)
        return self.evaluate(d, sigma, basis)

    def profile_blur(
        self, delta: np.ndarray, sigma: np.ndarray, basis: np.ndarray, n_iter: int = 3
    ) -> tuple[np.ndarray, _Eval]:
        """For each offset, the blur that fits best (a few Newton steps on the blur alone, all at once)."""
        s = np.asarray(sigma, float).copy()
        ev = self.evaluate(delta, s, basis, jac=True)
        for _ in range(n_iter):
            assert ev.grad is not None and ev.hess is not None
            step = np.clip(-ev.grad[:, 1] / np.maximum(ev.hess[:, 1, 1], 1e-300), -0.3, 0.3)
            s1 = np.maximum(s + step, 0.1)
            ev1 = self.evaluate(delta, s1, basis, jac=True)
            better = ev1.chi2 <= ev.chi2
            s = np.where(better, s1, s)
            ev = _Eval(
                np.where(better, ev1.chi2, ev.chi2),
                np.where(better[:, None], ev1.coef, ev.coef),
                np.where(better, ev1.deficit, ev.deficit),
                np.where(better[:, None], ev1.grad, ev.grad),  # type: ignore[arg-type]
                np.where(better[:, None, None], ev1.hess, ev.hess),  # type: ignore[arg-type]
            )
        return s, ev


def _posterior_moments(deltas: np.ndarray, deficits: np.ndarray, logp: np.ndarray) -> tuple[float, float]:
    """Mean and standard deviation of the deficit over the border's offsets ``deltas`` (sorted, px) given
    the log-posterior density ``logp`` there (trapezoid weights over the unevenly spaced offsets)."""
    dens = np.exp(logp - logp.max())
    gaps = np.diff(deltas)
    tw = np.zeros(deltas.size)
    tw[:-1] += 0.5 * gaps
    tw[1:] += 0.5 * gaps
    pw = dens * tw
    pw /= pw.sum()
    mean = float(pw @ deficits)
    return mean, math.sqrt(max(float(pw @ (deficits - mean) ** 2), 0.0))


def _lit_deficit(
    prob: _StripProblem,
    tried: list[tuple[int, float, float, _Eval]],
    best: tuple[float, float, _Eval],
    free_basis: np.ndarray,
    t_free: float,
) -> tuple[float, float]:
    """The deficit of a rounding's Lambert shading (the light's direction fitted) and its doubt.

    The doubt: the spread of the deficits of the lights tried, each weighed by its misfit (the lights the
    profiles cannot tell apart), how far the free shading's deficit lies from the arc's at the arc's own
    place and blur (where the profiles ask for another shading than the light's), and ``LIT_DEFICIT_FLOOR``
    (a real surface is no exact Lambertian, nor its light one direction).
    """
    d1, s1, ev1 = best
    chi = np.array([float(ev.chi2[0]) for *_, ev in tried] + [float(ev1.chi2[0])])
    dfs = np.array([float(ev.deficit[0]) for *_, ev in tried] + [float(ev1.deficit[0])])
    wts = np.exp(-(chi - chi.min()) / (2.0 * t_free))
    wts /= wts.sum()
    spread = math.sqrt(max(float(wts @ (dfs - float(ev1.deficit[0])) ** 2), 0.0))
    free_here = float(prob.evaluate(np.array([d1]), np.array([s1]), free_basis).deficit[0])
    doubt = math.sqrt(LIT_DEFICIT_FLOOR**2 + spread**2 + (free_here - float(ev1.deficit[0])) ** 2)
    return float(ev1.deficit[0]), doubt


def fit_strip_profile(
    r: np.ndarray,
    x: np.ndarray,
    outer: np.ndarray,
    width: np.ndarray,
    geom: ArrisGeometry,
    noise: float,
    blur0: float = 1.0,
    search_px: float = 0.0,
    prior: tuple[float, float] = (PRIOR_DEFICIT, PRIOR_SIGMA),
    shared: float = 0.0,
) -> StripFit | None:
    """Fit the strip's shading to normalised profiles (module docstring, step 2).

    Parameters
    ----------
    r : ndarray (N, P)
        Profiles across the edge in linear light, each normalised to 0 on the background and 1 on the hinge
        face (by its own plateaus), ordered from the background towards the door.
    x : ndarray (P,)
        Pixel-centre coordinates of the columns of ``r``, px.
    outer, width : ndarray (N,)
        Predicted outer border (same coordinates as ``x``) and strip width, px, per profile.
    geom : ArrisGeometry
        The strip's geometry (for a rounding's shading basis).
    noise : float
        Typical noise of ``r`` (normalised), for the misfit.
    blur0 : float
        Starting blur, px.
    search_px : float
        How far the outer border may lie from its prediction beyond 2 px (a first pose that took the
        strip's inner border for the edge), px.
    prior : (float, float)
        The deficit's prior, mean and standard deviation (:func:`deficit_prior`; default the neutral one).
    shared : float
        Variance (normalised) that the profiles binned at one phase share and their number does not average
        down: the rounding to grey levels where the noise is too weak to dither it. Measured: a 1.2 mm
        rounding under 0.06 grey levels of noise (arris bench seed 11524's door lit from +40 deg instead of
        -40) had its border placed 0.18 mm off at 14 sigma, the misfit's valleys weighed as if the
        rounding averaged out over the bins' ~5 profiles; with it, at 6.5 sigma (the free shading's two
        places fit alike there and no Lambert arc fits as well: not fixed).

    Returns
    -------
    StripFit or None
        None when there are too few profiles.

    Notes
    -----
    The profiles pin the strip's *area* (where an equivalent plain step would lie) to a small fraction of
    a pixel, but not how that area splits between the border's place and the strip's level: on a strip
    narrower than the blur the two trade off along a valley (a dark strip whose border lies outwards looks
    like a bright one whose border lies inwards; a strip at the background's or the face's level is a
    plain step at either border). A local optimum and its curvature would then report one end of the
    valley with a confidence the data do not give. So the deficit is the mean of its posterior along the
    valley: the misfit profiled over the border's offset (the blur refitted at each; every valley of a
    coarse profile over the search range refined and resolved finely), times the prior ``prior`` (the
    strip's radiance a fraction of the face's: :func:`deficit_prior`), and its standard deviation the posterior's,
    widened by how far the deficit moves when the blur model is off by ``BLUR_DOUBT``. Within a valley
    the misfit weighs at the scale of the residuals; between valleys (and along a flat one) the
    residuals' excess over the noise counts as model error common to all the profiles, so that a model
    that misses its profiles by more than their noise does not choose between two places for the border
    by less than that.
    """
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(outer) & np.isfinite(width) & (width > 0)
    r, outer, width = r[ok], outer[ok], width[ok]
    if r.shape[0] < 5:
        return None
    round_ = geom.section.profile == "round"
    w_med = float(np.median(width))
    # cells of at most half a pixel across a rounding's strip (its shading changes across it); a chamfer's
    # is one level
    n_cells = int(np.clip(math.ceil(2.0 * w_med), 4, _STRIP_CELLS)) if round_ else 1
    prob = _StripProblem(r, x, outer, width, n_cells, _PHASE_BINS, noise, shared)
    if round_:
        # A rounding's shading free, piecewise linear across its strip on parts at least _PART_PX wide
        # (what the blur leaves of the shading's detail): a Lambert model of the arc would need the light,
        # and a light whose terminator crosses the arc, a glossy finish or another reflectance would lead
        # it astray (0.36-0.58 mm on the arris bench), where free levels follow any shading.
        n_parts = int(np.clip(math.floor(w_med / _PART_PX), 1, 8))
        # piecewise linear in the strip's width (hat functions on n_parts + 1 knots, at the cells' centres)
        tau = (np.arange(n_cells) + 0.5) / n_cells
        basis0 = np.maximum(0.0, 1.0 - np.abs(tau[:, None] * n_parts - np.arange(n_parts + 1)[None, :]))
    else:
        basis0 = np.ones((n_cells, 1))  # a chamfer's strip: one level

    # The offset has local minima on narrow strips (strip and border trade places): profile the misfit over
    # a grid of offsets across the search range (the blur refitted at each), and refine from the best.
    # A strip at the face's level and one at the background's are both a plain step, at the outer or at
    # the inner border: the search (and the posterior) spans both, a strip's width and more either way.
    reach = search_px + max(2.0, w_med + 1.0)
    step = max(0.2, reach / 10.0)
    grid = np.arange(-reach, reach + 1e-9, step)
    # A place for the border that puts the background (or the face) beyond the profile is not measured by
    # it: the level there is free, and a strip of any level fits what remains (the levels' prior alone
    # sets it). Such a place beat the right one by misfit on the final pass, whose window has no room for
    # a strip's width outwards, and every line's edge left its window (arris bench seeds 7075, 7558: a
    # strip about as bright as the face, a 2.7 mm chamfer's bottom end and a 2.5 mm rounding's far arris
    # lost). The background and the face keep a pixel and twice the blur in view.
    margin = 1.0 + 2.0 * max(blur0, 0.7)
    lo_lim, hi_lim = float(np.max(x[0] + margin - outer)), float(np.min(x[-1] - margin - (outer + width)))
    inside = (grid >= lo_lim) & (grid <= hi_lim)
    if inside.sum() >= 3:
        grid = grid[inside]
    sg, ev = prob.profile_blur(grid, np.full(grid.size, max(blur0, 0.7)), basis0, n_iter=2)
    i0 = int(np.argmin(ev.chi2))
    d0, s0, ev0 = prob.refine(float(grid[i0]), float(sg[i0]), basis0)

    basis = basis0
    # the other shading model's misfit, deficit, and its linear parameters beyond the one in use
    alt: tuple[float, float, int] | None = None
    # the lit arc's deficit and its own doubt, a prior on the free shading's (when the arc is not in use)
    lit: tuple[float, float] | None = None
    if round_:
        # The free shading lets the level next to the silhouette trade off with the border's place; a
        # Lambert arc (the light's direction unknown, its terminator anywhere) does not. It is taken where
        # it explains the profiles about as well as the free shading (the extra parameters' worth of misfit
        # and three standard deviations of it more, at the misfit's scale).
        t_free = max(float(ev0.chi2[0]) / max(prob.y.size - basis0.shape[1] - 4, 1), noise**2)
        cands = [_strip_basis(geom, n_cells, None, False)] + [
            _strip_basis(geom, n_cells, t, lb)
            for t in np.linspace(0.025, 0.975, 20) * float(geom.theta.max())
            for lb in (False, True)
        ]
        # Each shading at many places for the border, not only at the free shading's best: where the
        # strip's outer part is in shadow (at the background's level) the free shading has two places for
        # the border that fit alike, and the arc's own best place is the one that tells them apart (arris
        # bench seed 11524, a 1.2 mm rounding lit from 58 deg above: at the free shading's place the arc
        # missed by 75 noise units, at its own 0.9 px away by 3).
        # The places: steps of a quarter pixel within 2.5 px of the free shading's (the coarse profile's
        # steps grow with the strip's width, 1.3 px on a 12 px strip, wider than an arc's valley).
        places = d0 + np.arange(-2.5, 2.5 + 1e-9, 0.25)
        places = places[(places >= lo_lim) & (places <= hi_lim)] if inside.sum() >= 3 else places
        if places.size == 0:
            places = np.array([d0])
        # (the free shading's own place scored with them, last, for the start it had alone before)
        at = np.append(places, d0)
        costs = prob.chi2_many(prob.pixel_terms(at, np.full(at.size, s0)), cands)  # (shadings, places)
        costs[1:] = np.where(costs[1:] < costs[:1] * 0.98, costs[1:], np.inf)  # a terminator must pay
        here, costs = costs[:, -1], costs[:, :-1]
        # the shadings best at some place, each refined there (its own blur: the free shading's is not
        # the arc's where the two place the border apart)
        best_at = np.argmin(costs, axis=1)
        starts = [
            (int(j), float(places[best_at[j]]), s0)
            for j in np.argsort(costs[np.arange(len(cands)), best_at])[:_SHADINGS_REFINED]
            if np.isfinite(costs[j, best_at[j]])
        ]
        starts.append((int(np.argmin(here)), d0, s0))  # the best shading at the free shading's place
        tried = [(j, *prob.refine(d, sd, cands[j], n_iter=4)) for j, d, sd in starts]
        j, d1, s1, _ = min(tried, key=lambda t: float(t[3].chi2[0]))
        b1 = cands[j]
        d1, s1, ev1 = prob.refine(d1, s1, b1)
        extra = max(basis0.shape[1] - b1.shape[1], 1)
        if (float(ev1.chi2[0]) - float(ev0.chi2[0])) / t_free <= extra + 3.0 * math.sqrt(2.0 * extra):
            alt = (float(ev0.chi2[0]), float(ev0.deficit[0]), extra)
            basis, d0, s0, ev0 = b1, d1, s1, ev1
        else:
            alt = (float(ev1.chi2[0]), float(ev1.deficit[0]), -extra)
            lit = _lit_deficit(prob, tried, (d1, s1, ev1), basis0, t_free)

    # The posterior of the deficit along the valley: the coarse profile over the whole search range, and
    # around each of its valleys a fine one (its width from that valley's curvature) that resolves it.
    # Another valley (a strip at the face's level, seen as one at the background's a strip's width away)
    # may be as deep as the optimum's but narrower than the coarse step: its best point is refined too.
    dof_b = max(prob.y.size - basis.shape[1] - 4, 1)
    # The residual variance per binned row: the noise, and what the model misses. Within one valley that
    # is the scale of the misfit (T_loc). Between valleys, and along a flat one, the misfit's excess is the
    # model's error, the same on every bin (the same shape at about the same phase): it does not average
    # down over the bins as the noise does, so there the bins weigh as one (T_glob). A model that misses
    # its profiles by more than their noise then cannot choose between two places for the border by
    # less than its own error.
    t_b = float(ev0.chi2[0]) / dof_b
    T_loc = max(t_b, noise**2)
    T_glob = noise**2 + prob.count.size * max(t_b - noise**2, 0.0)
    c = ev.chi2
    local = [
        i
        for i in range(c.size)
        if abs(grid[i] - d0) > 1.0 and (i == 0 or c[i] <= c[i - 1]) and (i == c.size - 1 or c[i] <= c[i + 1])
    ]
    modes = [(d0, s0, ev0)] + [
        prob.refine(float(grid[i]), float(sg[i]), basis, n_iter=8)
        for i in sorted(local, key=lambda i: c[i])[:2]
    ]
    keep = np.ones(grid.size, bool)
    fines: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
    for k, (dm, sm, em) in enumerate(modes):
        if k and min(abs(dm - d1) for d1, _, _ in modes[:k]) < 0.2:
            continue  # refined into a valley already resolved
        assert em.hess is not None
        try:
            s_m = math.sqrt(max(float(np.linalg.inv(em.hess[0] / 2.0)[0, 0]) * T_loc, 0.0))
        except np.linalg.LinAlgError:
            s_m = step
        s_m = float(np.clip(s_m, 1e-3, step))
        fine = dm + s_m * np.linspace(-6.0, 6.0, 25)
        _, evf = prob.profile_blur(fine, np.full(fine.size, sm), basis, n_iter=2)
        keep &= np.abs(grid - dm) > 6.0 * s_m
        fines.append((fine, evf.chi2, evf.deficit))
    if basis is basis0:  # the coarse profile is this model's already
        evc = ev
    else:
        _, evc = prob.profile_blur(grid, sg, basis, n_iter=2)
    chi_min = min(float(evc.chi2[keep].min()) if keep.any() else np.inf, *(float(f[1].min()) for f in fines))
    # log-likelihood: the coarse points against the best at T_glob; each valley's fine points against
    # the valley's own best at T_loc, and that best against the overall best at T_glob
    ll = [-(evc.chi2[keep] - chi_min) / (2.0 * T_glob)] + [
        -(f[1] - f[1].min()) / (2.0 * T_loc) - (float(f[1].min()) - chi_min) / (2.0 * T_glob) for f in fines
    ]
    deltas = np.concatenate([grid[keep], *(f[0] for f in fines)])
    order = np.argsort(deltas)
    deltas = deltas[order]
    dfc = np.concatenate([evc.deficit[keep], *(f[2] for f in fines)])[order]
    logp = np.concatenate(ll)[order] - 0.5 * ((dfc - prior[0]) / prior[1]) ** 2
    deficit, post_sd = _posterior_moments(deltas, dfc, logp)
    if lit is not None:
        # The lit arc's shading, a prior on the free shading's deficit: the free levels trade off with the
        # border's place along a valley that the light's shading cuts short where the two agree. Its width
        # is never narrower than the two disagree by (a prior the data contradict must not narrow them).
        lit_sd = max(lit[1], abs(deficit - lit[0]))
        held, held_sd = _posterior_moments(deltas, dfc, logp - 0.5 * ((dfc - lit[0]) / lit_sd) ** 2)
        # A prior that narrows one valley leaves the mean between the data's and its own; one that takes it
        # beyond both has chosen between the valleys of a skewed posterior, which it cannot tell apart any
        # better than the profiles (a 1.2 mm rounding in shadow at its silhouette: its first pass's bottom
        # end read 1.005 for a free 0.89 and an arc's 0.97, and the final pass went to a valley with
        # another blur, z in doubt by 0.18 mm): there the free shading's posterior stands.
        if min(deficit, lit[0]) <= held <= max(deficit, lit[0]) and held_sd <= post_sd:
            deficit, post_sd = held, held_sd
    if alt is not None:
        # The other shading model (Lambert arc or free shading) is one more place for the answer, weighed
        # as another valley is: a rounding whose two models disagree is in doubt by their difference.
        # Each linear parameter more that a model has costs it a factor e (Akaike's weight): without it
        # the free shading's better misfit, which its extra parameters buy anywhere, outweighed an arc
        # as good as it by 1500 to 1 and took the answer to its own valley with the sigma of the arc's
        # (arris bench seed 1557, a 2.9 mm rounding's bottom end: z 0.15 mm off at 2.1 sigma, where the arc
        # had the border right; with the factor 0.09 mm at about 1 sigma).
        log_w = (alt[0] - float(ev0.chi2[0])) / (2.0 * T_glob) + alt[2]
        w_alt = math.exp(-min(max(log_w, -30.0), 30.0))
        mean = (deficit + w_alt * alt[1]) / (1.0 + w_alt)
        post_sd = math.sqrt(post_sd**2 + w_alt / (1.0 + w_alt) ** 2 * (alt[1] - deficit) ** 2)
        deficit = mean

    # The fitted shape (the caller's area-estimate correction and line-by-line fit start from it) is the
    # valley's that the posterior favours, not the lowest misfit's: two places for the border can misfit
    # alike (a strip at the face's level, and one at the background's a strip's width outwards whose
    # background then lies beyond the window, so that any level fits it), and there the prior decides,
    # as it does for the deficit. Taking the lowest misfit there put every line's edge a strip's width
    # out of its window (arris bench seed 7075, a 2.7 mm chamfer as bright as the face: bottom end lost).
    def _log_post(em: _Eval) -> float:
        dev = (float(em.deficit[0]) - prior[0]) / prior[1]
        return -(float(em.chi2[0]) - chi_min) / (2.0 * T_glob) - 0.5 * dev * dev

    d0, s0, ev0 = max(modes, key=lambda m: _log_post(m[2]))

    # The model's own doubt: a strip narrower than the blur looks like a wider blur with another strip
    # level, and the real optics are no exact Gaussian. How far the deficit moves when the blur is off by
    # BLUR_DOUBT (the offset refitted):
    sgm = np.maximum(s0 + np.array([-BLUR_DOUBT, BLUR_DOUBT]), 0.05)
    e1 = prob.offset_at_blur(np.full(2, d0), sgm, basis, n_iter=3)
    moved = float(np.max(np.abs(e1.deficit - ev0.deficit[0])))
    sigma = min(math.hypot(post_sd, moved), prior[1])

    # the fitted profiles themselves (every line, not binned), for the caller's window correction
    bounds = (outer[None, :, None] + d0) + width[None, :, None] * prob.frac
    prim, _, _ = _pixel_terms(prob.edges, bounds, np.array([s0]))
    M, const = _mix(basis, n_cells)
    model = (prim @ M + const)[0] @ ev0.coef[0]  # (N, P)
    resid = model - r
    dof = max(r.size - basis.shape[1] - 4, 1)
    misfit = math.sqrt(float(np.sum(resid**2)) / dof) / max(noise, 1e-6)
    c0, cb, band = ev0.coef[0, 0], ev0.coef[0, 1], ev0.coef[0, 2:]
    levels = (basis @ band - c0) / (cb - c0)

    def deficit_at_blur(blur_px: float) -> float:
        """The best fit's deficit with the blur held at ``blur_px``: the offset's coarse profile over the
        search range, then Newton steps on the offset alone."""
        b = max(float(blur_px), 0.1)
        d = grid[int(np.argmin(prob.evaluate(grid, np.full(grid.size, b), basis).chi2))]
        return float(prob.offset_at_blur(np.array([d]), np.array([b]), basis, n_iter=6).deficit[0])

    return StripFit(
        deficit,
        sigma,
        d0,
        s0,
        misfit,
        levels,
        model,
        outer + d0,
        float(np.mean(1.0 - levels)),
        deficit_at_blur,
    )


def _line_borders(
    vals: np.ndarray,
    x: np.ndarray,
    border0: np.ndarray,
    width: np.ndarray,
    levels: np.ndarray,
    blur_px: float,
    n_iter: int = 6,
) -> np.ndarray:
    """Each scan line's outer border from the fitted strip shape: its place, its two levels free.

    ``vals`` (N, P) are the lines' profiles in linear light (background first), ``x`` (P,) their pixel
    centres, ``border0`` (N,) a start, ``width`` (N,) the strip's width, px; ``levels`` (C,) the strip
    cells' relative levels and ``blur_px`` the blur of :func:`fit_strip_profile`. Per line: the profile
    ``A + D s(x - b)``, with ``s`` the fitted shape (background 0 | strip cells | face 1, blurred and
    pixel-integrated), fitted in ``b`` (Gauss-Newton) with ``A`` and ``D`` solved linearly at each step.

    Why not the area estimate: it weighs every pixel of the window alike, so the texture of the hinge
    face inside the window (wood grain running along the edge and wandering across it) moves each line's
    edge by its integral: on the effects fixtures 0.2-0.7 px along the reference arris, which tilted the
    line (yaw up to 0.05 deg off) and bent it near the corner (refused ``corner_hidden``). The model
    weighs pixels by how much the border's place changes them: the strip's outer border (background to
    strip, where no face texture lies) pins it; the face's texture only enters through ``D``.
    Returns NaN for a line whose fit fails (no contrast, or a step beyond half a pixel on its last
    iteration). Compiled (:func:`_line_borders_compiled`): as array code, ~25 (N, P) array operations
    and the (N, P, J) pixel terms an iteration.
    """
    n_cells = levels.size
    frac = np.arange(n_cells + 1) / n_cells
    jumps = np.diff(np.concatenate([[0.0], levels, [1.0]]))  # (C + 1,) each boundary's step
    edges = np.concatenate([x[:1] - 0.5, x + 0.5])
    return _line_borders_compiled(
        np.ascontiguousarray(vals, np.float64),
        np.ascontiguousarray(edges, np.float64),
        np.array(border0, np.float64),
        np.ascontiguousarray(width, np.float64),
        frac,
        np.ascontiguousarray(jumps, np.float64),
        max(float(blur_px), 0.05),
        STEP_TAIL_SIGMAS,
        n_iter,
    )


def _line_borders_warm_up(k) -> None:
    vals = np.tile(np.linspace(10.0, 100.0, 12), (3, 1))
    edges = np.arange(13.0) - 0.5
    k(
        vals,
        edges,
        np.full(3, 5.0),
        np.full(3, 2.0),
        np.linspace(0, 1, 4),
        np.full(4, 0.25),
        0.8,
        STEP_TAIL_SIGMAS,
        6,
    )


@kernel(_line_borders_warm_up)
def _line_borders_compiled(vals, edges, b, w_in, frac, jumps, sigma, tail_sigmas, n_iter):
    """:func:`_line_borders`' iterations (``b`` (N,) updated in place): per line the shape and its slope
    from its boundaries' pixel terms (:func:`_pixel_terms_fill`), never as (N, P, J) arrays; each line's sums in numpy's pairwise order (:func:`jit.pairwise_sum`), the
    shape's sum over boundaries in their order (the array code's matrix product summed in BLAS's)."""
    n, n_p = vals.shape
    n_j = jumps.size
    ok = np.empty(n, np.bool_)
    w = np.empty(n)
    for i in range(n):
        ok[i] = math.isfinite(b[i]) and math.isfinite(w_in[i])
        if not ok[i]:
            b[i] = 0.0
        w[i] = w_in[i] if ok[i] else 0.0
    step = np.zeros(n)
    D = np.full(n, np.nan)
    bounds = np.empty((1, 1, n_j))
    sig = np.full(1, sigma)
    prim = np.empty((1, 1, n_p, n_j))
    d_b = np.empty((1, 1, n_p, n_j))
    d_s = np.empty((1, 1, n_p, n_j))
    shape = np.empty(n_p)
    dshape = np.empty(n_p)
    t = np.empty((4, n_p))
    for _ in range(n_iter):
        big = 0.0
        for i in range(n):
            for j in range(n_j):
                bounds[0, 0, j] = b[i] + w[i] * frac[j]
            _pixel_terms_fill(edges, bounds, sig, tail_sigmas, prim, d_b, d_s)
            shape[:] = 0.0
            dshape[:] = 0.0
            for j in range(n_j):
                for p in range(n_p):
                    shape[p] += prim[0, 0, p, j] * jumps[j]
                    dshape[p] += d_b[0, 0, p, j] * jumps[j]
            # A and D by least squares on the line: [1, shape]
            s_mean = pairwise_sum(shape, 0, n_p) / n_p
            v_mean = pairwise_sum(vals[i], 0, n_p) / n_p
            for p in range(n_p):
                sc = shape[p] - s_mean
                t[0, p] = sc * sc
                t[1, p] = sc * (vals[i, p] - v_mean)
            ss = pairwise_sum(t[0], 0, n_p)
            D[i] = pairwise_sum(t[1], 0, n_p) / max(ss, 1e-12) if ss > 1e-12 else np.nan
            A = v_mean - D[i] * s_mean
            # the border's Gauss-Newton step, the levels projected out (variable projection)
            for p in range(n_p):
                t[2, p] = D[i] * dshape[p]
            j_mean = pairwise_sum(t[2], 0, n_p) / n_p
            for p in range(n_p):
                t[2, p] = t[2, p] - j_mean  # Jc
                t[3, p] = t[2, p] * (shape[p] - s_mean)
            k = pairwise_sum(t[3], 0, n_p) / max(ss, 1e-12)
            for p in range(n_p):
                jp = t[2, p] - k * (shape[p] - s_mean)
                t[0, p] = jp * jp
                t[1, p] = jp * ((A + D[i] * shape[p]) - vals[i, p])
            jj = pairwise_sum(t[0], 0, n_p)
            s = -pairwise_sum(t[1], 0, n_p) / max(jj, 1e-18) if jj > 1e-18 else np.nan
            s = -0.5 if s < -0.5 else (0.5 if s > 0.5 else s)
            step[i] = s
            if math.isfinite(s):
                b[i] = b[i] + s
                big = max(big, abs(s))
        if big < 1e-4:
            break
    for i in range(n):
        good = (
            ok[i] and math.isfinite(step[i]) and abs(step[i]) < 0.5 and math.isfinite(D[i]) and abs(D[i]) > 0
        )
        if not good:
            b[i] = np.nan
    return b


def arris_edges(
    plane: np.ndarray,
    axis: Axis,
    scan: np.ndarray,
    centre: np.ndarray,
    half: int,
    band_px: np.ndarray,
    door_side: int,
    geom: ArrisGeometry,
    plateau: int = 4,
    scale_to_8bit: float = 1.0,
    lut: np.ndarray | None = None,
    blur0: float = 1.0,
    search: bool = False,
    level_px: int | None = None,
    line_fit: bool = True,
) -> tuple[EdgeSamples, StripFit | None]:
    """Outer border of an arris strip on each scan line (module docstring, step 3).

    Parameters
    ----------
    plane : ndarray
        Grey image plane.
    axis, scan : as :func:`doorloc.vision.edges.subpixel_edges`.
    centre : ndarray (N,)
        Predicted outer border on each scan line, px.
    half : int
        Window half-size beyond the strip, px.
    band_px : ndarray (N,)
        Strip width on each scan line, px.
    door_side : +1 or -1
        +1 when the door (strip, then face) lies at increasing ``along``.
    geom : ArrisGeometry
        The arris's geometry.
    plateau : int
        Samples on each side for the plateau levels.
    scale_to_8bit : float
        Grey-level scale to 0-255.
    lut : ndarray or None
        Linearising look-up table (camera response).
    blur0 : float
        Starting blur for the shading fit, px.
    search : bool
        The prediction may be off by up to the strip's width (a first pass on a coarse pose, whose edge
        may be the strip's inner border): widen the window by that much on both sides.
    level_px : int or None
        Samples of each plateau, nearest the window, whose mean is each scan line's two levels in its
        area estimate (None: all ``plateau``). The profile fit uses all ``plateau`` samples (the face
        beside the strip pins its brightness); each line's levels taken farther from the window pick up
        the texture along the edge (wood grain).
    line_fit : bool
        Each line's border from the fitted strip shape (:func:`_line_borders`) where that fit holds, the
        area estimate elsewhere; False: the area estimate on every line.

    Returns
    -------
    samples : EdgeSamples
        The outer border per scan line (``along``), step ``B - A`` signed along ``along``.
    fit : StripFit or None
        The strip's shading; None when it could not be fitted (then no sample is valid).
    """
    P = oriented(plane, axis)
    scan = np.asarray(scan, int)
    centre = np.asarray(centre, float)
    w = np.maximum(np.asarray(band_px, float), 0.0)
    finite = np.isfinite(centre) & np.isfinite(w)
    n_extra = int(math.ceil(np.nanmax(w))) if np.any(finite) else 0
    pad = n_extra if search else 0
    c0 = np.round(np.where(finite, centre, 0.0)).astype(int)
    length = 2 * (half + plateau + pad) + 1 + n_extra
    if door_side > 0:
        vals, inside = gather_profiles(P, scan, c0 - half - plateau - pad, length, lut=lut)
    else:  # mirror so that the door side is at increasing index
        vals, inside = gather_profiles(P, scan, c0 + half + plateau + pad - length + 1, length, lut=lut)
        vals, inside = vals[:, ::-1], inside[:, ::-1]
    vals = vals.astype(np.float64)
    left, right = vals[:, :plateau], vals[:, -plateau:]
    A, B = left.mean(axis=1), right.mean(axis=1)
    D = B - A
    nl = plateau if level_px is None else int(np.clip(level_px, 1, plateau))
    # the area estimate's levels: the nl samples of each plateau next to the window
    A_e, B_e = (
        vals[:, plateau - nl : plateau].mean(axis=1),
        vals[:, length - plateau : length - plateau + nl].mean(axis=1),
    )
    D_e = B_e - A_e
    core = vals[:, plateau : length - plateau]
    S = (core - A_e[:, None]).sum(axis=1)
    rel_e = (centre - c0) * door_side  # predicted border relative to c0, mirrored coordinates
    good = finite & inside.all(axis=1) & (np.abs(D) > 0)
    noise = np.sqrt(0.5 * (left.var(axis=1) + right.var(axis=1)))
    idx = np.nonzero(good)[0]
    fit = None
    if idx.size >= 5:
        pick = idx[np.linspace(0, idx.size - 1, min(idx.size, _FIT_LINES)).round().astype(int)]
        r = (vals[pick] - A[pick, None]) / D[pick, None]
        x = np.arange(length, dtype=float)
        outer = plateau + pad + half + rel_e[pick]
        # profile noise, normalised; at least the quantisation of the 8-bit scale (a noise-free render)
        nz = float(np.median(np.maximum(noise[pick], 0.3 / scale_to_8bit) / np.abs(D[pick])))
        # the rounding that the noise does not dither (DITHERING_NOISE_LEVELS), normalised (one
        # grey level taken as one unit of the linearised scale: a first-order figure under a camera response)
        dn = float(np.median(noise[pick])) * scale_to_8bit
        undithered = min(max(1.0 - dn / DITHERING_NOISE_LEVELS, 0.0), 1.0)
        shared = undithered * float(np.median((1.0 / 12.0) / (D[pick] * scale_to_8bit) ** 2))
        prior = deficit_prior(float(np.median(B[pick])), float(np.median(A[pick])))
        fit = fit_strip_profile(
            r, x, outer, w[pick], geom, nz, blur0, search_px=float(pad), prior=prior, shared=shared
        )
    bias = 0.0
    if fit is not None:
        # The area estimator on the fitted, noise-free profiles: what the window's ends and the plateaus'
        # blur tails cost it (the strip's two steps differ, so they do not cancel as on a plain step).
        mod = fit.model
        a_m = mod[:, plateau - nl : plateau].mean(axis=1)
        b_m = mod[:, length - plateau : length - plateau + nl].mean(axis=1)
        s_m = (mod[:, plateau : length - plateau] - a_m[:, None]).sum(axis=1)
        e_m = (length - 2 * plateau - 0.5) - s_m / (b_m - a_m) - w[pick] * fit.model_deficit
        bias = float(np.median(e_m - (fit.border - plateau)))
    if fit is None:
        nan = np.full(len(scan), np.nan)
        return EdgeSamples(axis, scan, nan, nan, nan, nan, nan, np.zeros(len(scan), bool)), None
    with np.errstate(divide="ignore", invalid="ignore"):
        K = (
            core.shape[1] - 0.5
        )  # door-side end of the window (core index units; core starts at c0 - half - pad)
        e_area = K - S / D_e - w * fit.deficit - bias - (half + pad)  # relative to c0
    # Each line's border from the fitted strip shape (:func:`_line_borders`), started at the area estimate
    # (vals index units: the window's first pixel is index 0, c0 at plateau + pad + half). The shape is
    # the best fit's, whose deficit may differ from the posterior's in use (a flat valley): the fit
    # starts from the area estimate with the best fit's deficit, and its border moves back by the
    # difference.
    x0 = plateau + pad + half
    if not line_fit:
        e_model = e_area
    else:
        e_model = (
            _line_borders(
                np.where(good[:, None], vals, 0.0),
                np.arange(length, dtype=float),
                e_area + x0 + w * (fit.deficit - fit.model_deficit),
                w,
                fit.levels,
                fit.blur_px,
            )
            + w * (fit.model_deficit - fit.deficit)
            - x0
        )
    with np.errstate(invalid="ignore"):
        # the model's border where its fit held and stayed near the area estimate's; that elsewhere (a
        # line whose profile the strip's mean shape does not describe)
        e_mirror = np.where(np.abs(e_model - e_area) <= 1.0 + 0.25 * w, e_model, e_area)
        # a line whose area estimate lies in its window has an edge point (the window was placed for it)
        in_window = np.abs(door_side * e_area + c0 - centre) <= half + pad
    if line_fit:
        # A strip much darker or brighter than both sides (a chamfer in shadow: face 150, strip 85,
        # background 133) leaves the area estimate ill-conditioned (its deficit is divided by a contrast the
        # strip dwarfs): on such a bottom end 40 % of the lines' estimates fell out of their 3-px windows
        # and the door was refused edge_not_straight with every other point within 0.1 px of its line
        # (bench_surfaces --sets combined --seed 500, image 36). Those lines' borders are fitted from the
        # predicted border instead (the window's centre), and kept where the fit lands in the window.
        lost = good & ~in_window & np.isfinite(w)
        if np.any(lost):
            shift = w[lost] * (fit.deficit - fit.model_deficit)
            e_lost = (
                _line_borders(
                    vals[lost],
                    np.arange(length, dtype=float),
                    rel_e[lost] + x0 + shift,
                    w[lost],
                    fit.levels,
                    fit.blur_px,
                )
                - shift
                - x0
            )
            with np.errstate(invalid="ignore"):
                held = np.isfinite(e_lost) & (
                    np.abs(door_side * e_lost + c0[lost] - centre[lost]) <= half + pad
                )
            e_mirror[np.flatnonzero(lost)[held]] = e_lost[held]
            in_window[np.flatnonzero(lost)[held]] = True
    along = c0 + door_side * e_mirror
    valid = good & np.isfinite(along) & in_window
    nan = np.full(len(scan), np.nan)
    return (
        EdgeSamples(
            axis,
            scan,
            np.where(valid, along, np.nan),
            D * door_side * scale_to_8bit,
            noise * scale_to_8bit,
            nan,
            np.maximum(A, B) * scale_to_8bit,
            valid,
        ),
        fit,
    )

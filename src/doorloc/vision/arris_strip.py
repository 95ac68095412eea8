"""The arris strip's fitting problem: the pixel integrals of a blurred background | strip | hinge-face profile,
the strip's shading basis, and the normal equations of its levels solved inside every evaluation (variable
projection), compiled.

:func:`doorloc.vision.arris_model.fit_strip_profile` drives it: it builds a :class:`StripProblem` from the
binned profiles and evaluates candidate outer-border offsets and blurs; :func:`pixel_terms` is also what the
per-line border fit (:mod:`doorloc.vision.arris_lines`) integrates. Units: pixels across the edge, levels
relative to the two plateaus (0 background, 1 hinge face), linear light.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.arris_geometry import ArrisGeometry
from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
from doorloc.vision.jit import kernel, pairwise_sum, read_only
from doorloc.vision.sampling import normal_cdf_pdf

__all__ = [
    "StripProblem",
    "StripEvaluation",
    "strip_basis",
    "pixel_terms",
    "mix_cells",
    "posterior_moments",
    "PRIOR_LEVEL",
    "PRIOR_LEVEL_SIGMA",
]

#: prior of each strip cell's relative level ``(strip - background) / (face - background)``: about the
#: middle, within a wide range (a strip in shadow is a little darker than the background, a lit one
#: brighter than the face). Weak beside what the profiles say of a strip a pixel wide or more; on a strip
#: much narrower than a pixel it is what keeps the levels finite (module docstring of StripProblem)
PRIOR_LEVEL, PRIOR_LEVEL_SIGMA = 0.5, 1.0


def pixel_terms(
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
    """:func:`pixel_terms`, compiled. The Gaussian terms (most of the cost: the strip fit evaluates them
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
    pixel_terms_fill(edges, bounds, sigma, tail_sigmas, prim, d_b, d_s)
    return prim, d_b, d_s


@kernel(inline=True)
def pixel_terms_fill(edges, bounds, sigma, tail_sigmas, prim, d_b, d_s):
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


def _cell_thetas(geom: ArrisGeometry, n_cells: int, sub: int) -> np.ndarray:
    """The surface angle at ``sub`` evenly spaced points inside each of the strip's ``n_cells`` cells, (C, sub)."""
    tau = (np.arange(n_cells)[:, None] + (np.arange(sub)[None, :] + 0.5) / sub) / n_cells
    return geom.theta_at(tau)


def strip_basis(geom: ArrisGeometry, n_cells: int, terminator: float | None, lit_below: bool) -> np.ndarray:
    """A rounding's Lambert shading basis on the strip cells, shape (C, k): ``1, cos, sin`` of ``theta`` (a
    light whose terminator lies off the arc), or ``1, max(0, +-sin(theta - terminator))``."""
    # cell means over 8 sub-samples: near the silhouette theta changes fast across one cell
    th = _cell_thetas(geom, n_cells, 8)
    if terminator is None:
        return np.stack([np.ones(n_cells), np.cos(th).mean(axis=1), np.sin(th).mean(axis=1)], axis=1)
    s = np.sin(th - terminator) * (-1.0 if lit_below else 1.0)
    return np.stack([np.ones(n_cells), np.maximum(s, 0.0).mean(axis=1)], axis=1)


def lit_basis(geom: ArrisGeometry, n_cells: int, light_cell: np.ndarray) -> np.ndarray:
    """A rounding's shading under a known light, shape (C, 2): the Lambert irradiance ``max(0, n . l)`` of
    the arc's normal ``n`` (:attr:`ArrisGeometry.normals_cell`) towards the light ``light_cell`` (unit vector,
    cell frame), cell means over 16 sub-samples, and a constant. In the fit's units (0 on the background, 1
    on the face) a Lambertian strip is affine in its irradiance: its albedo times the irradiance, less the
    background's share; the constant also takes an ambient light."""
    assert geom.normals_cell is not None
    n1, n2 = geom.normals_cell
    th = _cell_thetas(geom, n_cells, 16)
    irr = np.maximum(0.0, np.cos(th) * float(n1 @ light_cell) + np.sin(th) * float(n2 @ light_cell))
    m = irr.mean(axis=1)
    return np.stack([m, np.ones(n_cells)], axis=1)


def mix_cells(basis: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
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
class StripEvaluation:
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
        M, const = mix_cells(basis, 2)
        prim = np.random.default_rng(0).uniform(size=(2, 3, 5, 3))
        P = np.concatenate([np.full((2, 1), -0.5), np.full((2, 1), -0.5), basis], axis=1)
        for jac in (False, True):
            k(prim, prim, prim, M, const, np.ones(15), np.ones(15), P, basis, jac)


@kernel(_strip_solve_warm_up, reassociate=True)
def _strip_solve(prim, d_b, d_s, M, const, y, w, P, basis, jac):
    """:meth:`StripProblem.solve`, compiled: for each candidate ``b`` the design ``A = prim[b] M + const``
    (``n = R * P`` rows), the normal equations ``A'WA + P'P + 1e-12 I`` with the levels' prior rows ``P``,
    the coefficients, ``chi2``, the deficit, and with ``jac`` the variable projection's gradient and
    Gauss-Newton Hessian by (offset, blur). The array code's formulas; its matrix products summed in
    vector lanes (``reassociate``) instead of BLAS's blocks: the same numbers to rounding, and the
    coefficients, of ill-conditioned normal equations, to ~1e-9 relative. (As array code, ~20 array
    operations per call on a few hundred rows: 0.3 ms a call, a third of an arris frame.)
    """
    # why many parameters: a numba nopython kernel: the pixel terms, the basis's mix, the data, weights and the levels' prior rows pass as arrays (no dataclass in nopython code)
    # why long: per candidate the design (At, Aw), its normal equations' LU factors and the residual are built once and shared by the solve, chi2, the deficit and the variable projection's gradient and Hessian; split into kernels they would be passed and re-read per candidate in the hot loop
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
        M, const = mix_cells(basis, 2)
        P = np.concatenate([np.full((2, 1), -0.5), np.full((2, 1), -0.5), basis], axis=1)
        v = np.array([4.0, 5.0, 6.0])
        for jac, cand in ((False, v), (True, v), (False, read_only(v)), (True, read_only(v))):
            k(
                edges,
                v,
                v,
                np.linspace(0, 1, 3),
                cand,  # (the candidates' offsets and blurs: read-only where a search's grid is cached)
                cand,
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
    """:meth:`StripProblem.evaluate`: for each candidate ``b`` (offset ``delta[b]``, blur ``sigma[b]``)
    the strip's pixel terms (:func:`pixel_terms_fill`, its boundaries ``outer + delta[b] + width frac``)
    and their solve (:func:`_strip_solve`), one candidate at a time: the same numbers as the two kernels
    over all candidates, without their (B, R, P, J) arrays (three of them written and read again per
    call, a few hundred kB: most of an arris frame's time in the strip fit went to them)."""
    # why many parameters: a numba nopython kernel fusing pixel_terms_fill and _strip_solve per candidate: it takes both kernels' arrays and scalars (no dataclass in nopython code); StripProblem.evaluate is its one caller
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
        pixel_terms_fill(edges, bounds, sig, tail_sigmas, prim, d_b, d_s)
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


class StripProblem:
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

    def evaluate(
        self, delta: np.ndarray, sigma: np.ndarray, basis: np.ndarray, jac: bool = False
    ) -> StripEvaluation:
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
        return StripEvaluation(chi2, coef, deficit, grad if jac else None, hess if jac else None)

    def _basis_terms_of(self, basis: np.ndarray) -> tuple[np.ndarray, ...]:
        """A shading basis's mix (:func:`mix_cells`), its levels' prior rows and the basis itself, contiguous:
        a fit solves for a few bases ~20 times each, so they are kept by value."""
        key = (basis.shape, basis.tobytes())
        got = self._basis_terms.get(key)
        if got is None:
            M, const = mix_cells(basis, self.n_cells)
            # the levels' prior (class docstring): rows P, target 0, the same for every candidate
            C = basis.shape[0]
            P = np.concatenate(
                [np.full((C, 1), PRIOR_LEVEL - 1.0), np.full((C, 1), -PRIOR_LEVEL), basis], axis=1
            ) * math.sqrt(self.prior_weight)
            got = self._basis_terms[key] = (M, const, P, np.ascontiguousarray(basis, np.float64))
        return got

    def pixel_terms(self, delta: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`pixel_terms` of the strip's boundaries at a batch of (offset, blur) candidates: what
        :meth:`solve` needs for any shading basis."""
        delta = np.atleast_1d(np.asarray(delta, float))
        sigma = np.maximum(np.atleast_1d(np.asarray(sigma, float)), 0.05)
        bounds = (self.outer[None, :, None] + delta[:, None, None]) + self.width[None, :, None] * self.frac
        return pixel_terms(self.edges, bounds, sigma)

    def solve(
        self, terms: tuple[np.ndarray, np.ndarray, np.ndarray], basis: np.ndarray, jac: bool = False
    ) -> StripEvaluation:
        """The levels solved linearly for one shading basis, given :meth:`pixel_terms` (compiled:
        :func:`_strip_solve`)."""
        prim, d_b, d_s = terms
        M, const, P, basis_c = self._basis_terms_of(basis)
        chi2, coef, deficit, grad, hess = _strip_solve(
            prim, d_b, d_s, M, const, self.y_flat, self.w, P, basis_c, jac
        )
        return StripEvaluation(chi2, coef, deficit, grad if jac else None, hess if jac else None)

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
        Mc, const = mix_cells(np.eye(C), C)
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

    def refine_best_placed(
        self, places: np.ndarray, sigma: float, bases: list[np.ndarray], n_iter: int = 6
    ) -> list[tuple[float, float, StripEvaluation]]:
        """Each basis fitted at its own best place for the outer border: its misfit at every offset of
        ``places`` (px, at the blur ``sigma`` px; :meth:`chi2_many`, all bases at once), then :meth:`refine`
        from the least of them and from ``places[0]`` (the caller's own start), the better kept.

        Why not a refine from every place: over the ~70 lights a door's light is sought among, the
        refines were nine tenths of the ~3 s a door cost; screening the places first leaves two."""
        places = np.asarray(places, float)
        costs = self.chi2_many(self.pixel_terms(places, np.full(places.size, sigma)), bases)
        out = []
        for basis, cost in zip(bases, costs, strict=True):
            starts = {float(places[0]), float(places[int(np.argmin(cost))])}
            fits = [self.refine(d, sigma, basis, n_iter=n_iter) for d in sorted(starts)]
            out.append(min(fits, key=lambda f: float(f[2].chi2[0])))
        return out

    def refine(
        self, delta: float, sigma: float, basis: np.ndarray, n_iter: int = 12
    ) -> tuple[float, float, StripEvaluation]:
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

    def offset_at_blur(
        self, delta: np.ndarray, sigma: np.ndarray, basis: np.ndarray, n_iter: int
    ) -> StripEvaluation:
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
    ) -> tuple[np.ndarray, StripEvaluation]:
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
            ev = StripEvaluation(
                np.where(better, ev1.chi2, ev.chi2),
                np.where(better[:, None], ev1.coef, ev.coef),
                np.where(better, ev1.deficit, ev.deficit),
                np.where(better[:, None], ev1.grad, ev.grad),  # type: ignore[arg-type]
                np.where(better[:, None, None], ev1.hess, ev.hess),  # type: ignore[arg-type]
            )
        return s, ev


def posterior_moments(deltas: np.ndarray, deficits: np.ndarray, logp: np.ndarray) -> tuple[float, float]:
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

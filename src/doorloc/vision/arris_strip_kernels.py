"""The arris strip fit's compiled loops (:class:`doorloc.vision.arris_strip.StripProblem` calls them).

A strip profile is modelled as ``background | strip cells | hinge face``: Gaussian-blurred unit levels beyond
each boundary integrated over the pixels (:func:`pixel_terms_fill`), mixed into the design's columns by a
shading basis (:func:`mix_cells`), the levels solved linearly inside every evaluation (variable projection:
:func:`strip_solve`), one (offset, blur) candidate at a time (:func:`strip_evaluate`), and the Gauss-Newton
loop on the offset and the blur around it (:func:`strip_refine`). The kernels take flat arguments (numba
compiles them; a dataclass would be a jitclass): the pixel borders ``edges``, the binned profiles' outer
borders ``outer`` and strip widths ``width``, the cell boundaries' fractions ``frac`` of the width, the
basis's mix ``M`` and constant ``const``, the binned levels ``y`` and row weights ``w`` (flattened), the
levels' prior rows ``P`` and the basis itself. Units: pixels across the edge, levels relative to the two
plateaus (0 background, 1 hinge face), linear light.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
from doorloc.vision.jit import fma, kernel, pairwise_sum, read_only
from doorloc.vision.sampling import normal_cdf_pdf

__all__ = [
    "bin_means",
    "mix_cells",
    "pixel_terms_compiled",
    "pixel_terms_fill",
    "solve2x2",
    "strip_evaluate",
    "strip_refine",
    "strip_solve",
]


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


def _pixel_terms_warm_up(k) -> None:
    k(np.arange(12.0) - 5.5, np.array([[[-0.3, 0.6]], [[0.1, 1.2]]]), np.array([0.4, 1.1]), STEP_TAIL_SIGMAS)


@kernel(_pixel_terms_warm_up)
def pixel_terms_compiled(edges, bounds, sigma, tail_sigmas):
    """:func:`doorloc.vision.arris_strip.pixel_terms`, compiled. The Gaussian terms (most of the cost: the strip fit evaluates them
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
    """:func:`pixel_terms_compiled`'s terms written into ``prim``, ``d_b``, ``d_s`` (B, R, P, J)."""
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
    for _, M, const, P, basis, _ in _warm_up_problems():
        prim = np.random.default_rng(0).uniform(size=(2, 3, 5, 3))
        for jac in (False, True):
            k(prim, prim, prim, M, const, np.ones(15), np.ones(15), P, basis, jac)


@kernel(_strip_solve_warm_up, reassociate=True)
def strip_solve(prim, d_b, d_s, M, const, y, w, P, basis, jac):
    """:meth:`~doorloc.vision.arris_strip.StripProblem.solve`, compiled: for each candidate ``b`` the design ``A = prim[b] M + const``
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


def _warm_up_problems():
    """Small strip problems for the warm-ups: per shading basis of 1 and 3 levels, the pixel borders, the
    basis's mix and constant, the levels' prior rows, the basis, and three values for the bins' borders,
    widths and the candidates."""
    edges = np.arange(13.0) - 0.5
    for m in (1, 3):
        basis = np.ones((2, m))
        M, const = mix_cells(basis, 2)
        P = np.concatenate([np.full((2, 1), -0.5), np.full((2, 1), -0.5), basis], axis=1)
        yield edges, M, const, P, basis, np.array([4.0, 5.0, 6.0])


def _strip_evaluate_warm_up(k) -> None:
    for edges, M, const, P, basis, v in _warm_up_problems():
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
def strip_evaluate(edges, outer, width, frac, delta, sigma, tail_sigmas, M, const, y, w, P, basis, jac):
    """:meth:`~doorloc.vision.arris_strip.StripProblem.evaluate`: for each candidate ``b`` (offset ``delta[b]``, blur ``sigma[b]``)
    the strip's pixel terms (:func:`pixel_terms_fill`, its boundaries ``outer + delta[b] + width frac``)
    and their solve (:func:`strip_solve`), one candidate at a time: the same numbers as the two kernels
    over all candidates, without their (B, R, P, J) arrays (three of them written and read again per
    call, a few hundred kB: most of an arris frame's time in the strip fit went to them)."""
    # why many parameters: a numba nopython kernel fusing pixel_terms_fill and strip_solve per candidate: it takes both kernels' arrays and scalars (no dataclass in nopython code); arris_strip.StripProblem.evaluate and strip_refine are its callers
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
        c2, cf, df, gr, hs = strip_solve(prim, d_b, d_s, M, const, y, w, P, basis, jac)
        chi2[b] = c2[0]
        coef[b] = cf[0]
        deficit[b] = df[0]
        grad[b] = gr[0]
        hess[b] = hs[0]
    return chi2, coef, deficit, grad, hess


@kernel(inline=True)
def solve2x2(a00, a01, a10, a11, g0, g1):
    """``np.linalg.solve([[a00, a01], [a10, a11]], [g0, g1])``: LAPACK's getrf (partial pivoting, the
    multiplier by the pivot's reciprocal) and getrs, the two right-hand-side updates fused as OpenBLAS's
    kernels fuse them: numpy's numbers to the bit with the OpenBLAS of numpy's wheels on the development
    machine (280,000 random systems of every scale; BLAS kernels differ between processors, this does not).
    Not :func:`_lu_solve`: the same elimination, its updates unfused, differs from numpy in the last bits, and
    the refine's accept-or-damp decisions then part from the Python loop's. ``singular``: an exact zero
    pivot, where numpy raises LinAlgError."""
    if abs(a10) > abs(a00):
        a00, a01, a10, a11 = a10, a11, a00, a01
        g0, g1 = g1, g0
    if a00 == 0.0:
        return 0.0, 0.0, True
    l10 = a10 * (1.0 / a00)
    u11 = a11 - l10 * a01
    if u11 == 0.0:
        return 0.0, 0.0, True
    x1 = fma(-l10, g0, g1) / u11
    return fma(-a01, x1, g0) / a00, x1, False


@kernel(inline=True)
def _clipped(v, bound):
    """``np.clip(v, -bound, bound)`` (a NaN stays NaN)."""
    if v < -bound:
        return -bound
    if v > bound:
        return bound
    return v


def _strip_refine_warm_up(k) -> None:
    for edges, M, const, P, basis, v in _warm_up_problems():
        k(
            edges,
            v,
            v,
            np.linspace(0, 1, 3),
            0.1,
            1.0,
            STEP_TAIL_SIGMAS,
            M,
            const,
            np.ones(36),
            np.ones(36),
            P,
            basis,
            6,
        )


@kernel(_strip_refine_warm_up)
def strip_refine(edges, outer, width, frac, delta, sigma, tail_sigmas, M, const, y, w, P, basis, n_iter):
    """:meth:`~doorloc.vision.arris_strip.StripProblem.refine`'s Gauss-Newton loop on (offset, blur), compiled around
    :func:`strip_evaluate`: its Levenberg damping, clipped steps, acceptance and stops as the Python loop
    had them, the same numbers (it cost a Python-level evaluation, solve and clip per step: ~12,000 steps
    of a rounded door's light search). Returns the offset and blur, the last accepted evaluation's
    arrays, and whether a damped Hessian was exactly singular (numpy raised there)."""
    # why many parameters: strip_evaluate's arrays and scalars (no dataclass in nopython code), the start and the iteration count
    d = np.empty(1)
    s = np.empty(1)
    p0, p1 = delta, sigma
    d[0] = p0
    s[0] = 0.05 if p1 < 0.05 else p1  # (evaluate's floor on the blur; the iterate itself keeps its value)
    chi2, coef, deficit, grad, hess = strip_evaluate(
        edges, outer, width, frac, d, s, tail_sigmas, M, const, y, w, P, basis, True
    )
    lam = 1e-3
    for _ in range(n_iter):
        h00, h01, h10, h11 = hess[0, 0, 0], hess[0, 0, 1], hess[0, 1, 0], hess[0, 1, 1]
        x0, x1, singular = solve2x2(
            h00 + lam * (h00 + 1e-12),
            h01 + lam * 0.0,
            h10 + lam * 0.0,
            h11 + lam * (h11 + 1e-12),
            grad[0, 0],
            grad[0, 1],
        )
        if singular:
            return p0, p1, chi2, coef, deficit, grad, hess, True
        st0, st1 = _clipped(-x0, 0.5), _clipped(-x1, 0.3)
        q0, q1 = p0 + st0, p1 + st1
        if q1 < 0.1:
            q1 = 0.1
        d[0] = q0
        s[0] = q1  # (at least 0.1, or NaN: above evaluate's floor)
        chi2_1, coef_1, deficit_1, grad_1, hess_1 = strip_evaluate(
            edges, outer, width, frac, d, s, tail_sigmas, M, const, y, w, P, basis, True
        )
        if chi2_1[0] <= chi2[0]:
            floor = 1e-300 if chi2[0] < 1e-300 else chi2[0]
            done = chi2[0] - chi2_1[0] < 1e-9 * floor or (abs(st0) < 1e-5 and abs(st1) < 1e-5)
            p0, p1, lam = q0, q1, lam * 0.3
            chi2, coef, deficit, grad, hess = chi2_1, coef_1, deficit_1, grad_1, hess_1
            if done:
                break
        else:
            lam *= 10.0
            if lam > 1e6:
                break
    return p0, p1, chi2, coef, deficit, grad, hess, False


def _bin_means_warm_up(k) -> None:
    k(np.ones((5, 4)), np.arange(5.0), np.ones(5), np.array([0, 2, 2, 0, 1]), np.array([0, 1, 2]))


@kernel(_bin_means_warm_up)
def bin_means(r, outer, width, k, used):
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

"""The far-face fit's compiled loops (:func:`doorloc.vision.far_face.subpixel_edges_far_face` calls them).

Each scan line across the far arris is modelled as ``hinge face A | far face L | background B`` (and,
with an arris strip, a strip before the far face): Gaussian-blurred unit steps integrated over the pixels,
formed per scan line on the pixel boundaries (:func:`_far_face_row`), never as (N, M) arrays. The kernels
take flat arguments (numba compiles them; a dataclass would be a jitclass, and the calls are per
iteration): the profiles' cores ``core`` (N, M), their levels ``A`` and contrasts ``D``, the pixel
boundaries ``bounds``, the arrises ``e``, the band's predicted widths ``w0`` at ``e0`` and its
``band_slope``, the blur ``sigma`` and the tail cut ``tail`` (in sigmas), the strip widths ``strip`` and
``has_strip``, the band's relative level ``lam`` and the strip's ``mu``.
"""

from __future__ import annotations

import math

import numpy as np

from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS
from doorloc.vision.jit import kernel
from doorloc.vision.sampling import normal_cdf_pdf

__all__ = ["far_face_gauss_newton", "far_face_schur", "far_face_start_costs", "far_face_sums"]

#: a level's pull weight the warm-ups compile with (any float: numba compiles one version per type)
_WARM_UP_LEVEL_WEIGHT = 0.02


@kernel(inline=True)
def _unit_step_boundaries(bounds, x, sigma, cut, G, P, p, slopes):
    """A unit step at ``x`` blurred by a Gaussian ``sigma``, on each pixel boundary (M + 1,): the
    integral of its CDF ``G`` and, with ``slopes``, the CDF ``P`` and the density ``p`` per unit
    ``y / sigma``, as :func:`_step_pixel_values` forms them; the Gaussian terms on the boundaries within
    ``cut`` of ``x`` only, the exact limits elsewhere (every boundary for an
    ``x`` not finite). A row's pixel values are the differences of neighbouring boundaries'
    (``C = G[j+1] - G[j]``, ...)."""
    n_b = bounds.size
    j0, j1 = 0, n_b
    if math.isfinite(x):
        while j0 < n_b and bounds[j0] < x - cut:
            j0 += 1
        j1 = j0
        while j1 < n_b and bounds[j1] <= x + cut:
            j1 += 1
    for j in range(j0):
        G[j] = 0.0
    for j in range(j1, n_b):
        G[j] = bounds[j] - x
    if slopes:
        for j in range(j0):
            P[j] = 0.0
            p[j] = 0.0
        for j in range(j1, n_b):
            P[j] = 1.0
            p[j] = 0.0
    inv = 1.0 / sigma
    for j in range(j0, j1):
        y = bounds[j] - x
        Pj, pj = normal_cdf_pdf(y * inv)
        G[j] = y * Pj + sigma * pj
        if slopes:
            P[j] = Pj
            p[j] = pj


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(inline=True)
def _far_face_row(bounds, e, w0, e0, band_slope, strip, has_strip, sigma, cut, S, slopes):
    """One scan line's far-face steps at the arris ``e``: the arris, the band's back edge (its width ``w0``
    predicted at ``e0``, changing by ``band_slope`` per px, clipped at 0) and, with ``has_strip``, a strip's
    inner border at ``e - strip``, each on the pixel boundaries (:func:`_unit_step_boundaries`) into the
    rows of ``S`` (9, M + 1): ``G, P, p`` of the arris, then the back edge's, then the strip's. Returns
    whether a band is in view."""
    # why many parameters: an inline numba kernel called per scan line from the compiled loops; the line's pixel boundaries, arris, band and strip arrive as separate arrays and scalars (nopython code takes no dataclass) and S, slopes are filled in place
    w_raw = w0 + band_slope * (e - e0)
    has_band = w_raw > 0
    _unit_step_boundaries(bounds, e, sigma, cut, S[0], S[1], S[2], slopes)
    if has_band:
        _unit_step_boundaries(bounds, e + w_raw, sigma, cut, S[3], S[4], S[5], slopes)
    else:  # the back edge at the arris (step_blur's plain steps: no band anywhere)
        S[3:6] = S[0:3]
    if has_strip:
        _unit_step_boundaries(bounds, e - strip, sigma, cut, S[6], S[7], S[8], slopes)
    return has_band


def _far_face_warm_up(k, *extra) -> None:
    core, v, bounds = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5
    for strip in (False, True):
        k(core, v, v, bounds, v, v, v, -0.1, 0.1, STEP_TAIL_SIGMAS, v, strip, *extra)


def _far_face_start_costs_warm_up(k) -> None:
    core, v, bounds, shifts = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5, np.array([-0.5, 0.5])
    for strip in (False, True):
        k(
            core,
            v,
            v,
            bounds,
            v,
            v,
            -0.1,
            0.1,
            STEP_TAIL_SIGMAS,
            v,
            strip,
            0.1,
            _WARM_UP_LEVEL_WEIGHT,
            shifts,
            2,
        )


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_start_costs_warm_up, reassociate=True)
def far_face_start_costs(
    core, A, D, bounds, e0, w0, band_slope, sigma, tail, strip, has_strip, mu0, level_weight, shifts, every
):
    """The far-face fit's cost at each common shift of the arrises ``e0 + shift``, the band level solved
    (the model is linear in it) with its pull towards 0.5 included, and that level; on every ``every``-th
    profile only (a ranking of the shifts) or all (``every`` 1). A strip, if any, at its prior level
    ``mu0``."""
    # why many parameters: a numba nopython kernel (no dataclass in nopython code): the profiles' cores, their levels, the band's and the strip's per-line arrays and the fit's scalars each pass on their own; the list is what far_face.subpixel_edges_far_face and the warm-up call
    n, n_m = core.shape
    rows = np.arange(0, n, every)
    J = np.empty((rows.size, n_m))
    r0 = np.empty((rows.size, n_m))
    S = np.empty((9, n_m + 1))
    cut = tail * sigma
    costs = np.empty(shifts.size)
    lams = np.empty(shifts.size)
    for s in range(shifts.size):
        info = 0.0
        jr = 0.0
        for k in range(rows.size):
            i = rows[k]
            _far_face_row(
                bounds, e0[i] + shifts[s], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, S, False
            )
            for j in range(n_m):
                C1 = S[0, j + 1] - S[0, j]
                C2 = S[3, j + 1] - S[3, j]
                Jl = D[i] * (C1 - C2)
                if has_strip:
                    C2 = C2 + mu0 * ((S[6, j + 1] - S[6, j]) - C1)
                r = core[i, j] - (A[i] + D[i] * C2)  # the model at band level 0
                J[k, j] = Jl
                r0[k, j] = r
                info += Jl * Jl
                jr += Jl * r
        pull = level_weight * info
        lam = (jr + pull * 0.5) / max(info + pull, 1e-12)
        cost = 0.0
        for k in range(rows.size):
            for j in range(n_m):
                r = r0[k, j] - J[k, j] * lam
                cost += r * r
        costs[s] = cost + pull * (lam - 0.5) ** 2
        lams[s] = lam
    return costs, lams


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(lambda k: _far_face_warm_up(k, 0.5, 0.1), reassociate=True)
def _far_face_misfit(core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu):
    """The far-face model's sum of squared residuals over the profiles' cores, and the sum of squares of
    its derivative by the band level (the level's pull is that times _WARM_UP_LEVEL_WEIGHT): the model
    ``A + lam D C1 + (1 - lam) D C2`` (+ ``mu D (C0 - C1)`` with a strip), ``C1``, ``C2``, ``C0`` the
    arrises', back edges' and strip borders' pixel values (:func:`_far_face_row`)."""
    # why many parameters: a numba nopython kernel (no dataclass in nopython code): the model's profiles, levels, arrises, band, blur and strip pass as separate arrays and scalars, as the tests call it
    rows = np.empty((core.shape[0], 9, core.shape[1] + 1))
    has_band = np.empty(core.shape[0], dtype=np.bool_)
    return _far_face_misfit_rows(
        core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, rows, has_band
    )


def _far_face_misfit_rows_warm_up(k) -> None:
    core, v, bounds = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5
    for strip in (False, True):
        k(core, v, v, bounds, v, v, v, -0.1, 0.1, STEP_TAIL_SIGMAS, v, strip, 0.5, 0.1,
          np.empty((3, 9, 5)), np.empty(3, np.bool_))  # fmt: skip


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_misfit_rows_warm_up, reassociate=True)
def _far_face_misfit_rows(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, rows, has_band
):
    """:func:`_far_face_misfit`, each scan line's steps and their slopes (:func:`_far_face_row`) left in
    ``rows`` (N, 9, M + 1) and whether its band is in view in ``has_band`` (N,): the Gauss-Newton step
    that follows an accepted trial reads them there (:func:`_far_face_sums_from_rows`) instead of forming
    them again (the Gaussian terms are most of the fit's time)."""
    # why many parameters: _far_face_misfit's, and the two arrays the steps are left in
    n, n_m = core.shape
    cut = tail * sigma
    acc = 0.0
    info = 0.0
    for i in range(n):
        S = rows[i]
        has_band[i] = _far_face_row(
            bounds, e[i], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, S, True
        )
        a1 = lam * D[i]
        a2 = (1.0 - lam) * D[i]
        for j in range(n_m):
            C1 = S[0, j + 1] - S[0, j]
            C2 = S[3, j + 1] - S[3, j]
            m = A[i] + a1 * C1 + a2 * C2
            if has_strip:
                m = m + mu * (D[i] * ((S[6, j + 1] - S[6, j]) - C1))
            r = core[i, j] - m
            acc += r * r
            Jl = D[i] * (C1 - C2)
            info += Jl * Jl
    return acc, info


def _far_face_sums_warm_up(k) -> None:
    for blur in (False, True):
        _far_face_warm_up(k, 0.5, 0.1, blur)


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_sums_warm_up, reassociate=True)
def far_face_sums(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, with_blur
):
    """The far-face Gauss-Newton step's sums at the arrises ``e`` (the model of :func:`_far_face_misfit`):
    per profile ``h_ee`` (the arris derivative's squares, at least 1e-12), ``h_eg`` (its products with the
    shared unknowns' derivatives: band level, blur, strip level), ``b_e`` (with the residuals) and ``rr``
    (the residuals' squares); ``H`` and ``b_g``, the shared unknowns' products among themselves and with
    the residuals. Columns of an unknown not fitted (the blur without ``with_blur``, the strip level
    without ``has_strip``) are 0.

    The steps' pixel values and slopes are formed per scan line (:func:`_far_face_row`), never as (N, M)
    arrays (allocating and filling nine of those per evaluation was most of the fit's time).
    """
    # why many parameters: a numba nopython kernel (no dataclass in nopython code): the Gauss-Newton step's inputs (profiles, levels, arrises, band, blur, strip, level pulls) and its output arrays pass one by one
    n, n_m = core.shape
    rows = np.empty((n, 9, n_m + 1))
    has_band = np.empty(n, dtype=np.bool_)
    cut = tail * sigma
    for i in range(n):
        has_band[i] = _far_face_row(
            bounds, e[i], w0[i], e0[i], band_slope, strip[i], has_strip, sigma, cut, rows[i], True
        )
    return _far_face_sums_from_rows(core, A, D, rows, has_band, band_slope, has_strip, lam, mu, with_blur)


def _far_face_sums_from_rows_warm_up(k) -> None:
    core, v = np.full((3, 4), 0.5), np.ones(3)
    for strip in (False, True):
        for blur in (False, True):
            k(core, v, v, np.zeros((3, 9, 5)), np.ones(3, np.bool_), -0.1, strip, 0.5, 0.1, blur)


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_sums_from_rows_warm_up, reassociate=True)
def _far_face_sums_from_rows(core, A, D, rows, has_band, band_slope, has_strip, lam, mu, with_blur):
    """:func:`far_face_sums` from each scan line's steps and slopes ``rows`` (N, 9, M + 1) and whether its
    band is in view ``has_band`` (N,), as :func:`_far_face_row` forms them."""
    # why many parameters: far_face_sums' model terms (no dataclass in nopython code), its steps formed
    n, n_m = core.shape
    n_sh = 3 if has_strip else 2
    h_ee = np.empty(n)
    h_eg = np.zeros((n, n_sh))
    b_e = np.empty(n)
    rr = np.empty(n)
    H = np.zeros((n_sh, n_sh))
    b_g = np.zeros(n_sh)
    Jg = np.zeros(3)
    for i in range(n):
        S = rows[i]
        has_band_i = has_band[i]
        a1m = lam * D[i]  # the model's
        a2 = (1.0 - lam) * D[i]
        a1 = (lam - mu) * D[i]  # the arris derivative's (a strip's level takes its share)
        fb = 1.0 + band_slope * has_band_i
        muD = mu * D[i]
        ee = 0.0
        er = 0.0
        sr = 0.0
        eg0 = eg1 = eg2 = 0.0
        for j in range(n_m):
            C1 = S[0, j + 1] - S[0, j]
            C2 = S[3, j + 1] - S[3, j]
            m = A[i] + a1m * C1 + a2 * C2
            Je = -a1 * (S[1, j + 1] - S[1, j]) - a2 * (S[4, j + 1] - S[4, j]) * fb
            Jg[0] = D[i] * (C1 - C2)
            if with_blur:
                Jg[1] = a1 * (S[2, j + 1] - S[2, j]) + a2 * (S[5, j + 1] - S[5, j])
            if has_strip:
                Jg[2] = D[i] * ((S[6, j + 1] - S[6, j]) - C1)
                m = m + mu * Jg[2]
                Je = Je - muD * (S[7, j + 1] - S[7, j])
                if with_blur:
                    Jg[1] = Jg[1] + muD * (S[8, j + 1] - S[8, j])
            r = core[i, j] - m
            ee += Je * Je
            er += Je * r
            sr += r * r
            eg0 += Je * Jg[0]
            eg1 += Je * Jg[1]
            eg2 += Je * Jg[2]
            for k in range(n_sh):
                b_g[k] += Jg[k] * r
                for q in range(k + 1):
                    H[k, q] += Jg[k] * Jg[q]
        h_ee[i] = max(ee, 1e-12)
        b_e[i] = er
        rr[i] = sr
        h_eg[i, 0] = eg0
        h_eg[i, 1] = eg1
        if has_strip:
            h_eg[i, 2] = eg2
    for k in range(n_sh):
        for q in range(k):
            H[q, k] = H[k, q]
    return h_ee, h_eg, b_e, H, b_g, rr


@kernel(inline=True)
def _clip(x, lo, hi):
    """``np.clip`` of a number (NaN stays NaN)."""
    return lo if x < lo else (hi if x > hi else x)


@kernel(inline=True)
def _py_max(a, b):
    """Python's ``max(a, b)`` of two numbers (``a`` unless ``b`` is larger: a NaN ``a`` stays)."""
    return b if b > a else a


@kernel(inline=True)
def _py_min(a, b):
    """Python's ``min(a, b)`` of two numbers (``a`` unless ``b`` is smaller)."""
    return b if b < a else a


def _far_face_schur_warm_up(k) -> None:
    for n_sh in (2, 3):
        k(np.eye(n_sh), np.ones(n_sh), np.ones(3), np.ones((3, n_sh)), np.ones(3), 0.5, 0.1, 0.02, 1.0, 0.2)


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_schur_warm_up)
def far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, level_weight, pull_mu, mu0):
    """The far-face normal equations of the shared unknowns (band level, blur and, with a third column, a
    strip's level) with the arrises eliminated (Schur complement), in place in ``H`` and ``b_g``, from
    :func:`far_face_sums`.

    With the level's pull towards mid-grey (``level_weight`` times its information) and, with a strip,
    the strip level's pull ``pull_mu`` towards its prior ``mu0``; a small ridge keeps a level that no
    scan line sees (a band nowhere in view) from leaving the system singular."""
    # why many parameters: a numba kernel solving the normal equations in place: its blocks (H, b_g, h_ee, h_eg, b_e) and the damping and pulls' scalars are separate arrays and numbers in nopython code
    n, n_sh = h_eg.shape
    level_info = H[0, 0]  # sum of J_lam ** 2
    for k in range(n_sh):
        for q in range(n_sh):
            acc = 0.0
            for i in range(n):
                acc += h_eg[i, k] / h_ee[i] * h_eg[i, q]
            H[k, q] -= acc
        acc = 0.0
        for i in range(n):
            acc += h_eg[i, k] * (b_e[i] / h_ee[i])
        b_g[k] -= acc
    for k in range(n_sh):
        H[k, k] += max(H[k, k], 1e-12) * 1e-6 + 1e-9
    # Where the band is much narrower than the blur, its level and the arrises trade off (the Schur
    # complement keeps little of the level's information): a weak pull towards mid-grey between the two
    # sides then settles the level, as little as the data allow.
    prior = level_weight * level_info
    H[0, 0] += prior
    b_g[0] += prior * (0.5 - lam)
    if n_sh == 3:  # the strip's level: its prior (a strip narrower than the blur trades it with e)
        H[2, 2] += pull_mu
        b_g[2] += pull_mu * (mu0 - mu)


def _far_face_gauss_newton_warm_up(k) -> None:
    core, v, bounds = np.full((3, 4), 0.5), np.ones(3), np.arange(5.0) - 0.5
    for strip in (False, True):
        for blur in (False, True):
            k(core, v, v, bounds, v.copy(), v, v, -0.1, 0.5, STEP_TAIL_SIGMAS, v, strip, 0.5, 0.1, blur, 2,
              _WARM_UP_LEVEL_WEIGHT, 1.0, 0.1, -1.0, 2.0)  # fmt: skip


# (flat arguments: a numba kernel, called per iteration; see the module docstring)
@kernel(_far_face_gauss_newton_warm_up)
def far_face_gauss_newton(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, fit_blur, n_iter,
    level_weight, pull_mu, mu0, levels_lo, levels_hi,
):  # fmt: skip
    """:func:`subpixel_edges_far_face`'s Gauss-Newton iterations from the arrises ``e`` (N,), band level
    ``lam``, blur ``sigma`` and strip level ``mu``: each step moves every arris and the shared unknowns
    together (one unknown per scan line plus the shared ones, solved through the Schur complement: the
    arrises and the level are strongly coupled where the band is narrow), and is taken whole or halved
    up to three times, only where it lowers the cost (the band's width is clipped at zero, a kink a full
    step can jump across into the false minimum where the band has vanished). Returns the final
    ``e, lam, sigma, mu`` and cost (misfit and pulls). Compiled: as Python, ~20 numpy calls a step."""
    # why many parameters: the whole far-face iteration runs in one compiled call (as Python it was ~20 numpy calls a step), so every array and setting of the fit passes on its own: nopython code takes no dataclass
    e = e.copy()
    n = e.size
    # each scan line's steps at the arrises ``e`` (left by the cost there) and at a trial's
    rows, rows_trial = np.empty((n, 9, core.shape[1] + 1)), np.empty((n, 9, core.shape[1] + 1))
    band, band_trial = np.empty(n, dtype=np.bool_), np.empty(n, dtype=np.bool_)

    def cost_at(e, lam, sigma, mu, rows, band):
        misfit, info = _far_face_misfit_rows(
            core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, rows, band
        )
        c = misfit + level_weight * info * (lam - 0.5) ** 2
        return c + pull_mu * (mu - mu0) ** 2 if has_strip else c

    cost = cost_at(e, lam, sigma, mu, rows, band)
    de = np.empty(n)
    trial = np.empty(n)
    for _ in range(n_iter):
        h_ee, h_eg, b_e, H, b_g, _rr = _far_face_sums_from_rows(
            core, A, D, rows, band, band_slope, has_strip, lam, mu, fit_blur
        )
        far_face_schur(H, b_g, h_ee, h_eg, b_e, lam, mu, level_weight, pull_mu, mu0)
        d = np.linalg.solve(H, b_g)
        d_lam, d_sig = _clip(d[0], -1.0, 1.0), _clip(d[1], -0.5, 0.5)
        d_mu = _clip(d[2], -1.0, 1.0) if has_strip else 0.0
        for i in range(n):
            acc = h_eg[i, 0] * d_lam + h_eg[i, 1] * d_sig
            if has_strip:
                acc += h_eg[i, 2] * d_mu
            de[i] = _clip((b_e[i] - acc) / h_ee[i], -1.0, 1.0)
        accepted = False
        step = 1.0
        t_lam, t_sig, t_mu, c = lam, sigma, mu, cost
        for _h in range(4):
            for i in range(n):
                trial[i] = e[i] + step * de[i]
            t_lam = lam + step * d_lam
            t_sig = _clip(sigma + step * d_sig, 0.05, 5.0)
            t_mu = mu + step * d_mu
            if has_strip:
                t_lam = _py_min(_py_max(t_lam, levels_lo), levels_hi)
                t_mu = _py_min(_py_max(t_mu, levels_lo), levels_hi)
            c = cost_at(trial, t_lam, t_sig, t_mu, rows_trial, band_trial)
            if c <= cost:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        big = 0.0  # np.max(np.abs(step * de)), NaN as numpy's
        for i in range(n):
            v = abs(step * de[i])
            if v > big or v != v:
                big = v
        e, trial = trial, e
        rows, rows_trial = rows_trial, rows
        band, band_trial = band_trial, band
        lam, sigma, mu = t_lam, t_sig, t_mu
        done = cost - c <= 1e-9 * _py_max(cost, 1e-12) or (
            big < 1e-4 and abs(step * d_lam) < 1e-4 and abs(step * d_mu) < 1e-4
        )
        cost = c
        if done:
            break
    return e, lam, sigma, mu, cost

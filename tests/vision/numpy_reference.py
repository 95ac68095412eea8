"""The functions whose loops are now numba kernels (doorloc.vision.jit), as they were written with numpy:
the references tests/vision/test_jit.py holds the compiled ones to (texture_bias, transition_width,
plateau_levels, ransac_line, the response's asymmetry and its parabola vertex, the step fit, the arris
strip's pixel terms, solve and Gauss-Newton loop, the far-face Gauss-Newton loop, the arris lines' borders;
the area estimate is held to subpixel_edges' own numpy branch, the coarse finder to coarse_reference.py)."""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter1d

from doorloc.vision.blurred_step import pixel_step
from doorloc.vision.blurred_step import step_fit as compiled_step_fit
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.lines import ImageLine, _sample_pairs
from doorloc.vision.response_asymmetry import RESPONSE_PLATEAU_PX, _resampled_asymmetry
from doorloc.vision.sampling import gather_profile_rows, median, oriented
from doorloc.vision.texture import TextureBias


def _mean_square(x: np.ndarray) -> float:
    """``float(np.mean(x ** 2))`` of a 1-D float64 array (the same sum, without np.mean's dispatch)."""
    return float((x * x).sum()) / x.size


def texture_bias(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    plateau: int,
    lut: np.ndarray | None = None,
    n_shifts: int = 12,
    max_lines: int = 128,
    blur_px: float | None = None,
    door_skip_px: int = 0,
    door_side: int = 1,
) -> TextureBias:
    """Estimate the texture bias of the sub-pixel edge estimate on one edge from the texture beside its window.

    The estimators take the edge's two grey levels from near the transition and assume they hold under it;
    surface texture (wood grain along the edge) breaks that. The texture under the transition cannot be
    told from the step, but texture that runs along the edge is the same on every scan line at the same
    distance from it, so its mean profile beside the window is measured with little noise (the mean over
    the scan lines that the line fit kept, aligned on their edge points). Taking the texture as stationary across the edge, the
    estimator is run on that texture as if it lay under the window, at ``n_shifts`` positions beyond it on
    each side; the RMS of the edge shifts it makes is the 1-sigma. A plain or smoothly shaded surface
    gives ~0 (noise only).

    With ``blur_px`` None the estimator is :func:`subpixel_edges` (window ``half``, ``plateau`` px levels,
    a closed form); otherwise :func:`refine_step_fit` with that blur, run on a clean step with the texture added.

    Parameters
    ----------
    plane, samples, half, plateau, lut
        As given to :func:`subpixel_edges` (``half`` the final window half-size).
    mask : ndarray (N,) bool
        The samples the line fit kept.
    door_skip_px, door_side : int
        On an arris line the door side beside the edge is the arris strip, whose shading is no texture
        (a rounding's runs from dark to bright across it): its texture is read ``door_skip_px`` farther
        out, beyond the strip, on the side ``door_side`` (+1: increasing ``along``).

    Returns
    -------
    TextureBias
        NaN fields when fewer than 8 samples are usable.
    """
    m = mask & samples.valid & np.isfinite(samples.along)
    idx = np.flatnonzero(m)
    if idx.size < 8:
        return TextureBias(float("nan"), float("nan"))
    if idx.size > max_lines:  # a mean profile needs no more
        idx = idx[np.linspace(0, idx.size - 1, max_lines).astype(int)]
    P = oriented(plane, samples.axis)
    h = half + 1
    reach = max(2 * (half + plateau), 2 * h) + n_shifts + 2
    skip = max(int(door_skip_px), 0)
    R = reach + skip  # the gathered half-window: the door side's profile starts skip px farther out
    skip_plus, skip_minus = (skip, 0) if door_side > 0 else (0, skip)
    c0 = np.round(samples.along[idx]).astype(int)
    vals, ok = gather_profile_rows(P, samples.scan[idx], c0 - R, 2 * R + 1, lut=lut)
    n_ok = int(np.count_nonzero(ok))
    if n_ok < 8:
        return TextureBias(float("nan"), float("nan"))
    if n_ok < ok.size:
        vals = vals[ok]
        scan = samples.scan[idx][ok]
    else:
        scan = samples.scan[idx]
    if plateau == 1:
        D = median(np.abs(vals[:, -1] - vals[:, 0]))
    else:
        D = median(np.abs(vals[:, -plateau:].mean(axis=1) - vals[:, :plateau].mean(axis=1)))
    if not D > 0:
        return TextureBias(float("nan"), float("nan"))
    o = np.arange(half + plateau, half + plateau + n_shifts)
    if blur_px is not None:
        bounds = np.arange(-h, h + 2, dtype=np.float64) - 0.5
        C0, _, _ = pixel_step(bounds, np.zeros(1), max(float(blur_px), 0.05))
        k = np.arange(-h, h + 1)
        o = np.arange(h + 1, h + 1 + n_shifts)

    def pseudo_bias(Ts: list[np.ndarray]) -> list[np.ndarray]:
        """The estimator's error on each mean profile in ``Ts``: both sides' shifts, concatenated."""
        # prof[j - 1] = pixel j beyond c0, each side: the two sides of every profile as the rows of one array
        profs = np.stack(
            [
                p
                for T in Ts
                for p in (
                    T[R + 1 + skip_plus : R + 1 + skip_plus + reach],
                    T[: R - skip_minus][::-1][:reach],
                )
            ]
        )
        if blur_px is None:
            # the area estimator's error, closed form: for each shift o the window sum of pixels
            # o+1..o+half minus half times the mean of the plateau o+half+1..o+half+plateau
            c = np.zeros((profs.shape[0], profs.shape[1] + 1))
            c[:, 1:] = np.cumsum(profs, axis=1)  # row by row, as on each profile alone
            win = c[:, o + half] - c[:, o]
            lev = (c[:, o + half + plateau] - c[:, o + half]) / plateau
            err = (win - half * lev) / D
        else:
            # the step fit's error on a clean step of this contrast with this texture on one side
            # (every profile's every shift in one fit: the rows are fitted independently)
            tex = profs[:, o[:, None] + k[None, :] - 1]
            tex = tex - tex.mean(axis=2, keepdims=True)
            rows = (C0[None] * (D + tex)).reshape(-1, k.size)
            err = compiled_step_fit(rows, np.zeros(rows.shape[0]), bounds, max(float(blur_px), 0.05))
            err = err.reshape(profs.shape[0], o.size)
        return [np.concatenate([err[2 * i], err[2 * i + 1]]) for i in range(len(Ts))]

    # Mean profiles over the scan lines (the line fit's outliers are already out) of the two halves of
    # the edge; their mean is the whole edge's.
    order = np.argsort(scan)
    lo, hi = order[: order.size // 2], order[order.size // 2 :]
    T_lo, T_hi = vals[lo].mean(axis=0, dtype=np.float64), vals[hi].mean(axis=0, dtype=np.float64)
    with_tilt = lo.size >= 4 and hi.size >= 4
    pbs = pseudo_bias([0.5 * (T_lo + T_hi), T_hi, T_lo] if with_tilt else [0.5 * (T_lo + T_hi)])
    pb = pbs[0]
    # Both sides add (independent textures); the RMS over the shifts of each side, summed in quadrature.
    n = pb.size // 2
    off = math.sqrt(_mean_square(pb[:n]) + _mean_square(pb[n:]))
    tilt = float("nan")
    if with_tilt:
        d = pbs[1] - pbs[2]
        # mean scan line of each half (integer sums: exact, as np.mean's)
        lever = int(scan[hi].sum()) / hi.size - int(scan[lo].sum()) / lo.size
        if lever > 0:
            tilt = math.sqrt(_mean_square(d[:n]) + _mean_square(d[n:])) / lever
    return TextureBias(off, tilt)


def transition_width(
    plane: np.ndarray,
    samples: EdgeSamples,
    mask: np.ndarray,
    half: int,
    lut: np.ndarray | None = None,
    quiet_side: int = 0,
) -> float:
    """RMS width (px) of the mean edge transition of the masked samples: the optical blur plus the pixel.

    The profiles are aligned on their sub-pixel edge, normalised by their step and averaged before
    the second moment of the gradient is taken, so noise averages out instead of inflating the width.
    Returns NaN when no sample is usable.
    """
    m = mask & samples.valid
    if not np.any(m):
        return float("nan")
    P = oriented(plane, samples.axis)
    e = samples.along[m]
    c0 = np.round(e).astype(int)
    vals, ok = gather_profile_rows(P, samples.scan[m], c0 - half, 2 * half + 1, lut=lut)
    if not np.any(ok):
        return float("nan")
    step = samples.step[m]
    if not ok.all():
        vals, step, c0, e = vals[ok], step[ok], c0[ok], e[ok]
    g = np.diff(vals, axis=1) / step[:, None]  # step is 0-255 scaled; ratios only matter
    gsum = g.sum(axis=1, keepdims=True)
    g = g / np.maximum(np.abs(gsum), 1e-6) * np.sign(gsum)
    pos = np.arange(2 * half) + 0.5 - half + (c0 - e)[:, None]  # relative to each sub-pixel edge
    # Re-bin on a 0.25 px grid relative to the edge to average the aligned gradient.
    bins = np.round(pos * 4).astype(int)
    lo = bins.min()
    acc = np.bincount((bins - lo).ravel(), weights=g.ravel())
    cnt = np.bincount((bins - lo).ravel())
    gm = np.where(cnt > 0, acc / np.maximum(cnt, 1), 0.0)
    # The peak of the mean (unit-area) gradient gives the width of a Gaussian transition without
    # the noise that the tails add to a second moment. (Smoothed over the filled bins only: an edge along
    # a pixel row or column fills one bin in four, and a plain three-bin mean read its peak a third as
    # high, every such edge three times as wide as it is: a sharp one 2 px, blur 1 px 1.5.)
    filled = (cnt > 0).astype(np.float64)
    gs = np.convolve(gm, np.ones(3), mode="same") / np.maximum(
        np.convolve(filled, np.ones(3), mode="same"), 1.0
    )
    peak = float(gs.max())
    if peak <= 0:
        return float("nan")
    sigma = 1.0 / (peak * math.sqrt(2.0 * math.pi))
    if sigma >= 1.5 and quiet_side != 0:
        # the quiet side's half: twice its area from the highest filled bin over the peak (trapezoid over the
        # filled bins, out to 3 sigmas of the whole-step width)
        x = (np.arange(gm.size) + lo) / 4.0
        f = np.flatnonzero(cnt > 0)
        top = f[np.argmax(gm[f])]
        side = f[(np.sign(quiet_side) * (f - top) >= 0) & (np.abs(x[f] - x[top]) <= 3.0 * sigma)]
        side = side[np.argsort(np.abs(side - top))]
        area = float(np.sum(0.5 * (gm[side][1:] + gm[side][:-1]) * np.abs(np.diff(x[side]))))
        if side.size > 1 and 0 < 2.0 * area / (peak * math.sqrt(2.0 * math.pi)) < sigma:
            sigma = 2.0 * area / (peak * math.sqrt(2.0 * math.pi))
    if sigma < 1.5:
        # A sharp edge sampled at few sub-pixel phases makes a spiky mean gradient whose peak says
        # little: take the second moment within +-3 px instead (the tails, where noise lives, excluded).
        x = (np.arange(gm.size) + lo) / 4.0
        near = np.abs(x) <= 3.0
        wsum = float(gm[near].sum())
        if wsum > 0:
            mu = float((gm[near] * x[near]).sum()) / wsum
            sigma = math.sqrt(max(float((gm[near] * (x[near] - mu) ** 2).sum()) / wsum, 0.0))
    return float(sigma)


def plateau_levels(
    plane: np.ndarray, samples: EdgeSamples, mask: np.ndarray, half: int
) -> tuple[float, float]:
    """The dark and bright plateau's raw grey level just beyond the window (medians, full scale 1)."""
    if int(mask.sum()) < 3:
        return float("nan"), float("nan")
    P = oriented(plane, samples.axis)
    c0 = np.round(samples.along[mask]).astype(int)
    # the window's two end pixels alone, read directly (a profile inside the image at both ends is inside
    # it all through; the medians are np.median's, without its generic machinery)
    a, b = c0 - half - 1, c0 + half + 1
    inside = (a >= 0) & (b < P.shape[0])
    if int(np.count_nonzero(inside)) < 3:
        return float("nan"), float("nan")
    scan = samples.scan[mask][inside]
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    m = [median(P[ends[inside], scan].astype(np.float64)) / top for ends in (a, b)]
    return float(min(m)), float(max(m))


def _lsq_line(s: np.ndarray, a: np.ndarray) -> tuple[float, float]:
    """Least-squares ``a = a0 + b s``; returns (b, a0)."""
    sm, am = s.sum() / s.size, a.sum() / a.size  # = s.mean(), a.mean(): the same sum and division
    ds = s - sm
    den = float(ds @ ds)
    b = float(ds @ (a - am)) / den if den > 0 else 0.0
    return b, float(am - b * sm)


def ransac_line(
    scan: np.ndarray, along: np.ndarray, tol_px: float, n_trials: int = 48, seed: int = 0
) -> ImageLine | None:
    """Coarse line through (scan, along) samples that tolerates many outliers.

    Vectorised RANSAC over ``n_trials`` random sample pairs, then least squares on the inliers of
    the best pair. Returns None with fewer than 5 samples. Deterministic for a given ``seed``.
    """
    s = np.asarray(scan, float)
    a = np.asarray(along, float)
    n = s.size
    if n < 5:
        return None
    i, j = _sample_pairs(n, n_trials, seed)
    ds = s[j] - s[i]
    ok = np.abs(ds) >= max(1.0, 0.1 * (s.max() - s.min()))
    if not np.any(ok):
        return None
    i, j, ds = i[ok], j[ok], ds[ok]
    b = (a[j] - a[i]) / ds
    a0 = a[i] - b * s[i]
    res = np.abs(a[None, :] - (a0[:, None] + b[:, None] * s[None, :]))
    counts = (res <= tol_px).sum(axis=1)
    k = int(np.argmax(counts))
    inl = res[k] <= tol_px
    for _ in range(2):  # least-squares polish on the consensus set
        if inl.sum() < 3:
            break
        bb, aa = _lsq_line(s[inl], a[inl])
        inl = np.abs(a - (aa + bb * s)) <= tol_px
    if inl.sum() < 3:
        return None
    bb, aa = _lsq_line(s[inl], a[inl])
    return ImageLine(float(aa), float(bb), inl)


def plane_map_to_plane(m, uv: np.ndarray) -> np.ndarray:
    """:meth:`doorloc.vision.metric.PlaneMap.to_plane` as written with numpy (``m`` the map)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    if m._distorted:
        xy = m.camera.undistort(uv)
        x, y = xy[:, 0], xy[:, 1]
    else:
        fx, sk, cx, fy, cy = m._k
        y = (uv[:, 1] - cy) / fy
        x = (uv[:, 0] - cx - sk * y) / fx
    R = m.R.tolist()
    dx = R[0][0] * x + R[1][0] * y + R[2][0]
    dy = R[0][1] * x + R[1][1] * y + R[2][1]
    dz = R[0][2] * x + R[1][2] * y + R[2][2]
    c = m.centre.tolist()
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (m.depth_y - c[1]) / dy
    s = np.where(s > 0, s, np.nan)
    out = np.empty((len(uv), 2))
    out[:, 0] = c[0] + s * dx
    out[:, 1] = c[2] + s * dz
    return out


def plane_map_to_image(m, xz: np.ndarray) -> np.ndarray:
    """:meth:`doorloc.vision.metric.PlaneMap.to_image` as written with numpy."""
    xz = np.asarray(xz, float).reshape(-1, 2)
    R, t, Y = m.R.tolist(), m.t.tolist(), m.depth_y
    X, Z = xz[:, 0], xz[:, 1]
    pc = [R[i][0] * X + R[i][1] * Y + R[i][2] * Z + t[i] for i in range(3)]
    with np.errstate(divide="ignore", invalid="ignore"):
        zc = np.where(pc[2] > 0, pc[2], np.nan)
        x, y = pc[0] / zc, pc[1] / zc
    if m._distorted:
        return m.camera.normalized_to_pixel(m.camera.distort(np.stack([x, y], 1)))
    fx, sk, cx, fy, cy = m._k
    out = np.empty((len(xz), 2))
    out[:, 0] = fx * x + sk * y + cx
    out[:, 1] = fy * y + cy
    return out


def asymmetry(t, gammas: np.ndarray, blocks: np.ndarray | None = None, n_blocks: int = 0) -> np.ndarray:
    """:func:`doorloc.vision.response_asymmetry.asymmetry` as written with numpy."""
    G = len(gammas)
    with np.errstate(divide="ignore"):
        v = np.exp(np.asarray(gammas, float)[:, None, None] * np.log(t.raw)[None])  # (G, N, W)
    N, W = v.shape[1], v.shape[2]
    pk = RESPONSE_PLATEAU_PX
    size = min(2 * t.level_rows + 1, N)
    lo = uniform_filter1d(sum(v[:, :, j] for j in range(pk)) / pk, size, axis=1, mode="nearest")[:, :, None]
    hi = uniform_filter1d(sum(v[:, :, W - pk + j] for j in range(pk)) / pk, size, axis=1, mode="nearest")[
        :, :, None
    ]
    v = v[:, :, pk:-pk]
    span = hi - lo
    good = np.abs(span[:, :, 0]) > 1e-9  # (G, N)
    n = (v - lo) / np.where(good[:, :, None], span, 1.0)  # 0 on the first end, 1 on the last: any polarity
    L = n.shape[2]
    # area estimate, index units: (L - 1) minus the trapezoid area of the normalised profile
    centre = (L - 1) - (n.sum(axis=2) - 0.5 * (n[:, :, 0] + n[:, :, -1]))
    if t.one_phase:
        return _resampled_asymmetry(n, centre, good, blocks, n_blocks)
    d = np.arange(L)[None, None, :] - centre[:, :, None]
    inner = (np.abs(d) <= (L - 1) / 2.0 - 1.0) & good[:, :, None]
    B = 4 * (L - 1)  # |d| * 8 never exceeds it inside
    nb = 2 * B + 1
    groups = np.arange(G)[:, None, None] * max(n_blocks, 1)
    if blocks is not None:
        groups = groups + blocks[None, :, None]
        rows_ok = np.stack([np.bincount(blocks, weights=gd, minlength=n_blocks) for gd in good])
    else:
        rows_ok = good.sum(axis=1, keepdims=True)
    n_groups = G * max(n_blocks, 1)
    key = (groups * nb + np.round(d * 8).astype(np.int64) + B)[inner]
    acc = np.bincount(key, weights=n[inner], minlength=n_groups * nb).reshape(n_groups, nb)
    cnt = np.bincount(key, minlength=n_groups * nb).reshape(n_groups, nb)
    cp, cn = cnt[:, B + 1 :], cnt[:, B - 1 :: -1]  # bins at +d and -d, d = 1/8, 2/8, ...
    both = (cp > 0) & (cn > 0)
    r = np.where(
        both, acc[:, B + 1 :] / np.maximum(cp, 1) + acc[:, B - 1 :: -1] / np.maximum(cn, 1) - 1.0, 0.0
    )
    m = both.sum(axis=1)
    out = np.where(m >= 4, (r * r).sum(axis=1) / np.maximum(m, 1), np.nan)
    out = np.where(rows_ok.reshape(-1) >= 3, out, np.nan)
    return out.reshape(G, n_blocks) if blocks is not None else out


def vertex(grid: np.ndarray, a: np.ndarray) -> float:
    """:func:`doorloc.vision.response_asymmetry._vertex` as written in Python."""
    finite = np.isfinite(a)
    if not finite.any():
        return float("nan")
    i = int(np.nanargmin(a))
    if i == 0 or i == grid.size - 1 or not (math.isfinite(a[i - 1]) and math.isfinite(a[i + 1])):
        return float(grid[i])
    x0, x1, x2 = (math.log(float(g)) for g in grid[i - 1 : i + 2])
    y0, y1, y2 = float(a[i - 1]), float(a[i]), float(a[i + 1])
    s0, s2 = (y0 - y1) / (x0 - x1), (y2 - y1) / (x2 - x1)
    curv = (s2 - s0) / (x2 - x0)
    if curv <= 0:
        return float(grid[i])
    return float(math.exp(min(max(x1 - (s0 + curv * (x1 - x0)) / (2.0 * curv), x0), x2)))


def step_fit(
    vals: np.ndarray, e: np.ndarray, bounds: np.ndarray, sigma: float, n_iter: int = 4
) -> np.ndarray:
    """:func:`doorloc.vision.blurred_step.step_fit` as written with numpy (over the compiled pixel model)."""
    vals = np.asarray(vals, np.float64)
    e = np.asarray(e, np.float64).copy()
    for _ in range(n_iter):
        C, g, _ = pixel_step(bounds, e, sigma)
        X0 = 1.0 - C
        s00, s01, s11 = (X0 * X0).sum(1), (X0 * C).sum(1), (C * C).sum(1)
        b0, b1 = (X0 * vals).sum(1), (C * vals).sum(1)
        det = s00 * s11 - s01 * s01
        with np.errstate(divide="ignore", invalid="ignore"):
            A = (s11 * b0 - s01 * b1) / det
            B = (s00 * b1 - s01 * b0) / det
            r = vals - (A[:, None] * X0 + B[:, None] * C)
            J = (B - A)[:, None] * g  # -dm/de (g = -dC/de)
            jj = (J * J).sum(1)
            u0, u1 = (X0 * J).sum(1), (C * J).sum(1)
            # the Jacobian less its part the levels take up (variable projection)
            taken = (s11 * u0 * u0 - 2.0 * s01 * u0 * u1 + s00 * u1 * u1) / det
            den = np.where(jj - taken > 1e-9 * jj, jj - taken, jj)
            de = -(J * r).sum(1) / den
        e = e + np.clip(np.where(np.isfinite(de), de, 0.0), -0.5, 0.5)
    return e


def pixel_terms(edges: np.ndarray, bounds: np.ndarray, sigma: np.ndarray):
    """:func:`doorloc.vision.arris_strip.pixel_terms` as written with numpy (scipy's ndtr, every border)."""
    from scipy.special import ndtr

    s = np.asarray(sigma, float)[:, None, None, None]
    y = edges[None, None, :, None] - bounds[:, :, None, :]  # (B, R, P+1, J)
    u = y / s
    cdf = ndtr(u)
    pdf = np.exp(-0.5 * u * u) * (1.0 / math.sqrt(2.0 * math.pi))
    g = y * cdf + s * pdf
    return g[:, :, 1:] - g[:, :, :-1], cdf[:, :, :-1] - cdf[:, :, 1:], pdf[:, :, 1:] - pdf[:, :, :-1]


def strip_solve(prob, terms, basis: np.ndarray, jac: bool = False):
    """:meth:`doorloc.vision.arris_strip.StripProblem.solve` as written with numpy (batched matrix
    products): ``(chi2, coef, deficit, grad, hess)``."""
    from doorloc.vision.arris_strip import PRIOR_LEVEL
    from doorloc.vision.arris_strip_kernels import mix_cells as _mix

    prim, d_b, d_s = terms
    M, const = _mix(basis, prob.n_cells)
    B = prim.shape[0]
    A = (prim @ M + const).reshape(B, -1, M.shape[1])
    y, w = prob.y.ravel(), prob.w
    AwT = A.transpose(0, 2, 1) * w
    C = basis.shape[0]
    P = np.concatenate([np.full((C, 1), PRIOR_LEVEL - 1.0), np.full((C, 1), -PRIOR_LEVEL), basis], axis=1)
    P = P * math.sqrt(prob.prior_weight)
    N = AwT @ A + P.T @ P + 1e-12 * np.eye(M.shape[1])
    coef = np.linalg.solve(N, (AwT @ y)[..., None])[..., 0]
    f = (A @ coef[..., None])[..., 0] - y
    fp = coef @ P.T
    chi2 = (f * f) @ w + (fp * fp).sum(axis=1)
    c0, cb, band = coef[:, 0], coef[:, 1], coef[:, 2:]
    levels = (band @ basis.T - c0[:, None]) / (cb - c0)[:, None]
    deficit = np.mean(1.0 - levels, axis=1)
    grad = hess = None
    if jac:
        v = (coef @ M.T)[:, :, None]
        n_j = prim.shape[-1]
        J = np.concatenate([(d_b.reshape(B, -1, n_j) @ v), (d_s.reshape(B, -1, n_j) @ v)], axis=2)
        dcoef = np.linalg.solve(N, AwT @ J)
        J = J - A @ dcoef
        Jp = -(P @ dcoef)
        JwT = J.transpose(0, 2, 1) * w
        grad = 2.0 * ((JwT @ f[..., None])[..., 0] + (Jp.transpose(0, 2, 1) @ fp[..., None])[..., 0])
        hess = 2.0 * (JwT @ J + Jp.transpose(0, 2, 1) @ Jp)
    return chi2, coef, deficit, grad, hess


def strip_refine(
    prob, delta: float, sigma: float, basis: np.ndarray, n_iter: int = 12, solve=np.linalg.solve
):
    """:meth:`doorloc.vision.arris_strip.StripProblem.refine` as the loop was written in Python over its
    :meth:`~doorloc.vision.arris_strip.StripProblem.evaluate`: ``(offset, blur, evaluation)``. ``solve``:
    the 2x2 solve of each damped step (numpy's, as written)."""
    p = np.array([delta, sigma])
    ev = prob.evaluate(p[:1], p[1:], basis, jac=True)
    lam = 1e-3
    for _ in range(n_iter):
        H = ev.hess[0] + lam * np.diag(np.diag(ev.hess[0]) + 1e-12)
        step = -solve(H, ev.grad[0])
        step = np.clip(step, [-0.5, -0.3], [0.5, 0.3])
        q = p + step
        q[1] = max(q[1], 0.1)
        ev1 = prob.evaluate(q[:1], q[1:], basis, jac=True)
        if ev1.chi2[0] <= ev.chi2[0]:
            done = ev.chi2[0] - ev1.chi2[0] < 1e-9 * max(ev.chi2[0], 1e-300) or np.all(np.abs(step) < 1e-5)
            p, ev, lam = q, ev1, lam * 0.3
            if done:
                break
        else:
            lam *= 10.0
            if lam > 1e6:
                break
    return float(p[0]), float(p[1]), ev


def far_face_gauss_newton(
    core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, fit_blur, n_iter,
    level_weight, pull_mu, mu0, levels_lo, levels_hi,
):  # fmt: skip
    """subpixel_edges_far_face's Gauss-Newton iterations as they were written in Python over the compiled
    sums (far_face_kernels.far_face_gauss_newton compiles the loop, the Schur complement and the step)."""
    from doorloc.vision.far_face_kernels import _far_face_misfit, far_face_sums

    n_sh = 3 if has_strip else 2

    def total_cost(e, lam, sigma, mu):
        misfit, info = _far_face_misfit(
            core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu
        )
        c = misfit + level_weight * info * (lam - 0.5) ** 2
        return c + pull_mu * (mu - mu0) ** 2 if has_strip else c

    def step_system(e, lam, sigma, mu):
        h_ee, h_eg, b_e, H, b_g, _ = far_face_sums(
            core, A, D, bounds, e, w0, e0, band_slope, sigma, tail, strip, has_strip, lam, mu, fit_blur
        )
        level_info = float(H[0, 0])
        H -= (h_eg / h_ee[:, None]).T @ h_eg
        b_g -= (h_eg * (b_e / h_ee)[:, None]).sum(axis=0)
        H += np.diag(np.maximum(np.diag(H), 1e-12) * 1e-6 + 1e-9)
        prior = level_weight * level_info
        H[0, 0] += prior
        b_g[0] += prior * (0.5 - lam)
        if has_strip:
            H[2, 2] += pull_mu
            b_g[2] += pull_mu * (mu0 - mu)
        return H, b_g, h_ee, h_eg, b_e

    cost = total_cost(e, lam, sigma, mu)
    for _ in range(n_iter):
        H, b_g, h_ee, h_eg, b_e = step_system(e, lam, sigma, mu)
        d = np.linalg.solve(H, b_g)
        d_lam, d_sig = float(np.clip(d[0], -1.0, 1.0)), float(np.clip(d[1], -0.5, 0.5))
        d_mu = float(np.clip(d[2], -1.0, 1.0)) if has_strip else 0.0
        d_sh = np.array([d_lam, d_sig, d_mu][:n_sh])
        de = np.clip((b_e - h_eg @ d_sh) / h_ee, -1.0, 1.0)
        for step in (1.0, 0.5, 0.25, 0.125):
            trial = (
                e + step * de,
                lam + step * d_lam,
                float(np.clip(sigma + step * d_sig, 0.05, 5.0)),
                mu + step * d_mu,
            )
            if has_strip:
                trial = (
                    trial[0],
                    min(max(trial[1], levels_lo), levels_hi),
                    trial[2],
                    min(max(trial[3], levels_lo), levels_hi),
                )
            c = total_cost(*trial)
            if c <= cost:
                break
        else:
            break
        e, lam, sigma, mu = trial
        done = cost - c <= 1e-9 * max(cost, 1e-12) or (
            np.max(np.abs(step * de)) < 1e-4 and abs(step * d_lam) < 1e-4 and abs(step * d_mu) < 1e-4
        )
        cost = c
        if done:
            break
    return e, lam, sigma, mu, cost


def line_borders(
    vals: np.ndarray,
    x: np.ndarray,
    border0: np.ndarray,
    width: np.ndarray,
    levels: np.ndarray,
    blur_px: float,
    n_iter: int = 6,
) -> np.ndarray:
    """arris_lines._line_borders as it was written with numpy (the (N, P, J) pixel terms of
    arris_strip.pixel_terms, ~25 array operations an iteration)."""
    from doorloc.vision.arris_strip import pixel_terms as _pixel_terms

    n_cells = levels.size
    frac = np.arange(n_cells + 1) / n_cells
    jumps = np.diff(np.concatenate([[0.0], levels, [1.0]]))  # (C + 1,) each boundary's step
    edges = np.concatenate([x[:1] - 0.5, x + 0.5])
    b = np.asarray(border0, float).copy()
    ok = np.isfinite(b) & np.isfinite(width)
    b[~ok] = 0.0
    w = np.where(ok, width, 0.0)
    sigma = np.array([max(float(blur_px), 0.05)])
    step = np.zeros_like(b)
    for _ in range(n_iter):
        bounds = (b[:, None] + w[:, None] * frac[None, :])[None]  # (1, N, J)
        prim, d_b, _ = _pixel_terms(edges, bounds, sigma)
        shape = prim[0] @ jumps  # (N, P)
        dshape = d_b[0] @ jumps  # d shape / d b
        # A and D by least squares on each line: [1, shape] (N, P, 2)
        s_mean = shape.mean(axis=1, keepdims=True)
        v_mean = vals.mean(axis=1, keepdims=True)
        sc, vc = shape - s_mean, vals - v_mean
        ss = (sc * sc).sum(axis=1)
        D = np.where(ss > 1e-12, (sc * vc).sum(axis=1) / np.maximum(ss, 1e-12), np.nan)
        A = v_mean[:, 0] - D * s_mean[:, 0]
        res = A[:, None] + D[:, None] * shape - vals
        # the border's Gauss-Newton step, the levels projected out (variable projection)
        J = D[:, None] * dshape
        Jc = J - J.mean(axis=1, keepdims=True)
        Jp = Jc - ((Jc * sc).sum(axis=1) / np.maximum(ss, 1e-12))[:, None] * sc
        jj = (Jp * Jp).sum(axis=1)
        step = np.where(jj > 1e-18, -(Jp * res).sum(axis=1) / np.maximum(jj, 1e-18), np.nan)
        step = np.clip(step, -0.5, 0.5)
        b = b + np.where(np.isfinite(step), step, 0.0)
        if np.nanmax(np.abs(step), initial=0.0) < 1e-4:
            break
    good = ok & np.isfinite(step) & (np.abs(step) < 0.5) & np.isfinite(D) & (np.abs(D) > 0)
    return np.where(good, b, np.nan)


def residual_structure_tilt(
    scan: np.ndarray, residual_px: np.ndarray, inliers: np.ndarray, blocks: int = 4
) -> float:
    """edge_texture.residual_structure_tilt as numpy wrote it: the inliers' residuals sorted by scan line, their
    means over ``np.array_split``'s blocks, ``sd(means) / sqrt(sum (centre - mean centre)^2)``."""
    m = inliers & np.isfinite(residual_px)
    if int(m.sum()) < 8 * blocks:
        return float("nan")
    order = np.argsort(scan[m])
    s, res = scan[m][order].astype(float), residual_px[m][order]
    parts = np.array_split(np.arange(s.size), blocks)
    means = np.array([res[b].mean() for b in parts])
    centres = np.array([s[b].mean() for b in parts])
    spread = float(np.sum((centres - centres.mean()) ** 2))
    return float(np.std(means, ddof=1) / math.sqrt(spread)) if spread > 0 else float("nan")


def transition_skew_px(t, rows, g: float) -> float:
    """``doorloc.vision.response_asymmetry.transition_skew_px`` as numpy computed it before it was compiled."""
    levels, index = t.levels  # each distinct level raised once, whichever rows are asked for
    vals = (levels**g)[index[rows]]
    off = t.offset[rows]
    d = np.diff(vals, axis=1)
    tot = d.sum(axis=1, keepdims=True)
    good = np.abs(tot[:, 0]) > 1e-9
    if int(good.sum()) < 3:
        return float("nan")
    # positions from the dark side to the bright one: the skew's sign then says which way the exponent
    # is off, whichever the edge's polarity
    pos = (np.arange(d.shape[1]) + 0.5 + off[good][:, None]) * np.sign(tot[good])
    d = d[good] / tot[good]
    bins = np.round(pos * 4).astype(int)
    lo = bins.min()
    acc = np.bincount((bins - lo).ravel(), weights=d.ravel())
    cnt = np.bincount((bins - lo).ravel())
    x = (np.arange(cnt.size) + lo) / 4.0
    filled = cnt > 0
    gm = np.interp(x, x[filled], acc[filled] / cnt[filled])
    if gm.sum() <= 0:
        return float("nan")
    w = gm / gm.sum()
    centre = float(np.sum(w * x))
    cum = np.cumsum(w) - 0.5 * w
    k = int(np.searchsorted(cum, 0.5))
    if k <= 0 or k >= x.size:
        return float("nan")
    f = (0.5 - cum[k - 1]) / max(cum[k] - cum[k - 1], 1e-12)
    return float(x[k - 1] + f * (x[k] - x[k - 1]) - centre)


def plateau_scatter(raw: np.ndarray) -> float:
    """The median plateau scatter ``doorloc.vision.response_asymmetry.dithered`` compares with its threshold,
    as numpy computed it before it was compiled."""
    pk = RESPONSE_PLATEAU_PX
    ends = [raw[:, :pk], raw[:, -pk:]]
    var = sum(((e - e.mean(axis=1, keepdims=True)) ** 2).sum(axis=1) for e in ends) / (2 * pk - 2)
    return float(np.median(np.sqrt(var)))


def plateau_misses(raw: np.ndarray, rounding: float, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plateaus' noise and misses :func:`doorloc.vision.response_plateaus.plateau_level_rows` decides
    on (its kernel ``_plateau_misses``), written with numpy: each end's plateau noise variance (2,) and
    the median of the squared misses against the neighbours over each of ``rows`` lines (2, K)."""
    pk = RESPONSE_PLATEAU_PX
    N, W = raw.shape
    ends = np.stack([raw[:, :pk], raw[:, W - pk :]])
    m = ends.mean(axis=2)
    s2 = np.maximum(ends.var(axis=2, ddof=1).mean(axis=1), rounding) / pk
    c = np.concatenate([np.zeros((2, 1)), np.cumsum(m, axis=1)], axis=1)
    i, r = np.arange(N), np.asarray(rows)[:, None]
    lo, hi = np.maximum(i - r, 0), np.minimum(i + r + 1, N)
    neighbours = (c[:, hi] - c[:, lo] - m[:, None, :]) / (hi - lo - 1)
    return s2, np.median((m[:, None, :] - neighbours) ** 2, axis=2) / 0.454936

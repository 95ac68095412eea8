"""Robust straight-line fits: total least squares with Tukey IRLS, and a coarse RANSAC.

The door's hinge face is a rectangle, so its three visible edges share one direction: the bottom
end runs along door +X and both arrises along door +Z. :func:`fit_rectangle_edges` fits them
jointly — one normal angle, one offset per line — which uses every edge point for the yaw instead
of only the short bottom line (the thesis took the angle from the X-line alone).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from doorloc.vision.jit import kernel, partitioned_median, read_only
from doorloc.vision.sampling import median  # np.median's value, without its generic machinery

__all__ = [
    "ImageLine",
    "fit_image_line",
    "ransac_line",
    "RectangleFit",
    "fit_rectangle_edges",
    "fit_rectangle_lines",
    "revote_direction",
    "tukey_weights",
    "own_scatter_weights",
]

TUKEY_C = 4.685  # 95 % efficiency at the normal distribution


def tukey_weights(residuals: np.ndarray, scale: float) -> np.ndarray:
    """Tukey biweight ``(1 - (r / (c s))^2)^2`` inside ``c s``, 0 outside."""
    u = residuals / (TUKEY_C * scale)
    # (1 - min(u^2, 1))^2: the same numbers as where(|u| < 1, (1 - u^2)^2, 0) (NaN too: fmin drops it), fewer passes
    t = 1.0 - np.fmin(u * u, 1.0)
    return t * t


def own_scatter_weights(residuals: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A fitted line's points judged by their own scatter: the residuals (any unit) about their median, and
    their Tukey weights (:func:`tukey_weights`) at 1.4826 times their own median absolute deviation, the
    rule the joint fit applies at the door's common scale (points not ``valid`` and NaN residuals weigh 0).

    For the far arris beside a visible far face, which measures the thickness alone: wood grain beside it
    bends its points into a slow wave that the door's other, straighter lines do not share (a grained door,
    6.8 % grain under a 0.96 px blur, its far face a 10.5 px band: its points on a wave of +-0.7 px over the
    door's height, 135 of 549 within the common scale, and the door refused `edge_not_straight` with its
    thickness read 0.02 mm from the recipe's; ``bench_surfaces.py --sets grain --n 30 --seed 14100``, door
    3). An edge covered over a stretch still leaves those points beyond its own scatter."""
    r = np.asarray(residuals, np.float64)
    ok = np.isfinite(r) & np.asarray(valid, bool)
    if not np.any(ok):
        return np.zeros(r.size), r
    centred = r - float(np.median(r[ok]))
    spread = 1.4826 * float(np.median(np.abs(centred[ok])))
    return np.where(ok, tukey_weights(centred, max(spread, 1e-12)), 0.0), centred


def robust_scale(
    residuals: np.ndarray, weights: np.ndarray | None = None, floor: float = 0.0, max_samples: int = 512
) -> float:
    """MAD-based standard deviation of residuals (those with positive weight), at least ``floor``.

    At most ``max_samples`` evenly spread residuals are used: a scale needs no more, and medians cost.
    """
    r = residuals if weights is None else residuals[weights > 0]
    if r.size == 0:
        return floor
    if r.size > max_samples:
        r = r[:: r.size // max_samples + 1]
    return max(1.4826 * median(np.abs(r - median(r))), floor)


@dataclass(frozen=True)
class ImageLine:
    """A line ``along = a + b * scan`` in image coordinates, with the samples that support it.

    ``scan`` is the integer coordinate of a scan line (a column ``u`` for a near-horizontal edge, a row
    ``v`` for a near-vertical one) and ``along`` the position of the edge on that scan line, px.
    """

    a: float
    b: float
    inliers: np.ndarray  # bool mask over the input samples

    def at(self, scan: np.ndarray) -> np.ndarray:
        return self.a + self.b * np.asarray(scan, float)


@kernel(lambda k: k(np.arange(4.0), np.arange(4.0)))
def _lsq_line(s, a):
    """Least-squares ``a = a0 + b s``; returns (b, a0)."""
    sm = s.sum() / s.size
    am = a.sum() / a.size
    den = 0.0
    num = 0.0
    for q in range(s.size):
        d = s[q] - sm
        den += d * d
        num += d * (a[q] - am)
    b = num / den if den > 0 else 0.0
    return b, am - b * sm


def fit_image_line(scan: np.ndarray, along: np.ndarray) -> ImageLine:
    """The least-squares line ``along = a + b * scan`` through all the samples (every one an inlier; ``b`` 0
    where they share one scan line).

    Raises
    ------
    ValueError
        Fewer than 2 samples, or ``scan`` and ``along`` of different lengths.
    """
    s = np.asarray(scan, np.float64)
    a = np.asarray(along, np.float64)
    if s.shape != a.shape or s.ndim != 1 or s.size < 2:
        raise ValueError(f"need two or more (scan, along) samples of one length, got {s.shape} and {a.shape}")
    b, a0 = _lsq_line(s, a)
    return ImageLine(float(a0), float(b), np.ones(s.size, bool))


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
    found, aa, bb, inl = _ransac(s, a, i, j, float(tol_px))
    return ImageLine(aa, bb, inl) if found else None


def _ransac_warm_up(k) -> None:
    s = np.arange(8.0)
    k(s, 2.0 * s, np.array([0, 1, 2]), np.array([5, 6, 7]), 3.0)
    k(s, 2.0 * s, read_only(np.array([0, 1, 2])), read_only(np.array([5, 6, 7])), 3.0)  # cached pairs


@kernel(_ransac_warm_up)
def _ransac(s, a, i, j, tol_px):
    """The search of :func:`ransac_line`, compiled (:mod:`doorloc.vision.jit`): the sample pairs ``(i, j)``
    far enough apart along the scan, the one with the most samples within ``tol_px`` (the first of
    equals), then least squares on its consensus set twice. Returns ``(found, a0, b, inliers)``."""
    n = s.size
    inl = np.zeros(n, np.bool_)
    span = s.max() - s.min()
    min_ds = max(1.0, 0.1 * span)
    best = -1
    best_b = best_a0 = 0.0
    for t in range(i.size):
        ds = s[j[t]] - s[i[t]]
        if not abs(ds) >= min_ds:
            continue
        b = (a[j[t]] - a[i[t]]) / ds
        a0 = a[i[t]] - b * s[i[t]]
        count = 0
        for q in range(n):
            if abs(a[q] - (a0 + b * s[q])) <= tol_px:
                count += 1
        if count > best:
            best, best_b, best_a0 = count, b, a0
    if best < 0:
        return False, 0.0, 0.0, inl
    for q in range(n):
        inl[q] = abs(a[q] - (best_a0 + best_b * s[q])) <= tol_px
    for _ in range(2):  # least-squares polish on the consensus set
        if inl.sum() < 3:
            break
        bb, aa = _lsq_line(s[inl], a[inl])
        for q in range(n):
            inl[q] = abs(a[q] - (aa + bb * s[q])) <= tol_px
    if inl.sum() < 3:
        return False, 0.0, 0.0, inl
    bb, aa = _lsq_line(s[inl], a[inl])
    return True, aa, bb, inl


@functools.lru_cache(maxsize=256)
def _sample_pairs(n: int, n_trials: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The RANSAC sample pairs for ``n`` samples: fixed by the seed, so drawn once per sample count
    (making a generator costs more than the rest of a coarse line fit)."""
    rng = np.random.default_rng(seed)
    i = rng.integers(0, n, n_trials)
    j = rng.integers(0, n, n_trials)
    i.setflags(write=False)
    j.setflags(write=False)
    return i, j


@dataclass(frozen=True)
class RectangleFit:
    """Joint fit of the hinge face's edges on the hinge-face plane (mm).

    The reference and far arrises satisfy ``cos(t) X + sin(t) Z = c``, the bottom end
    ``-sin(t) X + cos(t) Z = c``, with ``t`` the door yaw.

    Attributes
    ----------
    angle_rad : float
        Common normal angle ``t`` (door yaw), radians.
    offsets : dict[str, float]
        Line offset ``c`` per line name, mm.
    residuals : dict[str, ndarray]
        Signed distance of every sample to its line, mm.
    weights : dict[str, ndarray]
        Final Tukey weight of every sample (0 = outlier).
    scale : float
        Robust residual scale (MAD), mm.
    angle_sigma_rad, offset_sigma : float, dict[str, float]
        Standard errors from the weighted fit (residual scale / information).
    """

    angle_rad: float
    offsets: dict[str, float]
    residuals: dict[str, np.ndarray]
    weights: dict[str, np.ndarray]
    scale: float
    angle_sigma_rad: float
    offset_sigma: dict[str, float]


def _to_common(points: np.ndarray, along_x: bool) -> np.ndarray:
    # Bottom-end points (along door X) turned by -90 deg share the arrises' normal.
    return np.stack([points[:, 1], -points[:, 0]], axis=1) if along_x else points


@kernel(inline=True)
def _weighted_sums(P, w, lo, hi):
    """The weights of points ``lo:hi`` of ``P`` (N, 2) and their weighted coordinates' sums, in order."""
    sw = sx = sz = 0.0
    for i in range(lo, hi):
        sw += w[i]
        sx += w[i] * P[i, 0]
        sz += w[i] * P[i, 1]
    return sw, sx, sz


@kernel(inline=True)
def _least_normal(a, b, d):
    """The smallest-eigenvalue eigenvector of the scatter ``[[a, b], [b, d]]``, in closed form, and its length
    (to divide by; 0 for an isotropic scatter): from the row of ``A - lam I`` with the larger entries. For a
    line near one axis the other row's ``lam - a`` (or ``lam - d``) is a difference of near-equal numbers
    whose rounding (~1e-16 of the scatter) would turn the normal by ~1e-16 / angle rad (1e-6 deg at an angle
    of 3e-7 deg)."""
    lam = 0.5 * (a + d) - math.sqrt(0.25 * (a - d) ** 2 + b * b)
    u0, u1 = b, lam - a
    v0, v1 = lam - d, b
    if u0 * u0 + u1 * u1 >= v0 * v0 + v1 * v1:
        n0, n1 = u0, u1
    else:
        n0, n1 = v0, v1
    return n0, n1, math.hypot(n0, n1)


def _irls_warm_up(k) -> None:
    P = np.array([[0.0, 0.0], [0.0, 1.0], [0.1, 2.0], [1.0, 0.0], [2.0, 0.1]])
    k(P, np.array([0, 3]), np.array([3, 2]), np.ones(5, bool), np.ones(5), False, 1e-4, 9, 512)


@kernel(_irls_warm_up)
def _irls(P, starts, sizes, mask0, votes, use_votes, scale_floor, n_iter, max_samples):
    """The IRLS loop of :func:`fit_rectangle_edges`, compiled (:mod:`doorloc.vision.jit`).

    ``P`` (N, 2) points in the common frame, groups ``[starts[g], starts[g] + sizes[g])``; ``votes`` weigh
    the direction where ``use_votes``. Returns ``(status, n0, n1, offsets (G,), residuals (N,), weights (N,),
    centred points (N, 2))`` of the last iteration (the weights updated after it unless it converged);
    ``status`` is ``-1 - g`` when group ``g`` has no weight left, else 0.
    """
    # why many parameters: a numba nopython kernel takes arrays and scalars only (the line groups flattened)
    # why long: one compiled IRLS iteration (means, closed-form normal, MAD scale, weights) as numpy sums it
    N = P.shape[0]
    G = sizes.size
    w = np.empty(N)
    gid = np.empty(N, np.int64)
    for g in range(G):
        for i in range(starts[g], starts[g] + sizes[g]):
            gid[i] = g
    for i in range(N):
        w[i] = 1.0 if mask0[i] else 0.0
    Q = np.empty((N, 2))
    r = np.empty(N)
    means = np.empty((G, 2))
    off = np.empty(G)
    state = np.empty(2 + G)
    prev = np.empty(2 + G)
    have_prev = False
    scale = scale_floor
    n0, n1 = 1.0, 0.0
    for it in range(n_iter):
        for g in range(G):
            sw, sx, sz = _weighted_sums(P, w, starts[g], starts[g] + sizes[g])
            if not sw > 0:
                return -1 - g, n0, n1, off, r, w, Q
            means[g, 0] = sx / sw
            means[g, 1] = sz / sw
        # weighted scatter of the centred points (the voting ones)
        a = b = d = 0.0
        for i in range(N):
            q0 = P[i, 0] - means[gid[i], 0]
            q1 = P[i, 1] - means[gid[i], 1]
            Q[i, 0] = q0
            Q[i, 1] = q1
            wv = w[i] * votes[i] if use_votes else w[i]
            a += wv * q0 * q0
            b += wv * q0 * q1
            d += wv * q1 * q1
        n0, n1, h = _least_normal(a, b, d)
        if not h > 0:  # an isotropic scatter (or none): any normal fits it
            n0, n1, h = 1.0, 0.0, 1.0
        n0, n1 = n0 / h, n1 / h
        if n0 < 0:
            n0, n1 = -n0, -n1
        for g in range(G):
            off[g] = means[g, 0] * n0 + means[g, 1] * n1
        for i in range(N):
            r[i] = P[i, 0] * n0 + P[i, 1] * n1 - off[gid[i]]
        state[0], state[1] = n0, n1
        state[2:] = off
        if have_prev and it > 3 and np.all(np.abs(state - prev) < 1e-8):
            break
        prev[:] = state
        have_prev = True
        if it < 4 or it % 2 == 0:  # the scale settles quickly; re-estimating it every time costs medians
            # robust_scale: the MAD of the residuals with weight, at most max_samples of them evenly spread
            kept = r[w > 0]
            if kept.size == 0:
                scale = scale_floor
            else:
                if kept.size > max_samples:
                    kept = kept[:: kept.size // max_samples + 1]
                m = kept.size // 2
                med = partitioned_median(np.partition(kept, m), m)
                mad = partitioned_median(np.partition(np.abs(kept - med), m), m)
                scale = max(1.4826 * mad, scale_floor)
        if it < 3:
            # Huber: 1 inside, 1/u beyond (the first iterations: they cannot lose the solution)
            c = 1.345 * scale
            for i in range(N):
                u = abs(r[i]) / c
                w[i] = 1.0 / (u if (u > 1.0 or u != u) else 1.0)
        else:
            c = TUKEY_C * scale
            for i in range(N):
                u = r[i] / c
                uu = u * u
                t = 1.0 - (uu if uu < 1.0 else 1.0)  # NaN -> weight 0, as tukey_weights
                w[i] = t * t
        for i in range(N):
            if not mask0[i]:
                w[i] = w[i] * 0.0
    return 0, n0, n1, off, r, w, Q


def _stacked_groups(
    groups: dict[str, tuple[np.ndarray, bool]],
    init_weights: dict[str, np.ndarray] | None,
    offset_only: tuple[str, ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """:func:`fit_rectangle_edges`' groups as the IRLS kernel takes them:
    ``(P, mask0, votes, sizes, starts)``, the points of all groups in the common frame (N, 2) mm, in the
    order of ``groups``; where a starting weight is > 0; each point's vote on the direction (None: all vote);
    each group's size and first index."""
    names = list(groups)
    sizes_l = [len(groups[k][0]) for k in names]
    if 0 in sizes_l:
        raise ValueError("a line group has no points")
    P = np.concatenate([_to_common(np.asarray(groups[k][0], float), groups[k][1]) for k in names])
    mask0 = (
        np.concatenate([np.asarray(init_weights[k], float) for k in names]) > 0
        if init_weights is not None
        else np.ones(len(P), bool)
    )
    voting_subset = any(k in offset_only for k in names)  # else votes are all 1 (w * 1.0 == w)
    votes = (
        np.concatenate([np.full(n, k not in offset_only, float) for k, n in zip(names, sizes_l, strict=True)])
        if voting_subset
        else None
    )
    sizes = np.array(sizes_l, np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
    return P, mask0, votes, sizes, starts


def fit_rectangle_edges(
    groups: dict[str, tuple[np.ndarray, bool]],
    *,
    scale_floor: float = 1e-4,
    n_iter: int = 9,
    init_weights: dict[str, np.ndarray] | None = None,
    offset_only: tuple[str, ...] = (),
) -> RectangleFit:
    """Fit lines sharing one direction to groups of plane points, robustly (Tukey IRLS, TLS).

    Parameters
    ----------
    groups : dict
        ``name -> (points (N, 2) as (X, Z) mm, along_x)``; ``along_x`` is True for a line that runs
        along door +X (the bottom end), False for one along door +Z (an arris).
    scale_floor : float
        Smallest residual scale the weights may assume, mm (keeps noise-free data from zeroing
        out good points).
    n_iter : int
        IRLS iterations (the first three use Huber weights, which cannot lose the solution).
    init_weights : dict, optional
        Starting weights per group (e.g. 0 for samples already known to be bad).
    offset_only : tuple of str
        Groups that get an offset but do not vote on the common direction (an edge whose shape
        may be less trustworthy, e.g. the far arris beside a visible far face).

    Returns
    -------
    RectangleFit

    Examples
    --------
    >>> t = np.radians(1.0); c, s = np.cos(t), np.sin(t)
    >>> z = np.linspace(5, 100, 50); x = np.linspace(5, 45, 30)
    >>> ref = np.stack([2 - z * s, 3 + z * c], 1) ; bot = np.stack([2 + x * c, 3 + x * s], 1)
    >>> f = fit_rectangle_edges({"reference": (ref, False), "bottom": (bot, True)})
    >>> round(float(np.degrees(f.angle_rad)), 9)
    1.0
    """
    names = list(groups)
    G = len(names)
    n, off, r, w, Q, votes, sizes = _rectangle_irls(groups, init_weights, offset_only, scale_floor, n_iter)
    # Standard errors: residual variance over the weighted information of each parameter.
    sw = np.bincount(np.repeat(np.arange(G), sizes), weights=w, minlength=G)
    var = float((w * r * r).sum()) / max(float(sw.sum()) - G - 1, 1.0)
    tdir = np.array([-n[1], n[0]])
    spread = float(((w * votes if votes is not None else w) * (Q @ tdir) ** 2).sum())
    ang_sigma = math.sqrt(var / max(spread, 1e-12))
    bounds = np.concatenate([[0], np.cumsum(sizes)]).tolist()
    sw_l = sw.tolist()
    off_sigma = {k: math.sqrt(var / max(sw_l[i], 1e-12)) for i, k in enumerate(names)}
    res = {k: r[bounds[i] : bounds[i + 1]] for i, k in enumerate(names)}
    wd = {k: w[bounds[i] : bounds[i + 1]] for i, k in enumerate(names)}
    offsets = dict(zip(names, off.tolist(), strict=True))
    angle = float(np.arctan2(n[1], n[0]))
    return RectangleFit(angle, offsets, res, wd, math.sqrt(var), ang_sigma, off_sigma)


def fit_rectangle_lines(
    groups: dict[str, tuple[np.ndarray, bool]], *, scale_floor: float = 1e-4, n_iter: int = 9
) -> tuple[float, dict[str, float]]:
    """The common direction (rad) and each line's offset (mm) of :func:`fit_rectangle_edges` with the same
    arguments, bit for bit, without its residuals, weights and standard errors.

    For callers that fit thousands of outlines and read only the lines (the model check's analytic forward
    model): the statistics cost more than the fit itself there.
    """
    n, off, *_ = _rectangle_irls(groups, None, (), scale_floor, n_iter)
    return float(np.arctan2(n[1], n[0])), dict(zip(list(groups), off.tolist(), strict=True))


def _rectangle_irls(groups, init_weights, offset_only, scale_floor: float, n_iter: int):
    """The joint IRLS of :func:`fit_rectangle_edges`: the common normal ``n`` (2,), the offsets, residuals,
    weights, stacked points, votes (None: every point votes) and group sizes; ValueError naming a line that
    lost every point."""
    names = list(groups)
    P, mask0, votes, sizes, starts = _stacked_groups(groups, init_weights, offset_only)
    status, n0, n1, off, r, w, Q = _irls(
        np.ascontiguousarray(P),
        starts,
        sizes,
        mask0,
        votes if votes is not None else np.ones(len(P)),
        votes is not None,
        float(scale_floor),
        int(n_iter),
        512,
    )
    if status < 0:
        raise ValueError(f"no usable points on the {names[-1 - status]} line")
    return np.array([n0, n1]), off, r, w, Q, votes, sizes


def revote_direction(
    fit: RectangleFit, groups: dict[str, tuple[np.ndarray, bool]], votes: dict[str, float]
) -> RectangleFit:
    """``fit`` (of ``groups``, :func:`fit_rectangle_edges`) with its common direction voted again: each line's
    direction weighs ``votes[k]`` (the inverse variance of its direction, any common unit; a line not in
    ``votes`` or at 0 keeps its offset only), the robust weights kept. The offsets, residuals and the
    direction's standard error follow; the residual scale and the offsets' standard errors are kept.

    The joint fit weighs each line's direction by the spread of its points, which is its weight where the
    points' noise is all its doubt. A line whose direction is in more doubt than that (wood grain that
    wanders along it, JPEG blocks, an arris strip's shading) is weighed by its whole doubt here.

    Written out rather than run through the IRLS kernel again: one weighted solve of a 2x2 scatter, the
    weights fixed (a new IRLS would judge the points again and move the weights with the votes).

    >>> t = np.radians(1.0); c, s = np.cos(t), np.sin(t)
    >>> z = np.linspace(5, 100, 50); x = np.linspace(5, 45, 30)
    >>> ref = np.stack([2 - z * s, 3 + z * c], 1) ; bot = np.stack([2 + x * c, 3 + x * s], 1)
    >>> g = {"reference": (ref, False), "bottom": (bot, True)}
    >>> f = revote_direction(fit_rectangle_edges(g), g, {"reference": 1.0, "bottom": 4.0})
    >>> round(float(np.degrees(f.angle_rad)), 9)
    1.0
    """
    names = list(groups)
    P, _, _, sizes, starts = _stacked_groups(groups, None, ())
    w = np.concatenate([fit.weights[k] for k in names])
    vote = np.array([max(votes.get(k, 0.0), 0.0) for k in names])
    ok, n0, n1, off, r, ang_var_per_var = _revoted(
        np.ascontiguousarray(P), starts, sizes, w, vote, fit.angle_rad
    )
    if not ok:
        return fit
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    offsets = {k: float(off[g]) for g, k in enumerate(names)}
    residuals = {k: r[bounds[g] : bounds[g + 1]] for g, k in enumerate(names)}
    n = np.array([n0, n1])
    ang_var = fit.scale**2 * ang_var_per_var
    return RectangleFit(
        float(np.arctan2(n[1], n[0])),
        offsets,
        residuals,
        fit.weights,
        fit.scale,
        math.sqrt(ang_var),
        fit.offset_sigma,
    )


def _revoted_warm_up(k) -> None:
    P = np.array([[0.0, 0.0], [0.0, 1.0], [0.1, 2.0], [1.0, 0.0], [2.0, 0.1]])
    k(P, np.array([0, 3]), np.array([3, 2]), np.ones(5), np.ones(2), 0.0)


@kernel(_revoted_warm_up)
def _revoted(P, starts, sizes, w, vote, angle):
    """:func:`revote_direction`'s solve, compiled (one weighted pass over the points: numpy's two dozen
    calls cost 0.12 ms a frame). ``P`` (N, 2) the points in the common frame, groups ``[starts[g],
    starts[g] + sizes[g])``, ``w`` their robust weights, ``vote`` each group's, ``angle`` the joint fit's
    direction. Returns ``(ok, n0, n1, offsets (G,), residuals (N,), the direction's variance per unit
    residual variance)``; ``ok`` False where no group votes."""
    N = P.shape[0]
    G = sizes.size
    means = np.zeros((G, 2))
    info = np.zeros(G)
    t0, t1 = -math.sin(angle), math.cos(angle)  # along the arrises
    for g in range(G):
        sw, sx, sz = _weighted_sums(P, w, starts[g], starts[g] + sizes[g])
        if sw > 0:
            means[g, 0], means[g, 1] = sx / sw, sz / sw
        for i in range(starts[g], starts[g] + sizes[g]):
            u = (P[i, 0] - means[g, 0]) * t0 + (P[i, 1] - means[g, 1]) * t1
            info[g] += w[i] * u * u
    a = b = d = spread = spread2 = 0.0
    for g in range(G):
        alpha = vote[g] / info[g] if info[g] > 0 else 0.0
        spread += alpha * info[g]
        spread2 += alpha * alpha * info[g]
        for i in range(starts[g], starts[g] + sizes[g]):
            q0, q1 = P[i, 0] - means[g, 0], P[i, 1] - means[g, 1]
            wa = w[i] * alpha
            a += wa * q0 * q0
            b += wa * q0 * q1
            d += wa * q1 * q1
    off = np.zeros(G)
    r = np.zeros(N)
    if not spread > 0:
        return False, 1.0, 0.0, off, r, 0.0
    n0, n1, h = _least_normal(a, b, d)
    if not h > 0:  # an isotropic scatter: no direction to vote
        return False, 1.0, 0.0, off, r, 0.0
    n0, n1 = n0 / h, n1 / h
    if n0 < 0:
        n0, n1 = -n0, -n1
    for g in range(G):
        off[g] = means[g, 0] * n0 + means[g, 1] * n1
        for i in range(starts[g], starts[g] + sizes[g]):
            r[i] = P[i, 0] * n0 + P[i, 1] * n1 - off[g]
    return True, n0, n1, off, r, spread2 / spread / spread

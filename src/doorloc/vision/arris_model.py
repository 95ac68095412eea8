"""The virtual sharp corner behind a chamfered or rounded arris.

An arris of size ``a`` shows as a strip between the background and the hinge face. Its outer border is
the chamfer's far edge, or on a rounding the silhouette where the view ray grazes the cylinder; its inner
border the tangent line on the hinge face. Both are straight lines whose places follow from the
geometry (:class:`doorloc.arris.ArrisSection`); the strip's brightness does not: it depends on the light,
the wood and the camera's response. Where an edge estimator that assumes a plain step puts the edge inside
the strip depends on that brightness, so locate measures it:

1. :func:`arris_geometry`: from the current pose, each arris's cross-section seen from the camera: the
   outer border's place on the outline plane (``y = a``; inwards from the sharp corner's line, mm), the
   inner border's, and the map from the fraction of the strip's image width to the surface angle ``theta``;
2. :func:`fit_strip_profile`: the strip's shading, fitted to the profiles of many scan lines at once
   (linear light, each normalised by its own two plateaus): background | strip | hinge face, blurred by a
   Gaussian and integrated over the pixels, with the outer border's offset and the blur free, and the strip
   a chamfer's constant level or a rounding's Lambert shading ``alpha + kappa max(0, cos(theta - psi))``
   (light direction, ambient and albedo unknown). What it returns is the strip's *deficit*: the fraction
   of its width by which the area of the strip falls short of the hinge face;
3. :func:`arris_edges`: per scan line the area estimator (blur-free: it only uses areas) with that deficit,
   ``e = K - S / D - w * deficit``, which puts every edge point on the outer border; the caller moves it
   to the sharp corner's line by the geometry.

What the deficit leaves in doubt (its standard error from the fit, widened by how far the fit's residual
exceeds the noise) is reported per line as ``arris_correction_sigma_mm`` for the uncertainty budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.special import ndtr

from doorloc.arris import ArrisSection
from doorloc.pose import yaw_rotation_matrix
from doorloc.vision.edges import Axis, EdgeSamples, _gather, oriented

__all__ = ["ArrisGeometry", "StripFit", "arris_geometry", "fit_strip_profile", "arris_edges"]

#: sub-intervals of the strip (uniform in image width) over which its shading is taken constant in the fit
_STRIP_CELLS = 16
#: scan lines the shading fit uses at most (spread evenly over the edge)
_FIT_LINES = 40
#: plausible error of the Gaussian blur model, px (sets the model's doubt in the strip's deficit)
BLUR_DOUBT = 0.1
#: prior of the deficit: a strip somewhere between the background and the hinge face
PRIOR_DEFICIT, PRIOR_SIGMA = 0.5, 0.5


@dataclass(frozen=True)
class ArrisGeometry:
    """One arris seen from the camera, in its cross-section (:mod:`doorloc.arris`).

    Attributes
    ----------
    section : ArrisSection
        Size, profile and the camera centre in cross-section coordinates.
    w_outer_mm, w_inner_mm : float
        The strip's outer and inner borders on the outline plane ``y = a``, measured inwards from the
        sharp corner's line, mm (a chamfer: ``0`` and about ``a``; a rounding's silhouette lies a little inside ``0``).
    tau, theta : ndarray
        Fraction of the strip's image width from its outer border (0) to its inner border (1), and the
        surface angle there (``theta = 0`` on the hinge face), increasing ``tau``.
    """

    section: ArrisSection
    w_outer_mm: float
    w_inner_mm: float
    tau: np.ndarray
    theta: np.ndarray

    def theta_at(self, tau: np.ndarray) -> np.ndarray:
        return np.interp(tau, self.tau, self.theta)


def arris_geometry(
    size_mm: float,
    profile: str,
    eye_cell: np.ndarray,
    corner_xz: np.ndarray,
    yaw_deg: float,
    face_y: float,
    thickness_mm: float,
) -> dict[str, ArrisGeometry]:
    """Cross-sections of the bottom, reference and far arrises for a door at this pose.

    Parameters
    ----------
    size_mm, profile : float, str
        The arris (chamfer leg or rounding radius, mm; ``"chamfer"`` or ``"round"``).
    eye_cell : ndarray (3,)
        Camera centre, cell frame, mm.
    corner_xz : ndarray (2,)
        The reference corner (cell X, Z), mm; ``yaw_deg`` the door's yaw.
    face_y : float
        Depth of the hinge face, mm.
    thickness_mm : float
        Door thickness (where the far arris is), mm.

    Returns
    -------
    dict
        ``{"bottom": ..., "reference": ..., "far": ...}``; an arris with nothing in view is left out.
    """
    R = yaw_rotation_matrix(yaw_deg)
    eye = R.T @ (np.asarray(eye_cell, float) - np.array([corner_xz[0], face_y, corner_xz[1]]))
    coords = {
        "reference": (eye[0], eye[1]),
        "bottom": (eye[2], eye[1]),
        "far": (thickness_mm - eye[0], eye[1]),
    }
    out = {}
    for name, (ew, ey) in coords.items():
        sec = ArrisSection(size_mm, profile, float(ew), float(ey))
        th_a, th_b = sec.visible_arc()
        if not np.isfinite(th_a) or th_a > 1e-9:
            continue  # the hinge side of the arris is turned away: not a strip beside the hinge face
        a = size_mm
        th = np.linspace(0.0, th_b, 257)
        on_face = sec.on_plane(th, 0.0)
        tau = (on_face - on_face[-1]) / (on_face[0] - on_face[-1])  # 1 at the inner border, 0 at the outer
        tau, th = tau[::-1], th[::-1]  # increasing tau: from the outer border inwards
        if np.any(np.diff(tau) <= 0):
            continue
        out[name] = ArrisGeometry(sec, float(sec.on_plane(th_b, a)), float(sec.on_plane(0.0, a)), tau, th)
    return out


@dataclass(frozen=True)
class StripFit:
    """The strip's shading fitted over many scan lines (:func:`fit_strip_profile`).

    Attributes
    ----------
    deficit : float
        ``1/w`` times the integral over the strip of ``(face - strip) / (face - background)``: 0 for a strip as
        bright as the hinge face (the edge is the outer border), 1 for one as dark as the background.
    deficit_sigma : float
        Its standard error, widened by the fit's misfit (residual RMS over the profiles' noise).
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
    """

    deficit: float
    deficit_sigma: float
    offset_px: float
    blur_px: float
    misfit: float
    levels: np.ndarray
    model: np.ndarray
    border: np.ndarray


def _G(y: np.ndarray, sigma: float) -> np.ndarray:
    """Integral of the Gaussian CDF, ``G(y) = y Phi(y / s) + s phi(y / s)``."""
    u = y / sigma
    return y * ndtr(u) + sigma * np.exp(-0.5 * u * u) * (1.0 / math.sqrt(2.0 * math.pi))


def _design(
    x: np.ndarray, outer: np.ndarray, width: np.ndarray, sigma: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel responses to the hinge face (unit step at the inner border) and to each strip cell.

    ``x`` (N, P) pixel centres; ``outer``, ``width`` (N,) the strip's outer border and width, px. Returns
    ``step`` (N, P) and ``cells`` (N, P, C): each pixel's integral of the blurred unit level over the face /
    one cell of the strip.
    """
    bounds = (
        outer[:, None] + width[:, None] * (np.arange(_STRIP_CELLS + 1) / _STRIP_CELLS)[None, :]
    )  # (N, C+1)
    # consecutive pixels share their borders: G once per pixel border, then differences
    edges = np.concatenate([x[:, :1] - 0.5, x + 0.5], axis=1)  # (N, P+1)
    g = _G(edges[:, :, None] - bounds[:, None, :], sigma)
    prim = g[:, 1:] - g[:, :-1]  # (N, P, C+1): pixel integral of the unit level beyond each boundary
    cells = prim[:, :, :-1] - prim[:, :, 1:]
    return prim[:, :, -1], cells


def _strip_basis(geom: ArrisGeometry, terminator: float | None, lit_below: bool) -> np.ndarray:
    """Shading basis on the strip cells, shape (C, k): a chamfer's constant; a rounding's ``1, cos, sin`` of
    ``theta`` (a light whose terminator lies off the arc), or ``1, max(0, +-sin(theta - terminator))``."""
    if geom.section.profile == "chamfer":
        return np.ones((_STRIP_CELLS, 1))
    # cell means over 8 sub-samples: near the silhouette theta changes fast across one cell
    tau = (np.arange(_STRIP_CELLS)[:, None] + (np.arange(8)[None, :] + 0.5) / 8) / _STRIP_CELLS
    th = geom.theta_at(tau)
    if terminator is None:
        return np.stack([np.ones(_STRIP_CELLS), np.cos(th).mean(axis=1), np.sin(th).mean(axis=1)], axis=1)
    s = np.sin(th - terminator) * (-1.0 if lit_below else 1.0)
    return np.stack([np.ones(_STRIP_CELLS), np.maximum(s, 0.0).mean(axis=1)], axis=1)


def fit_strip_profile(
    r: np.ndarray,
    x: np.ndarray,
    outer: np.ndarray,
    width: np.ndarray,
    geom: ArrisGeometry,
    noise: float,
    blur0: float = 1.0,
    search_px: float = 0.0,
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

    Returns
    -------
    StripFit or None
        None when there are too few profiles.
    """
    ok = np.all(np.isfinite(r), axis=1) & np.isfinite(outer) & np.isfinite(width) & (width > 0)
    r, outer, width = r[ok], outer[ok], width[ok]
    if r.shape[0] < 5:
        return None
    xx = np.broadcast_to(x[None, :], r.shape)
    y = np.concatenate([r.ravel(), [0.0]])
    # A weak prior on the deficit, 0.5 +- 0.5 (a strip between background and face), as one more residual
    # row (linear in the levels: mean strip level - (background + face) / 2). It decides only where the
    # profiles cannot: a strip narrower than the blur, whose level and border trade off; the fit's
    # standard error then shows that doubt instead of hiding it.
    w_prior = noise / PRIOR_SIGMA

    def solve(params: np.ndarray, basis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        delta, sigma = params[0], max(abs(params[1]), 0.05)
        step, cells = _design(xx, outer + delta, width, sigma)
        band = cells @ basis  # (N, P, k)
        bg = 1.0 - step - cells.sum(axis=2)
        A = np.concatenate([bg[..., None], step[..., None], band], axis=2).reshape(y.size - 1, -1)
        prior = w_prior * np.concatenate([[-0.5, -0.5], basis.mean(axis=0)])
        A = np.vstack([A, prior[None, :]])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        return A @ coef - y, coef, A

    candidates: list[tuple[float | None, bool]] = [(None, False)]
    if geom.section.profile == "round":
        th_max = float(geom.theta.max())
        candidates += [(t, lb) for t in np.linspace(0.05, 0.95, 10) * th_max for lb in (False, True)]

    def fit(term: float | None, lit_below: bool, x0: np.ndarray, nfev: int):
        basis = _strip_basis(geom, term, lit_below)
        res = least_squares(
            lambda p: solve(p, basis)[0], x0, diff_step=1e-3, max_nfev=nfev, x_scale=[0.1, 0.1]
        )
        return res, basis

    # The offset has local minima on narrow strips (strip and border trade places): start from the best
    # of a grid over offset and blur.
    if geom.section.profile == "round":
        # a generic strip shape (four free levels across it) for the search, so that a light whose
        # terminator crosses the arc does not lead it astray before the physical shading is fitted
        b0 = np.kron(np.eye(4), np.ones((_STRIP_CELLS // 4, 1)))
    else:
        b0 = _strip_basis(geom, None, False)

    def cost0(p: tuple[float, float]) -> float:
        return float(np.sum(solve(np.array(p), b0)[0] ** 2))

    reach = search_px + 2.0
    coarse = sorted(np.arange(-reach, reach + 0.01, 1.0), key=lambda d: cost0((d, max(blur0, 0.7))))
    centres: list[float] = []
    for d in coarse:  # the two best coarse offsets at distinct places
        if all(abs(d - d1) > 1.5 for d1 in centres):
            centres.append(float(d))
        if len(centres) == 2:
            break
    grid = sorted(
        (cost0((c + d, sg)), c + d, sg)
        for c in centres
        for d in np.arange(-1.0, 1.01, 0.5)
        for sg in (0.3, 0.8, 1.6)
    )
    starts: list[tuple[float, float]] = []
    for _, d, sg in grid:  # the best starts at distinct offsets
        if all(abs(d - d1) > 0.75 for d1, _ in starts):
            starts.append((d, sg))
        if len(starts) == 2:
            break
    res, basis = min(
        (fit(None, False, np.array(st), 20) for st in starts), key=lambda rb: float(np.sum(rb[0].fun ** 2))
    )
    best: tuple[float, float | None, bool, Any, np.ndarray] = (
        float(np.sum(res.fun**2)),
        None,
        False,
        res,
        basis,
    )
    for term, lb in candidates[1:]:
        b = _strip_basis(geom, term, lb)
        cost = float(np.sum(solve(res.x, b)[0] ** 2))
        if cost < best[0] * 0.98:
            best = (cost, term, lb, None, b)
    if best[3] is None:
        # a light whose terminator crosses the arc: refine where, with the offset and the blur
        lit_below = best[2]

        def fun3(p: np.ndarray) -> np.ndarray:
            return solve(p[:2], _strip_basis(geom, float(p[2]), lit_below))[0]

        r3 = least_squares(fun3, np.r_[res.x, best[1]], diff_step=1e-3, max_nfev=20, x_scale=[0.1, 0.1, 0.05])
        if np.sum(r3.fun**2) < np.sum(res.fun**2):
            basis = _strip_basis(geom, float(r3.x[2]), lit_below)
            res = least_squares(
                lambda p: solve(p, basis)[0], r3.x[:2], diff_step=1e-3, max_nfev=5, x_scale=[0.1, 0.1]
            )
    resid, coef, A = solve(res.x, basis)
    c0, cb, band = coef[0], coef[1], coef[2:]
    levels = (basis @ band - c0) / (cb - c0)
    deficit = float(np.mean(1.0 - levels))
    # standard error of the deficit: linear-parameter covariance at the optimum, plus the offset and the
    # blur through a numerical derivative (they trade off with the strip's level on narrow strips)
    dof = max(y.size - A.shape[1] - 2, 1)
    s2 = float(resid @ resid) / dof
    eps = np.array([1e-3, 1e-3])
    J = np.empty((y.size, 2))
    model = A @ coef
    for i in range(2):
        p = res.x.copy()
        p[i] += eps[i]
        J[:, i] = (solve(p, basis)[2] @ coef - model) / eps[i]  # at fixed levels: the joint Jacobian
    full = np.concatenate([A, J], axis=1)
    try:
        cov = s2 * np.linalg.pinv(full.T @ full)
    except np.linalg.LinAlgError:
        return None
    # d deficit / d (c0, cb, band coefficients); the nonlinear ones act through the linear refit (ignored here)
    k = basis.shape[1]
    g = np.zeros(full.shape[1])
    mean_basis = basis.mean(axis=0)
    f_mean = float(mean_basis @ band)
    D = cb - c0
    g[0] = (1.0 / D) - (f_mean - c0) / D**2
    g[1] = (f_mean - c0) / D**2
    g[2 : 2 + k] = -mean_basis / D
    var = float(g @ cov @ g)
    misfit = math.sqrt(s2) / max(noise, 1e-6)
    # Profiles along one edge share their texture and their plateau errors: the residuals are not
    # independent from line to line, which the plain standard error ignores. Widen it by the misfit.
    stat = math.sqrt(max(var, 0.0)) * max(misfit, 1.0)
    # The model's own doubt: a strip narrower than the blur looks like a wider blur with another strip
    # level (the two trade off along a valley that noise-free data hardly tells apart, and the real
    # optics are no exact Gaussian). How far the deficit moves when the blur is off by BLUR_DOUBT:
    moved = []
    for d_sigma in (-BLUR_DOUBT, BLUR_DOUBT):
        sg = max(abs(res.x[1]) + d_sigma, 0.05)
        r1 = least_squares(
            lambda p, sg=sg: solve(np.array([p[0], sg]), basis)[0],
            res.x[:1],
            diff_step=1e-3,
            max_nfev=8,
            x_scale=[0.1],
        )
        _, c1, _ = solve(np.array([r1.x[0], sg]), basis)
        lv = (basis @ c1[2:] - c1[0]) / (c1[1] - c1[0])
        moved.append(abs(float(np.mean(1.0 - lv)) - deficit))
    sigma = math.hypot(stat, max(moved))
    # Combined with the prior (0.5 +- 0.5): where the profiles leave the deficit in doubt, the answer
    # leans towards a mid-grey strip, whose worst case is half the strip's width.
    w_data, w_pri = 1.0 / max(sigma, 1e-9) ** 2, 1.0 / PRIOR_SIGMA**2
    deficit = (w_data * deficit + w_pri * PRIOR_DEFICIT) / (w_data + w_pri)
    sigma = 1.0 / math.sqrt(w_data + w_pri)
    model_profiles = model[:-1].reshape(r.shape)
    return StripFit(
        deficit,
        sigma,
        float(res.x[0]),
        float(abs(res.x[1])),
        misfit,
        levels,
        model_profiles,
        outer + res.x[0],
    )


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
        vals, inside = _gather(P, scan, c0 - half - plateau - pad, length, lut=lut)
    else:  # mirror so that the door side is at increasing index
        vals, inside = _gather(P, scan, c0 + half + plateau + pad - length + 1, length, lut=lut)
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
        fit = fit_strip_profile(r, x, outer, w[pick], geom, nz, blur0, search_px=float(pad))
    bias = 0.0
    if fit is not None:
        # The area estimator on the fitted, noise-free profiles: what the window's ends and the plateaus'
        # blur tails cost it (the strip's two steps differ, so they do not cancel as on a plain step).
        mod = fit.model
        a_m = mod[:, plateau - nl : plateau].mean(axis=1)
        b_m = mod[:, length - plateau : length - plateau + nl].mean(axis=1)
        s_m = (mod[:, plateau : length - plateau] - a_m[:, None]).sum(axis=1)
        e_m = (length - 2 * plateau - 0.5) - s_m / (b_m - a_m) - w[pick] * fit.deficit
        bias = float(np.median(e_m - (fit.border - plateau)))
    if fit is None:
        nan = np.full(len(scan), np.nan)
        return EdgeSamples(axis, scan, nan, nan, nan, nan, nan, np.zeros(len(scan), bool)), None
    with np.errstate(divide="ignore", invalid="ignore"):
        K = (
            core.shape[1] - 0.5
        )  # door-side end of the window (core index units; core starts at c0 - half - pad)
        e_mirror = K - S / D_e - w * fit.deficit - bias - (half + pad)  # relative to c0
        along = c0 + door_side * e_mirror
    valid = good & np.isfinite(along) & (np.abs(along - centre) <= half + pad)
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

"""The arris strip's fitting problem: the pixel integrals of a blurred background | strip | hinge-face profile,
the strip's shading basis, and the normal equations of its levels solved inside every evaluation (variable
projection), compiled (:mod:`doorloc.vision.arris_strip_kernels`).

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
from doorloc.vision.arris_strip_kernels import (
    bin_means,
    mix_cells,
    pixel_terms_compiled,
    strip_evaluate,
    strip_refine,
    strip_solve,
)
from doorloc.vision.blurred_step import STEP_TAIL_SIGMAS

__all__ = [
    "StripProblem",
    "StripEvaluation",
    "strip_basis",
    "pixel_terms",
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
    ``d prim / d b`` and ``d prim / d s``, each (B, R, P, J) (compiled:
    :func:`~doorloc.vision.arris_strip_kernels.pixel_terms_compiled`).
    """
    sigma = np.asarray(sigma, np.float64).reshape(-1)
    n_b = max(bounds.shape[0], sigma.size)  # (the candidates broadcast, as in the array formula)
    if bounds.shape[0] != n_b:
        bounds = np.broadcast_to(bounds, (n_b, *bounds.shape[1:]))
    if sigma.size != n_b:
        sigma = np.broadcast_to(sigma, (n_b,))
    return pixel_terms_compiled(
        np.ascontiguousarray(edges, np.float64),
        np.ascontiguousarray(bounds, np.float64),
        np.ascontiguousarray(sigma),
        STEP_TAIL_SIGMAS,
    )


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


@dataclass(frozen=True)
class StripEvaluation:
    """The strip model at a batch of (offset, blur) candidates, its levels solved linearly."""

    chi2: np.ndarray  # (B,) weighted residual sum of squares
    coef: np.ndarray  # (B, m) background, face, shading coefficients
    deficit: np.ndarray  # (B,)
    grad: np.ndarray | None  # (B, 2) d chi2 / d (offset, blur), variable projection
    hess: np.ndarray | None  # (B, 2, 2) its Gauss-Newton Hessian


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
        self.count, self.y, self.outer, self.width = bin_means(  # (R,), (R, P), (R,), (R,)
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
        candidate at a time: :func:`~doorloc.vision.arris_strip_kernels.strip_evaluate`)."""
        delta = np.atleast_1d(np.asarray(delta, float))
        sigma = np.maximum(np.atleast_1d(np.asarray(sigma, float)), 0.05)
        n_b = max(delta.size, sigma.size)  # (the candidates broadcast, as in pixel_terms)
        M, const, P, basis_c = self._basis_terms_of(basis)
        chi2, coef, deficit, grad, hess = strip_evaluate(
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
        :func:`~doorloc.vision.arris_strip_kernels.strip_solve`)."""
        prim, d_b, d_s = terms
        M, const, P, basis_c = self._basis_terms_of(basis)
        chi2, coef, deficit, grad, hess = strip_solve(
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
        from the least of them.

        Why not a refine from every place: over the ~70 lights a door's light is sought among, the
        refines were nine tenths of the ~3 s a door cost; screening the places first leaves one. Until
        2026-12-05 ``places[0]`` (the caller's own start) was refined as well and the better fit kept:
        of 5,806 lights whose two starts differed (six rounded doors) it ended better on 2,174, by more
        than 0.01 in the log misfit on 92. Left out, over the arris bench's 384 doors (``bench_arris_range.py
        --n 32 --seed S --sets round,chamfer,ambient,small``, S 9100, 9900, 10100) no refusal changed and no
        answer moved by more than 0.0003 mm (a sigma by 0.0011 mm; with the cell's light stated,
        ``--light-told``, 96 doors of 9100: by 0.0015 mm), and the rounded doors' median locate fell
        10-18 %."""
        places = np.asarray(places, float)
        costs = self.chi2_many(self.pixel_terms(places, np.full(places.size, sigma)), bases)
        return [
            self.refine(float(places[int(np.argmin(cost))]), sigma, basis, n_iter=n_iter)
            for basis, cost in zip(bases, costs, strict=True)
        ]

    def refine(
        self, delta: float, sigma: float, basis: np.ndarray, n_iter: int = 12
    ) -> tuple[float, float, StripEvaluation]:
        """Gauss-Newton (variable projection, analytic Jacobian, Levenberg damping) on the offset and the
        blur from ``delta``, ``sigma`` (px), at most ``n_iter`` steps (compiled:
        :func:`~doorloc.vision.arris_strip_kernels.strip_refine`)."""
        M, const, P, basis_c = self._basis_terms_of(basis)
        p0, p1, chi2, coef, deficit, grad, hess, singular = strip_refine(
            self.edges,
            self.outer,
            self.width,
            self.frac,
            float(delta),
            float(sigma),
            STEP_TAIL_SIGMAS,
            M,
            const,
            self.y_flat,
            self.w,
            P,
            basis_c,
            int(n_iter),
        )
        if singular:
            raise np.linalg.LinAlgError("Singular matrix")
        return p0, p1, StripEvaluation(chi2, coef, deficit, grad, hess)

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

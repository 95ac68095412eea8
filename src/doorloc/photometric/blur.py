"""Blur that changes over the field or with the edge's direction, read from the edges' fitted blurs.

Each edge's blur (Gaussian sigma, px, from :func:`doorloc.photometric.profiles.fit_profiles`) is modelled as
``sigma^2 = s_p + field (r / r_corner)^2 + anisotropy cos(2 phi)`` with one level ``s_p`` per photograph (focus
changes from photograph to photograph), ``r`` the edge's distance from the image centre and ``phi`` the angle of
its normal from the image's u axis (``cos 2 phi`` = +1 for vertical edges, -1 for horizontal ones). Each term is
kept only where, fitted without a fold of photographs, it predicts the held-out photographs' edge-to-edge blur
differences better than nothing does (paired over photographs, as :mod:`doorloc.photometric.fit` chooses causes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from doorloc.photometric.catalogue import PROFILE_CAUSES, keep_sigmas

__all__ = ["EdgeBlurs", "BlurTerms", "blur_terms"]


@dataclass(frozen=True)
class EdgeBlurs:
    """One photograph's edges: ``blur_px`` (E,), ``mid_px`` (E, 2), ``normal`` (E, 2), ``image_size`` (w, h)."""

    blur_px: np.ndarray
    mid_px: np.ndarray
    normal: np.ndarray
    image_size: tuple[int, int]

    def features(self) -> np.ndarray:
        w, h = self.image_size
        c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
        r2 = ((self.mid_px - c) ** 2).sum(1) / float((c**2).sum())
        cos2 = self.normal[:, 0] ** 2 - self.normal[:, 1] ** 2
        return np.stack([r2, cos2], 1)


@dataclass(frozen=True)
class BlurTerms:
    """The kept terms (names of :mod:`doorloc.photometric.catalogue`), their values and 1-sigma (px^2 of blur
    variance), and each term's held-out gain (mean paired reduction of squared error, and its standard error)."""

    causes: tuple[str, ...]
    values: dict[str, float]
    sigma: dict[str, float]
    gains: dict[str, tuple[float, float]]


_NAMES = ("blur_field", "blur_anisotropy")


def _demeaned(photos: Sequence[EdgeBlurs]) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for p in photos:
        ok = np.isfinite(p.blur_px)
        y = p.blur_px[ok] ** 2
        X = p.features()[ok]
        out.append((y - y.mean(), X - X.mean(0)) if y.size > 2 else (np.zeros(0), np.zeros((0, 2))))
    return out


def _fit(data: list[tuple[np.ndarray, np.ndarray]], cols: list[int]) -> np.ndarray:
    y = np.concatenate([d[0] for d in data])
    X = np.concatenate([d[1][:, cols] for d in data])
    if y.size < len(cols) + 2:
        return np.zeros(len(cols))
    return np.linalg.lstsq(X, y, rcond=None)[0]


def blur_terms(photos: Sequence[EdgeBlurs], folds: np.ndarray) -> BlurTerms:
    """Choose and fit the blur terms by held-out photographs (module docstring)."""
    data = _demeaned(photos)
    kept: list[int] = []
    gains: dict[str, tuple[float, float]] = {}

    def heldout_sse(cols: list[int]) -> np.ndarray:
        sse = np.zeros(len(photos))
        for f in np.unique(folds):
            train = [d for d, g in zip(data, folds, strict=True) if g != f]
            coef = _fit(train, cols) if cols else np.zeros(0)
            for i in np.flatnonzero(folds == f):
                y, X = data[i]
                sse[i] = np.mean((y - X[:, cols] @ coef) ** 2) if y.size else 0.0
        return sse

    base = heldout_sse([])
    for j in (0, 1):
        trial = heldout_sse([*kept, j])
        d = base - trial
        g, se = float(d.mean()), float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
        gains[_NAMES[j]] = (g, se)
        if g > keep_sigmas(len(PROFILE_CAUSES)) * se:
            kept.append(j)
            base = trial
    values: dict[str, float] = {}
    sigma: dict[str, float] = {}
    if kept:
        coef = _fit(data, kept)
        per_fold = np.array(
            [_fit([d for d, g in zip(data, folds, strict=True) if g != f], kept) for f in np.unique(folds)]
        )
        k = per_fold.shape[0]
        sd = (
            np.sqrt((k - 1) / k * ((per_fold - per_fold.mean(0)) ** 2).sum(0))
            if k > 1
            else np.full(len(kept), np.nan)
        )
        for j, c, s in zip(kept, coef, sd, strict=True):
            values[_NAMES[j]] = float(c)
            sigma[_NAMES[j]] = float(s)
    return BlurTerms(tuple(_NAMES[j] for j in kept), values, sigma, gains)

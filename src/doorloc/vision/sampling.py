"""Sampling primitives that every edge model reads the pixel plane with.

Profiles run along integer scan lines (an image column for ``axis="col"``, a row for ``axis="row"``):
:func:`oriented` gives the view with profiles along axis 0, :func:`gather_profiles` and
:func:`gather_profile_rows` read windows of them (mapped through a linearising table,
:func:`linearizing_lut`, where the camera's response is not linear), :func:`pixel_buffer` hands a plane
to a compiled kernel as a flat buffer and two pitches. Beside them the small numerical helpers several
models share: running means along a line (:func:`smooth_along`), ``np.median``'s value for less
(:func:`median`) and the standard normal CDF with its density (:func:`normal_cdf_pdf`, a compiled helper
the blurred-step models inline).

Nothing here knows an edge model; the models (:mod:`doorloc.vision.edges`,
:mod:`doorloc.vision.arris_model`, :mod:`doorloc.vision.response`) and the coarse search
(:mod:`doorloc.vision.coarse`) build on it.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator
from typing import Literal

import numpy as np

from doorloc.vision.jit import kernel, read_only

__all__ = [
    "Axis",
    "NO_LUT",
    "flat_view",
    "gather_profile_rows",
    "gather_profiles",
    "linearizing_lut",
    "median",
    "median_with_error",
    "normal_cdf_pdf",
    "oriented",
    "pixel_buffer",
    "smooth_along",
    "smooth_along_rows",
    "warm_up_planes",
]

Axis = Literal["col", "row"]


def oriented(plane: np.ndarray, axis: Axis) -> np.ndarray:
    """View with profiles along axis 0: ``P[along, scan]`` (the plane itself for columns, its transpose for rows)."""
    return plane if axis == "col" else plane.T


def smooth_along(x: np.ndarray, n: int) -> np.ndarray:
    """Moving average over ``2 n + 1`` neighbours (fewer at the ends and where ``x`` is NaN)."""
    ok = np.isfinite(x)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, x, 0.0))])
    m = np.concatenate([[0], np.cumsum(ok)])
    i = np.arange(x.size)
    lo, hi = np.maximum(i - n, 0), np.minimum(i + n + 1, x.size)
    return (c[hi] - c[lo]) / np.maximum(m[hi] - m[lo], 1)


def smooth_along_rows(x: np.ndarray, n: int) -> np.ndarray:
    """:func:`smooth_along` of each row of ``x`` (K, N), in one pass (the same numbers: running sums are
    sequential either way; with no NaN the counts are the window lengths)."""
    k, size = x.shape
    lo, hi, length = _smoothing_windows(size, n)
    ok = np.isfinite(x)
    all_ok = bool(ok.all())
    c = np.zeros((k, size + 1))
    c[:, 1:] = np.cumsum(x if all_ok else np.where(ok, x, 0.0), axis=1)  # in x's precision, as smooth_along
    if all_ok:
        return (c[:, hi] - c[:, lo]) / length
    m = np.zeros((k, size + 1), np.int64)
    np.cumsum(ok, axis=1, out=m[:, 1:])
    return (c[:, hi] - c[:, lo]) / np.maximum(m[:, hi] - m[:, lo], 1)


@functools.lru_cache(maxsize=64)
def _smoothing_windows(size: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Window bounds ``lo``, ``hi`` of :func:`smooth_along` over ``size`` samples and ``max(hi - lo, 1)``
    (read-only, made once per size)."""
    i = np.arange(size)
    lo, hi = np.maximum(i - n, 0), np.minimum(i + n + 1, size)
    length = np.maximum(hi - lo, 1)
    for a in (lo, hi, length):
        a.setflags(write=False)
    return lo, hi, length


def flat_view(P: np.ndarray) -> tuple[np.ndarray, int, int] | None:
    """``(flat, pitch0, pitch1)`` with ``P[i, j] == flat[i * pitch0 + j * pitch1]`` for a plane or its
    transpose stored contiguously (a view, no copy); None for other layouts."""
    if P.flags.c_contiguous:
        return P.reshape(-1), P.shape[1], 1
    if P.flags.f_contiguous:
        return P.T.reshape(-1), 1, P.shape[0]
    return None


def pixel_buffer(P: np.ndarray) -> tuple[np.ndarray, int, int]:
    """``(buf, pitch0, pitch1)`` with ``P[i, j] == buf[i * pitch0 + j * pitch1]``, for a kernel: a view of a
    plane or its transpose (:func:`flat_view`), else of a C-ordered copy."""
    flat = flat_view(P)
    if flat is None:
        flat = flat_view(np.ascontiguousarray(P))
        assert flat is not None
    return flat


def _take_profiles(
    P: np.ndarray, scan: np.ndarray, start: np.ndarray, length: int, stride: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Raw profiles ``P[start + stride k, scan]`` (N, length), clamped to the image, and the per-row flag
    "every sample lies in the image".

    One flat ``take`` from the plane's buffer instead of 2-D fancy indexing (which walks the transposed
    view for row profiles and costs several times more); other layouts fall back to fancy indexing.
    """
    n_along, n_scan = P.shape
    k = stride * np.arange(length)
    last = start + k[-1] if length else start
    lo_end, hi_end = np.minimum(start, last), np.maximum(start, last)
    rows_in = (lo_end >= 0) & (hi_end < n_along)
    flat = flat_view(P)
    if flat is not None and scan.size and int(scan.min()) >= 0 and int(scan.max()) < n_scan:
        f, p0, p1 = flat
        if stride > 0 and int(lo_end.min()) >= 0 and int(hi_end.max()) < n_along:
            # all inside (the usual case): rows of a strided view of the buffer (row b holds the profile
            # that starts at flat index b), picked by their first index - no index array per sample
            view = np.lib.stride_tricks.as_strided(
                f,
                shape=(f.size - stride * p0 * (length - 1), length),
                strides=(f.itemsize, stride * p0 * f.itemsize),
                writeable=False,
            )
            return view[start * p0 + scan * p1], rows_in
        idx = start[:, None] + k[None, :]
        np.clip(idx, 0, n_along - 1, out=idx)
        return f.take(idx * p0 + (scan * p1)[:, None]), rows_in
    idx = start[:, None] + k[None, :]
    return P[np.clip(idx, 0, n_along - 1), scan[:, None]], rows_in


def gather_profiles(
    P: np.ndarray,
    scan: np.ndarray,
    start: np.ndarray,
    length: int,
    stride: int = 1,
    lut: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Profiles ``P[start + stride k, scan]`` for k < length as float32 (N, length), and an in-image mask.

    ``lut`` (float32, one entry per grey level) maps the stored values first, e.g. to linear light.
    """
    vals, _ = gather_profile_rows(P, scan, start, length, stride, lut)
    idx = start[:, None] + stride * np.arange(length)[None, :]
    inside = (idx >= 0) & (idx < P.shape[0])
    return vals, inside


def gather_profile_rows(
    P: np.ndarray,
    scan: np.ndarray,
    start: np.ndarray,
    length: int,
    stride: int = 1,
    lut: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`gather_profiles`, with the in-image flag per profile (N,) (``inside.all(axis=1)``) instead of
    per sample: what most callers need, for less work."""
    raw, rows_in = _take_profiles(P, np.asarray(scan), np.asarray(start), length, stride)
    vals = lut[raw] if lut is not None else raw.astype(np.float32)
    return vals, rows_in


def linearizing_lut(dtype: np.dtype, gamma: float) -> np.ndarray | None:
    """Look-up table undoing a camera response ``out = in ** (1 / gamma)``, in grey levels of ``dtype``.

    The area estimator needs grey levels proportional to light; None when ``gamma`` is 1. The table is
    made once per (dtype, gamma) and shared (read-only): a 16-bit one takes longer than a locate.
    """
    if gamma == 1.0:
        return None
    return _linearizing_lut(np.dtype(dtype) == np.uint8, float(gamma))


@functools.lru_cache(maxsize=16)
def _linearizing_lut(eight_bit: bool, gamma: float) -> np.ndarray:
    top = 255.0 if eight_bit else 65535.0
    x = np.arange(int(top) + 1, dtype=np.float64) / top
    lut = (x**gamma * top).astype(np.float32)
    lut.setflags(write=False)
    return lut


NO_LUT = np.zeros(0, np.float32)


def warm_up_planes(n: int) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(flat buffer, level table) of an ``n`` x ``n`` step image for the kernels' warm-ups: the argument
    types locate passes a plane kernel (8- and 16-bit levels, without and with a response table)."""
    img = np.zeros((n, n), np.uint8)
    img[:, n // 2 :] = 100
    for buf in (img.reshape(-1), img.astype(np.uint16).reshape(-1)):
        yield buf, NO_LUT
        table = np.arange(256 if buf.dtype == np.uint8 else 65536, dtype=np.float32)
        yield buf, table
        yield buf, read_only(table)  # the cached response tables locate passes are read-only


def median(x: np.ndarray) -> float:
    """``np.median`` of a 1-D float array, the same value bit for bit, without its generic machinery.

    The IRLS loops take two medians per iteration on a few hundred residuals, where ``np.median``'s
    dispatch costs more than the partition itself.
    """
    n = x.size
    k = n // 2
    # as np.median: partition at the middle element(s) and the last one (NaN check), mean of the middle
    p = np.partition(x, [k - 1, k, n - 1] if n % 2 == 0 and n > 1 else [k, n - 1])
    if np.isnan(p[-1]):
        return float("nan")
    return float(p[k]) if n % 2 else float((p[k - 1] + p[k]) / 2.0)


def median_with_error(x: np.ndarray) -> tuple[float, float]:
    """The median of a 1-D float array (:func:`median`) and its standard error from the values' spread:
    1.2533 (the median's efficiency against the mean) times 1.4826 times their median absolute deviation
    (a Gaussian's sigma), over the root of their count."""
    med = median(x)
    return med, 1.2533 * 1.4826 * median(np.abs(x - med)) / math.sqrt(x.size)


#: Cephes' erfc (S. L. Moshier's library, as in scipy.special): erfc(z) = exp(-z^2) P(z) / Q(z) for
#: 1 <= z < 8 and exp(-z^2) R(z) / S(z) beyond, the denominators' leading 1 implicit
_ERFC_P = (
    2.46196981473530512524e-10, 5.64189564831068821977e-1, 7.46321056442269912687e0,
    4.86371970985681366614e1, 1.96520832956077098242e2, 5.26445194995477358631e2,
    9.34528527171957607540e2, 1.02755188689515710272e3, 5.57535335369399327526e2,
)  # fmt: skip
_ERFC_Q = (
    1.32281951154744992508e1, 8.67072140885989742329e1, 3.54937778887819891062e2,
    9.75708501743205489753e2, 1.82390916687909736289e3, 2.24633760818710981792e3,
    1.65666309194161350182e3, 5.57535340817727675546e2,
)  # fmt: skip
_ERFC_R = (
    5.64189583547755073984e-1, 1.27536670759978104416e0, 5.01905042251180477414e0,
    6.16021097993053585195e0, 7.40974269950448939160e0, 2.97886665372100240670e0,
)  # fmt: skip
_ERFC_S = (
    2.26052863220117276590e0, 9.39603524938001434673e0, 1.20489539808096656605e1,
    1.70814450747565897222e1, 9.60896809063285878198e0, 3.36907645100081516050e0,
)  # fmt: skip


@kernel(inline=True)
def normal_cdf_pdf(u):
    """The standard normal CDF ``Phi(u)`` and density ``phi(u)``, with one exponential between them.

    The blurred-step models need both on every boundary near an edge; the C library's erfc computes its own
    ``exp(-z^2)`` (and more: 32 ns a call here against 9 ns for exp), so for ``|u| >= sqrt(2)`` the CDF is
    Cephes' rational form times the density's exponential (``z^2 = u^2 / 2``). Within ``|u| < 1`` it is
    scipy.special.ndtr's ``0.5 + 0.5 erf(u / sqrt(2))``, between them ``0.5 erfc`` of the C library, as
    before (23 ns for both, against 41). Against scipy's ndtr: within 2e-14 relative in the tails up to
    ``|u| = 10`` (the exponential's argument rounded once, not split as Cephes' expx2 does), an ulp or two
    elsewhere.
    """
    E = math.exp(-0.5 * u * u)
    phi = E * 0.3989422804014327  # 1 / sqrt(2 pi)
    x = u * 0.7071067811865476  # 1 / sqrt(2)
    z = abs(x)
    if z < 0.7071067811865476:
        return 0.5 + 0.5 * math.erf(x), phi
    if z < 1.0:
        y = 0.5 * math.erfc(z)
    else:
        num, den = _rational(z, _ERFC_P, _ERFC_Q) if z < 8.0 else _rational(z, _ERFC_R, _ERFC_S)
        y = 0.5 * E * num / den
    return (1.0 - y if x > 0 else y), phi


@kernel(inline=True)
def _rational(z, num, den):
    """The polynomials ``num(z)`` and ``den(z)``, their coefficients highest power first, ``den``'s leading
    1 implicit (Cephes' polevl / p1evl)."""
    p = num[0]
    for c in num[1:]:
        p = p * z + c
    q = z + den[0]
    for c in den[1:]:
        q = q * z + c
    return p, q

"""Does a door that its recipe calls sharp-edged show an arris strip? Asked of its plain edges.

A door whose recipe gives no arris (``arris_mm`` 0) has its edges read as plain steps. A chamfer or a
rounding that the recipe does not give lays a strip of its own shade between the hinge face and the
background, a few pixels to more than ten wide, and the area estimator puts the edge somewhere inside it:
of the arris bench's 120 arris doors located with ``arris_mm`` 0 (``bench/bench_arris_range.py
--recipe-arris-zero --seed 71100``, 2026-12-06) 40 were answered, 32 of them 0.1-1.1 mm off, 19 beyond 5
sigma. Where the strip's shade differs from both the face's and the background's it shows itself: the
edge's area estimate moves when its plateaus are read farther out (:func:`wide_reading_shift`), by the
strip's excess area. A plain step under any even point spread leaves it in place, whatever the camera's
response (both readings linearise alike and the stretches the wide one adds are flat), and so does a lens's
halo read at the camera's exponent. Texture along an edge moves it: wood grain runs along the door's height,
beside the long arrises (up to 2.7 px there on the surfaces bench's grain and thin doors), but across the
bottom end, whose scan lines each run along one stripe (0.29 px at most there over 336 sharp-edged doors
of the benches' sets, read at the camera's exponent). So the strip is asked of the bottom end and the
reference arris together (:func:`untold_arris_refusal`); a line's strip lit apart from the other's, or
anything else beside one edge alone (a shadow on the background, a fixture's edge), is not enough.

A strip whose shade equals the background's (or the face's) does not show: it looks like a plain step at
its other border, and only the door's thickness can tell (``thickness_mismatch``), by twice the arris's
size against the recipe's tolerance. A recipe must give the door's arrises.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.jit import grey, kernel, median_in_place
from doorloc.vision.quality import Refusal
from doorloc.vision.sampling import NO_LUT, linearizing_lut, oriented, pixel_buffer, warm_up_planes
from doorloc.vision.state import Refined

__all__ = [
    "UNTOLD_ARRIS_LINES",
    "UNTOLD_ARRIS_SIGMAS",
    "WIDE_PLATEAU_PX",
    "WIDE_READ_PX",
    "WideShift",
    "untold_arris_check",
    "untold_arris_refusal",
    "wide_reading_shift",
]

#: the wide reading's reach each side of the edge, px: a 3 mm arris's strip is about 14 px wide in the
#: thesis cell, and its plateaus then lie beyond it
WIDE_READ_PX = 20
#: pixels averaged at each end of the wide reading for its plateaus
WIDE_PLATEAU_PX = 4
#: scan lines read at most per line (evenly spread): a median of a few hundred is steady to a few
#: hundredths of a pixel, and the compiled pass costs about 0.01 ms a line
WIDE_MAX_LINES = 256
#: the lines asked, and how a person names them
UNTOLD_ARRIS_LINES = {"bottom": "the bottom end", "reference": "the reference arris"}
#: a shift counts where it is this many of its standard errors (from blocks of scan lines) as well
UNTOLD_ARRIS_SIGMAS = 5.0
_BLOCKS = 8


@dataclass(frozen=True)
class WideShift:
    """How far an edge's area estimate moves when its plateaus are read :data:`WIDE_READ_PX` out.

    Attributes
    ----------
    shift_px : float
        The median over the scan lines of the wide reading less the edge point, px, positive along the
        scan line's increasing coordinate.
    standard_error_px : float
        Its standard error from the medians of contiguous blocks of scan lines, px.
    n_lines : int
        Scan lines read.
    """

    shift_px: float
    standard_error_px: float
    n_lines: int

    @property
    def significant(self) -> bool:
        """Whether the shift stands out of its own scatter (:data:`UNTOLD_ARRIS_SIGMAS`)."""
        return abs(self.shift_px) >= UNTOLD_ARRIS_SIGMAS * self.standard_error_px


def wide_reading_shift(
    plane: np.ndarray, samples: EdgeSamples, lut: np.ndarray | None = None
) -> WideShift | None:
    """The shift of the edge points ``samples`` when each scan line's transition is read between plateaus
    :data:`WIDE_READ_PX` px out (module docstring); None with fewer than 32 scan lines whose wide window
    lies in the image and steps. Up to :data:`WIDE_MAX_LINES` scan lines, evenly spread, are read.

    ``plane`` holds grey levels, ``lut`` (one entry per level) turns them into linear light (None: the levels
    as they are). The area estimate of a profile normalised to 0 and 1 by its plateaus is the place that
    splits it into equal areas: a flat stretch added at either end leaves it where it was, a strip of
    another shade moves it by the strip's width times its shade's difference from the plateau beyond it.
    """
    P = oriented(plane, samples.axis)
    n = int(np.count_nonzero(samples.valid))
    shift, se, n_lines = _wide_shift(
        *pixel_buffer(P),
        P.shape[0],
        np.ascontiguousarray(samples.scan, np.int64),
        np.ascontiguousarray(samples.along, np.float64),
        np.ascontiguousarray(samples.valid, np.bool_),
        lut if lut is not None else NO_LUT,
        max(1, -(-n // WIDE_MAX_LINES)),
    )
    return WideShift(shift, se, n_lines) if n_lines >= 32 else None


def _wide_shift_warm_up(k) -> None:
    n = 40
    for buf, table in warm_up_planes(3 * WIDE_READ_PX):
        k(
            buf,
            1,
            3 * WIDE_READ_PX,
            3 * WIDE_READ_PX,
            np.arange(n),
            np.full(n, 29.6),
            np.ones(n, np.bool_),
            table,
            1,
        )


@kernel(_wide_shift_warm_up)
def _wide_shift(buf, pitch_along, pitch_scan, n_along, scan, along, valid, lut, every):
    """:func:`wide_reading_shift`'s figures, compiled: the median shift, its standard error from the medians
    of :data:`_BLOCKS` contiguous blocks of the scan lines, and the count of scan lines read (every
    ``every``-th valid one whose window lies in the image and steps, their count cut to a multiple of the
    blocks'). Written with numpy the same took about 0.2 ms a line, most of it the calls' own cost.

    Why not the area estimator itself (:func:`doorloc.vision.edges.subpixel_edges` with a window of
    ``WIDE_READ_PX - WIDE_PLATEAU_PX`` and plateaus of ``WIDE_PLATEAU_PX``, then the medians in numpy): it
    reads the same moves to about 0.01 px (the trapezoid here, its rectangle sum there; two doors of 128 at
    ``bench_arris_range.py --recipe-arris-zero --seed 71100``, near the limit, fell the other side) but
    took 0.14 ms a realistic frame against this pass's 0.02 (2026-12-06; the Python around its kernel and
    the medians), on every frame of a door without an arris."""
    # why many parameters: a numba nopython kernel over the plane's flat buffer takes arrays and scalars only
    length = 2 * WIDE_READ_PX + 1
    inner = length - 2 * WIDE_PLATEAU_PX
    shifts = np.empty(scan.size)
    m = 0
    seen = 0
    for i in range(scan.size):
        if not (valid[i] and np.isfinite(along[i])):
            continue
        seen += 1
        if (seen - 1) % every:
            continue
        c0 = int(np.rint(along[i]))
        start = c0 - WIDE_READ_PX
        if start < 0 or start + length > n_along:
            continue
        base = scan[i] * pitch_scan
        lo = 0.0
        hi = 0.0
        for j in range(WIDE_PLATEAU_PX):
            lo += grey(lut, buf[(start + j) * pitch_along + base])
            hi += grey(lut, buf[(start + length - 1 - j) * pitch_along + base])
        lo /= WIDE_PLATEAU_PX
        hi /= WIDE_PLATEAU_PX
        if not abs(hi - lo) > 1e-6 * max(abs(hi), abs(lo)):
            continue  # (a scan line that does not step between its plateaus has no edge to place)
        # the trapezoid area of the inner pixels normalised by the plateaus, (v - lo) / (hi - lo); the place
        # from the first inner pixel's centre is their count less one, less that area
        total = 0.0
        for j in range(inner):
            total += grey(lut, buf[(start + WIDE_PLATEAU_PX + j) * pitch_along + base])
        first = grey(lut, buf[(start + WIDE_PLATEAU_PX) * pitch_along + base])
        last = grey(lut, buf[(start + WIDE_PLATEAU_PX + inner - 1) * pitch_along + base])
        area = (total - 0.5 * (first + last) - (inner - 1) * lo) / (hi - lo)
        shifts[m] = (start + WIDE_PLATEAU_PX + inner - 1 - area) - along[i]
        m += 1
    m = m // _BLOCKS * _BLOCKS
    if m < 2 * _BLOCKS:
        return np.nan, np.nan, m
    size = m // _BLOCKS
    blocks = np.empty(_BLOCKS)
    for b in range(_BLOCKS):
        blocks[b] = median_in_place(shifts[b * size : (b + 1) * size].copy())
    spread = 0.0
    mean = blocks.mean()
    for b in range(_BLOCKS):
        spread += (blocks[b] - mean) ** 2
    se = np.sqrt(spread / (_BLOCKS - 1)) / np.sqrt(_BLOCKS)
    return median_in_place(shifts[:m].copy()), se, m


def untold_arris_refusal(
    plane: np.ndarray,
    samples: dict[str, EdgeSamples],
    lut: np.ndarray | None,
    scale_mm_per_px: float,
    limit_px: float,
) -> tuple[Refusal | None, dict[str, float]]:
    """``arris_mismatch`` where the bottom end and the reference arris both move by ``limit_px`` or more
    (and :data:`UNTOLD_ARRIS_SIGMAS` standard errors) when read wide (:func:`wide_reading_shift`), and each
    line's shift, px, for the diagnostics. Only for a door whose recipe gives no arris, whose lines were
    read as plain steps (``samples``: the final edge points); ``limit_px`` 0 asks nothing."""
    if limit_px <= 0:
        return None, {}
    shifts = {k: wide_reading_shift(plane, samples[k], lut) for k in UNTOLD_ARRIS_LINES}
    seen = {k: round(s.shift_px, 3) for k, s in shifts.items() if s is not None}
    if not all(s is not None and s.significant and abs(s.shift_px) >= limit_px for s in shifts.values()):
        return None, seen
    moved = "; ".join(
        f"{UNTOLD_ARRIS_LINES[k]} by {abs(px):.1f} px, {abs(px) * scale_mm_per_px:.2f} mm"
        for k, px in seen.items()
    )
    return (
        Refusal(
            "arris_mismatch",
            f"the door's edges are not the sharp steps its recipe gives (arris_mm 0): read with their "
            f"plateaus {WIDE_READ_PX} px out they move ({moved}), as the strip of a chamfered or "
            "rounded arris beside them makes; if the door's arrises are chamfered or rounded, give "
            "their size and profile in the recipe (arris_mm, arris_profile); else look for paint, tape "
            "or a shadow along the door's edges",
        ),
        seen,
    )


def untold_arris_check(
    plane: np.ndarray, refined: Refined, door: DoorSize, cell: Cell, cfg: LocateConfig, diagnostics: dict
) -> Refusal | None:
    """The gate's question (:func:`untold_arris_refusal`) for a door whose recipe gives no arris, asked of the
    refined edge points in the light of the cell's exponent as used (``cell``, the image's where it replaced
    the cell's); each line's shift into ``diagnostics["plain_edge_wide_shift_px"]``. A strip the recipe does
    not give explains broken lines and a wrong thickness too: the gate says it first."""
    if door.arris_mm > 0:
        return None
    lut = linearizing_lut(plane.dtype, cell.response_gamma)
    refusal, diagnostics["plain_edge_wide_shift_px"] = untold_arris_refusal(
        plane, refined.samples, lut, refined.pose.scale_mm_per_px, cfg.untold_arris_shift_px
    )
    return refusal

"""Which edges the refine stage's final pass reads by the blurred-step fit, and with what blur
(:class:`doorloc.vision.edge_models.StepFit`): from the first pass's transition widths, checked where noise
may have widened them against the step's own blur on the lines whose pixel phase hardly changes along them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence

import numpy as np

from doorloc.vision.blurred_step import STEP_FIT_MIN_BLUR_PX
from doorloc.vision.config import LocateConfig
from doorloc.vision.edge_models import FACE_SLOPE_LINES
from doorloc.vision.edge_samples import EdgeSamples
from doorloc.vision.lines import fit_image_line
from doorloc.vision.transition import narrowest_blur

__all__ = ["STEP_FIT_PHASE_SWEEP_PX", "phase_sweep_px", "phase_swept", "step_fit_lines"]

#: under the fit's least blur (``STEP_FIT_MIN_BLUR_PX``, read on the step itself), how far along a line its
#: pixel phases must sweep (px) for the step fits to read it with the blur the widths gave
#: (:func:`phase_swept`). Noise widens the transitions that blur comes from: a sharp (0.24 px), faint (a
#: step of 36 grey levels) door read 0.32-0.37 px of optical blur without noise, 0.46-0.69 with 2 grey
#: levels of it (six draws), and was step-fitted with that blur in three; the step model's shape then
#: follows the pixel's phase, and on a nearly square line its points drift along it: the yaw 0.011 deg off
#: at 5.3 sigma. That door at 8 yaws from 0.03 to 0.7 deg, each at 3 phases and 3 noise draws (9 answers a
#: yaw, step-fitted): the yaw's worst |error| / sigma 1.8, 3.7, 0.7, 1.7, 0.9, 1.1, 0.9, 0.8 (0.03 deg: the
#: line at nearly one phase, its bias an offset; 0.06-0.15 deg: its reference arris sweeps 0.8-2 px);
#: slanted, the fit's reading is the more precise under grain (the hard surfaces set, seed 63002: z RMS
#: 0.0040 mm step-fitted, 0.0079 with the fit turned off wherever the step's own blur is under 0.5 px)
STEP_FIT_PHASE_SWEEP_PX = 3.0


def step_fit_lines(
    cfg: LocateConfig,
    bottom_reference: Sequence[float],
    samples: dict[str, EdgeSamples],
    step_blur: Callable[[], float],
) -> tuple[dict[str, float], float]:
    """The lines the final pass refines by the blurred-step fit, with the optical blur (px) it uses, and
    that blur alone (NaN where none is), from which the final pass reads a long arris under strong texture
    with its face sloped (:func:`_step_fit_blur`).

    The blur is the same on every edge; an edge whose transition looks wider than the narrowest carries a
    second structure (an end face seen nearly edge-on, a strip) that the step model lacks, while the area
    estimator is exact whatever the shape: only edges within 25 % of the narrowest width are fitted, with
    that width's blur. Below ``STEP_FIT_MIN_BLUR_PX`` none is: the area estimator is exact there and its
    window small (little texture in it), while the step model's shape depends on the pixel phase. Where a
    line to be fitted sweeps few phases, ``step_blur()`` (the step's own blur, px, which noise does not
    widen; NaN: not read) is asked, and under that least the line keeps its area estimate
    (:func:`phase_swept`).
    """
    widths = dict(zip(("bottom", "reference"), bottom_reference, strict=True))
    optical = _step_fit_blur(cfg, widths.values())
    if not math.isfinite(optical):
        return {}, optical
    narrow = min(w for w in widths.values() if math.isfinite(w))
    fitted = {k: optical for k, w in widths.items() if math.isfinite(w) and w <= 1.25 * narrow}
    swept, swept_sloped = phase_swept(fitted, optical, samples)
    if (swept != fitted or math.isnan(swept_sloped)) and step_blur() < STEP_FIT_MIN_BLUR_PX:
        return swept, swept_sloped
    return fitted, optical


def phase_swept(
    step_fit: dict[str, float], face_slope_blur: float, samples: dict[str, EdgeSamples]
) -> tuple[dict[str, float], float]:
    """The step fits (``step_fit``, and the sloped one on ``FACE_SLOPE_LINES`` from ``face_slope_blur``)
    kept on the lines whose pixel phases sweep at least ``STEP_FIT_PHASE_SWEEP_PX`` along them
    (:func:`phase_sweep_px` on the first pass's points ``samples``): a fit given too large a blur reads with
    a bias that follows the pixel's phase, which averages out along a line that sweeps many phases and tilts
    one that sweeps about one. The sloped fit stays only where every line it reads sweeps that far."""
    swept = {k for k, s in samples.items() if phase_sweep_px(s) >= STEP_FIT_PHASE_SWEEP_PX}
    kept = {k: b for k, b in step_fit.items() if k in swept}
    sloped = face_slope_blur if all(k in swept for k in FACE_SLOPE_LINES if k in samples) else float("nan")
    return kept, sloped


def phase_sweep_px(samples: EdgeSamples) -> float:
    """How far (px, across the edge) a line's points move over its length: its slope against the scan
    lines times the scan lines it spans (0 with fewer than 3 points)."""
    ok = samples.valid & np.isfinite(samples.along)
    if np.count_nonzero(ok) < 3:
        return 0.0
    scan = samples.scan[ok]
    return abs(fit_image_line(scan, samples.along[ok]).b) * float(scan.max() - scan.min())


def _step_fit_blur(cfg: LocateConfig, widths: Iterable[float]) -> float:
    """The optical blur (px) the blurred-step fits use, from the narrowest of the first pass's transition
    ``widths`` (the pixel's share taken out); NaN where they are off (``locate.step_fit``), none is finite
    or the blur is below ``STEP_FIT_MIN_BLUR_PX``. The fit with the face sloped (texture along an edge)
    searches its blur from it on the long arrises: a flank of grain beside an edge widens that edge's
    transition, so its own width would not do."""
    if not cfg.step_fit:
        return float("nan")
    optical = narrowest_blur(widths)
    return optical if optical >= STEP_FIT_MIN_BLUR_PX else float("nan")

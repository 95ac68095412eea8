"""Edge models behind one protocol: each kind of edge is read by the model its kind names."""

from __future__ import annotations

import numpy as np
import pytest

from doorloc.vision.edge_models import EDGE_MODELS, EdgeReading, ScanWindow, edge_kind, step_fit_witness
from doorloc.vision.region import Track


def test_the_kind_of_an_edge_names_its_model(pass_settings):
    scan, centre = np.arange(10), np.full(10, 50.0)
    plain = Track(scan, centre)
    band = Track(scan, centre, band_px=np.full(10, 3.0))
    beside = Track(scan, centre, beside_far_face=True, band_px=np.full(10, 3.0))
    strip = Track(scan, centre, band_px=np.full(10, 3.0), outline_shift_px=np.full(10, 0.5))
    assert edge_kind("bottom", plain, pass_settings()) == "plain"
    assert edge_kind("bottom", plain, pass_settings(step_blur_px={"bottom": 0.8})) == "step_fit"
    assert edge_kind("reference", plain, pass_settings(step_blur_px={"bottom": 0.8})) == "plain"
    assert edge_kind("far", beside, pass_settings()) == "far_face"
    assert edge_kind("far", band, pass_settings()) == "banded"
    assert edge_kind("reference", strip, pass_settings()) == "banded"  # no geometry: the band is not modelled
    assert edge_kind("reference", strip, pass_settings(arris={"reference": object()})) == "arris_strip"
    assert set(EDGE_MODELS) == {"plain", "step_fit", "banded", "arris_strip", "far_face"}


@pytest.mark.parametrize("edge", [40.3, 40.5, 40.77])
def test_the_plain_model_reads_a_step_where_it_is(edge, pass_settings):
    # a box-filtered step along columns: rows above ``edge`` dark, below bright, the pixel across it mixed
    rows = np.arange(100, dtype=float)[:, None]
    img = (40 + 160 * np.clip(rows + 0.5 - edge, 0.0, 1.0)) * np.ones((1, 60))
    plane = np.round(img).astype(np.uint8)
    window = ScanWindow(plane, "col", np.arange(10, 50), np.full(40, 40.0), 4, 3, 1.0, None, 0, 1)
    reading = EDGE_MODELS["plain"].read(window, "bottom", Track(window.scan, window.centre), pass_settings())
    assert isinstance(reading, EdgeReading) and reading.far_fit is None and reading.strip is None
    # rounding to grey levels moves it by at most half a level of the 160-level step
    assert np.allclose(reading.samples.along, edge, atol=0.5 / 160 + 1e-9)


def _slanted_sharp_step(grain_dn: float) -> tuple[np.ndarray, np.ndarray]:
    """A box-filtered step along columns whose edge slants 0.05 px per column (so its points sweep the
    pixel's phases), 40 -> 200 grey levels, with a stripe ``grain_dn`` darker over the first three bright
    rows beyond it (wood grain at the edge); the plane (16 bit, to keep the stripe's fractions) and each
    column's true edge."""
    rows = np.arange(100, dtype=float)[:, None]
    edge = 40.3 + 0.05 * np.arange(60)[None, :]
    bright = np.clip(rows + 0.5 - edge, 0.0, 1.0)
    stripe = np.clip(rows + 0.5 - edge, 0.0, 1.0) - np.clip(rows - 2.5 - edge, 0.0, 1.0)
    img = 40 + 160 * bright - grain_dn * stripe
    return np.round(img * 256).astype(np.uint16), edge[0]


@pytest.mark.parametrize("grain_dn", [0.0, 30.0])
def test_the_step_fit_witness_reads_grain_at_a_sharp_edge(grain_dn, pass_settings):
    """The area estimator takes the face's level a few pixels out, the witness right beside the
    transition: a clean sharp step reads the two readers together, a dark stripe at the edge apart by
    a good part of the stripe's share of the step (the area estimator moved towards the face)."""
    plane, edge = _slanted_sharp_step(grain_dn)
    cols = np.arange(5, 55)
    window = ScanWindow(plane, "col", cols, np.full(cols.size, 42.0), 4, 3, 1.0 / 256, None, 0, 1)
    area = EDGE_MODELS["plain"].read(window, "bottom", Track(cols, window.centre), pass_settings()).samples
    apart = step_fit_witness(plane, area, 4, None)
    assert apart is not None
    if grain_dn == 0.0:
        assert np.allclose(area.along, edge[cols], atol=0.01)
        assert abs(apart.shift_px) < 0.03
    else:
        moved = float(np.median(area.along - edge[cols]))
        assert moved > 0.3  # (the stripe, 30 of 160 levels over three pixels, reads as face further out)
        assert apart.shift_px < -0.5 * moved

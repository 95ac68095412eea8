"""Edge models behind one protocol: each kind of edge is read by the model its kind names."""

from __future__ import annotations

import numpy as np
import pytest

from doorloc.vision.edge_models import EDGE_MODELS, EdgeReading, ScanWindow, edge_kind
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

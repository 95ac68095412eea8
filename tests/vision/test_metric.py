"""PlaneMap (pixels <-> hinge-face plane) agrees with the shared camera model, distortion included."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from doorloc.calib.camera import CameraModel, Extrinsics, PosedCamera
from doorloc.vision.metric import PlaneMap


@settings(max_examples=30, deadline=None)
@given(
    st.floats(-0.2, 0.1),
    st.floats(-0.05, 0.05),
    st.floats(-0.002, 0.002),
    st.floats(-80, 80),
    st.floats(-60, 60),
    st.floats(-30, 30),
)
def test_planemap_matches_posed_camera(k1, k2, p1, x, z, depth):
    cam = CameraModel.from_values(
        [[1678.35, 0, 946.41], [0, 1727.22, 510.71], [0, 0, 1]], [k1, k2, p1, -p1, 0.0], (1920, 1080)
    )
    posed = PosedCamera(cam, Extrinsics([math.pi / 2 + 0.01, 0.02, -0.01], [-30.0, 40.0, 350.0]))
    pm = PlaneMap(posed, depth)
    uv = pm.to_image(np.array([[x, z]]))
    ref_uv = posed.project_cell(np.array([[x, depth, z]]))
    assert np.allclose(uv, ref_uv, atol=1e-9)
    back = pm.to_plane(uv)
    ref_back = posed.intersect_plane_y(ref_uv, depth)[:, [0, 2]]
    assert np.allclose(back, ref_back, atol=1e-7)
    assert np.allclose(back, [[x, z]], atol=1e-6)
    assert math.isclose(
        pm.scale_mm_per_px(np.array([x, z])),
        posed.scale_mm_per_px(np.array([x, depth, z]), depth),
        rel_tol=1e-9,
    )

"""Hypothesis strategies for millable hinges (imported by the recipe tests)."""

from __future__ import annotations

from hypothesis import strategies as st

from doorloc.recipes.models import DoorRecipe, Hinge, PointCorrection


@st.composite
def tool_and_hinge(draw, path_points=None):
    """``(tool_diameter_mm, Hinge)`` that pass every recipe rule on a 60 mm x 2100 mm door."""
    d = draw(st.floats(6.0, 25.0))
    n = path_points or draw(st.sampled_from([6, 9]))
    # a 6-point path may overcut a corner arc by at most 0.5 mm: r - d/2 <= 0.5 / (sqrt 2 - 1)
    r = draw(st.floats(d / 2, d if n == 9 else d / 2 + 1.2))
    w = draw(st.floats(2 * r, min(2 * d, 55.0)))
    length = draw(st.floats(max(2 * r, w), 300.0))
    x = draw(st.floats(0.0, 60.0 - w))
    z = draw(st.floats(0.0, 1500.0))
    corr = draw(
        st.one_of(
            st.just(()),
            st.lists(
                st.builds(
                    PointCorrection,
                    dx_mm=st.floats(-0.5, 0.5),
                    dy_mm=st.floats(-0.5, 0.5),
                    dz_mm=st.floats(-0.5, 0.5),
                ),
                min_size=n,
                max_size=n,
            ),
        )
    )
    depth = draw(st.floats(0.5, 20.0))
    return d, Hinge(
        z_mm=z,
        length_mm=length,
        width_mm=w,
        x_mm=x,
        depth_mm=depth,
        corner_radius_mm=r,
        path_points=n,
        corrections=tuple(corr),
    )


@st.composite
def recipes(draw):
    d, h = draw(tool_and_hinge())
    width = draw(st.floats(190.0, 1350.0))
    return DoorRecipe(
        door_id="P-1",
        width_mm=width,
        height_mm=2100,
        thickness_mm=60,
        hinges=[h],
        tool_diameter_mm=d,
        spindle_rpm=18000,
        feed_mm_s=25,
    )

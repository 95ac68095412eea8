"""The lines' disagreement about the door's direction, against their doubts (direction_vote.direction_spread)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from doorloc.vision.direction_vote import birge_widening

_lines = st.lists(st.tuples(st.floats(-1e-2, 1e-2), st.floats(1e-10, 1e-4)), min_size=2, max_size=3).map(
    lambda v: {f"line{i}": x for i, x in enumerate(v)}
)


@given(_lines)
def test_widened_doubts_hold_the_lines_disagreement(lines):
    """Each variance grows by the Birge ratio where it exceeds 1, so that the lines agree within their
    widened doubts (the ratio recomputed is 1); where they agree already nothing is added."""
    departures = {k: d for k, (d, _) in lines.items()}
    variances = {k: v for k, (_, v) in lines.items()}
    ratio2, add = birge_widening(departures, variances)
    widened = {k: variances[k] + add[k] ** 2 for k in variances}
    again, more = birge_widening(departures, widened)
    if ratio2 > 1.0:
        assert math.isclose(again, 1.0, rel_tol=1e-9)
        for k in variances:
            assert math.isclose(widened[k], ratio2 * variances[k], rel_tol=1e-9)
    else:
        assert all(a == 0.0 for a in add.values())
        assert again == ratio2
    # (the ratio recomputed is 1 to rounding, and what its square root adds is as small)
    assert all(m <= 1e-6 * math.sqrt(widened[k]) for k, m in more.items())


def test_a_line_that_disagrees_by_three_of_its_sigmas_widens_every_line():
    ratio2, add = birge_widening({"reference": 3e-3, "far": 0.0}, {"reference": 1e-6, "far": 1e-6})
    assert math.isclose(ratio2, 9.0)
    assert math.isclose(add["reference"], math.sqrt(8.0) * 1e-3) and math.isclose(
        add["far"], add["reference"]
    )

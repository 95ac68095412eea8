"""Golden text files with numbers in them (RAPID modules and target files), compared by value.

The text around the numbers must be identical; each number must lie within GOLDEN_REL (relative) or
GOLDEN_ABS (absolute) of the golden one, so that a last-digit change of a single-precision number (a
different numpy or libm rounding) is not a failure, while a target moved by a micrometre is.
"""

from __future__ import annotations

import re

import pytest

#: a number as RAPID files print them: 22.64532, -10, 9E+09
RAPID_NUMBER = re.compile(r"[-+]?\d+(?:\.\d*)?(?:[Ee][-+]?\d+)?")
#: far below anything a robot or a milled pocket can show (mm, and unit quaternion components)
GOLDEN_REL, GOLDEN_ABS = 2e-6, 1e-5


def assert_same_values(expected: str, produced: str, name: str) -> None:
    """Same lines, same text around the numbers, every number within the tolerances of the golden one."""
    exp_lines, got_lines = expected.splitlines(), produced.splitlines()
    assert len(got_lines) == len(exp_lines), f"{name}: {len(got_lines)} lines, golden has {len(exp_lines)}"
    for k, (e, g) in enumerate(zip(exp_lines, got_lines, strict=True), start=1):
        assert RAPID_NUMBER.sub("#", e) == RAPID_NUMBER.sub("#", g), f"{name} line {k}: {g!r} != {e!r}"
        ev = [float(v) for v in RAPID_NUMBER.findall(e)]
        gv = [float(v) for v in RAPID_NUMBER.findall(g)]
        assert gv == pytest.approx(ev, rel=GOLDEN_REL, abs=GOLDEN_ABS), f"{name} line {k}: {g!r} != {e!r}"

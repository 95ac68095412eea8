"""The model-check benchmark's bookkeeping: a data set the model check refuses is reported, not a crash.

The render and the check are stand-ins (the bench takes them as arguments), so this runs in a moment;
the real renders and checks are the bench's own business.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from doorloc.cell import load_cell
from doorloc.modelcheck import DatasetError

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("bench_modelcheck", ROOT / "bench" / "bench_modelcheck.py")
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

CELL = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
REFUSAL = (
    "locate answered on only 0 of 40 images with this cell (refused: overexposed 40; overexposed: the hinge "
    "face is overexposed): 40 of 40 images cannot be measured as taken, whatever the cell; retake the data set"
)


def _render(out, nominal, hidden, spec, arris_profile="chamfer"):
    Path(out).mkdir(parents=True, exist_ok=True)
    return Path(out) / "truth.csv"


def _refusing_check(data, nominal, out):
    raise DatasetError(REFUSAL)


def _case(k: int, kind: str, hidden: dict) -> dict:
    return {"case": k, "seed": 2026000 + k, "kind": kind, "hidden": hidden, "profile": "chamfer"}


def test_a_refused_control_is_reported_apart_and_is_no_false_alarm(tmp_path):
    case = _case(8, "control", {})
    case.update(bench.run_case(case, CELL, tmp_path, 40, render=_render, check=_refusing_check))
    assert case["checkable"] is False
    assert case["not_checkable"] == REFUSAL
    line = bench.case_line(case)
    assert "seed 2026008" in line and "NOT CHECKABLE" in line and "overexposed" in line
    # a control that answered nothing beside it: one checkable control, no false alarm
    quiet = {**_case(7, "control", {}), "checkable": True, "named": [], "right": True}
    quiet.update(gain=float("nan"), beyond_prior={}, unflagged=[], check_s=1.0)
    lines = bench.summary([quiet, case])
    assert "false alarms: 0/1 checkable controls" in lines
    assert "not checkable (the model check refused the data): 1" in lines
    assert any("control case 8 seed 2026008" in ln and "overexposed" in ln for ln in lines)


def test_a_refused_single_counts_as_not_named_right_and_no_gain(tmp_path):
    case = _case(3, "single", {"camera_roll": [0.1]})
    case.update(bench.run_case(case, CELL, tmp_path, 40, render=_render, check=_refusing_check))
    named = {**_case(4, "single", {"camera_roll": [0.3]}), "checkable": True, "named": ["camera_roll"]}
    named.update(right=True, gain=40.0, beyond_prior={}, unflagged=[], check_s=1.0)
    lines = bench.summary([named, case])
    assert "singles named right: 1/2 = 50 %" in lines
    assert any(ln.startswith("median verified held-out gain: 20.0x") for ln in lines)


def test_any_other_failure_of_the_check_still_stops_the_bench(tmp_path):
    # only the model check's own refusal of the data is an outcome; a bug is not
    def broken(data, nominal, out):
        raise KeyError("plausibility")

    with pytest.raises(KeyError):
        bench.run_case(_case(0, "control", {}), CELL, tmp_path, 40, render=_render, check=broken)


def _arris_report(out: Path, variant: str):
    """A stand-in report that names a 0.3 mm arris of ``variant`` and passes its verification."""
    from types import SimpleNamespace

    return SimpleNamespace(
        causes=["arris"],
        plausibility={"arris": {"sigmas_from_cell": 0.2, "variant": variant}},
        heldout_gain=20.0,
        verdict={"status": "extend"},
        extended_cell="cell_extended.yaml",
        heldout_refused_after=[],
        heldout_rms_before={},
        heldout_rms_after={},
    )


@pytest.mark.parametrize(("answered", "right"), [("round", True), ("chamfer", False)])
def test_an_arris_is_named_right_only_with_its_profile(tmp_path, answered, right):
    # a hidden rounded 0.32 mm arris answered as a 0.22 mm chamfer was counted right on its name alone
    case = {**_case(0, "single", {"arris": [0.32]}), "profile": "round"}
    out = bench.run_case(
        case, CELL, tmp_path, 40, render=_render, check=lambda d, n, o: _arris_report(o, answered)
    )
    assert out["arris_profile"] == answered and out["right"] is right
    assert f"['arris'] {answered} {'OK' if right else 'WRONG'}" in bench.case_line({**case, **out})

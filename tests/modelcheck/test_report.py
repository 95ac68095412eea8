"""report.md and the verdict: a verdict and an action first, in plain words, every figure explained."""

from __future__ import annotations

from doorloc.modelcheck.check import ModelCheckReport
from doorloc.modelcheck.report import report_markdown
from doorloc.modelcheck.verdict import verdict_of


def _report(**kw) -> ModelCheckReport:
    base = dict(
        dataset="data",
        cell="cell.yaml",
        causes=["camera_roll"],
        parameters={"camera_roll": {"roll_deg": {"value": 0.2, "sigma": 0.001}}},
        heldout_rms_before={
            "x_mm": 0.05,
            "z_mm": 0.04,
            "yaw_deg": 0.00113,
            "thickness_mm": 0.01,
            "lever_mm": 0.2,
        },
        heldout_rms_after={
            "x_mm": 0.002,
            "z_mm": 0.002,
            "yaw_deg": 0.00151,
            "thickness_mm": 0.01,
            "lever_mm": 0.02,
        },
        heldout_gain=10.0,
        heldout_images=[f"h{k}.png" for k in range(12)],
        train_images=[f"t{k}.png" for k in range(28)],
        extended_cell="cell_extended.yaml",
        alternatives=[],
        indistinguishable={},
        noise={"x_mm": 0.003, "z_mm": 0.003, "yaw_deg": 0.001, "thickness_mm": 0.01},
        selection_steps=[
            {"step": 1, "candidate": "camera_roll", "cv_ratio": 0.01, "f_test_p": 1.6e-71, "accepted": True}
        ],
        unexplained_test={
            "structured": False,
            "f_test_p": 2.8e-10,
            "cv_ratio": 0.9,
            "share_of_original": 0.001,
        },
        refused=[],
        elapsed_s=1.0,
        plausibility={
            "camera_roll": {
                "prior_sigma": {"roll_deg": 0.1},
                "prior_source": "default",
                "sigmas_from_cell": 2.0,
                "implausible": False,
            }
        },
        considered=[
            {
                "cause": "camera_roll",
                "variant": "",
                "cv_ratio": 0.01,
                "prior_chi2": 4.0,
                "score": 10.0,
                "values": {"roll_deg": 0.2},
                "cv_rms_weighted": 1.0,
            },
            {
                "cause": "focal_length",
                "variant": "",
                "cv_ratio": 0.5,
                "prior_chi2": 400.0,
                "score": 900.0,
                "values": {"focal_pct": 0.7},
                "cv_rms_weighted": 5.0,
            },
        ],
        priors={
            "camera_roll": {"sigma": [0.1], "source": "default"},
            "focal_length": {"sigma": [0.05], "source": "default"},
        },
    )
    base.update(kw)
    return ModelCheckReport(**base)


def test_report_leads_with_verdict_and_action_and_explains_its_figures():
    md = report_markdown(_report())
    head = md.split("\n## ")[0]
    assert "**Verdict.**" in head and "**Action.**" in head
    assert "turned +0.200 deg about its optical axis" in head
    assert "cell_extended.yaml" in head
    assert "1 m up the door" in md and "lever_mm" in md  # lever explained where it is shown
    # a component that got worse is commented, not left under the gain silently
    yaw_row = next(line for line in md.splitlines() if line.startswith("| yaw_deg"))
    assert "worse" in yaw_row and "noise" in yaw_row
    # the two p-values answer opposite questions, and the report says so
    assert "small = real" in md and "small p means *something is left*" in md
    # the runner-up's physical meaning
    assert "Runner-up `focal_length`" in md and "focal length is +0.700 % off" in md


def test_verdicts_in_plain_words():
    assert verdict_of(_report(causes=[], parameters={}, plausibility={})).status == "fits"
    assert verdict_of(_report()).status == "extend"
    flagged = _report(
        plausibility={
            "camera_roll": {
                "prior_sigma": {"roll_deg": 0.01},
                "prior_source": "default",
                "sigmas_from_cell": 20.0,
                "implausible": True,
            }
        }
    )
    v = verdict_of(flagged)
    assert v.status == "recalibrate" and "20 sigma" in v.headline
    refused = verdict_of(
        _report(heldout_refused_after=["h1.png"], heldout_refusal_reasons=["uncertain: too doubtful"])
    )
    assert refused.status == "not_verified" and "uncertain" in refused.headline
    assert "Do not use" in refused.action
    assert verdict_of(_report(causes=["unexplained"], parameters={}, plausibility={})).status == "unexplained"


def test_a_grey_level_value_located_again_is_reported_with_its_error_before_and_after():
    steps = [
        {"value": 1.5839, "sse": 25.95, "grid_values": 8},
        {"value": 1.5587, "sse": 4.064, "grid_values": 9},
    ]
    md = report_markdown(_report(grey_levels_refined={"response_gamma": steps}))
    assert "`response_gamma` located again at its own best value" in md
    assert "1.584 (weighted SSE 25.95) -> 1.559 (4.064)" in md
    assert "located again at its own best value" not in report_markdown(_report())

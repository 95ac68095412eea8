"""The thesis's worked examples for `check-model` (docs/benchmarks.md, "Model check"), one command each.

    PYTHONPATH=src python bench/modelcheck_examples.py pixel-aspect
    PYTHONPATH=src python bench/modelcheck_examples.py distortion
    PYTHONPATH=src python bench/modelcheck_examples.py shop-floor

- ``pixel-aspect``: the world has the thesis's camera (fx = 1678.35, fy = 1727.22); the cell given to
  check-model is the thesis's own model, one scale factor for both axes (fx = fy = their mean). check-model
  should name ``pixel_aspect`` and the fitted fy/fx should be the thesis's.
- ``distortion``: the thesis's distortion coefficients [0.0206, 10.4073, -115.4536] (k1 k2 k3) put in the
  cell, a lens without distortion in the world: where that polynomial stops being physical (the radius
  where its radial map folds over, :func:`doorloc.calib.camera.distortion_validity`) and what check-model
  makes of the poses.
- ``shop-floor``: the effects doorloc's renderer models on a real shop floor (wood grain, arris, a
  non-linear camera response), one data set each: which check-model names from poses alone.

Each writes its data sets and reports under ``--out`` (default: a temporary folder) and prints the figures.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from doorloc.calib.camera import CameraModel, distortion_validity
from doorloc.cell import Cell, load_cell
from doorloc.modelcheck import DatasetError, check_model
from doorloc.modelcheck.synth import MEASURED_PHOTOMETRY, SetSpec, render_measured_set

REPO = Path(__file__).resolve().parents[1]
THESIS_DIST = [0.0206, 10.4073, 0.0, 0.0, -115.4536]


def _summary(rep) -> str:
    b, a = rep.heldout_rms_before, rep.heldout_rms_after
    return (
        f"causes {rep.causes}; parameters {json.dumps(rep.parameters)}\n"
        f"  held-out RMS x {b['x_mm']:.4f} -> {a['x_mm']:.4f} mm, z {b['z_mm']:.4f} -> {a['z_mm']:.4f} mm, "
        f"yaw {b['yaw_deg']:.5f} -> {a['yaw_deg']:.5f} deg, thickness {b['thickness_mm']:.4f} -> "
        f"{a['thickness_mm']:.4f} mm; gain {rep.heldout_gain:.1f}x; alternatives "
        f"{[(x['cause'], round(x['cv_rms_weighted'], 2)) for x in rep.alternatives]}"
    )


def _with_camera(cell: Cell, K=None, dist=None) -> Cell:
    c = cell.camera
    return replace(
        cell,
        camera=CameraModel(
            c.camera_matrix if K is None else np.asarray(K, float),
            c.dist_coeffs if dist is None else np.asarray(dist, float),
            c.image_size,
        ),
    )


def pixel_aspect(out: Path, thesis: Cell) -> None:
    fx, fy = thesis.camera.fx, thesis.camera.fy
    f = (fx + fy) / 2
    K1 = thesis.camera.camera_matrix.copy()
    K1[0, 0] = K1[1, 1] = f
    one_scale = _with_camera(thesis, K=K1)
    # the world: the thesis's calibrated camera, i.e. the one-scale model with the aspect it lacks
    aspect_pct = 200 * (fy - fx) / (fx + fy)
    render_measured_set(out / "data", one_scale, {"pixel_aspect": [aspect_pct]}, SetSpec(seed=7))
    rep = check_model(out / "data", one_scale, out / "report")
    fitted = rep.parameters.get("pixel_aspect", {}).get(
        "aspect_pct", {"value": float("nan"), "sigma": float("nan")}
    )
    a = fitted["value"]
    print(f"true fx {fx}, fy {fy} (fy/fx {fy / fx:.5f}); cell given: fx = fy = {f:.2f}")
    print(f"fitted aspect {a:.4f} +- {fitted['sigma']:.4f} % -> fy/fx {(1 + a / 200) / (1 - a / 200):.5f}")
    print(_summary(rep))


def distortion(out: Path, thesis: Cell) -> None:
    cam = _with_camera(thesis, dist=THESIS_DIST).camera
    v = distortion_validity(cam)
    print(f"thesis distortion {THESIS_DIST}: {json.dumps(v.to_dict())}")
    bad_cell = _with_camera(thesis, dist=THESIS_DIST)
    render_measured_set(out / "data", thesis, {}, SetSpec(seed=8))
    try:
        rep = check_model(out / "data", bad_cell, out / "report")
        print(_summary(rep))
    except DatasetError as e:
        print(f"check-model refuses: {e}")


def shop_floor(out: Path, thesis: Cell) -> None:
    cases = {
        "wood grain (contrast 0.06)": ({}, replace(MEASURED_PHOTOMETRY, grain_contrast=0.06)),
        "arris (1.0 mm chamfer)": ({"arris": [1.0]}, MEASURED_PHOTOMETRY),
        "camera response gamma 2.2": ({"response_gamma": [2.2]}, MEASURED_PHOTOMETRY),
    }
    for k, (label, (hidden, photometry)) in enumerate(cases.items()):
        d = out / f"case{k}"
        render_measured_set(
            d / "data",
            thesis,
            hidden,
            SetSpec(seed=20 + k, photometry=photometry),
            arris_profile="round" if "round" in label else "chamfer",
        )
        rep = check_model(d / "data", thesis, d / "report")
        print(f"{label}: {_summary(rep)}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("example", choices=["pixel-aspect", "distortion", "shop-floor"])
    ap.add_argument("--out", help="folder for the data sets and reports (default: temporary)")
    args = ap.parse_args()
    thesis = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    fn = {"pixel-aspect": pixel_aspect, "distortion": distortion, "shop-floor": shop_floor}[args.example]
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        fn(Path(args.out), thesis)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            fn(Path(tmp), thesis)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python
"""Doors photographed by a real camera's photometric model: does locate hold its figures and its sigmas?

The board photographs in ``../shared/data`` give each public camera a photometric model (`doorloc
check-model --boards`: its response beyond a power law, the point spread's asymmetry and halo, the blur's
change over the field and with direction; :class:`doorloc.photometric.model.PhotometricModel`, written into the
extended calibration file). Locate does not place edges with that model: it linearises with the cell's
``response_gamma`` and measures what it can on each image. This bench renders doors as such a camera makes
them and measures what that costs:

- the scene is the hard sets' (:func:`bench_surfaces._hard_effects`: albedos, ambient and directional light from
  either side, a shadow band, wood grain of 0-10 % along the height), doors 30-100 mm thick at random poses in
  the envelope, half of them with a 0.5-2.5 mm chamfer on every arris;
- the box-filtered radiance goes through :func:`doorloc.sim.photometric.apply_camera` with the camera's model:
  blur 0.6-1.8 px at the centre, an exposure that puts the scene's bright end at 0.5-0.95 of full scale, read
  noise 0.5-3 grey levels, JPEG 88 / 95 or none (drawn per image, seed printed; ``--jpeg Q``: every image at the
  camera's own quality);
- the cell (the thesis cell) states as its ``response_gamma`` the power law nearest the camera's response
  (:func:`stated_exponent`: what a power-law measurement of the camera reads) and nothing else of the model;
  the rendered camera's geometry is exact, so the calibration term is off (``calibration_sigma_px`` 0), as in
  bench_surfaces; its optics are not, so a cell without the model keeps the doubt of an unmeasured camera's
  optics (``locate.optics_edge_sigma_px``, 0.13 px by default), and one with it takes the model's residual;
- the point spread's asymmetry (``edge_shift_u_px``, ``edge_shift_v_px``: every edge moved against the
  corners' frame the calibration was made in) is rendered by moving the principal point of the camera the
  doors are rendered through by that much (the cell keeps the calibrated one);
- ``told``: the same photographs, the cell carrying the camera's model as well (``Cell.camera_photometry``:
  locate maps the levels through its response, :func:`doorloc.vision.luminance.camera_levels`, and takes the
  edges' shift off);
- ``plain``: the same scenes through a power-law camera of the stated exponent (a camera the cell describes
  exactly): the difference between the columns is what the camera's photometry does to locate, and what
  telling its response gives back.

Per column: answered, RMS and max error of x, z, yaw, the share within 2 claimed sigma and the count beyond 5,
the largest |error| / sigma, and the refusals by code.
Each door's line says what its plain edges read of the camera response (:func:`response_read`).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_camera_doors.py --model DIR_OR_FILE [--model ...]
        [--n 24] [--seed 3500] [--jpeg 50] [--quality-known]

``--quality-known``: each JPEG located with its quality, as the service, the CLI and batch read it from the
file (by default as an array, whose blocks tell it).

``--model``: an extended calibration file (``photometric_model`` section), or a `check-model --boards` report
folder (its report.json's model is read), e.g. ``doorloc check-model --boards ../shared/data/opencv-left
--pattern 9x6 --square 25 --out /tmp/cm_opencv`` then ``--model /tmp/cm_opencv``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))

from bench_surfaces import _hard_effects, _pose  # noqa: E402

from doorloc.calib.camera import CameraModel  # noqa: E402
from doorloc.calib.io import load_calibration  # noqa: E402
from doorloc.cell import DoorSize, load_cell  # noqa: E402
from doorloc.photometric.model import PLAIN, PhotometricModel  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.sim.photometric import CameraRendering, apply_camera  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def read_model(path: Path) -> tuple[str, PhotometricModel]:
    """The photometric model of an extended calibration file, or of a `check-model --boards` report folder."""
    if path.is_dir():
        report = json.loads((path / "report.json").read_text())
        return str(path), PhotometricModel.from_dict(report["photometric_model"])
    cal = load_calibration(path)
    if not cal.photometric_model:
        raise SystemExit(f"{path}: no photometric_model section (run doorloc check-model --boards first)")
    return str(path), PhotometricModel.from_dict(cal.photometric_model)


def stated_exponent(model: PhotometricModel) -> float:
    """The exponent of the power law nearest the model's response over the grey levels 0.1-0.95 that store some
    light (above a pedestal; least squares of log light against log grey, through full scale): what a cell
    describing the camera by a power law states."""
    g = np.linspace(0.1, 0.95, 200)
    light = model.light_from_grey(g)
    g, light = g[light > 0], light[light > 0]
    lg = np.log(g)
    return float(np.sum(lg * np.log(light)) / np.sum(lg * lg))


def scenes(n: int, seed: int):
    """``(name, pose, door, scene effects, camera rendering, seed)`` per image: the hard sets' scene with the
    sensor's effects taken out (the camera model adds its own), half the doors chamfered."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        fx = _hard_effects(rng)
        chamfer = bool(rng.random() < 0.5)
        door = DoorSize(
            900,
            float(rng.uniform(30, 100)),
            2100,
            float(rng.uniform(0.5, 2.5)) if chamfer else 0.0,
            "chamfer",
        )
        scene = dataclasses.replace(
            fx,
            arris_profile="chamfer",
            gradient_u=0.0,
            gradient_v=0.0,
            vignetting=0.0,
            blur_sigma_px=0.0,
            full_well_e=0.0,
            read_noise_dn=0.0,
            jpeg_quality=0,
            bit_depth=8,
        )
        cam = CameraRendering(
            blur_px=float(rng.uniform(0.6, 1.8)),
            exposure=float(rng.uniform(0.5, 0.95)),  # of the scene's bright end (scaled per image below)
            read_noise=float(rng.uniform(0.5, 3.0)),
            jpeg_quality=int(rng.choice([0, 88, 95])),
        )
        yield f"door_{i:03d}", _pose(rng), door, scene, cam, seed * 1000 + i


def seen_through(cell, model: PhotometricModel):
    """The cell whose camera the doors are rendered through: its principal point moved by the model's edge
    shift (which moves every edge's image by it, as the point spread's asymmetry does). Written here rather
    than taken from :func:`doorloc.cell.edge_camera_cell`, so that the bench's truth does not rest on the code
    it measures (a sign error there would agree with itself)."""
    cam = cell.camera
    K = cam.camera_matrix.copy()
    K[0, 2] += model.edge_shift_u_px
    K[1, 2] += model.edge_shift_v_px
    return dataclasses.replace(cell, camera=CameraModel(K, cam.dist_coeffs, cam.image_size))


def response_read(d: dict) -> str:
    """What the image's plain edges read of the camera response (``diagnostics.camera_response``), short:
    the exponent the answer rests on where the image's replaced the cell's, the reading where the cell's
    was kept, or that nothing was read. (A camera whose response is no power law is read as one: a shoulder
    read as a steep exponent moved answers 0.13 mm, so each door's line says what was read.)"""
    if not d.get("checked"):
        return "response=unchecked"
    # (a checked reading always carries its exponent and sigma: doorloc.vision.response_check)
    return f"response={d['fitted']:.2f}+-{d['sigma']:.2f}" + (" absorbed" if d["absorbed"] else " cell kept")


def run_column(
    cell, model: PhotometricModel, gamma: float, items, told: bool = False, quality_known: bool = False
) -> dict:
    """Locate every item photographed through ``model``; the cell states the exponent ``gamma`` (and, with
    ``told``, the model itself); ``quality_known``: each JPEG located with its quality, as the service
    reads it from the file."""
    stated = dataclasses.replace(
        cell,
        response_gamma=gamma,
        response_gamma_sigma=None,
        camera_photometry=model if told and model.used_by_locate else None,
    )
    seen = seen_through(cell, model)
    cfg = dataclasses.replace(stated.locate, calibration_sigma_px=0.0)
    errs, sigs, lines = [], [], []
    codes: Counter[str] = Counter()
    for name, pose, door, scene, cam, s in items:
        rd = render_door(seen, door, pose, effects=scene, seed=s)
        bright = float(np.percentile(rd.radiance, 99.5))
        cam = dataclasses.replace(cam, exposure=cam.exposure / max(bright, 1e-6))
        img = apply_camera(rd.radiance, model, cam, seed=s)
        quality = cam.jpeg_quality if quality_known else 0
        r = locate(img, stated, door, image_name=name, config=cfg, jpeg_quality=quality)
        what = (
            f"{name} seed {s} T={door.thickness_mm:.1f} arris={door.arris_mm:.2f} blur={cam.blur_px:.2f} "
            f"jpeg={cam.jpeg_quality} light={scene.light_directional:.2f}@{scene.light_azimuth_deg:+.0f}"
            f"/{scene.light_elevation_deg:+.0f} grain={scene.grain_contrast:.3f}"
            f" {response_read(r.diagnostics.get('camera_response', {}))}"
        )
        if not r.ok:
            codes[str(r.error_code)] += 1
            lines.append(f"{what}  REFUSED {r.error_code}: {(r.error or '')[:90]}")
            continue
        e = (r.x_mm - pose.x_mm, r.z_mm - pose.z_mm, r.yaw_deg - pose.yaw_deg)
        u = r.uncertainty
        assert u is not None  # (an answer carries its uncertainty)
        errs.append(e)
        sigs.append((u.x_mm, u.z_mm, u.yaw_deg))
        lines.append(
            f"{what}  e {e[0]:+.4f} {e[1]:+.4f} {e[2]:+.5f}  sigma {u.x_mm:.4f} {u.z_mm:.4f} {u.yaw_deg:.5f}"
        )
    out: dict = {"n": len(items), "answered": len(errs), "refused": dict(codes), "images": lines}
    if errs:
        ea, sg = np.array(errs), np.array(sigs)
        z = np.abs(ea) / sg
        for i, k in enumerate(("x_mm", "z_mm", "yaw_deg")):
            out[k] = {
                "rms": float(np.sqrt(np.mean(ea[:, i] ** 2))),
                "max": float(np.max(np.abs(ea[:, i]))),
                "within_2sigma": float(np.mean(z[:, i] <= 2.0)),
                "beyond_5sigma": int(np.sum(z[:, i] > 5.0)),
                "max_z": float(np.max(z[:, i])),
                "median_sigma": float(np.median(sg[:, i])),
            }
    return out


def show(label: str, s: dict) -> None:
    for line in s["images"]:
        print(f"    {line}")
    print(f"  {label:10s} answered {s['answered']}/{s['n']}  refused {s['refused'] or '{}'}")
    for k in ("x_mm", "z_mm", "yaw_deg"):
        if k in s:
            v = s[k]
            print(
                f"    {k:8s} RMS {v['rms']:.4f} max {v['max']:.4f}  within 2 sigma {100 * v['within_2sigma']:.0f} %"
                f"  beyond 5 sigma {v['beyond_5sigma']}  max |e|/sigma {v['max_z']:.2f}"
                f"  median sigma {v['median_sigma']:.4f}"
            )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", action="append", type=Path, required=True)
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=3500)
    ap.add_argument(
        "--jpeg",
        type=int,
        help="every image stored at this JPEG quality, the camera's own (check-model's report gives it per "
        "photograph: OpenCV's are 50) instead of one drawn from none, 88 and 95",
    )
    ap.add_argument(
        "--quality-known",
        action="store_true",
        help="locate each JPEG with its quality, as the service reads it from the file",
    )
    ap.add_argument("--json")
    a = ap.parse_args()
    known = a.quality_known
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    items = list(scenes(a.n, a.seed))
    if a.jpeg is not None:
        items = [(n, p, d, s, dataclasses.replace(c, jpeg_quality=a.jpeg), k) for n, p, d, s, c, k in items]
    print(f"{a.n} doors, seed {a.seed}" + (f", JPEG {a.jpeg}" if a.jpeg is not None else ""))
    out: dict[str, dict] = {}
    for p in a.model:
        where, model = read_model(p)
        changed = {k: v for k, v in model.to_dict().items() if v != PLAIN.to_dict()[k]}
        gamma = stated_exponent(model)
        print(f"camera {where}: {json.dumps({k: round(v, 4) for k, v in changed.items()})}")
        print(f"  the cell states response_gamma {gamma:.3f}; plain: a power-law camera of that exponent")
        out[where] = {
            "response_gamma": gamma,
            "camera": run_column(cell, model, gamma, items, quality_known=known),
            "told": run_column(cell, model, gamma, items, told=True, quality_known=known),
            "plain": run_column(cell, PhotometricModel(gamma=gamma), gamma, items, quality_known=known),
        }
        for column in ("camera", "told", "plain"):
            show(column, out[where][column])
    if a.json:
        Path(a.json).write_text(
            json.dumps(out, indent=1, default=lambda x: None if not math.isfinite(x) else x)
        )


if __name__ == "__main__":
    main()

#!/usr/bin/env python
"""Real door surfaces: accuracy on wood grain, and whether the claimed uncertainty covers the error.

Sets (rendered through the thesis cell, fixtures/cell_thesis.yaml, each with its seed printed; every
effect drawn over a wide random range per image, so nothing is tuned to one look):

- grain        the acceptance set: wood grain on the hinge face (lines along the height, period 2-8 mm,
               contrast 0-10 %, random phase), low contrast, illumination gradients, vignetting, blur
               0.6-1.8 px, read noise 0-4 grey levels, JPEG quality 88. Wanted: RMS x, z <= 0.02 mm,
               yaw <= 0.01 deg, no image refused.
- plain        default photometry, random poses and thicknesses.
- hard         everything the renderer has except an arris: directional light from either side, shadow
               band, grain, gradients, vignetting, blur 0-2 px, shot and read noise, JPEG 80-95 or none,
               16-bit on some.
- thin         hard photometry on thin doors (28-40 mm) shifted so the far face is in view.
- combined     (not in the default sets) hard photometry on chamfered and rounded arrises (0-3 mm) lit
               from either side, through a camera of response 1.0-2.4 that the cell file states.
- thin-arris   (not in the default sets) thin doors (28-34 mm) with their far face in view and a 0.5-3 mm
               chamfer or rounding on every arris, wide random lighting: the far arris's strip between the
               hinge face and the far face.

Every set also reports the thickness: RMS, and how often it lies within 2 (beyond 5) of the sigma its
check used (``diagnostics.thickness_check.sigma_mm``). ``--response-factor F`` sets the rendered sets'
``locate.response_unmeasured_factor`` (a cell whose response was measured: ``doorloc calibrate`` prints
it; 1.11 for Bouguet's photographs). ``--quality-known`` locates each JPEG with its quality, as the
service, the CLI and batch read it from the file (by default as an array, whose blocks tell it).
``--wrong-thickness MM`` renders every door MM thicker than its recipe
(negative: thinner) and locates it with the recipe: every answer is then a wrong door passed, and the
refusals say how the thickness check caught the others (the thin-arris set is where that is hard: the far
arris's strip and the far face's back edge are both candidates for the far side).
- grain_square (not in the default sets) the grain set's doors square to the camera, through cameras of
               exponent 1.0-2.4 that the cell states: the camera response read between the pixels (each
               line's reading at one pixel phase against the rendered exponent: its pulls, printed).
- grain_strong (not in the default sets) the grain set's doors with 2.5 times the grain's contrast (0-25 %):
               an RMS of the texture near a single 10 % sinusoid's, as another renderer's grain has.
- fixtures/*   the committed rendered fixtures (grid, widths, distractors, effects).

For every set: n, answered, RMS and max error, and the uncertainty's coverage: the fraction of
|error| <= 2 sigma per coordinate (ideal 95 %), the count beyond 5 sigma, the median sigma, and every
refusal with its reason. The rendered camera is exact, so the calibration term is off
(``calibration_sigma_px=0``) and so is the doubt of an unmeasured camera's optics (``optics_edge_sigma_px=0``):
the coverage is that of the image-measurement part (fit + edge model).

More sets: add a generator to ``SETS`` (name -> function(n, seed) yielding (name, pose, door, effects,
seed)), e.g. arris profiles or camera responses; ``--sets`` picks which run.

Speed (``--speed``): the grid set of bench/bench_locate.py (27 default-photometry images), timed in
subprocess workers that import either this checkout's ``src`` or ``--baseline-src`` (default
/work/main/src, the code before this change), alternating A/B for ``--rounds`` rounds on the same
machine in the same run; per image the best of all its calls, then the median over images (what the code
costs, not what other processes cost). One thread.

Run:  OMP_NUM_THREADS=1 python bench/bench_surfaces.py [--n 60] [--seed 11] [--sets grain,plain,...]
      [--response-factor F] [--speed] [--json out.json]
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Iterator  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import TypedDict  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from doorloc.cell import Cell, DoorSize, load_cell  # noqa: E402
from doorloc.pose import DoorPose  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.sim.effects import Effects  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
Item = tuple[str, DoorPose, DoorSize, Effects | None, int]


# -- rendered sets -------------------------------------------------------------------------------------
def _pose(rng: np.random.Generator) -> DoorPose:
    return DoorPose(*rng.uniform([-10, -10, -2], [10, 10, 2]))


def grain_set(n: int, seed: int) -> Iterator[Item]:
    rng = np.random.default_rng(seed)
    for i in range(n):
        bg = rng.uniform(0.1, 0.3)
        eff = Effects(
            albedo_hinge=bg + rng.uniform(0.1, 0.3),
            albedo_background=bg,
            albedo_side=bg + rng.uniform(-0.05, 0.3),
            gradient_u=rng.uniform(-0.2, 0.2),
            gradient_v=rng.uniform(-0.2, 0.2),
            vignetting=rng.uniform(0.0, 0.4),
            grain_contrast=rng.uniform(0.0, 0.10),
            grain_period_mm=rng.uniform(2.0, 8.0),
            blur_sigma_px=rng.uniform(0.6, 1.8),
            read_noise_dn=rng.uniform(0.0, 4.0),
            jpeg_quality=88,
        )
        # the grain's phases and wander come from the image seed (sim.effects.wood_grain)
        yield f"grain_{i:03d}", _pose(rng), DoorSize(900, rng.uniform(30, 100), 2100), eff, seed * 1000 + i


#: the strong grain set's contrast over the grain set's (grain 0-25 %: an RMS near 7 % of the face, a single
#: sinusoid's of 10 %; the grain set's five summed sinusoids of 0-10 % have about 3 %)
STRONG_GRAIN = 2.5


def grain_strong_set(n: int, seed: int) -> Iterator[Item]:
    """The grain set's doors with :data:`STRONG_GRAIN` times the grain's contrast."""
    for name, pose, door, eff, s in grain_set(n, seed):
        yield (
            name.replace("grain", "grain_strong", 1),
            pose,
            door,
            replace(eff, grain_contrast=eff.grain_contrast * STRONG_GRAIN),
            s,
        )


def plain_set(n: int, seed: int) -> Iterator[Item]:
    rng = np.random.default_rng(seed)
    for i in range(n):
        yield (
            f"plain_{i:03d}",
            _pose(rng),
            DoorSize(rng.uniform(700, 1100), rng.uniform(30, 100), 2100),
            None,
            seed * 1000 + i,
        )


def _hard_effects(rng: np.random.Generator) -> Effects:
    bg = rng.uniform(0.08, 0.3)
    jpeg = int(rng.choice([0, 80, 88, 95]))
    return Effects(
        albedo_hinge=bg + rng.uniform(0.1, 0.45),
        albedo_background=bg,
        albedo_side=bg + rng.uniform(-0.05, 0.35),
        light_ambient=rng.uniform(0.6, 1.0),
        light_directional=rng.uniform(0.0, 0.4),
        light_azimuth_deg=rng.uniform(-60, 60),
        light_elevation_deg=rng.uniform(-30, 45),
        gradient_u=rng.uniform(-0.25, 0.25),
        gradient_v=rng.uniform(-0.25, 0.25),
        vignetting=rng.uniform(0.0, 0.4),
        grain_contrast=rng.uniform(0.0, 0.10),
        grain_period_mm=rng.uniform(2.0, 8.0),
        shadow_strength=rng.uniform(0.0, 0.3) if rng.random() < 0.3 else 0.0,
        shadow_z_mm=rng.uniform(20, 80),
        blur_sigma_px=rng.uniform(0.0, 2.0),
        full_well_e=rng.choice([0.0, 20000.0]),
        read_noise_dn=rng.uniform(0.0, 4.0),
        jpeg_quality=jpeg,
        bit_depth=16 if (jpeg == 0 and rng.random() < 0.3) else 8,
    )


def hard_set(n: int, seed: int) -> Iterator[Item]:
    rng = np.random.default_rng(seed)
    for i in range(n):
        yield (
            f"hard_{i:03d}",
            _pose(rng),
            DoorSize(900, rng.uniform(30, 100), 2100),
            _hard_effects(rng),
            seed * 1000 + i,
        )


def thin_set(n: int, seed: int) -> Iterator[Item]:
    rng = np.random.default_rng(seed)
    for i in range(n):
        pose = DoorPose(rng.uniform(-10.0, 10.0), rng.uniform(-10, 10), rng.uniform(-2, 2))
        yield (
            f"thin_{i:03d}",
            pose,
            DoorSize(900, rng.uniform(28.0, 40.0), 2100),
            _hard_effects(rng),
            seed * 1000 + i,
        )


def _unclipped_light(
    rng: np.random.Generator, brightest_albedo: float, ambient_min: float, directional_max: float
) -> tuple[float, float]:
    """Ambient and directional light drawn in ``[ambient_min, 1]`` and ``[0, directional_max]``, scaled down
    together where the brightest face would clip at white."""
    amb, direct = float(rng.uniform(ambient_min, 1.0)), float(rng.uniform(0.0, directional_max))
    k = min(1.0, 0.95 / (brightest_albedo * (amb + direct)))
    return amb * k, direct * k


class _SideLight(TypedDict):
    light_azimuth_deg: float
    light_elevation_deg: float
    blur_sigma_px: float


def _side_light_and_blur(rng: np.random.Generator) -> _SideLight:
    """The arris sets' light direction (from either side: azimuth +-10..80 deg, elevation -30..60 deg) and
    blur (0.6-1.8 px), as ``Effects`` keywords."""
    return _SideLight(
        light_azimuth_deg=float(rng.choice([-1.0, 1.0]) * rng.uniform(10.0, 80.0)),
        light_elevation_deg=float(rng.uniform(-30.0, 60.0)),
        blur_sigma_px=float(rng.uniform(0.6, 1.8)),
    )


def combined_set(n: int, seed: int) -> Iterator[Item]:
    """Every effect at once: hard photometry (grain, gradients, vignetting, shadow, noise, JPEG) on doors
    with a chamfer or rounding of 0-3 mm (none on a quarter), lit from either side, seen by a camera of
    response exponent 1.0-2.4 that the cell file states (``run_rendered`` sets the cell's
    ``response_gamma`` to the rendered one)."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        eff = _hard_effects(rng)
        profile = str(rng.choice(["chamfer", "round"]))
        arris = float(rng.uniform(0.3, 3.0)) if rng.random() < 0.75 else 0.0
        hinge, chamfer = eff.albedo_hinge, float(rng.uniform(0.3, 0.95)) * eff.albedo_hinge / 0.6
        ambient, directional = _unclipped_light(rng, max(hinge, chamfer), 0.3, 0.8)
        eff = replace(
            eff,
            arris_profile=profile,  # type: ignore[arg-type]
            albedo_chamfer=chamfer,
            light_ambient=ambient,
            light_directional=directional,
            **_side_light_and_blur(rng),
            gamma=float(rng.uniform(1.0, 2.4)),
        )
        door = DoorSize(900, float(rng.uniform(30, 100)), 2100, arris_mm=arris, arris_profile=profile)  # type: ignore[arg-type]
        yield f"combined_{i:03d}", _pose(rng), door, eff, seed * 1000 + i


def thin_arris_set(n: int, seed: int) -> Iterator[Item]:
    """Thin doors (28-34 mm) shifted towards -X so that the far face is in view, with a chamfer or rounding
    of 0.5-3 mm on every arris: the far arris's strip lies between the hinge face and the far face. Wide
    random lighting from either side, mild noise, a linear camera."""
    rng = np.random.default_rng(seed)
    for i in range(n):
        profile = ("chamfer", "round")[i % 2]
        hinge, chamfer = float(rng.uniform(0.5, 0.9)), float(rng.uniform(0.3, 0.95))
        ambient, directional = _unclipped_light(rng, max(hinge, chamfer), 0.2, 0.9)
        eff = Effects(
            arris_profile=profile,  # type: ignore[arg-type]
            albedo_hinge=hinge,
            albedo_chamfer=chamfer,
            albedo_background=float(rng.uniform(0.05, 0.2)),
            light_ambient=ambient,
            light_directional=directional,
            **_side_light_and_blur(rng),
            read_noise_dn=float(rng.uniform(0.0, 1.0)),
        )
        door = DoorSize(
            900,
            float(rng.uniform(28, 34)),
            2100,
            arris_mm=float(rng.uniform(0.5, 3.0)),
            arris_profile=profile,
        )  # type: ignore[arg-type]
        pose = DoorPose(*rng.uniform([-8, -8, -1.5], [0, 8, 1.5]))
        yield f"thin_arris_{i:03d}", pose, door, eff, seed * 1000 + i


def grain_square_set(n: int, seed: int) -> Iterator[Item]:
    """The grain set's doors square to the camera (yaw 0: every edge at one pixel phase), through cameras
    of exponent 1.0, 1.8, 2.2 or 2.4 that the cell states: where the response is read between the pixels."""
    rng = np.random.default_rng(seed + 1)
    for name, pose, door, eff, s in grain_set(n, seed):
        gamma = float(rng.choice([1.0, 1.8, 2.2, 2.4]))
        square = DoorPose(pose.x_mm, pose.z_mm, 0.0)
        yield name.replace("grain", "grain_square", 1), square, door, replace(eff, gamma=gamma), s


#: name -> generator(n, seed); add arris / response sets here
SETS: dict[str, Callable[[int, int], Iterator[Item]]] = {
    "grain": grain_set,
    "grain_square": grain_square_set,
    "plain": plain_set,
    "hard": hard_set,
    "thin": thin_set,
    "combined": combined_set,
    "thin-arris": thin_arris_set,
    "grain_strong": grain_strong_set,
}
FIXTURES = ("grid", "widths", "distractors", "effects")


# -- evaluation ------------------------------------------------------------------------------------------
def _evaluate(results: list[tuple[str, object, tuple[float, float, float]]]) -> dict:
    """results: (image name, LocateResult, truth (x, z, yaw)) -> the set's figures."""
    errs, sigs, refusals, thick = [], [], [], []
    for name, r, truth in results:
        if not r.ok:  # type: ignore[attr-defined]
            refusals.append({"image": name, "code": r.error_code, "reason": r.error})  # type: ignore[attr-defined]
            continue
        errs.append((r.x_mm - truth[0], r.z_mm - truth[1], r.yaw_deg - truth[2]))  # type: ignore[attr-defined]
        u = r.uncertainty  # type: ignore[attr-defined]
        sigs.append((u.x_mm, u.z_mm, u.yaw_deg))
        if len(truth) > 3:  # the thickness and the sigma its check used
            thick.append((r.thickness_mm - truth[3], r.diagnostics["thickness_check"]["sigma_mm"]))  # type: ignore[attr-defined]
    out: dict = {"n": len(results), "ok": len(errs), "refusals": refusals}
    if thick:
        t = np.array(thick)
        tz = np.abs(t[:, 0]) / t[:, 1]
        out |= {
            "rms_thickness_mm": float(np.sqrt(np.mean(t[:, 0] ** 2))),
            "max_thickness_mm": float(np.max(np.abs(t[:, 0]))),
            "thickness_within_2sigma": float(np.mean(tz <= 2.0)),
            "thickness_beyond_5sigma": int(np.sum(tz > 5.0)),
        }
    if not errs:
        return out
    e, s = np.array(errs), np.array(sigs)
    z = np.abs(e) / s
    keys = ("x_mm", "z_mm", "yaw_deg")
    out |= {f"rms_{k}": float(np.sqrt(np.mean(e[:, i] ** 2))) for i, k in enumerate(keys)}
    out |= {f"max_{k}": float(np.max(np.abs(e[:, i]))) for i, k in enumerate(keys)}
    out |= {f"within_2sigma_{k}": float(np.mean(z[:, i] <= 2.0)) for i, k in enumerate(keys)}
    out |= {f"beyond_5sigma_{k}": int(np.sum(z[:, i] > 5.0)) for i, k in enumerate(keys)}
    out |= {f"median_sigma_{k}": float(np.median(s[:, i])) for i, k in enumerate(keys)}
    out |= {f"max_z_{k}": float(np.max(z[:, i])) for i, k in enumerate(keys)}
    out["_z"] = z.tolist()
    return out


def _print_set(name: str, s: dict, seed: int | None) -> None:
    head = f"{name:20s} seed={seed if seed is not None else '-':>5} n={s['n']:3d} ok={s['ok']:3d}"
    if not s["ok"]:
        print(head)
    else:
        print(
            f"{head}  RMS x {s['rms_x_mm']:.4f} z {s['rms_z_mm']:.4f} mm yaw {s['rms_yaw_deg']:.4f} deg | max x "
            f"{s['max_x_mm']:.4f} z {s['max_z_mm']:.4f} yaw {s['max_yaw_deg']:.4f}\n"
            f"{'':20s} within 2 sigma (ideal 95 %): x {100 * s['within_2sigma_x_mm']:.0f} % z "
            f"{100 * s['within_2sigma_z_mm']:.0f} % yaw {100 * s['within_2sigma_yaw_deg']:.0f} %; beyond 5 sigma: "
            f"{s['beyond_5sigma_x_mm']}/{s['beyond_5sigma_z_mm']}/{s['beyond_5sigma_yaw_deg']}; worst "
            f"{s['max_z_x_mm']:.1f}/{s['max_z_z_mm']:.1f}/{s['max_z_yaw_deg']:.1f} sigma; median sigma x "
            f"{s['median_sigma_x_mm']:.4f} z {s['median_sigma_z_mm']:.4f} mm yaw {s['median_sigma_yaw_deg']:.4f} deg"
        )
    if "rms_thickness_mm" in s:
        print(
            f"{'':20s} thickness: RMS {s['rms_thickness_mm']:.4f} mm, max {s['max_thickness_mm']:.4f} mm, within 2 "
            f"sigma {100 * s['thickness_within_2sigma']:.0f} %, beyond 5 sigma {s['thickness_beyond_5sigma']}"
        )
    if "one_phase_pulls" in s:
        p, at_end = (np.array(v) for v in zip(*s["one_phase_pulls"], strict=True))
        inner = p[~at_end.astype(bool)]
        print(
            f"{'':20s} response read at one pixel phase on {p.size} lines: pulls {np.sqrt(np.mean(p**2)):.2f} "
            f"RMS, {100 * np.mean(np.abs(p) <= 2.0):.0f} % within 2 sigma; the {inner.size} read inside the "
            f"range {np.sqrt(np.mean(inner**2)) if inner.size else float('nan'):.2f} RMS, "
            f"{100 * np.mean(np.abs(inner) <= 2.0) if inner.size else float('nan'):.0f} %"
        )
    for r in s["refusals"]:
        print(f"{'':20s} refused {r['image']}: {r['code']}: {r['reason']}")


def run_rendered(
    cell: Cell,
    name: str,
    n: int,
    seed: int,
    response_factor: float | None = None,
    wrong_mm: float = 0.0,
    quality_known: bool = False,
) -> dict:
    """One rendered set located through ``cell``; ``wrong_mm``: each door rendered that much thicker than
    the recipe it is located with (a wrong door); ``quality_known``: each JPEG located with its quality, as
    the service, the CLI and batch read it from the file (else as an array: its blocks tell it)."""
    from doorloc.vision.locate import locate

    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)  # the camera is exact
    if response_factor is not None:  # a cell whose response was measured (doorloc calibrate's factor)
        cfg = replace(cfg, response_unmeasured_factor=response_factor)
    results, pulls = [], []
    for img_name, pose, door, eff, s in SETS[name](n, seed):
        rendered = replace(door, thickness_mm=door.thickness_mm + wrong_mm)
        img = render_door(cell, rendered, pose, effects=eff, seed=s).image
        # the cell file states the camera's response (a set of non-linear cameras renders its exponent)
        stated = (
            cell
            if eff is None or eff.gamma == cell.response_gamma
            else replace(cell, response_gamma=eff.gamma)
        )
        results.append(
            (
                img_name,
                locate(
                    img,
                    stated,
                    door,
                    image_name=img_name,
                    config=cfg,
                    jpeg_quality=eff.jpeg_quality if quality_known and eff is not None else 0,
                ),
                (pose.x_mm, pose.z_mm, pose.yaw_deg, rendered.thickness_mm),
            )
        )
        pulls += _one_phase_pulls(results[-1][1], eff.gamma if eff is not None else cell.response_gamma)
    out = _evaluate(results)
    if pulls:
        out["one_phase_pulls"] = pulls
    return out


def _one_phase_pulls(r, camera_gamma: float) -> list[tuple[float, bool]]:
    """Each line's camera exponent read at one pixel phase, off the rendered camera's, over its sigma; and
    whether the reading lies at an end of the range read (no least inside it)."""
    from doorloc.vision.response import RESPONSE_GAMMA_RANGE

    lines = ((r.diagnostics or {}).get("camera_response") or {}).get("lines", {})
    lo, hi = RESPONSE_GAMMA_RANGE
    return [
        ((v["gamma"] - camera_gamma) / v["sigma"], not lo * 1.01 < v["gamma"] < hi * 0.99)
        for v in lines.values()
        if v.get("one_phase") and v.get("gamma") is not None and v.get("sigma")
    ]


def run_fixture(folder: str) -> dict:
    from doorloc.vision.locate import locate

    d = REPO / "fixtures" / "rendered" / folder
    cell = load_cell(d / "cell.yaml")
    cfg = replace(cell.locate, calibration_sigma_px=0.0, optics_edge_sigma_px=0.0)
    results = []
    with open(d / "truth.csv", newline="") as f:
        for row in csv.DictReader(f):
            door = DoorSize(
                float(row["width_mm"]),
                float(row["thickness_mm"]),
                float(row["height_mm"]),
                arris_mm=float(row["arris_mm"]),
                arris_profile=row["arris_profile"],
            )  # type: ignore[arg-type]
            img = cv2.imread(str(d / row["image"]), cv2.IMREAD_UNCHANGED)
            results.append(
                (
                    row["image"],
                    locate(img, cell, door, image_name=row["image"], config=cfg),
                    (
                        float(row["x_mm"]),
                        float(row["z_mm"]),
                        float(row["yaw_deg"]),
                        float(row["thickness_mm"]),
                    ),
                )
            )
    return _evaluate(results)


# -- speed -------------------------------------------------------------------------------------------------
def _grid_items() -> list[tuple[DoorPose, DoorSize]]:
    ts = [30.0, 47.5, 65.0, 82.5, 100.0]
    out = []
    for x in (-10.0, 0.0, 10.0):
        for z in (-10.0, 0.0, 10.0):
            for yaw in (-2.0, 0.0, 2.0):
                out.append((DoorPose(x, z, yaw), DoorSize(900, ts[len(out) % 5], 2100)))
    return out


def time_worker(repeats: int) -> None:
    """Run in a subprocess: time locate (whichever doorloc is on the path) over the grid set, print JSON."""
    from doorloc.vision.locate import locate

    cv2.setNumThreads(1)
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    imgs = [(render_door(cell, d, p).image, d) for p, d in _grid_items()]
    locate(imgs[0][0], cell, imgs[0][1])  # warm-up (imports, caches)
    best = []
    for img, d in imgs:
        ts = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            locate(img, cell, d)
            ts.append((time.perf_counter() - t0) * 1e3)
        best.append(min(ts))
    print(json.dumps(best))


def run_speed(baseline_src: Path, rounds: int, repeats: int) -> dict:
    srcs = {"this": REPO / "src", "baseline": baseline_src}
    per: dict[str, list[list[float]]] = {k: [] for k in srcs}
    for _ in range(rounds):
        for k, src in srcs.items():  # alternate A/B so both see the same machine load
            env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
            out = subprocess.run(
                [sys.executable, __file__, "--time-worker", "--repeats", str(repeats)],
                env=env,
                check=True,
                capture_output=True,
                text=True,
            ).stdout
            per[k].append(json.loads(out.strip().splitlines()[-1]))
    med = {k: float(np.median(np.min(np.array(v), axis=0))) for k, v in per.items()}
    return {
        "median_of_best_ms_this": med["this"],
        "median_of_best_ms_baseline": med["baseline"],
        "ratio": med["this"] / med["baseline"],
        "baseline_src": str(baseline_src),
        "rounds": rounds,
        "repeats": repeats,
        "images": len(per["this"][0]),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[1])
    ap.add_argument("--n", type=int, default=60, help="images per rendered set")
    ap.add_argument("--seed", type=int, default=11, help="base seed; set k uses seed + k")
    ap.add_argument(
        "--sets", default="grain,plain,hard,thin,fixtures", help="comma list of sets (fixtures = all folders)"
    )
    ap.add_argument(
        "--response-factor",
        type=float,
        help="rendered sets: locate.response_unmeasured_factor (a cell whose response was measured, e.g. 1.11)",
    )
    ap.add_argument(
        "--wrong-thickness",
        type=float,
        default=0.0,
        metavar="MM",
        help="rendered sets: each door rendered MM thicker than its recipe (wrong doors: an answer is a wrong door passed)",
    )
    ap.add_argument(
        "--quality-known",
        action="store_true",
        help="rendered sets: locate each JPEG with its quality, as the service reads it from the file",
    )
    ap.add_argument("--speed", action="store_true", help="also time the grid set against --baseline-src")
    ap.add_argument("--baseline-src", type=Path, default=Path("/work/main/src"))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--time-worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.time_worker:
        time_worker(args.repeats)
        return
    cv2.setNumThreads(1)
    cell = load_cell(REPO / "fixtures" / "cell_thesis.yaml")
    report: dict = {"sets": {}}
    pooled_z = []
    names = [s for s in args.sets.split(",") if s]
    for name in names:
        if name == "fixtures":
            for folder in FIXTURES:
                s = run_fixture(folder)
                _print_set(f"fixtures/{folder}", s, None)
                pooled_z += s.pop("_z", [])
                report["sets"][f"fixtures/{folder}"] = s
            continue
        if name not in SETS:
            raise SystemExit(f"unknown set {name!r}; known: {', '.join(SETS)}, fixtures")
        seed = args.seed + list(SETS).index(name)  # a set keeps its seed whichever sets run
        s = run_rendered(
            cell, name, args.n, seed, args.response_factor, args.wrong_thickness, args.quality_known
        )
        s["seed"] = seed
        _print_set(name, s, seed)
        pooled_z += s.pop("_z", [])
        report["sets"][name] = s
    if pooled_z:
        z = np.array(pooled_z)
        pooled = {
            "answers": len(z),
            "within_2sigma": [float(v) for v in (z <= 2).mean(axis=0)],
            "beyond_5sigma": [int(v) for v in (z > 5).sum(axis=0)],
            "refusals": sum(len(s["refusals"]) for s in report["sets"].values()),
            "refusals_without_reason": sum(
                1 for s in report["sets"].values() for r in s["refusals"] if not r["reason"]
            ),
        }
        report["all_sets"] = pooled
        print(
            f"all sets: {pooled['answers']} answers; within 2 sigma x {100 * pooled['within_2sigma'][0]:.1f} % "
            f"z {100 * pooled['within_2sigma'][1]:.1f} % yaw {100 * pooled['within_2sigma'][2]:.1f} % (ideal 95 %); "
            f"beyond 5 sigma {pooled['beyond_5sigma']}; {pooled['refusals']} refusals, "
            f"{pooled['refusals_without_reason']} without a reason"
        )
    if args.speed:
        sp = run_speed(args.baseline_src, args.rounds, args.repeats)
        report["speed"] = sp
        print(
            f"speed, grid set ({sp['images']} images, one thread, per image best of {sp['rounds']}x{sp['repeats']} "
            f"calls, median over images): this {sp['median_of_best_ms_this']:.2f} ms, baseline "
            f"({sp['baseline_src']}) {sp['median_of_best_ms_baseline']:.2f} ms, ratio {sp['ratio']:.3f}"
        )
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

"""The cell's light measured from its doors, and what locate gains with it on doors held out.

Each cell draws one light (azimuth +-10..80 deg either side, elevation -30..60 deg, as the arris bench's
lights), one camera exponent (1.0-2.4, stated in the cell as measured, ``response_unmeasured_factor``
1.11) and renders doors with rounded arrises of 0.5-3 mm as the arris bench's ``round`` set draws them
(blur, albedos, noise, poses), every door under the cell's light. The light is measured from the first
``--measure`` doors (:func:`doorloc.vision.cell_light.measure_cell_light`); the next ``--test`` doors are
located four ways: no light stated (the free shading, ``locate.light_from_door`` off), each door's own
light (``light_from_door``, the default), the measured light with its measured doubt, and the renderer's
own light (the default doubt). Per cell: the measured direction, its angle from the true
one, its doubt and any other direction the doors could not rule out; per way: the answered share and the
refusals, and RMS of x, z and yaw with the shares within 2 claimed sigma and beyond 5 (the arris bench's
summary). The time the measurement took (thread CPU, the first cell's includes compiling).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_cell_light.py [--cells 3] [--first-cell 0]
        [--measure 8] [--test 16] [--seed 8500] [--ambient]

``--ambient``: the same doors under ambient light alone; the measurement is to refuse (no direction).

``--response``: the camera's response measured from the same doors as well
(:func:`doorloc.vision.cell_response.measure_cell_response`), the cell stating the camera's exponent but not
as measured (``response_unmeasured_factor`` 2.2, the default: a plant that only states its camera's gamma);
the held-out doors are then located as the cell states them (each door's own light), under the light
measured at the stated exponent, and with the response and the light measured. ``--test-sets`` draws the
held-out doors from these arris bench sets in turn (``round,chamfer``: the rounded and chamfered doors a
plant's cell sees; the response is measured from rounded doors only). ``--finish P``: every door of the
cell with the renderer's ``finish_exponent`` P (a finish that is no matt surface). ``--mixed-lights``: every
door under its own light, as the arris bench draws them (no lamp common to the doors: the light is to
refuse; the response is read under each door's own light, and is to hold the truth within what it states).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_cell_light.py --response [--test-sets round,chamfer]
        [--finish P] [--mixed-lights] [--cells 3] [--first-cell 0] [--measure 8] [--test 16] [--seed 8500]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from bench_arris_range import Outcome, draw, summary  # noqa: E402

from doorloc.cell import load_cell  # noqa: E402
from doorloc.pose import directions_apart_deg  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.vision.cell_light import LightNotMeasurable, measure_cell_light  # noqa: E402
from doorloc.vision.cell_response import ResponseNotMeasurable, measure_cell_response  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cells", type=int, default=3)
    ap.add_argument("--first-cell", type=int, default=0)
    ap.add_argument("--measure", type=int, default=8, help="doors the light is measured from")
    ap.add_argument("--test", type=int, default=16, help="doors located after, held out")
    ap.add_argument("--seed", type=int, default=8500)
    ap.add_argument(
        "--ambient",
        action="store_true",
        help="the cell's doors under ambient light alone (the lamp's share added to it): no direction to measure",
    )
    ap.add_argument(
        "--response", action="store_true", help="measure the camera's response from the doors too"
    )
    ap.add_argument(
        "--test-sets", default="round", help="arris bench sets the held-out doors come from, in turn"
    )
    ap.add_argument("--finish", type=float, default=1.0, help="the doors' finish_exponent (1: matt)")
    ap.add_argument(
        "--mixed-lights",
        action="store_true",
        help="every door under its own light (as the arris bench draws it): no lamp common to the doors",
    )
    args = ap.parse_args()
    base = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    for c in range(args.first_cell, args.first_cell + args.cells):
        rng = np.random.default_rng([args.seed, c])
        light = (float(rng.choice([-1, 1]) * rng.uniform(10, 80)), float(rng.uniform(-30, 60)))
        gamma = float(rng.uniform(1.0, 2.4))
        cell = dataclasses.replace(
            base,
            response_gamma=gamma,
            locate=dataclasses.replace(
                base.locate, response_unmeasured_factor=2.2 if args.response else 1.11
            ),
        )
        test_sets = args.test_sets.split(",")
        frames = []
        for i in range(args.measure + args.test):
            seed = args.seed * 100 + 1000 * c + i
            held_out = i >= args.measure
            set_name = test_sets[(i - args.measure) % len(test_sets)] if held_out else "round"
            door, pose, fx, _ = draw(set_name, i, seed)
            fx = dataclasses.replace(
                fx,
                light_azimuth_deg=fx.light_azimuth_deg if args.mixed_lights else light[0],
                light_elevation_deg=fx.light_elevation_deg if args.mixed_lights else light[1],
                gamma=gamma,
                finish_exponent=args.finish,
            )
            if args.ambient:
                fx = dataclasses.replace(
                    fx, light_ambient=fx.light_ambient + fx.light_directional, light_directional=0.0
                )
            frames.append((render_door(cell, door, pose, effects=fx, seed=seed).image, door, pose))
        t0 = time.thread_time()
        try:
            m = measure_cell_light([(im, d) for im, d, _ in frames[: args.measure]], cell)
        except LightNotMeasurable as e:
            print(f"cell {c}: {'ambient light' if args.ambient else 'the lamp'}; not measured: {e}")
            if not args.response:
                continue
            m = None
        took = time.thread_time() - t0
        if m is not None:
            off = directions_apart_deg(m.direction_deg, light)
            print(
                f"cell {c}: light [{light[0]:+.1f}, {light[1]:+.1f}], gamma {gamma:.2f}; measured "
                f"[{m.direction_deg[0]:+.1f}, {m.direction_deg[1]:+.1f}] +- {m.sigma_deg:g} deg ({off:.1f} deg "
                f"off; {m.strips} strips of {m.doors} doors, score {m.score:.3f}; {took:.1f} s thread CPU)"
                + (
                    f"; also [{m.runner_up_deg[0]:+.0f}, {m.runner_up_deg[1]:+.0f}] at {m.runner_up_score:.3f}"
                    if m.runner_up_deg
                    else ""
                )
            )
        if args.response:
            ways = _response_ways(cell, frames[: args.measure], m, gamma)
            if ways is None:
                continue
            _locate_ways(ways, frames[args.measure :])
            sys.stdout.flush()
            continue
        ways = {
            "no light": dataclasses.replace(cell.locate, light_direction_deg=None, light_from_door=False),
            "each door's own": dataclasses.replace(
                cell.locate, light_direction_deg=None, light_from_door=True
            ),
            "measured": dataclasses.replace(
                cell.locate, light_direction_deg=m.direction_deg, light_direction_sigma_deg=m.sigma_deg
            ),
            "true": dataclasses.replace(cell.locate, light_direction_deg=light),
        }
        _locate_ways({k: (cell, cfg) for k, cfg in ways.items()}, frames[args.measure :])
        sys.stdout.flush()


def _response_ways(cell, frames, light, gamma):
    """The cells the held-out doors are located with under ``--response`` (None where the response could not
    be measured): the cell as it states the camera's exponent, with the light measured at it (``light``), and
    with the response and the light measured from ``frames``."""
    t0 = time.thread_time()
    try:
        r = measure_cell_response([(im, d) for im, d, _ in frames], cell)
    except ResponseNotMeasurable as e:
        print(f"  response not measured: {e}")
        return None
    print(
        f"  response measured: {r.gamma:.3f} (the camera's {gamma:.3f}, {r.gamma / gamma:.3f}x), factor "
        f"{r.factor:.3f}: the camera's {'inside' if r.gamma / r.factor <= gamma <= r.gamma * r.factor else 'OUTSIDE'}"
        + (
            f"; light [{r.light.direction_deg[0]:+.1f}, {r.light.direction_deg[1]:+.1f}] +- {r.light.sigma_deg:g}"
            if r.light is not None
            else "; no light common to the doors (each door's own)"
        )
        + (
            f"; a shoulder from {r.shoulder.knee:g} {'ruled out' if r.shoulder.ruled_out else 'not ruled out'} "
            f"({r.shoulder.shouldered:.3f} against {r.shoulder.plain:.3f}), doubted from {r.shoulder.doubted_from:.2f}"
            if r.shoulder is not None
            else ""
        )
        + f" ({time.thread_time() - t0:.0f} s thread CPU)"
    )
    measured = r.applied_to(cell)
    ways = {"stated (each door's own light)": (cell, cell.locate)}
    if light is not None:  # (None: the light could not be measured at the stated exponent)
        ways["stated, light measured"] = (
            cell,
            dataclasses.replace(
                cell.locate,
                light_direction_deg=light.direction_deg,
                light_direction_sigma_deg=light.sigma_deg,
            ),
        )
    ways["response measured (each door's own light)"] = (measured, measured.locate)
    if r.light is not None:  # (None: the doors share no lamp, each door's strips read under its own)
        lit = {"light_direction_deg": r.light.direction_deg, "light_direction_sigma_deg": r.light.sigma_deg}
        ways["response and light measured"] = (measured, dataclasses.replace(measured.locate, **lit))
    return ways


def _locate_ways(ways, frames) -> None:
    """Locate ``frames`` (image, door, pose) with each way's (cell, locate settings) and print its summary
    (nothing where there are none: ``--test 0`` measures only)."""
    if not frames:
        return
    for label, (way_cell, cfg) in ways.items():
        rows = []
        for im, door, pose in frames:
            t = time.thread_time()
            r = locate(im, way_cell, door, config=cfg)
            took = time.thread_time() - t
            rows.append(
                Outcome(
                    None,
                    (r.x_mm - pose.x_mm, r.z_mm - pose.z_mm, r.yaw_deg - pose.yaw_deg, math.nan),
                    (r.uncertainty.x_mm, r.uncertainty.z_mm, r.uncertainty.yaw_deg, math.nan),
                    locate_s=took,
                )
                if r.ok
                else Outcome(r.error_code, locate_s=took)
            )
        summary(f"  {label}", rows)


if __name__ == "__main__":
    main()

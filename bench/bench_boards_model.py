#!/usr/bin/env python
"""The camera's photometric model checked on board photographs (`doorloc check-model --boards`).

- real: both public photograph sets in ../shared/data (OpenCV's left camera, 9x6 inner corners, 25 mm nominal;
  Bouguet's example, 13x12 inner corners, 30 mm), each calibrated from its own photographs: per photograph the
  median edge offset with the plain model and, held out, with the extended one; the held-out RMS over
  photographs, its standard error from noise; the causes and parameters with 1-sigma; the profile misfit
  against the noise and against what each photograph's rendered twin leaves (its pose, noise and compression);
- hidden: rendered board photographs (random poses, blur, exposure and noise per photograph; seeds printed) with
  one catalogue effect hidden at a random strength, and controls with none: is the effect named, does the held-out
  offset or profile misfit fall, and do the controls answer [].

Run:  OMP_NUM_THREADS=1 python bench/bench_boards_model.py [real] [hidden --seeds 3 --controls 5 --views 8
      [--effects response_gamma,print_spread] [--first-seed 0]]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np

from doorloc.calib.camera import CameraModel
from doorloc.calib.detect import Chessboard
from doorloc.calib.io import CalibrationFile, save_calibration
from doorloc.photometric.check import BoardCheck, check_boards
from doorloc.photometric.model import TONE_KNOTS, TONE_NAMES, PhotometricModel
from doorloc.sim.boards import Checkerboard
from doorloc.sim.photometric import random_board_views

REPO = Path(__file__).resolve().parents[1]
DATA = REPO.parent / "shared" / "data"

#: each catalogue effect hidden at a strength drawn from these ranges (a sign drawn too where both occur)
HIDDEN = {
    "response_gamma": lambda r: {"gamma": r.uniform(1.6, 2.4)},
    "response_toe": lambda r: {"gamma": r.uniform(1.8, 2.4), "black_level": r.uniform(0.06, 0.12)},
    "response_shoulder": lambda r: {"shoulder": r.uniform(0.6, 0.8)},
    # a log-log bend on a camera's power law, drawn after the bend's sign and size (each seed keeps them); a
    # bend > 0 turns the response back at ln g = -gamma / (2 bend): held to 0.9 of the bend that reaches the
    # lowest stored level there (a bend of 0.26 on a linear camera, once drawn, held it flat below 37 grey)
    "response_curvature": lambda r: (
        lambda c, g: {"curvature": min(c, 0.9 * g / (2 * np.log(255.0))), "gamma": g}
    )(r.choice([-1, 1]) * r.uniform(0.15, 0.3), r.uniform(1.8, 2.4)),
    "print_spread": lambda r: {"print_spread_mm": r.choice([-1, 1]) * r.uniform(0.1, 0.25)},
    "blur_field": lambda r: {"blur_field": r.uniform(1.0, 2.0)},
    "blur_anisotropy": lambda r: {"blur_anisotropy": r.choice([-1, 1]) * r.uniform(0.3, 0.6)},
    "psf_tail": lambda r: {"psf_tail": r.uniform(0.06, 0.15), "psf_tail_px": 3.0},
    # last, so the other effects keep their seeds; exposures run 0.55-1.05: most light squares pass the clip
    "sensor_clipping": lambda r: {"clip_level": r.uniform(0.6, 0.75)},
    # a white level below the brighter photographs' light squares, reached through a shoulder 0.15-0.3 wide
    # rolling off at an order of 1.5-4 (quadratic at 2)
    "soft_saturation": lambda r: (
        lambda w: {
            "white_level": w,
            "shoulder": w - r.uniform(0.15, 0.3),
            "shoulder_order": r.uniform(1.5, 4.0),
        }
    )(r.uniform(0.75, 0.9)),
    # a bend of ln light over the grey scale that no closed form draws: a whole sine wave of random phase through
    # the six knots (half a wave is a log-log curvature, and is named so); its slope, at most 6 x 0.15 ln per
    # full scale, keeps the response monotone
    "response_tone": lambda r: (
        lambda a, phi: {
            n: a * np.sin(2 * np.pi * g + phi) for n, g in zip(TONE_NAMES, TONE_KNOTS, strict=True)
        }
    )(r.uniform(0.1, 0.15), r.uniform(0, 2 * np.pi)),
    # an interlaced camera's fields out of register by 0.1-0.25 px, mostly along the columns (a field's
    # vertical registration; motion between the fields' exposures adds a horizontal part and a scatter from
    # one photograph to the next)
    "interlaced_fields": lambda r: (
        lambda mag, side: {
            "field_offset_v_px": side * mag,
            "field_offset_u_px": r.uniform(-0.3, 0.3) * mag,
            "field_offset_scatter_px": r.uniform(0.0, 0.03),
        }
    )(r.uniform(0.1, 0.25), r.choice([-1.0, 1.0])),
}

#: causes the renderer makes beside the photometric model: the spread's asymmetry as a ghost (a fraction of the
#: light displaced by 2.5-4 px in a random direction, :class:`~doorloc.sim.photometric.CameraRendering`)
HIDDEN_RENDERED = {
    "psf_asymmetry": lambda r: (lambda a, d, phi: (a, d * np.cos(phi), d * np.sin(phi)))(
        r.uniform(0.2, 0.3), r.uniform(2.5, 4.0), r.uniform(0, 2 * np.pi)
    ),
}

#: effects that need more photographs than ``--views`` (the free tone curve is read on each photograph's median:
#: 16, where a paired gain over the photographs can reach its threshold); the controls are then rendered with as many
MIN_VIEWS = {"response_tone": 16}

#: each effect's place in the seeds (35000 + 97 seed + place): an effect added later goes at the end, so that the
#: others keep their draws
SEED_ORDER = [
    *(k for k in HIDDEN if k not in ("response_tone", "interlaced_fields")),
    *HIDDEN_RENDERED,
    "response_tone",
    "interlaced_fields",
]

CAMERA = CameraModel.from_values(
    [[600, 0, 319.5], [0, 600, 239.5], [0, 0, 1]], [-0.2, 0.05, 0, 0, 0], (640, 480)
)


def summary(name: str, c: BoardCheck) -> None:
    off = c.heldout_rms("offset")
    prof = c.heldout_rms("profile_rms")
    print(f"  {name}: causes {c.causes}")
    for cause, ps in c.parameters.items():
        print(
            "    "
            + cause
            + ": "
            + ", ".join(f"{k} = {v['value']:.4g} +- {v['sigma']:.2g}" for k, v in ps.items())
        )
    if c.alternatives:
        print(f"    cannot tell apart: {c.alternatives}")
    print(
        f"    held-out edge offset RMS over {len(c.photographs)} photographs: plain {off['before']:.4f} px, "
        f"extended {off['after']:.4f} px (standard error from noise {c.offset_standard_error_px:.4f} px; "
        f"1.5x: {1.5 * c.offset_standard_error_px:.4f})"
    )
    print(
        f"    held-out profile misfit RMS: plain {prof['before']:.2f}, extended {prof['after']:.2f} grey levels; "
        f"noise on the plateaus: median {c.noise_grey:.2f} (1.5x: {1.5 * c.noise_grey:.2f}), RMS over the "
        f"windows {c.noise_rms_grey:.2f} (1.5x: {1.5 * c.noise_rms_grey:.2f})"
    )
    twin = c.profile_over_twin()
    print(
        f"    the same over the photographs' twins' misfit (rendered at their poses with their noise and "
        f"compression; goal 1.5): plain {twin['before']:.2f}, extended {twin['after']:.2f}"
    )
    print(
        "    per photograph (before -> after px): "
        + " ".join(f"{p.image}:{p.offset_before_px:+.3f}->{p.offset_after_px:+.3f}" for p in c.photographs)
    )


def real() -> None:
    print("public photograph sets (calibrated from their own photographs, 5 folds by photograph)")
    for folder, board in (
        ("opencv-left", Chessboard(9, 6, 25.0)),
        ("bouguet-calib-example", Chessboard(13, 12, 30.0)),
    ):
        summary(folder, check_boards(DATA / folder, board))


def hidden(seeds: int, controls: int, views: int, effects: list[str], first_seed: int = 0) -> None:
    board = Checkerboard(9, 6, 25.0)
    control_views = max([views, *(MIN_VIEWS.get(e, 0) for e in effects)])
    print(
        f"hidden effects in rendered boards ({views} photographs each, more where an effect needs them: "
        f"{ {e: n for e, n in MIN_VIEWS.items() if e in effects and n > views} }; controls {control_views}; "
        "camera fx 600, k1 -0.2)"
    )
    named = named_or_tie = total = 0
    with tempfile.TemporaryDirectory() as tmp:
        cal = Path(tmp) / "camera.yaml"
        save_calibration(CalibrationFile(CAMERA), cal)
        runs = [(name, s) for name in effects for s in range(first_seed, first_seed + seeds)] + [
            ("control", s) for s in range(first_seed, first_seed + controls)
        ]
        false_alarms = 0
        for name, s in runs:
            seed = 35000 + 97 * s + (SEED_ORDER.index(name) if name in SEED_ORDER else 50)
            rng = np.random.default_rng(seed)
            values = HIDDEN[name](rng) if name in HIDDEN else {}
            ghost = HIDDEN_RENDERED[name](rng) if name in HIDDEN_RENDERED else (0.0, 0.0, 0.0)
            model = PhotometricModel(**values)
            shown = (
                {"ghost": ghost[0], "ghost_du_px": ghost[1], "ghost_dv_px": ghost[2]} if ghost[0] else values
            )
            folder = Path(tmp) / f"{name}_{s}"
            folder.mkdir()
            n_views = control_views if name == "control" else max(views, MIN_VIEWS.get(name, 0))
            for fname, img in random_board_views(CAMERA, board, model, n_views, seed, ghost=ghost):
                cv2.imwrite(str(folder / fname), img)
            c = check_boards(folder, Chessboard(9, 6, 25.0), CalibrationFile(CAMERA))
            off, prof = c.heldout_rms("offset"), c.heldout_rms("profile_rms")
            if name == "control":
                ok = c.causes == []
                false_alarms += not ok
            else:
                ok = name in c.causes
                told_apart = ok or any(name in others for others in c.alternatives.values())
                named += ok
                named_or_tie += told_apart
                total += 1
            vals = ", ".join(f"{k} {v:.3g}" for k, v in shown.items())
            alts = f" (cannot tell apart: {c.alternatives})" if c.alternatives else ""
            print(
                f"  {name} (seed {seed}{'; ' + vals if vals else ''}): named {c.causes} -> {'ok' if ok else 'MISSED'}; "
                f"offset {off['before']:.3f} -> {off['after']:.3f} px, profile {prof['before']:.2f} -> {prof['after']:.2f}"
                + alts
            )
        print(
            f"  named {named}/{total} ({100 * named / max(total, 1):.0f} %); false alarms {false_alarms}/{controls}"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", default=["real", "hidden"])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--controls", type=int, default=5)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument(
        "--effects",
        default=",".join([*HIDDEN, *HIDDEN_RENDERED]),
        help="comma-separated catalogue names to hide",
    )
    ap.add_argument("--first-seed", type=int, default=0, help="index of the first seed of each effect")
    args = ap.parse_args()
    if "real" in args.parts:
        real()
    if "hidden" in args.parts:
        hidden(args.seeds, args.controls, args.views, args.effects.split(","), args.first_seed)


if __name__ == "__main__":
    main()

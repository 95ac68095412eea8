"""Locate over the whole range of arrises, lights, blurs, responses and grain, seeds printed.

Each set draws its doors from wide random ranges (nothing tuned to the renderer; the lighting, albedos
and noise come from :func:`bench_arris.random_effects`), the camera's gamma is told in the cell's
``camera.response_gamma`` and the arris's size and profile in the door's recipe:

- ``round``, ``chamfer``: arrises of 0.5-3 mm, light from either side (azimuth +-10..80 deg), blur
  0.7-1.8 px, gamma 1.0-2.4;
- ``ambient``: rounds and chamfers of 0.5-3 mm under ambient light alone;
- ``small``: rounds and chamfers of 0.5-1 mm under 1.0-1.5 px of blur (where the strip and the blur trade off);
- ``sharp``: doors without an arris (the range's 0 mm end), otherwise as ``round``;
- ``grain``: arrises of 0-3 mm (either profile) with wood grain of 0-10 % along the height (period 2-8 mm);
- ``dark``: rounds and chamfers of 0.5-3 mm whose wood is as dark as the background, under ambient light
  (the arris's outer border has no contrast: it must be refused, or answered with an honest doubt);
- ``focused``, ``focused_dark``: as ``round`` and ``chamfer`` together, and as ``dark``, through a sharp lens
  (0.3-0.7 px of blur);
- ``finish`` (only when named): as ``round`` and ``chamfer`` together on a finish that is no matt surface,
  the renderer's ``finish_exponent`` drawn from 0.5-2 (locate's arc model is Lambertian).
- ``halo``, ``defocus`` (only when named): as ``round`` and ``chamfer`` together, a third of the doors
  plain, through a point spread that is no Gaussian (locate's edge models assume one): a halo of 10-33 % of
  the light at 2-4x the blur, or a defocus disk of 1-3 px radius before 0.3-0.8 px of Gaussian blur;
  ``sharp_halo`` (only when named): ``sharp``'s plain doors through ``halo``'s halo;
- ``sharpened`` (only when named): as ``halo``'s doors through a camera that sharpens its grey levels (an
  unsharp mask of amount 0.3-1, radius 0.8-2 px), which locate does not model.
- ``astigmatic`` (only when named): ``small``'s doors with 0.3-1.2 px more blur along the image's columns
  than along its rows: the bottom end's blur differs from the long edges', which each strip's blur prior
  (the other strips' reading) must not hide.

Per image: the seed, the conditions (with ``diagnostics.noise_scale_ratio`` / ``noise_scale_ratio_box2``
where the first reads under 2), the errors of x, z, yaw and thickness and their claimed sigmas (x, z, yaw:
the answer's ``uncertainty``; thickness: ``diagnostics.thickness_check.sigma_mm``), or the refusal and its
code, and the locate's thread CPU time. Per set: the answered share, RMS of each error, the share within 2
claimed sigma and beyond 5, the refusals by code, and the median and largest locate time; answers whose
thickness the image could not verify (reported under ``locate.thickness_check: report``) are counted apart.
Where more than one set is run, the same over all their doors together (the figures a plant with all those
doors sees).

``--cell-gamma-off`` tells the cell a wrong exponent, within the cell's ``response_unmeasured_factor``
(``within``: the camera's times the factor to a power drawn from -1..1; ``bound``: at -1 or +1, a linear
camera assumed for an sRGB one or the reverse), which is what the arris lines' response doubt is for.
Measured at seed 7300 (n 16; round, chamfer, ambient, small, and grain, dark with the exponent right), the
factor 2.2: the exponent right, 90 % of the arris doors' errors within 0.13 of their sigma (x, z;
thickness 0.09), the worst 0.30; ``within``, the worst 1.27; ``bound``, 90 % within 1.4 and the worst
1.69, every one within 2 (answered: round 9, chamfer 13-14, ambient 11-12, small 5-7 of 16).

    OMP_NUM_THREADS=1 PYTHONPATH=src python bench/bench_arris_range.py [--n 16] [--seed 7000]
        [--sets round,chamfer,ambient,small,sharp,grain,dark,focused,focused_dark,finish,halo,defocus,sharp_halo,sharpened]
        [--thickness-check refuse|report]
        [--recipe-arris-zero]   (every door located with a recipe that gives no arris: untold arrises)
        [--response-factor F]   (a cell whose camera response was measured, e.g. 1.11)
        [--cell-gamma-off within|bound]   (the cell told a wrong exponent: the camera's times the cell's
                                           factor to a power drawn from -1..1 (within), or at +-1 (bound))
        [--off-factor F]   (with --cell-gamma-off: the exponent off by F, not by the cell's factor)
        [--open-limits]   (the cell's limits on the uncertainty opened and the thickness reported: the errors
                           and sigmas of every door, those the cell would refuse counted apart)
        [--light-told]    (the cell states its light's direction, locate.light_direction_deg, as measured
                           once for fixed lamps: the renderer's)
        [--light-error DEG]   (with --light-told: the stated direction DEG off the renderer's, turned a
                               way drawn from the door's seed)
        [--light-sigma DEG]   (the cell's locate.light_direction_sigma_deg; default the cell's, 10)
        [--no-door-light]   (locate.light_from_door false: where no light is stated, a rounding's shading
                             free only, not also sought under the door's own light)
        [--optics-sigma PX]   (the cell's locate.optics_edge_sigma_px; default the cell's, 0.13 px for a camera
                               whose optics nobody measured; 0: the rendered camera's optics exact, the
                               sigmas the image's own doubts)
        [--thickness MM]   (every door this thick; default drawn from 40, 50 and 70 mm)
        [--wrong-thickness MM]   (wrong doors: each door rendered MM thicker than its recipe, negative
                                  thinner, and located with the recipe; every answer is a wrong door passed,
                                  and the refusals say how the thickness check caught the others)
        [--response-ends]   (each answered door located again with the cell's exponent at the two ends of
                             its response_unmeasured_factor: the answer's real move there beside its
                             ``response`` doubt; with --open-limits, the refused doors' too)
        [--measured-photometry]   (the cell carries its camera's photometric model, a power law at the
                                   cell's exponent and no shoulder, as `doorloc check-model --boards` writes
                                   it for a camera that keeps its power law, its edges' held-out residual
                                   the unmeasured optics' doubt (0.13 px): the doubt of a shoulder nobody
                                   measured, ``response_shoulder``, is lifted up to --measured-to)
        [--demosaic bilinear|edge_aware]   (every camera a single-chip colour camera: a Bayer filter's samples
                                            demosaiced by OpenCV before the response; colour images)
        [--srgb]   (every camera delivers the sRGB transfer curve instead of its drawn power law, and the
                    cell states 2.2, as a user says of such a camera: a response no power law is)
        [--bit-depth 8|10|12|14|16]   (every camera's stored depth; 10-14: its levels from 0 in 16-bit
                                       images, the cell stating camera.stored_bits)
        [--measured-to LEVEL]   (with --measured-photometry: the level, fraction of full scale, its board
                                 photographs read the response up to, ``response_measured_to``; default 1,
                                 the whole range: above it a shoulder is still doubted)

``--open-limits`` measures what the model gets wrong on the doors it refuses as uncertain: are their
sigmas as large as their errors (an honest refusal: the model must improve), or far larger (the doubt is
what must shrink)? The limits opened are ``locate.max_uncertainty_mm``, ``max_uncertainty_deg`` and
``max_sigma_mm``, and the thickness check is ``report``; refusals of another kind stay.

``--response-ends`` asks whether the doubt of a response nobody measured is as large as it must be: each
answered door is located again (limits opened, ``response_unmeasured_factor`` 1) with the cell's exponent
times and over the factor (within ``RESPONSE_PLAUSIBLE``), and half the range of the two moves and no move
(the doubt's own rule, :func:`doorloc.vision.doubts.edge_doubts`) is printed beside the answer's
``response`` term of ``diagnostics.uncertainty_budget`` for x, z and the thickness; per set, the median and
the range of their ratio (real over claimed). A ratio well under 1 is a doubt that could shrink; near or
above 1, the doubt is what a cell off by the factor does to the answer, and only a measured response
(a smaller factor) narrows it.
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

from bench_arris import random_effects  # noqa: E402

from doorloc.cell import DoorSize, load_cell  # noqa: E402
from doorloc.photometric.model import PhotometricModel  # noqa: E402
from doorloc.pose import DoorPose, direction_cell, directions_across  # noqa: E402
from doorloc.sim.door import render_door  # noqa: E402
from doorloc.vision.config import LocateConfig  # noqa: E402
from doorloc.vision.locate import locate  # noqa: E402
from doorloc.vision.response import RESPONSE_PLAUSIBLE  # noqa: E402

ROOT = Path(__file__).parents[1]
#: per set: the arris range (mm), the profiles, the blur range (px), light (side or ambient), grain range
SETS: dict[str, dict] = {
    "round": dict(arris=(0.5, 3.0), profiles=("round",), blur=(0.7, 1.8), ambient=False, grain=(0, 0)),
    "chamfer": dict(arris=(0.5, 3.0), profiles=("chamfer",), blur=(0.7, 1.8), ambient=False, grain=(0, 0)),
    "ambient": dict(
        arris=(0.5, 3.0), profiles=("round", "chamfer"), blur=(0.7, 1.8), ambient=True, grain=(0, 0)
    ),
    "small": dict(
        arris=(0.5, 1.0), profiles=("round", "chamfer"), blur=(1.0, 1.5), ambient=False, grain=(0, 0)
    ),
    "sharp": dict(arris=(0.0, 0.0), profiles=("round",), blur=(0.7, 1.8), ambient=False, grain=(0, 0)),
    "grain": dict(
        arris=(0.0, 3.0), profiles=("round", "chamfer"), blur=(0.7, 1.8), ambient=False, grain=(0.0, 0.10)
    ),
    # the arris's wood as dark as the background behind it, under ambient light: its outer border (a
    # rounding's silhouette) has no contrast
    "dark": dict(
        arris=(0.5, 3.0),
        profiles=("round", "chamfer"),
        blur=(0.7, 1.8),
        ambient=True,
        grain=(0, 0),
        arris_as_background=True,
    ),
    # a sharp lens (0.3-0.7 px of blur): every border of a strip resolved, and a strip at one plateau's level
    # indistinguishable from a plain step at its other border
    "focused": dict(
        arris=(0.5, 3.0), profiles=("round", "chamfer"), blur=(0.3, 0.7), ambient=False, grain=(0, 0)
    ),
}
SETS["focused_dark"] = dict(SETS["dark"], blur=(0.3, 0.7))  # ``dark`` through the sharp lens
#: the sets a run takes unless told (``finish`` is asked for by name)
DEFAULT_SETS = tuple(SETS)
# ``round`` and ``chamfer`` together on a finish that is no matt surface: the directional term raised to a
# power drawn log-uniformly from 0.5-2 (a rough finish's flatter shading to a satin one's peak)
SETS["finish"] = dict(SETS["focused"], blur=(0.7, 1.8), finish=(0.5, 2.0))
# ``round`` and ``chamfer`` together, and a third of the doors plain, through point spreads that are no
# Gaussian (locate's edge models assume one): ``halo``, a tenth to a third of the light spread 2-4 times
# wider than the core's blur; ``defocus``, a lens out of focus, a uniform disk of 1-3 px radius and a
# Gaussian of 0.3-0.8 px after it
SETS["halo"] = dict(SETS["focused"], blur=(0.7, 1.8), halo=((0.1, 0.33), (2.0, 4.0)), plain=1 / 3)
SETS["defocus"] = dict(SETS["focused"], blur=(0.3, 0.8), disk=(1.0, 3.0), plain=1 / 3)
SETS["sharp_halo"] = dict(SETS["sharp"], halo=SETS["halo"]["halo"])  # plain doors only, as ``sharp``
# a camera that sharpens its grey levels (an unsharp mask of amount 0.3-1 and radius 0.8-2 px), which locate
# does not model: rounds, chamfers and a third plain, as ``halo``
SETS["sharpened"] = dict(SETS["focused"], blur=(0.7, 1.8), sharpen=((0.3, 1.0), (0.8, 2.0)), plain=1 / 3)
# ``small``'s doors through a lens that blurs more along the image's columns than along its rows (0.3-1.2 px
# more: astigmatism, or the door moving while exposed): the bottom end's blur is not the long edges'
SETS["astigmatic"] = dict(SETS["small"], astigmatism=(0.3, 1.2))


#: the cell's limits on the uncertainty opened and the thickness reported (``--open-limits``, and the
#: relocations of ``--response-ends``): every door answered that locate can place
OPENED_LIMITS: dict = dict(
    max_uncertainty_mm=1e6, max_uncertainty_deg=1e6, max_sigma_mm=1e6, thickness_check="report"
)


@dataclasses.dataclass(frozen=True)
class Outcome:
    """One door's answer: errors and claimed sigmas (mm, deg), or the refusal's code."""

    code: str | None
    errors: tuple[float, float, float, float] = (math.nan,) * 4  # x, z, yaw, thickness
    sigmas: tuple[float, float, float, float] = (math.nan,) * 4
    thickness_verified: bool = True
    over_limits: bool = False  # answered only because the limits were opened (``--open-limits``)
    #: real move at the response factor's ends over the ``response`` doubt, x, z, thickness (``--response-ends``)
    response_ratios: tuple[float, float, float] | None = None
    locate_s: float = math.nan  # the locate's thread CPU time, s (one thread: run with OMP_NUM_THREADS=1)


def draw(name: str, i: int, seed: int):
    """The door, pose, effects and camera gamma of image ``i`` of set ``name`` (all from ``seed``)."""
    spec = SETS[name]
    rng = np.random.default_rng(seed)
    profile = str(rng.choice(spec["profiles"]))
    a = float(rng.uniform(*spec["arris"]))
    door = DoorSize(900, float(rng.choice([40.0, 50.0, 70.0])), 2100, arris_mm=a, arris_profile=profile)
    pose = DoorPose(rng.uniform(-8, 8), rng.uniform(-8, 8), rng.uniform(-1.5, 1.5))
    gamma = float(rng.uniform(1.0, 2.4))
    fx = random_effects(rng, profile, gamma)
    fx = dataclasses.replace(
        fx,
        blur_sigma_px=float(rng.uniform(*spec["blur"])),
        grain_contrast=float(rng.uniform(*spec["grain"])),
        grain_period_mm=float(rng.uniform(2.0, 8.0)),
    )
    if spec.get("finish"):
        lo, hi = spec["finish"]
        fx = dataclasses.replace(fx, finish_exponent=float(math.exp(rng.uniform(math.log(lo), math.log(hi)))))
    if spec.get("halo"):
        (f_lo, f_hi), (s_lo, s_hi) = spec["halo"]
        fx = dataclasses.replace(
            fx,
            blur_halo_fraction=float(rng.uniform(f_lo, f_hi)),
            blur_halo_sigma_px=float(rng.uniform(s_lo, s_hi)) * fx.blur_sigma_px,
        )
    if spec.get("disk"):
        fx = dataclasses.replace(fx, blur_disk_px=float(rng.uniform(*spec["disk"])))
    if spec.get("astigmatism"):
        fx = dataclasses.replace(fx, blur_astigmatism_px=float(rng.uniform(*spec["astigmatism"])))
    if spec.get("sharpen"):
        (a_lo, a_hi), (r_lo, r_hi) = spec["sharpen"]
        fx = dataclasses.replace(
            fx,
            sharpen_amount=float(rng.uniform(a_lo, a_hi)),
            sharpen_radius_px=float(rng.uniform(r_lo, r_hi)),
        )
    if spec.get("plain") and rng.uniform() < spec["plain"]:
        door = dataclasses.replace(door, arris_mm=0.0)
    if spec.get("arris_as_background"):
        fx = dataclasses.replace(fx, albedo_chamfer=fx.albedo_background)
    if spec["ambient"]:
        fx = dataclasses.replace(
            fx, light_ambient=fx.light_ambient + fx.light_directional, light_directional=0.0
        )
    return door, pose, fx, gamma


def told_gamma(gamma: float, factor: float, off: str | None, seed: int) -> float:
    """The exponent the cell states for a camera of ``gamma``: the camera's (``off`` None), or off by the
    cell's ``factor`` to a power drawn from -1..1 (``within``) or at -1 or +1 (``bound``), within the
    exponents cameras have (1.0-2.4); drawn from its own generator, so that the doors stay those of
    ``seed``."""
    if off is None:
        return gamma
    rng = np.random.default_rng(seed + 500_000)
    u = float(rng.uniform(-1.0, 1.0)) if off == "within" else float(rng.choice([-1.0, 1.0]))
    told = gamma * factor**u
    if not 1.0 <= told <= 2.4:  # beyond the cameras' range: the other way
        told = gamma * factor ** (-u)
    return float(np.clip(told, 1.0, 2.4))


def run_one(
    cell,
    door: DoorSize,
    pose: DoorPose,
    fx,
    gamma: float,
    seed: int,
    label: str,
    told: float | None = None,
    limits: LocateConfig | None = None,
    real: DoorSize | None = None,
    response_ends: bool = False,
    photometry: float | None = None,
) -> Outcome:
    """Locate one rendered door and compare with its true pose. ``limits``: the cell's own ``locate``
    settings where ``cell``'s are opened (``--open-limits``): an answer beyond them is marked. ``real``: the
    door in the image where it is not the recipe's ``door`` (``--wrong-thickness``, ``--recipe-arris-zero``);
    the thickness's error is against it. ``response_ends``: the answer located again at the ends of the cell's response factor
    (:func:`response_end_moves`). ``photometry`` (not None): the cell carries its camera's photometric model, the
    power law at the cell's exponent with a held-out edge residual of the cell's ``optics_edge_sigma_px``,
    measured on board photographs that read the response up to this level (``--measured-photometry``,
    ``--measured-to``)."""
    img = render_door(cell, real or door, pose, effects=fx, seed=seed).image
    cell = dataclasses.replace(cell, response_gamma=gamma if told is None else told)
    if photometry is not None:
        # residual_edge_px: what check-model --boards leaves on the photographs' real edges, held out; a cell
        # reads a model without one (nor anything else beyond a power law) as none (Cell.camera_photometry):
        # here the size of the doubt an unmeasured camera's optics get, so that only the shoulder's doubt goes
        # response_measured_to: the level its board photographs read the response up to (--measured-to)
        model = PhotometricModel(
            gamma=cell.response_gamma,
            residual_edge_px=cell.locate.optics_edge_sigma_px,
            response_measured_to=photometry,
        )
        cell = dataclasses.replace(cell, camera_photometry=model)
    t0 = time.thread_time()
    res = locate(img, cell, door)
    locate_s = time.thread_time() - t0
    own = res.diagnostics.get("door_light")
    if own is not None:
        label += f" own light [{own['direction_deg'][0]:+.0f}, {own['direction_deg'][1]:+.0f}]" + (
            "" if own["used"] else " unused"
        )
    ratio = res.diagnostics.get("noise_scale_ratio")
    if ratio is not None and ratio < 2.0:  # the noise read as a sensor's (about 1) or sharpened (below)
        label += f" noise ratio {ratio:.2f}/{res.diagnostics.get('noise_scale_ratio_box2', float('nan')):.2f}"
    if not res.ok:
        print(
            f"  seed {seed:6d} {label:44s} REFUSED {res.error_code}: {(res.error or '')[:110]} "
            f"({locate_s * 1e3:.0f} ms)"
        )
        return Outcome(res.error_code, locate_s=locate_s)
    tc = res.diagnostics.get("thickness_check", {})
    errors = (
        res.x_mm - pose.x_mm,
        res.z_mm - pose.z_mm,
        res.yaw_deg - pose.yaw_deg,
        res.thickness_mm - (real or door).thickness_mm,
    )
    u = res.uncertainty
    sigmas = (u.x_mm, u.z_mm, u.yaw_deg, float(tc.get("sigma_mm", math.nan)))
    verified = bool(getattr(res, "thickness_verified", True) is not False)
    over = limits is not None and (
        max(u.x_mm, u.z_mm) > limits.max_uncertainty_mm
        or u.yaw_deg > limits.max_uncertainty_deg
        or float(res.diagnostics.get("corner_sigma_mm", 0.0)) > limits.max_sigma_mm
        or (not verified and limits.thickness_check == "refuse")
    )
    print(
        f"  seed {seed:6d} {label:44s} ex {errors[0]:+.4f} ez {errors[1]:+.4f} eyaw {errors[2]:+.5f} "
        f"dT {errors[3]:+.4f} sigma {sigmas[0]:.4f} {sigmas[1]:.4f} {sigmas[2]:.5f} {sigmas[3]:.4f}"
        + ("" if verified else " thickness UNVERIFIED")
        + (" OVER THE CELL'S LIMITS" if over else "")
        + f" ({locate_s * 1e3:.0f} ms)"
    )
    ratios = response_end_moves(img, cell, door, res) if response_ends else None
    return Outcome(None, errors, sigmas, verified, over, ratios, locate_s)


def response_end_moves(img, cell, door: DoorSize, res) -> tuple[float, float, float] | None:
    """``res``'s real move where the cell's camera exponent sits at the two ends of its
    ``response_unmeasured_factor``, or of the exponents the door's strips allowed (located again with the
    limits opened and the factor 1): half the range of the two moves and no move, over the answer's
    ``response`` doubt (``diagnostics.uncertainty_budget``), for x, z and the thickness; printed, and returned as those three ratios (None: no response doubt, one
    the image read itself, or a relocation refused)."""
    budget = {b["source"]: b for b in res.diagnostics.get("uncertainty_budget", [])}.get("response")
    factor = cell.locate.response_unmeasured_factor
    if (
        budget is None
        or not factor > 1.0
        or "unchecked_because" not in res.diagnostics.get("camera_response", {})
    ):
        return None  # (a response the image read itself has a doubt of its own)
    # the ends the doubt took: the factor's, or those the door's strips allowed
    told = cell.response_gamma
    ends = res.diagnostics.get("response_from_strips", {}).get("allowed_gammas") or [
        float(np.clip(told / factor, *RESPONSE_PLAUSIBLE)),
        float(np.clip(told * factor, *RESPONSE_PLAUSIBLE)),
    ]
    flat = dataclasses.replace(
        cell,
        locate=dataclasses.replace(cell.locate, response_unmeasured_factor=1.0, **OPENED_LIMITS),
    )
    moves = []
    for g in ends:
        again = locate(img, dataclasses.replace(flat, response_gamma=float(g)), door)
        if not again.ok:
            print(f"      response end {g:.2f}: REFUSED {again.error_code}")
            return None
        moves.append((again.x_mm - res.x_mm, again.z_mm - res.z_mm, again.thickness_mm - res.thickness_mm))
    m = np.array([(0.0, 0.0, 0.0), *moves])
    real = 0.5 * (m.max(axis=0) - m.min(axis=0))
    claimed = np.array([budget.get(k) or math.nan for k in ("x_mm", "z_mm", "thickness_mm")], float)
    ratios = tuple(float(r / c) if c > 0 else math.nan for r, c in zip(real, claimed, strict=True))
    print(
        f"      response ends {ends[0]:.2f} / {ends[1]:.2f}: real half range x {real[0]:.4f} "
        f"z {real[1]:.4f} T {real[2]:.4f} mm against the doubt {claimed[0]:.4f} {claimed[1]:.4f} "
        f"{claimed[2]:.4f} (ratio {ratios[0]:.2f} {ratios[1]:.2f} {ratios[2]:.2f})"
    )
    return ratios  # type: ignore[return-value]


def summary(name: str, rows: list[Outcome]) -> None:
    ok = [r for r in rows if r.code is None]
    codes: dict[str, int] = {}
    for r in rows:
        if r.code is not None:
            codes[r.code] = codes.get(r.code, 0) + 1
    unverified = sum(1 for r in ok if not r.thickness_verified)
    over = sum(1 for r in ok if r.over_limits)
    times = np.array([r.locate_s for r in rows]) * 1e3
    print(
        f"{name}: {len(ok)}/{len(rows)} answered ({len(ok) / max(len(rows), 1):.1%}), "
        f"{unverified} of them with the thickness unverified; refused: {codes or 'none'}"
        + (f"; {over} answered only with the limits opened" if over else "")
        + f"; locate {np.median(times):.0f} ms median, {times.max():.0f} max (thread CPU)"
    )
    if not ok:
        return
    ratios = np.array([r.response_ratios for r in ok if r.response_ratios is not None], float)
    if ratios.size:
        print(
            f"  response doubt against the real move at the factor's ends (real / claimed, n {len(ratios)}): "
            + ", ".join(
                f"{lab} median {np.nanmedian(ratios[:, k]):.2f} ({np.nanmin(ratios[:, k]):.2f}-"
                f"{np.nanmax(ratios[:, k]):.2f})"
                for k, lab in enumerate(("x", "z", "thickness"))
            )
        )
    e, s = np.array([r.errors for r in ok]), np.array([r.sigmas for r in ok])
    for k, (lab, unit) in enumerate((("x", "mm"), ("z", "mm"), ("yaw", "deg"), ("thickness", "mm"))):
        keep = np.isfinite(e[:, k]) & np.isfinite(s[:, k])
        if k == 3:  # the thickness's doubt is judged where it was verified
            keep &= np.array([r.thickness_verified for r in ok])
        if not keep.any():
            continue
        ek, sk = e[keep, k], s[keep, k]
        print(
            f"  {lab:9s} RMS {np.sqrt(np.mean(ek**2)):.4f} {unit}, max |{np.abs(ek).max():.4f}|, "
            f"within 2 sigma {np.mean(np.abs(ek) <= 2 * sk):.0%}, beyond 5 sigma {np.mean(np.abs(ek) > 5 * sk):.0%}, "
            f"median sigma {np.median(sk):.4f} (n {keep.sum()})"
        )


def stated_light(
    azimuth_deg: float, elevation_deg: float, error_deg: float, seed: int
) -> tuple[float, float]:
    """The light's direction as a cell states it: ``error_deg`` off the true ``[azimuth, elevation]``
    (deg), turned about the true direction by an angle drawn from ``seed``; exact where ``error_deg`` is 0."""
    if error_deg == 0.0:
        return azimuth_deg, elevation_deg
    true = direction_cell(azimuth_deg, elevation_deg)
    side, up = directions_across(true)
    turn = np.random.default_rng([seed, 4242]).uniform(0.0, 2 * np.pi)
    e = math.radians(error_deg)
    d = math.cos(e) * true + math.sin(e) * (math.cos(turn) * side + math.sin(turn) * up)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, d[2]))))
    azimuth = math.degrees(math.atan2(d[0], -d[1]))
    return azimuth, elevation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=16, help="doors per set")
    ap.add_argument("--seed", type=int, default=7000, help="first seed; set k uses seed + 1000 k + i")
    ap.add_argument("--sets", default=",".join(DEFAULT_SETS))
    ap.add_argument(
        "--thickness-check",
        choices=("refuse", "report"),
        default=None,
        help="the cell's locate.thickness_check (default: the cell's)",
    )
    ap.add_argument(
        "--response-factor",
        type=float,
        default=None,
        help="the cell's locate.response_unmeasured_factor (default: the cell's, 2.2, a response stated, not "
        "measured); e.g. 1.11, what doorloc calibrate allows for a response measured to +-0.12 at 2.15",
    )
    ap.add_argument(
        "--cell-gamma-off",
        choices=("within", "bound"),
        default=None,
        help="the cell states a wrong exponent: the camera's times the cell's factor to a power drawn from "
        "-1..1 (within) or at -1 or +1 (bound); default: the camera's",
    )
    ap.add_argument(
        "--off-factor",
        type=float,
        default=None,
        help="with --cell-gamma-off: how far the stated exponent may be off, as a factor (default: the cell's "
        "response_unmeasured_factor); e.g. 2.2 with --response-factor 1.11, a cell that trusts a stated "
        "exponent more than a linear camera taken for an sRGB one allows",
    )
    ap.add_argument(
        "--srgb",
        action="store_true",
        help="every camera delivers the sRGB transfer curve (IEC 61966-2-1) instead of its drawn power law, and "
        "the cell states 2.2 (the seeds' doors, lights and blurs stay theirs)",
    )
    ap.add_argument(
        "--demosaic",
        choices=("bilinear", "edge_aware"),
        default=None,
        help="every camera is a single-chip colour camera: the light sampled through a Bayer filter and "
        "demosaiced by OpenCV (bilinear or edge-aware) before its response (the renderer's "
        "Effects.demosaic); the image is colour",
    )
    ap.add_argument(
        "--open-limits",
        action="store_true",
        help="open the cell's limits on the uncertainty and report the thickness: every door's errors and "
        "sigmas, those the cell would refuse marked",
    )
    ap.add_argument(
        "--light-told",
        action="store_true",
        help="the cell states its light (locate.light_direction_deg: the renderer's direction, as a cell that "
        "measured its fixed lamps once would)",
    )
    ap.add_argument(
        "--light-error",
        type=float,
        default=0.0,
        help="with --light-told: the stated direction off the renderer's by this angle, deg, in a direction "
        "drawn from the door's seed (a lamp measured with a tape and stated to a few degrees)",
    )
    ap.add_argument(
        "--no-door-light",
        action="store_true",
        help="locate.light_from_door false: a rounding without a stated light is shaded freely only",
    )
    ap.add_argument(
        "--light-sigma",
        type=float,
        default=None,
        help="the cell's locate.light_direction_sigma_deg (default: the cell's); 0 takes the stated light as exact",
    )
    ap.add_argument(
        "--thickness",
        type=float,
        default=None,
        help="every door this thick, mm (default: drawn from 40, 50 and 70 mm; the rest of each draw unchanged)",
    )
    ap.add_argument(
        "--wrong-thickness",
        type=float,
        default=0.0,
        help="wrong doors: each rendered this many mm thicker than its recipe (negative: thinner) and located "
        "with the recipe; an answer is a wrong door passed",
    )
    ap.add_argument(
        "--recipe-arris-zero",
        action="store_true",
        help="every door located with a recipe that gives no arris (arris_mm 0), whatever its arrises: an "
        "answer for a door with an arris is an untold arris passed (its errors against the door in the image)",
    )
    ap.add_argument(
        "--response-ends",
        action="store_true",
        help="locate each answered door again with the cell's exponent at the ends of its "
        "response_unmeasured_factor and print the real move beside the answer's response doubt",
    )
    ap.add_argument(
        "--measured-photometry",
        action="store_true",
        help="the cell carries its camera's photometric model as `doorloc check-model --boards` measures a "
        "camera that keeps its power law (the cell's exponent, no shoulder; its edges' held-out residual the "
        "cell's optics_edge_sigma_px): the doubt of a shoulder nobody measured is lifted",
    )
    ap.add_argument(
        "--measured-to",
        type=float,
        default=1.0,
        help="with --measured-photometry: the level (fraction of full scale) the model's board photographs "
        "read the response up to (response_measured_to; default 1: the whole range)",
    )
    ap.add_argument(
        "--optics-sigma",
        type=float,
        default=None,
        help="the cell's locate.optics_edge_sigma_px (default: the cell's, 0.13); 0 takes the rendered camera's "
        "optics as exact",
    )
    ap.add_argument(
        "--bit-depth",
        type=int,
        default=8,
        choices=(8, 10, 12, 14, 16),
        help="every camera stores this many bits (10-14: from 0 in 16-bit images, the cell stating "
        "camera.stored_bits)",
    )
    args = ap.parse_args()
    sets = args.sets.split(",")
    if unknown := [s for s in sets if s not in SETS]:
        ap.error(f"unknown set(s) {', '.join(unknown)}; the sets are {', '.join(SETS)}")
    cell = load_cell(ROOT / "fixtures" / "cell_thesis.yaml")
    if args.thickness_check is not None:
        cell = dataclasses.replace(
            cell, locate=dataclasses.replace(cell.locate, thickness_check=args.thickness_check)
        )
    if args.response_factor is not None:
        cell = dataclasses.replace(
            cell, locate=dataclasses.replace(cell.locate, response_unmeasured_factor=args.response_factor)
        )
    if args.no_door_light:
        cell = dataclasses.replace(cell, locate=dataclasses.replace(cell.locate, light_from_door=False))
    if args.light_sigma is not None:
        cell = dataclasses.replace(
            cell, locate=dataclasses.replace(cell.locate, light_direction_sigma_deg=args.light_sigma)
        )
    if args.optics_sigma is not None:
        cell = dataclasses.replace(
            cell, locate=dataclasses.replace(cell.locate, optics_edge_sigma_px=args.optics_sigma)
        )
    if 8 < args.bit_depth < 16:
        cell = dataclasses.replace(cell, stored_bits=args.bit_depth)
    # the first locate of a process loads the compiled kernels: done before any door is timed
    door, pose, fx, gamma = draw(sets[0], 0, args.seed)
    locate(render_door(cell, door, pose, effects=fx, seed=args.seed).image, cell, door)
    limits = None
    if args.open_limits:
        limits = cell.locate
        cell = dataclasses.replace(cell, locate=dataclasses.replace(cell.locate, **OPENED_LIMITS))
    every: list[Outcome] = []
    for name in sets:
        k = list(SETS).index(name)
        rows = []
        for i in range(args.n):
            seed = args.seed + 1000 * k + i
            door, pose, fx, gamma = draw(name, i, seed)
            if args.srgb:
                fx = dataclasses.replace(fx, gamma=1.0, response_curve="srgb")
                gamma = fx.stated_gamma
            if args.demosaic:
                fx = dataclasses.replace(fx, demosaic=args.demosaic)
            if args.bit_depth != 8:
                fx = dataclasses.replace(fx, bit_depth=args.bit_depth)
            if args.thickness:
                door = dataclasses.replace(door, thickness_mm=args.thickness)
            off_by = args.off_factor or cell.locate.response_unmeasured_factor
            told = told_gamma(gamma, off_by, args.cell_gamma_off, seed)
            label = (
                f"{door.arris_profile} a={door.arris_mm:.2f} T={door.thickness_mm:g} "
                f"blur={fx.blur_sigma_px:.2f} "
                + ("sRGB " if args.srgb else f"g={gamma:.2f} ")
                + (f"{args.demosaic} " if args.demosaic else "")
                + (f"az={fx.light_azimuth_deg:+.0f}" if fx.light_directional else "amb")
                + (f" grain={fx.grain_contrast:.3f}" if fx.grain_contrast else "")
                + (f" finish={fx.finish_exponent:.2f}" if fx.finish_exponent != 1.0 else "")
                + (
                    f" halo={fx.blur_halo_fraction:.2f}@{fx.blur_halo_sigma_px:.1f}"
                    if fx.blur_halo_fraction
                    else ""
                )
                + (f" disk={fx.blur_disk_px:.2f}" if fx.blur_disk_px else "")
                + (f" astig={fx.blur_astigmatism_px:.2f}" if fx.blur_astigmatism_px else "")
                + (
                    f" sharpen={fx.sharpen_amount:.2f}@{fx.sharpen_radius_px:.1f}"
                    if fx.sharpen_amount
                    else ""
                )
                + (f" cell {told:.2f}" if args.cell_gamma_off else "")
            )
            lit = (
                dataclasses.replace(
                    cell,
                    locate=dataclasses.replace(
                        cell.locate,
                        light_direction_deg=stated_light(
                            fx.light_azimuth_deg, fx.light_elevation_deg, args.light_error, seed
                        ),
                    ),
                )
                if args.light_told
                else cell
            )
            # the door in the image, and the recipe it is located with (--wrong-thickness, --recipe-arris-zero)
            real = dataclasses.replace(door, thickness_mm=door.thickness_mm + args.wrong_thickness)
            recipe = dataclasses.replace(door, arris_mm=0.0) if args.recipe_arris_zero else door
            rows.append(
                run_one(
                    lit,
                    recipe,
                    pose,
                    fx,
                    gamma,
                    seed,
                    label,
                    told,
                    limits,
                    real if real != recipe else None,
                    args.response_ends,
                    args.measured_to if args.measured_photometry else None,
                )
            )
        wrong = f", every door {args.wrong_thickness:+g} mm off its recipe" if args.wrong_thickness else ""
        wrong += ", every recipe without an arris" if args.recipe_arris_zero else ""
        summary(f"{name} (seeds {args.seed + 1000 * k}..{args.seed + 1000 * k + args.n - 1}{wrong})", rows)
        every += rows
        sys.stdout.flush()
    if len(sets) > 1:  # the acceptance's figures are over all the doors, not set by set
        summary(f"all {len(sets)} sets together ({', '.join(sets)})", every)


if __name__ == "__main__":
    main()

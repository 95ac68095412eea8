"""The camera's response measured from images of the cell's doors: ``camera.response_gamma`` and its doubt.

Where no board photographs measured the camera's response (``doorloc calibrate``), the cell states an
exponent and locate takes it as known only within ``locate.response_unmeasured_factor`` (2.2 unless set): a
door whose every edge is an arris cannot check it, and that doubt refuses many rounded doors as uncertain.
One door's rounded strips hardly tell the exponent (read with a wrong one, a rounding's shading bends away
from every matt arc, but one door's three strips fit some arc under some light about alike under most
exponents: :mod:`doorloc.vision.strip_response`). The lamps and the camera of a cell are fixed, though: read
with the camera's exponent, every door's strips fit matt arcs under *one* light, and with another exponent
they do not. So each door is located with each trial exponent (its strips as locate fits them,
:func:`doorloc.vision.cell_light.rounded_strips`), all the doors' strips are scored together under their
best common light (:func:`doorloc.vision.light_search.light_from_strips`: the mean log misfit ratio of
matt arcs over free shadings; the light sought a quarter as finely again about the best,
:func:`common_light`), and the exponent of the least score is the camera's.

Measured before it was built (8 rounded doors each of three rendered cells, lamps and exponents drawn as
``bench/bench_cell_light.py`` draws them, trial exponents 0.5-2 times the camera's in steps of 15 %, scored
on the light search's own grid): the least score lay at the camera's exponent on all three cells (0.011,
0.032 and 0.079; 0.033-0.30 one step either side), while each door alone put its least anywhere from 0.5 to
1.5 times the camera's. Under a finish that is no matt surface (the renderer's ``finish_exponent`` 0.5 and
2) the least stayed at the camera's exponent on five of six cells and one step (15 %) off on the sixth, the
scores higher (0.05-0.39) and the curve flatter; through a lens halo the arcs fit no better than 0.76.

Where the doors share no lamp (each lit from its own side, daylight through a window, lamps moved
between them), no common light explains their strips at any exponent, or one does on average only (doors
under ambient light, or roundings too small to tell a light, fit every direction alike and flatten the
mean) while two doors or more rule it out (:func:`doorloc.vision.cell_light.doors_ruling_out`); then each
door's strips are scored under the door's own best light (:func:`doorloc.vision.cell_light.own_lights`),
and the doors' scores, weighed by their strips, are averaged per exponent. One door alone tells little,
but its valley lies near the camera's exponent, and many doors' valleys together single it out. Doors
that cannot tell it are left out: those whose strips no matt arc explains under any light at any
exponent of the first grid (a light the search missed, a finish) and those whose own light is a diffuse
one (ambient light, roundings too small). Measured
before it was built (12 rounded doors each of three rendered sets, `bench/bench_arris_range.py`'s
``round`` draws, each door its own lamp, the cameras 1.0, 1.6 and 2.2; 13 exponents over the plausible
range): the common light scored 0.59-1.12 everywhere (no lamp is common), and the own lights' least lay at
0.997, 1.549 and 2.156, the exponents within ``RESPONSE_MARGIN`` of it 0.89-1.11, 1.39-1.73 and 2.16.

So the measurement states the range of exponents whose score lies within ``RESPONSE_MARGIN`` of the least
(the doors cannot rule them out; the light's own margin, ``light_search.RUNNER_UP_MARGIN``), one fine step
wider (the grid's resolution), as its doubt, and refuses where the roundings cannot tell: no rounded
strip, a diffuse light (no common direction), a least score above ``strip_response.ARC_EXPLAINS``'s (the
shading is no matt arc under one light at any exponent: a finish, a halo or a second lamp the model lacks),
or a least at the end of the exponents searched.

The doors can also rule out a shoulder in the response (:mod:`doorloc.vision.response_shoulder`), which a door
located alone doubts wherever its image reaches above ``locate.response_shoulder_knee`` and its own strips
cannot rule it out (a rounding under ambient light, or lit from the front, fits either reading alike). Read
through a shoulder from the knee, with the measured exponent and with the two ends of its range (a shoulder
may pass for another exponent), the doors' strips are scored as above; where the best of them still scores
more than ``RESPONSE_MARGIN`` above the plain reading (as an exponent the doors rule out does), the camera
keeps its power law up to the brightest level the doors reach (:class:`ShoulderReading`), and the doubt is
taken from there only. Measured before it was built (the six jobs of ``bench/bench_batch_response.py --sets
round,chamfer`` at seeds 9000 and 9100, eight rounded doors each, rendered with a power law, the shoulder read
at the measured exponent): three jobs' doors fit the shoulder 1.25-1.46 times worse (mean log ratio +0.27 to
+0.38 over the plain reading's, though several of their doors alone could not tell), three hardly worse
(+0.003 to +0.037); about 10 s of locates a reading.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from doorloc.cell import Cell, DoorSize
from doorloc.vision import light_search as ls
from doorloc.vision.cell_light import DISAGREEING_DOORS, doors_ruling_out, own_lights, rounded_strips
from doorloc.vision.light_search import LightMeasurement
from doorloc.vision.luminance import luminance_plane
from doorloc.vision.response import RESPONSE_PLAUSIBLE
from doorloc.vision.response_shoulder import shouldered_camera
from doorloc.vision.strip_response import ARC_EXPLAINS, ARC_RULED_OUT

__all__ = [
    "RESPONSE_COARSE_STEPS",
    "RESPONSE_FACTOR_FLOOR",
    "RESPONSE_FINE_STEPS",
    "RESPONSE_MARGIN",
    "ResponseMeasurement",
    "ResponseNotMeasurable",
    "ShoulderReading",
    "common_light",
    "doors_agree",
    "exponent_range",
    "measure_cell_response",
]

#: exponents of the first grid, spread evenly in log over ``response.RESPONSE_PLAUSIBLE`` (16 % apart)
RESPONSE_COARSE_STEPS = 10
#: the fine grid divides a coarse step into this many, and reaches this many fine steps each way of the
#: coarse least
RESPONSE_FINE_STEPS = 4
#: exponents whose all-doors score lies within this of the least: the doors cannot rule them out
RESPONSE_MARGIN = ls.RUNNER_UP_MARGIN
#: the least doubt stated, as a factor on the exponent (``locate.response_unmeasured_factor``): matt arcs
#: under one light are a model of the doors, not the doors (the arris bench's measured-response sets use 1.11)
RESPONSE_FACTOR_FLOOR = 1.1


class ResponseNotMeasurable(ValueError):
    """The door images cannot tell the camera's response (the message says why and what to do)."""


@dataclass(frozen=True)
class ShoulderReading:
    """The doors read through a shoulder in the camera's response (:func:`measure_cell_response`).

    ``knee``: the level (fraction of full scale) the shoulder was tried from (``locate.
    response_shoulder_knee``); ``reached``: the brightest level of the doors' images; ``plain`` and
    ``shouldered``: the doors' all-doors score read as a power law with the measured exponent and through the
    shoulder with ``gamma``, the exponent of the measured range that fits it best (the same doors, the same
    scoring as the exponents'); ``ruled_out``: whether the shouldered reading scores more than
    ``RESPONSE_MARGIN`` above the plain one, as an exponent the doors rule out does."""

    knee: float
    reached: float
    plain: float
    shouldered: float
    gamma: float

    @property
    def ruled_out(self) -> bool:
        """Whether the doors' strips rule the shoulder out."""
        return self.shouldered - self.plain > RESPONSE_MARGIN

    @property
    def doubted_from(self) -> float:
        """The level from which a shoulder is still doubted (``locate.response_shoulder_knee`` for the doors
        located with this measurement): above the brightest level the doors reached where they rule it
        out, else from the knee tried."""
        return max(self.knee, self.reached) if self.ruled_out else self.knee


@dataclass(frozen=True)
class ResponseMeasurement:
    """A camera response measured by :func:`measure_cell_response`.

    ``gamma``: the exponent (``camera.response_gamma``); ``sigma``: the 1-sigma to state with it
    (``camera.response_gamma_sigma``), such that ``doorloc.cell.measured_response_factor(gamma, sigma)`` is
    ``factor``, the range the doors allow (the exponents within ``RESPONSE_MARGIN`` of the least, one fine
    step wider, at least ``RESPONSE_FACTOR_FLOOR``); ``scores``: each exponent tried and its all-doors
    score (the mean log misfit ratio of matt arcs over free shadings under the strips' best common light,
    0: as well as a free shading), in increasing exponent; ``cell_score``: the score of the cell's own
    exponent; ``light``: the light the strips fit best read with ``gamma`` (None where the doors share no
    lamp: ``own_lights``, each door's strips scored under its own light); ``strips`` rounded strips of
    ``doors`` doors; ``shoulder``: the doors read through a shoulder (None where no door's image reaches
    above ``locate.response_shoulder_knee``, or the knee is 1: no shoulder is doubted)."""

    gamma: float
    sigma: float
    factor: float
    scores: tuple[tuple[float, float], ...]
    cell_gamma: float
    cell_score: float
    light: LightMeasurement | None
    strips: int
    doors: int
    own_lights: bool = False
    shoulder: ShoulderReading | None = None

    @property
    def cell_ruled_out(self) -> bool:
        """Whether the cell's own exponent lies outside the range the doors allow."""
        return not (self.gamma / self.factor <= self.cell_gamma <= self.gamma * self.factor)

    def applied_to(self, cell: Cell) -> Cell:
        """``cell`` with this measurement: its camera's exponent and 1-sigma, the doubt of the exponent the
        measured range (``locate.response_unmeasured_factor``), and a shoulder doubted only from where the
        doors left it open (``locate.response_shoulder_knee``: :attr:`ShoulderReading.doubted_from`)."""
        knee = cell.locate.response_shoulder_knee if self.shoulder is None else self.shoulder.doubted_from
        return replace(
            cell,
            response_gamma=self.gamma,
            response_gamma_sigma=self.sigma,
            locate=replace(cell.locate, response_unmeasured_factor=self.factor, response_shoulder_knee=knee),
        )


def _trial_cell(cell: Cell, gamma: float) -> Cell:
    """``cell`` with its camera's exponent ``gamma`` taken as exact: every strip read with it (no image's own
    reading in its place, no second reading at the ends of a doubt no one asks for here)."""
    return replace(
        cell,
        response_gamma=float(gamma),
        response_gamma_sigma=1e-6,
        locate=replace(cell.locate, response_check="where_unmeasured", response_unmeasured_factor=1.0),
    )


def measure_cell_response(
    frames: Sequence[tuple[np.ndarray, DoorSize]],
    cell: Cell,
    *,
    progress: Callable[[str], None] | None = None,
) -> ResponseMeasurement:
    """The camera's response exponent from images of the cell's doors, ``frames`` (image, door) pairs, the
    doors with rounded arrises under the cell's fixed lamp (chamfers and sharp edges do not tell it).

    Each door is located with every trial exponent (``RESPONSE_COARSE_STEPS`` over
    ``response.RESPONSE_PLAUSIBLE``, then ``RESPONSE_FINE_STEPS`` finer steps each way of the least, and
    the cell's own), its rounded strips kept; per exponent all the strips are scored under their best
    common light (:func:`common_light`). ``progress`` hears a line per exponent. About two dozen
    locates per door: a minute for eight doors on one core.

    Raises
    ------
    ResponseNotMeasurable
        No door with a rounded arris (or no strip located), a diffuse light, a shading no matt arc
        explains at any exponent, or a least at the end of the exponents searched.
    """
    if cell.camera_photometry is not None:
        raise ResponseNotMeasurable(
            "the cell's camera carries a measured photometric model (camera.photometric_model or its "
            "calibration's): its response is measured already; remove the model to measure it from doors"
        )
    if not any(door.arris_mm > 0 and door.arris_profile == "round" for _, door in frames):
        raise ResponseNotMeasurable(
            "no door with a rounded arris among the images (arris_profile round, arris_mm > 0 in the cell's "
            "default door or the manifest): only a rounding's shading tells the camera's response"
        )
    lo, hi = RESPONSE_PLAUSIBLE
    readings = _Readings(frames, cell, progress)
    readings.read(np.geomspace(lo, hi, RESPONSE_COARSE_STEPS).tolist())
    g_coarse = min(readings.scores, key=readings.scores.__getitem__)
    if readings.scores[g_coarse] > math.log(ARC_EXPLAINS) or readings.doors_disagree_on_light(g_coarse):
        readings.take_own_lights()  # (no common lamp explains the doors at any exponent, or some rule it out)
        g_coarse = min(readings.scores, key=readings.scores.__getitem__)
    if not readings.own_lights:
        _not_diffuse(readings.lights[g_coarse])  # (said before the finer grid is read)
    step = (hi / lo) ** (1.0 / ((RESPONSE_COARSE_STEPS - 1) * RESPONSE_FINE_STEPS))
    fine = [g_coarse * step**k for k in range(-RESPONSE_FINE_STEPS + 1, RESPONSE_FINE_STEPS) if k != 0]
    readings.read([g for g in fine if lo <= g <= hi] + [cell.response_gamma])
    readings.keep_steady_doors()
    scores, strips = readings.scores, readings.strips
    gamma, factor = exponent_range(scores, step)
    if readings.own_lights:
        doors_agree(readings.own_scores, gamma)
    else:
        _not_diffuse(readings.lights[gamma])
    ends = (gamma / factor, gamma, gamma * factor)
    shoulder = readings.read_shoulder(gamma, ends, cell.locate.response_shoulder_knee)
    return ResponseMeasurement(
        gamma=gamma,
        sigma=(factor - 1.0) * gamma / 2.0,
        factor=factor,
        scores=tuple(sorted(scores.items())),
        cell_gamma=cell.response_gamma,
        cell_score=scores[float(cell.response_gamma)],
        light=None if readings.own_lights else _light(strips[gamma]),
        strips=sum(len(d) for d in strips[gamma]),
        doors=sum(1 for d in strips[gamma] if d),
        own_lights=readings.own_lights,
        shoulder=shoulder,
    )


class _Readings:
    """The doors read with trial exponents: per exponent every door's rounded strips (``strips``) and their
    all-doors score (``scores``): under their best common light (:func:`common_light`, ``lights``), or,
    once :meth:`take_own_lights` found that no lamp is common to the doors, each door's under its own
    (:func:`own_lights`, ``own``) averaged over the doors, weighed by their strips."""

    def __init__(
        self,
        frames: Sequence[tuple[np.ndarray, DoorSize]],
        cell: Cell,
        progress: Callable[[str], None] | None,
    ) -> None:
        self.frames, self.cell, self.progress = list(frames), cell, progress
        self.strips: dict[float, list[list[ls.StripScore]]] = {}
        self.lights: dict[float, LightMeasurement] = {}  # (:func:`common_light`)
        self.own: dict[float, list[LightMeasurement | None]] = {}  # (:func:`own_lights`, once ``own_lights``)
        self.own_lights = False

    @property
    def scores(self) -> dict[float, float]:
        """Each exponent read and its all-doors score."""
        if not self.own_lights:
            return {g: m.score for g, m in self.lights.items()}
        return {g: _strip_weighted_mean(v, self.strips[g]) for g, v in self.own_scores.items()}

    @property
    def own_scores(self) -> dict[float, list[float | None]]:
        """Per exponent read, each door's score under its own light (None: a door without a strip)."""
        return {g: [None if m is None else m.score for m in v] for g, v in self.own.items()}

    def read(self, gammas: Sequence[float]) -> None:
        """Locate every door with each of ``gammas`` not read yet, and score its strips."""
        for g in map(float, gammas):
            if g in self.strips:
                continue
            self.strips[g] = rounded_strips(self.frames, _trial_cell(self.cell, g))
            n_strips = sum(len(d) for d in self.strips[g])
            if n_strips == 0:
                raise ResponseNotMeasurable(
                    f"locate fitted no rounded arris strip on these images read with exponent {g:.2f}: they "
                    "cannot tell the response (check that the doors are in the fixture and their recipes' "
                    "arris_mm)"
                )
            if self.own_lights:
                self.own[g] = own_lights(self.strips[g])
            else:
                self.lights[g] = common_light(self.strips[g])
            if self.progress is not None:
                under = "each door's own light" if self.own_lights else "one light"
                self.progress(
                    f"exponent {g:.3f}: {n_strips} rounded strips fit matt arcs under {under} at "
                    f"{self.scores[g]:.3f} ({len(self.strips)} exponents tried)"
                )

    def read_shoulder(self, gamma: float, exponents: Sequence[float], knee: float) -> ShoulderReading | None:
        """The doors read through a shoulder from ``knee`` (fraction of full scale) with each of
        ``exponents`` (the measured range's), scored as the exponents are, the best of them against the plain
        reading with ``gamma`` (the least) on the same doors (those whose strips both readings located
        alike); None where the knee is 1 or no door's image reaches above it (no shoulder is doubted there),
        or no door's strips were located alike."""
        reached = max(_brightest(image, self.cell) for image, _ in self.frames)
        if not (knee < 1.0 and reached > knee):
            return None
        plain = self.strips[gamma]
        readings = []
        for g in exponents:
            bent_cell = replace(_trial_cell(self.cell, g), camera_photometry=shouldered_camera(g, knee))
            bent = rounded_strips(self.frames, bent_cell)
            alike = [k for k, (p, b) in enumerate(zip(plain, bent, strict=True)) if p and len(p) == len(b)]
            if alike:
                # (the plain reading's score on every door with strips is the exponent's own, already found)
                every = len(alike) == sum(1 for p in plain if p)
                p_score = self.scores[gamma] if every else self._score([plain[k] for k in alike])
                b_score = self._score([bent[k] for k in alike])
                readings.append(ShoulderReading(knee, reached, p_score, b_score, float(g)))
        if not readings:
            return None
        reading = min(readings, key=lambda r: r.shouldered - r.plain)
        if self.progress is not None:
            self.progress(
                f"through a shoulder from {knee:g} of full scale the strips fit at best at {reading.shouldered:.3f} "
                f"(exponent {reading.gamma:.3f}) against {reading.plain:.3f}: "
                + ("ruled out" if reading.ruled_out else "not ruled out")
                + f" up to {reached:.2f}, the brightest level of the doors"
            )
        return reading

    def _score(self, strips: list[list[ls.StripScore]]) -> float:
        """The all-doors score of ``strips`` (per door), as the exponents' are scored now: under their best
        common light, or each door's under its own light, weighed by its strips."""
        if not self.own_lights:
            return common_light(strips).score
        own = [None if m is None else m.score for m in own_lights(strips)]
        return _strip_weighted_mean(own, strips)

    def doors_disagree_on_light(self, gamma: float) -> bool:
        """Whether ``cell_light.DISAGREEING_DOORS`` doors or more, read with ``gamma``, rule out the light
        common to the doors (:func:`doorloc.vision.cell_light.doors_ruling_out`): each has a lamp of its own.
        Doors lit from many sides can still score under one light within ``ARC_EXPLAINS`` on average, where
        doors under ambient light (whose strips fit every direction alike) or roundings too small to tell a
        light make up much of the mean."""
        light = self.lights[gamma].direction_deg
        return len(doors_ruling_out(self.strips[gamma], light)) >= DISAGREEING_DOORS

    def take_own_lights(self) -> None:
        """Score every exponent read, and those read from now on, under each door's own light, and leave out
        the doors that tell nothing of the exponent (:func:`_tells_exponent`)."""
        lights = {g: own_lights(d) for g, d in self.strips.items()}
        kept = [k for k in range(len(self.frames)) if _tells_exponent([v[k] for v in lights.values()])]
        if not kept:
            raise ResponseNotMeasurable(
                "no door's roundings tell the exponent: no light common to the doors explains them, and under "
                "each door's own light they fit no matt arc at any exponent (a finish, a second lamp or a lens "
                "the model lacks) or shade alike from every direction (ambient light, roundings too small); "
                "measure the response on board photographs (doorloc calibrate) instead"
            )
        self.own_lights = True
        self.frames = [self.frames[k] for k in kept]
        for g, per_door in lights.items():
            self.strips[g] = [self.strips[g][k] for k in kept]
            self.own[g] = [per_door[k] for k in kept]
        self.lights.clear()
        if self.progress is not None:
            self.progress(
                "no light common to the doors explains their roundings (each door has its own lamp): each "
                f"door's strips scored under its own light, on the {len(kept)} doors lit from one side whose "
                "strips some matt arc explains"
            )

    def keep_steady_doors(self) -> None:
        """Score every exponent again on the doors read alike with all of them (:func:`_steady_doors`) where
        some door's strips were lost with some exponents: it would score only with the others."""
        steady = _steady_doors(self.strips)
        ever = sum(1 for k in range(len(self.frames)) if any(d[k] for d in self.strips.values()))
        if len(steady) == ever:
            return
        if not steady:
            raise ResponseNotMeasurable(
                "no door's rounded strips were located alike with every exponent tried: the doors cannot "
                "tell the response (check their recipes' arris sizes and the images' exposure)"
            )
        self.frames = [self.frames[k] for k in steady]
        for g in self.strips:
            self.strips[g] = [self.strips[g][k] for k in steady]
            if self.own_lights:
                self.own[g] = [self.own[g][k] for k in steady]
            else:
                self.lights[g] = common_light(self.strips[g])
        if self.progress is not None:
            self.progress(
                f"scored again on the {len(steady)} doors whose rounded strips every exponent located"
            )


def _brightest(image: np.ndarray, cell: Cell) -> float:
    """The brightest level of ``image``'s luminance as locate reads it (its camera's stored bits brought to
    full scale), a fraction of full scale: the level a door's shoulder doubt is weighed against
    (:func:`doorloc.vision.response_shoulder.shoulder_doubted`)."""
    plane = luminance_plane(image, cell.response_gamma, cell.stored_bits).plane
    top = 255.0 if plane.dtype == np.uint8 else 65535.0
    return float(plane.max()) / top


def _tells_exponent(door: Sequence[LightMeasurement | None]) -> bool:
    """Whether one door's own lights, one per exponent of the first grid (``door``), can tell the exponent:
    some matt arc explains its strips (a least score within ``ARC_EXPLAINS``: not a light the search
    missed, nor a finish), and under its least the light is no diffuse one (no more than
    ``light_search.DIFFUSE_SHARE`` of the directions alike: ambient light, or roundings too small to show
    a direction, shade alike under every exponent and only flatten the doors' mean)."""
    read = [m for m in door if m is not None]
    if not read:
        return False
    least = min(read, key=lambda m: m.score)
    return least.score <= math.log(ARC_EXPLAINS) and least.alike_share <= ls.DIFFUSE_SHARE


def doors_agree(own: Mapping[float, Sequence[float | None]], gamma: float) -> None:
    """Raise :class:`ResponseNotMeasurable` where some door's strips, each scored under its own light
    (``own``: per exponent, per door), rule ``gamma`` out as locate's own reading of one door's strips does
    (:data:`doorloc.vision.strip_response.ARC_RULED_OUT` times its best score's misfit): the doors disagree
    on their camera's exponent (more than one camera, or a gamma setting changed between the images), and
    one exponent for all would be answered with a doubt too small for some. (On 12 rounded doors of one
    camera, each its own lamp, the measured exponent scored within 1.035 of every door's best.)"""
    ruled_out = math.log(ARC_RULED_OUT)
    for k in range(len(own[gamma])):
        door = {g: v for g, per_door in own.items() if (v := per_door[k]) is not None}
        if gamma not in door:
            continue
        best = min(door, key=door.__getitem__)
        if door[gamma] - door[best] > ruled_out:
            raise ResponseNotMeasurable(
                f"the doors disagree on the camera's response: one door's roundings fit best read with exponent "
                f"{best:.2f} and {math.exp(door[gamma] - door[best]):.2f} times worse with {gamma:.2f}, which the "
                "others prefer: more than one camera, or a gamma setting changed between the images? Measure "
                "each camera's response apart (doorloc calibrate on board photographs)"
            )


def _strip_weighted_mean(scores: Sequence[float | None], strips: Sequence[Sequence[ls.StripScore]]) -> float:
    """The doors' ``scores`` averaged, each weighed by its number of ``strips`` (as the common light's score
    weighs every strip alike); doors without a strip left out."""
    pairs = [(v, len(d)) for v, d in zip(scores, strips, strict=True) if v is not None and d]
    n = sum(k for _, k in pairs)
    return sum(v * k for v, k in pairs) / n if n else math.inf


def common_light(strips: Sequence[Sequence[ls.StripScore]]) -> LightMeasurement:
    """The best common light of the doors' rounded strips (``strips``, per door) and their mean log misfit
    ratio under it (``score``): :func:`doorloc.vision.light_search.light_from_strips` (its grid, a quarter
    step finer one step around the best, every direction stated), then
    :func:`doorloc.vision.light_search.finer_light` about that best and its rivals (a lamp low beside the
    doors leaves a valley in the score narrower than the first grid's steps, which would hide the
    exponent's)."""
    return ls.finer_light(strips, ls.light_from_strips(strips, fine_steps=1, diffuse_share=math.inf))


def _steady_doors(read: dict[float, list[list[ls.StripScore]]]) -> list[int]:
    """The doors (their places in each exponent's list) with the same number of rounded strips, at least
    one, under every exponent read (``read``: per exponent, per door its strips' scores)."""
    counts = np.array([[len(door) for door in doors] for doors in read.values()])  # (exponents, doors)
    return [k for k in range(counts.shape[1]) if counts[0, k] > 0 and np.all(counts[:, k] == counts[0, k])]


def _not_diffuse(light: LightMeasurement) -> None:
    """Raise :class:`ResponseNotMeasurable` where ``light``'s first grid scored more than
    ``light_search.DIFFUSE_SHARE`` of its directions alike (a diffuse light tells no exponent), as
    :func:`doorloc.vision.light_search.light_from_strips` refuses a light there."""
    if light.alike_share > ls.DIFFUSE_SHARE:
        raise ResponseNotMeasurable(
            f"the doors' roundings are shaded about alike under {light.alike_share:.0%} of the directions "
            "tried: the light is diffuse (or the roundings too small to tell it), and the roundings cannot "
            "tell the camera's response either: measure it on board photographs (doorloc calibrate)"
        )


def _light(strips: list[list[ls.StripScore]]) -> LightMeasurement:
    """The light the strips fit best (:func:`doorloc.vision.light_search.light_from_strips`, its direction and
    score :func:`doorloc.vision.light_search.finer_light`'s about it)."""
    # (not diffuse: the strips' light was checked, :func:`_not_diffuse`, on the same first grid)
    return ls.finer_light(strips, ls.light_from_strips(strips, diffuse_share=math.inf))


def exponent_range(scores: Mapping[float, float], step: float) -> tuple[float, float]:
    """The exponent of the least all-doors score and the factor about it the doors allow, from each trial
    exponent's score (``scores``, as :class:`ResponseMeasurement`'s) and the fine grid's step (a factor):
    the widest ratio to an exponent scoring within ``RESPONSE_MARGIN`` of the least, times ``step`` (the
    camera's exponent may lie up to a step beyond the last one tried there), at least
    ``RESPONSE_FACTOR_FLOOR``.

    Raises
    ------
    ResponseNotMeasurable
        The least score is above ``strip_response.ARC_EXPLAINS``'s (no matt arc under one light explains
        the roundings at any exponent), or the least lies within a step of ``response.RESPONSE_PLAUSIBLE``'s
        ends.
    """
    lo, hi = RESPONSE_PLAUSIBLE
    g_best = min(scores, key=scores.__getitem__)
    least = scores[g_best]
    if not least <= math.log(ARC_EXPLAINS):
        raise ResponseNotMeasurable(
            f"the doors' roundings fit no matt arc under one light at any exponent (at best {least:.2f}, "
            f"{math.exp(least):.2f} times a free shading's misfit): a finish, a second lamp or a lens the "
            "model lacks; measure the response on board photographs (doorloc calibrate) instead"
        )
    if g_best <= lo * step or g_best >= hi / step:
        raise ResponseNotMeasurable(
            f"the doors' roundings fit best read with exponent {g_best:.2f}, at the end of those a camera's "
            f"response may have ({lo:g}-{hi:g}): check the camera's gamma or tone-curve setting and the "
            "doors' arris sizes and profiles"
        )
    near = [g for g, v in scores.items() if v <= least + RESPONSE_MARGIN]
    reach = max(max(g / g_best, g_best / g) for g in near) * step
    return g_best, max(reach, RESPONSE_FACTOR_FLOOR)

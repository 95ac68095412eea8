"""The camera exponents a door's rounded strips allow, where no plain edge could measure the response.

Where every edge of a door is an arris, the image's plain-edge response reading has nothing to read, the
cell's ``camera.response_gamma`` is taken as known within ``locate.response_unmeasured_factor``, and each
arris line's response doubt is the move of its strip reading between the factor's two ends
(:func:`doorloc.vision.doubts.edge_doubts`). A rounding's strip can say more. Under a light from one
direction its shading, in linear light, is a matt arc's: ``albedo (ambient + directional max(0, n.l))``
over the arc's normals ``n``, which the strip model fits under trial lights
(``StripFit.misfit_under_lights``); grey levels turned to light with a wrong exponent bend that shading
away from every arc. So the strips read again with each trial exponent are also scored as arcs under
their best light (:func:`arc_score`, the door's own light's search, :func:`doorloc.vision.light_search.
light_from_strips`, with a shorter fine grid), and an exponent whose arcs fit markedly worse than the best exponent's
(:data:`ARC_RULED_OUT`) is ruled out: the doubt's end on that side moves inwards, half way between the
last exponent the strips allow and the first they rule out (:func:`allowed_response_ends`).

A chamfer's strip is one level under any exponent, but its two borders are blurred steps, which a wrong
exponent skews as it skews a plain edge: a chamfered door's strips read with each trial exponent are
scored by how well their fitted profiles reproduce the image in the camera's own grey levels
(:func:`grey_score`, ``StripFit.grey_misfit``; in linear light the noise itself changes with the exponent
tried, and that misfit was lowest at a wrong exponent on many doors), and an exponent scoring
:data:`GREY_RULED_OUT` times the best is ruled out the same way.

It rules out nothing where the strips give no such evidence: a rounding under ambient light alone or one
narrower than the blur, a chamfer narrow or faint enough (every exponent fits alike), a finish the arc
does not describe (its best fit more than :data:`ARC_EXPLAINS` times the free shading's misfit), chamfers
whose best reading misses the image by more than :data:`GREY_EXPLAINS` times its noise, and where the
cell's own exponent is itself ruled out (the cell is wrong for this camera: the gate refuses the
door ``uncertain``, the cell's exponent and the one the strips prefer named). Measured before it was built (rendered roundings of the arris range bench, seeds
7900 and 9100, the door located with the cell stating each of seven exponents across the factor): with
the cell right, the best arcs fit within 1.00-1.07 of the free shading at the camera's exponent, and at
the factor's ends up to 1.1-3.5 times; with the cell told the wrong end of the factor, the cell's exponent
was ruled out, or the camera's was among those kept (docs/benchmarks.md, 2026-11-30); on 130 chamfered
doors (arris bench chamfer, ambient and small sets, seeds 10100-13115, five exponents across the factor
each) the camera's exponent scored within 1.03 of the best, the cell told right, 2.2 times or 1/2.2 times
the camera's (docs/benchmarks.md, 2026-11-30).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from doorloc.vision.light_search import StripScore, light_of_one_door
from doorloc.vision.response import RESPONSE_PLAUSIBLE

__all__ = [
    "ARC_EXPLAINS",
    "ARC_RULED_OUT",
    "CELL_DISPUTED",
    "GREY_EXPLAINS",
    "GREY_RULED_OUT",
    "AllowedEnds",
    "CellDisputed",
    "ReadStrips",
    "StripReadings",
    "allowed_response_ends",
    "arc_score",
    "grey_score",
]

#: the rounded strips' best matt arc fits about as well as their free shading (misfit ratio at most this)
#: at some exponent: the arc describes the finish, and its misfit can rule exponents out
ARC_EXPLAINS = 1.15
#: an exponent whose best arcs' misfit exceeds the best exponent's by this ratio is ruled out (the light
#: search's own margin between directions it cannot tell apart is 1.05; on the rendered roundings a right
#: cell's exponent scored within 1.15 of the best and a wrong one's 1.17-3.5 where it could be told)
ARC_RULED_OUT = 1.25
#: the chamfered strips' best reading misses the image by at most this many times its grey-level noise
#: (``StripFit.grey_misfit``): the one-level strip between blurred borders describes them
GREY_EXPLAINS = 2.0
#: an exponent whose chamfered strips' grey-level misfit exceeds the best exponent's by this ratio is ruled
#: out (on the arris bench's 130 chamfered doors the camera's scored within 1.03 of the best; as the arcs')
GREY_RULED_OUT = 1.25
#: why nothing was narrowed where the cell's own exponent is ruled out (the gate refuses such a door)
CELL_DISPUTED = (
    "the cell's exponent fits the arris strips worse than another: the cell's response_gamma is in doubt"
)
#: the finer light grid's steps each way around the coarse best when scoring an exponent (the door's own
#: light takes 2: 24 more directions; 1 takes 8, the search a quarter cheaper, and every exponent is scored
#: alike)
ARC_FINE_STEPS = 1
#: the least factor between the cell's exponent and the one the strips fit best for the cell's to be disputed
DISPUTE_APART = 1.2
#: why nothing was narrowed where an exponent near the cell's fits better than the cell's
NEAR_BEST = "an exponent near the cell's fits the arris strips better than the cell's: nothing is told"
#: fractions of the factor's reach (in log exponent) read on a side whose end is ruled out, inwards
INNER_STEPS = (0.5,)


def arc_score(strips: Sequence[StripScore]) -> float:
    """The rounded strips' mean log misfit ratio (matt arc over free shading) under the light they fit best
    (``light_search.light_of_one_door``, every direction stated), at least 0; NaN where there is no
    rounded strip.

    An arc fitting better than the free shading (a ratio under 1) says the free fit missed its best place
    at that exponent, not that the exponent is right: under ambient light alone (arris bench ambient seed
    11101, a camera of 2.07) the strips read with 1.09 scored 0.80 and made a cell of 2.40, scoring 1.05,
    look 1.32 times worse."""
    light = light_of_one_door(strips, fine_steps=ARC_FINE_STEPS)
    return math.nan if light is None else max(float(light.score), 0.0)


def grey_score(grey_misfits: Sequence[float]) -> float:
    """The chamfered strips' mean log misfit in the camera's grey levels (``StripFit.grey_misfit``); NaN
    where there is none, or one was not measured."""
    values = np.asarray(grey_misfits, float)
    if not values.size or not np.all(np.isfinite(values) & (values > 0)):
        return math.nan
    return float(np.mean(np.log(values)))


@dataclass(frozen=True)
class StripReadings:
    """Arris strips read again with trial camera exponents (:func:`doorloc.vision.refine.
    arris_response_shifts`): per arris line the shift of its points at each exponent (px, NaN where its
    strip was lost there), the strips' score at each exponent and at the exponent in use (NaN: none), and
    what the scores are: ``"arcs"`` (the rounded strips' :func:`arc_score`) or ``"chamfers"`` (the
    chamfered strips' :func:`grey_score`)."""

    shifts: dict[str, np.ndarray]
    scores: np.ndarray
    used_score: float
    evidence: str = "arcs"


#: exponents in, and which readings to score (``"all"``; ``"trials"``: not the exponent in use;
#: ``"none"``), the strips read with each out
ReadStrips = Callable[[list[float], str], StripReadings]


@dataclass(frozen=True)
class CellDisputed:
    """The door's arris strips rule out the cell's own camera exponent: they fit best when read with
    ``best_gamma``, and ``cell_over_best`` times worse (misfit ratio) with the cell's; ``evidence`` as
    :attr:`StripReadings.evidence` (rounded strips as matt arcs, or chamfered ones in grey levels)."""

    best_gamma: float
    cell_over_best: float
    evidence: str = "arcs"


@dataclass(frozen=True)
class AllowedEnds:
    """The two ends of the camera exponents an arris door's response doubt spans, and each arris line's
    shift there (px; NaN where its strip was lost: the caller takes the plain step's figure).

    ``gammas``: (upper, lower) exponent; ``shifts``: per line (upper, lower) shift; ``figure``: what the
    strips showed, for the diagnostics (exponents read, the strips' misfits there, and why nothing was
    ruled out where so); ``disputed``: where the strips rule out the cell's own exponent (the gate refuses
    the door), else None."""

    gammas: tuple[float, float]
    shifts: dict[str, tuple[float, float]]
    figure: dict = field(default_factory=dict)
    disputed: CellDisputed | None = None


@dataclass(frozen=True)
class _Rules:
    """How one kind of evidence (:attr:`StripReadings.evidence`) rules exponents out: the best score that
    says the model describes the strips (log), the ratio over the best beyond which an exponent is ruled out,
    the strips' name, the figure's key in the diagnostics and why nothing is ruled out where the best score
    is beyond ``explains``."""

    evidence: str
    explains: float
    ruled_out: float
    strips: str
    key: str
    unexplained: str


_RULES = {
    rules.evidence: rules
    for rules in (
        _Rules(
            "arcs",
            math.log(ARC_EXPLAINS),
            ARC_RULED_OUT,
            "rounded strips",
            "arc_misfit_over_free",
            "no matt arc shades the rounded strips as well as a free shading at any exponent tried",
        ),
        _Rules(
            "chamfers",
            math.log(GREY_EXPLAINS),
            GREY_RULED_OUT,
            "chamfered strips",
            "chamfer_grey_misfit",
            "the chamfered strips' fitted profiles miss the image by more than its noise allows at every "
            "exponent tried",
        ),
    )
}


def allowed_response_ends(used_gamma: float, factor: float, read: ReadStrips) -> AllowedEnds:
    """The ends of the exponents ``used_gamma`` times ``factor`` to the powers -1..1 (within
    ``RESPONSE_PLAUSIBLE``) that the door's rounded or chamfered strips allow (module docstring).

    The strips are read at the two ends first; only a side whose end their scores rule out is read again at
    :data:`INNER_STEPS` of the reach. On a side, the end is the farthest reach with every reach inside it
    allowed, moved half way to the first ruled out, and each line's shift there is read there (a third
    reading; interpolated linearly in the reach between the two readings beside it, 0 at the exponent in
    use, where a strip is lost at the end)."""

    def gamma_at(reach: float) -> float:
        return float(np.clip(used_gamma * factor**reach, *RESPONSE_PLAUSIBLE))

    def shown_at(reach: float) -> float:
        # (the cell's own exponent as told, also beyond RESPONSE_PLAUSIBLE; the others as read)
        return used_gamma if reach == 0.0 else gamma_at(reach)

    def at_the_factors_ends(readings: StripReadings) -> AllowedEnds:
        return AllowedEnds(
            (gamma_at(1.0), gamma_at(-1.0)),
            {k: (float(v[0]), float(v[1])) for k, v in readings.shifts.items()},
        )

    if factor < DISPUTE_APART:
        # (a measured response: its ends are too near the cell's exponent for the strips to tell them apart)
        return at_the_factors_ends(read([gamma_at(1.0), gamma_at(-1.0)], "none"))
    first = read([gamma_at(1.0), gamma_at(-1.0)], "all")
    rules = _RULES[first.evidence]
    reaches = {1.0: 0, -1.0: 1}
    score = {0.0: first.used_score, 1.0: float(first.scores[0]), -1.0: float(first.scores[1])}
    full = at_the_factors_ends(first)

    why = _no_evidence(score, factor, rules)
    if why is None and all(score[r] <= _limit(score, rules) for r in (1.0, -1.0)):
        why = f"every exponent within the factor fits the {rules.strips} alike"
    if why is None:  # a side whose end is ruled out is read inwards
        inner = [
            side * step for side in (1.0, -1.0) if score[side] > _limit(score, rules) for step in INNER_STEPS
        ]
        more = read([gamma_at(r) for r in inner], "trials")
        for i, r in enumerate(inner):
            reaches[r] = i
            score[r] = float(more.scores[i])
        why = _no_evidence(score, factor, rules)
    if why is not None:
        disputed = _disputed(score, gamma_at, rules, why)
        return replace(full, figure=_figure(score, shown_at, rules, why, disputed), disputed=disputed)

    def shift_at(line: str, reach: float) -> float:
        if reach == 0.0:
            return 0.0
        src = first if abs(reach) == 1.0 else more
        values = src.shifts.get(line)
        return float(values[reaches[reach]]) if values is not None else math.nan

    sides = _side_ends(score, rules)
    # A moved end is read where it lies: between the last exponent allowed and the first ruled out the
    # strips' move need not be linear (a reading ruled out can sit in another valley of the strip's fit, a
    # pixel or more away), and the doubt is the move at the ends; interpolated where a strip is lost there.
    moved = [gamma_at(end) for _, out, end in sides if out is not None]
    at = read(moved, "none") if moved else None
    shifts: dict[str, list[float]] = {k: [] for k in first.shifts}
    j = 0
    for kept, out, end in sides:
        for k in shifts:
            if out is None:
                shifts[k].append(shift_at(k, kept))
                continue
            read_there = float(at.shifts[k][j]) if at is not None and k in at.shifts else math.nan
            w = (end - kept) / (out - kept)
            interpolated = (1.0 - w) * shift_at(k, kept) + w * shift_at(k, out)
            shifts[k].append(read_there if math.isfinite(read_there) else interpolated)
        j += out is not None
    ends = (gamma_at(sides[0][2]), gamma_at(sides[1][2]))
    return AllowedEnds(
        ends, {k: (v[0], v[1]) for k, v in shifts.items()}, _figure(score, shown_at, rules, None, None, ends)
    )


def _side_ends(score: dict[float, float], rules: _Rules) -> list[tuple[float, float | None, float]]:
    """Per side (upper, lower): the farthest reach whose every reach inside it is allowed, the first ruled
    out beyond it (None: none read, or none ruled out), and the end's reach (half way between the two)."""
    out_list: list[tuple[float, float | None, float]] = []
    for side in (1.0, -1.0):
        kept, out = 0.0, None
        for step in (*INNER_STEPS[::-1], 1.0):
            r = side * step
            if r not in score:
                continue
            # (a side not read inwards keeps its end: its end was allowed against the ends' best)
            if score[r] > _limit(score, rules) and side * INNER_STEPS[0] in score:
                out = r
                break
            kept = r
        out_list.append((kept, out, kept if out is None else 0.5 * (kept + out)))
    return out_list


def _limit(score: dict[float, float], rules: _Rules) -> float:
    """The score beyond which an exponent is ruled out: the best read so far's, times ``rules.ruled_out``."""
    return min(score.values()) + math.log(rules.ruled_out)


def _no_evidence(score: dict[float, float], factor: float, rules: _Rules) -> str | None:
    """Why the strips' scores rule nothing out (None: they may)."""
    if not all(math.isfinite(v) for v in score.values()):
        return "no rounded or chamfered strip was read at every exponent"
    if min(score.values()) > rules.explains:
        return rules.unexplained
    if score[0.0] > _limit(score, rules):
        best = min(score, key=score.__getitem__)
        # (an exponent near the cell's that fits better is the scores' noise, not a wrong cell)
        return CELL_DISPUTED if abs(best) * math.log(factor) >= math.log(DISPUTE_APART) else NEAR_BEST
    return None


def _disputed(
    score: dict[float, float], gamma_at: Callable[[float], float], rules: _Rules, why: str | None
) -> CellDisputed | None:
    """Where the scores rule out the cell's exponent (``why`` is :data:`CELL_DISPUTED`): the exponent read
    best and the cell's misfit over its (rounded as the diagnostics say them); else None."""
    if why != CELL_DISPUTED:
        return None
    best = min(score, key=score.__getitem__)
    return CellDisputed(
        round(gamma_at(best), 3), round(math.exp(score[0.0] - score[best]), 3), rules.evidence
    )


def _figure(
    score: dict[float, float],
    gamma_at: Callable[[float], float],
    rules: _Rules,
    why: str | None,
    disputed: CellDisputed | None = None,
    ends: tuple[float, float] | None = None,
) -> dict:
    """The diagnostics' account: exponents read (``gamma_at``: the cell's own as told), the strips' misfits
    there (``rules.key``: the arcs' over the free shading's, or the chamfers' in grey levels over the noise),
    the ends kept, or why none moved (with ``disputed``, where that is the cell's exponent ruled out)."""
    rows: list[tuple[float, float]] = []  # (exponent, score), each exponent read once
    for r in sorted(score):
        g = round(gamma_at(r), 3)
        # (two reaches brought to one bound of RESPONSE_PLAUSIBLE are one reading)
        if not rows or rows[-1][0] != g:
            rows.append((g, score[r]))
    out: dict = {
        "gammas": [g for g, _ in rows],
        rules.key: [round(math.exp(v), 4) if math.isfinite(v) else None for _, v in rows],
    }
    if ends is None:
        out["unchanged_because"] = why
        if disputed is not None:
            out["cell_disputed"] = {
                "best_gamma": disputed.best_gamma,
                "cell_over_best": disputed.cell_over_best,
            }
    else:
        out["allowed_gammas"] = [round(min(ends), 3), round(max(ends), 3)]
    return out

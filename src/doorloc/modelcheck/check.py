"""``check_model``: what the cell model gets wrong on a measured data set, its cause, the extended model, the gain.

1. Locate every image with the given cell; pose errors = measured minus reference.
2. Split off a held-out third (never used to fit or choose).
3. On the training images: forward models of every catalogue effect (analytic through the camera model,
   or by locating again for grey-level effects: the arris in both profiles, each judged by locate itself,
   thickness reading included), forward selection by cross-validated error plus each fitted value's
   prior penalty (:mod:`doorloc.modelcheck.priors`) with an F-test against the noise measured from the
   data, continuing past a cause that leaves structure and trying the best singles in pairs; then a test
   for structure no catalogue entry explains.
4. Extended cell = the given cell with the fitted values put in (with a ``provenance:`` section that
   flags any value beyond 5 prior sigmas as implausible).
5. Locate the held-out images with the extended cell: the held-out RMS before and after is the gain; a
   held-out image it refuses is reported with locate's reason, and the verdict then says not to use it
   (:mod:`doorloc.modelcheck.verdict`).
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from doorloc import __version__
from doorloc.cell import Cell, measured_response_factor, save_cell
from doorloc.modelcheck.catalogue import CATALOGUE, Effect, arris_variants
from doorloc.modelcheck.dataset import (
    Dataset,
    read_dataset,
    read_measured_image,
    too_few_located,
)
from doorloc.modelcheck.fit import (
    FittedModel,
    Predictor,
    Selection,
    SelectionRules,
    fit_model,
    select_effects,
    structured_residual,
)
from doorloc.modelcheck.forward import (
    COMPONENTS,
    AnalyticModel,
    Observation,
    RelocateTable,
    locate_errors,
    observe,
    relocate_grid,
)
from doorloc.modelcheck.priors import IMPLAUSIBLE_SIGMAS, Prior, priors_for
from doorloc.modelcheck.verdict import LEVER_EXPLAINED, verdict_of
from doorloc.vision.sampling import median_with_error

__all__ = ["ModelCheckReport", "CheckOptions", "check_model", "EXTENDED_CELL_NAME", "LEVER_MM"]

EXTENDED_CELL_NAME = "cell_extended.yaml"
#: The combined pose error is that of a point this far up the door (mm): a hinge's lever on the yaw.
LEVER_MM = 1000.0


@dataclass(frozen=True)
class CheckOptions:
    """Settings of a model check.

    Attributes
    ----------
    heldout_fraction : float
        Share of the images kept out of every fit (at least 5 images).
    seed : int
        Seeds the held-out draw.
    reference_noise : tuple of float
        Noise floor of the reference measurement (x mm, z mm, yaw deg, thickness mm), 1 sigma, added in
        quadrature to locate's own uncertainty to weight the pose components against each other.
    rules : SelectionRules
        Significance and held-out gain an effect needs, and how many effects at most.
    folds : int
        Cross-validation folds on the training images.
    """

    heldout_fraction: float = 0.3
    seed: int = 0
    reference_noise: tuple[float, float, float, float] = (0.002, 0.002, 0.0002, 0.002)
    rules: SelectionRules = SelectionRules()
    folds: int = 5


@dataclass
class ModelCheckReport:
    """The outcome of :func:`check_model`; :meth:`to_dict` is ``report.json`` (SPEC section 8 fields and more)."""

    dataset: str
    cell: str
    causes: list[str]
    parameters: dict[str, dict[str, dict[str, float]]]
    heldout_rms_before: dict[str, float]
    heldout_rms_after: dict[str, float]
    heldout_gain: float
    heldout_images: list[str]
    train_images: list[str]
    extended_cell: str
    alternatives: list[dict]
    indistinguishable: dict[str, list[str]]
    noise: dict[str, float]
    selection_steps: list[dict]
    unexplained_test: dict
    refused: list[dict]
    elapsed_s: float
    response_measured_by_locate: dict = field(default_factory=dict)
    response_bound: dict = field(default_factory=dict)
    refined_by_relocation: dict = field(default_factory=dict)
    grey_levels_refined: dict = field(default_factory=dict)
    heldout_refused_after: list[str] = field(default_factory=list)
    heldout_refusal_reasons: list[str] = field(default_factory=list)
    plausibility: dict[str, dict] = field(default_factory=dict)
    considered: list[dict] = field(default_factory=list)
    priors: dict[str, dict] = field(default_factory=dict)
    plots: list[str] = field(default_factory=list)
    # arrays for the plots (not in report.json)
    observations: list[Observation] = field(default_factory=list, repr=False)
    train_prediction: np.ndarray | None = field(default=None, repr=False)
    train_rows: np.ndarray | None = field(default=None, repr=False)
    heldout_rows: np.ndarray | None = field(default=None, repr=False)
    heldout_after: np.ndarray | None = field(default=None, repr=False)

    @property
    def verdict(self) -> dict[str, str]:
        """Status, headline and action in plain words (:func:`doorloc.modelcheck.verdict.verdict_of`)."""
        return verdict_of(self).to_dict()

    def to_dict(self) -> dict[str, Any]:
        keys = [
            "dataset",
            "cell",
            "causes",
            "parameters",
            "heldout_rms_before",
            "heldout_rms_after",
            "heldout_gain",
            "heldout_images",
            "train_images",
            "extended_cell",
            "alternatives",
            "indistinguishable",
            "noise",
            "selection_steps",
            "response_measured_by_locate",
            "response_bound",
            "refined_by_relocation",
            "grey_levels_refined",
            "unexplained_test",
            "refused",
            "heldout_refused_after",
            "heldout_refusal_reasons",
            "plausibility",
            "considered",
            "priors",
            "verdict",
            "elapsed_s",
            "plots",
        ]
        doc = {k: getattr(self, k) for k in keys}
        doc["version"] = __version__
        doc["gain_definition"] = (
            f"RMS over held-out images of the error of a point {LEVER_MM:g} mm up the door "
            "(corner x, z and yaw), before / after"
        )
        doc["lever_mm_definition"] = LEVER_EXPLAINED
        return _jsonable(doc)


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, np.floating | float):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _rms(errors: np.ndarray) -> dict[str, float]:
    out = {}
    for k, c in enumerate(COMPONENTS):
        col = errors[:, k]
        col = col[np.isfinite(col)]
        out[c] = float(np.sqrt(np.mean(col**2))) if col.size else float("nan")
    return out


def _lever_rms(errors: np.ndarray) -> float:
    e = np.sqrt(errors[:, 0] ** 2 + errors[:, 1] ** 2 + (LEVER_MM * np.radians(errors[:, 2])) ** 2)
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def _features(obs: Sequence[Observation], cell: Cell) -> np.ndarray:
    """Per image: reference pose, door size and corner pixel, scaled to about unit range."""
    env = cell.envelope
    cx, cy = cell.camera.cx, cell.camera.cy
    return np.array(
        [
            [
                o.item.reference.x_mm / env.x_mm,
                o.item.reference.z_mm / env.z_mm,
                o.item.reference.yaw_deg / env.yaw_deg,
                (o.item.door.width_mm - 900.0) / 200.0,
                (o.item.door.thickness_mm - 50.0) / 20.0,
                (o.corner_px[0] - cx) / 500.0,
                (o.corner_px[1] - cy) / 500.0,
            ]
            for o in obs
        ]
    )


def _split(n: int, fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng([seed, 777])
    perm = rng.permutation(n)
    n_held = max(5, int(round(fraction * n)))
    return np.sort(perm[n_held:]), np.sort(perm[:n_held])


def _parameters(model: FittedModel) -> dict[str, dict[str, dict[str, float]]]:
    out = {}
    for e, v, s in zip(model.effects, model.values, model.sigmas, strict=True):
        out[e.name] = {p: {"value": float(v[i]), "sigma": float(s[i])} for i, p in enumerate(e.params)}
    return out


def _plausibility(model: FittedModel, priors: dict[str, Prior], cell: Cell) -> dict[str, dict]:
    """Per cause: its prior (1 sigma, source), how many prior sigmas the fitted value lies from the cell's,
    and whether that makes it implausible (beyond :data:`~doorloc.modelcheck.priors.IMPLAUSIBLE_SIGMAS`)."""
    out = {}
    for e, v in zip(model.effects, model.values, strict=True):
        pr = priors[e.name]
        away = pr.sigmas_away(np.asarray(v, float) - e.nominal(cell))
        out[e.name] = {
            "prior_sigma": dict(zip(e.params, pr.sigma, strict=True)),
            "prior_source": pr.source,
            "sigmas_from_cell": away,
            "implausible": bool(away > IMPLAUSIBLE_SIGMAS),
            **({"variant": e.variant} if e.variant else {}),
        }
    return out


def _extended_cell(
    cell: Cell, model: FittedModel, dataset: Dataset, causes: list[str], plausibility: dict[str, dict]
) -> Cell:
    ext = model.apply(cell)
    prov = dict(cell.provenance)
    prov["model_check"] = {
        "dataset": str(dataset.folder),
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "doorloc_version": __version__,
        "base_cell": cell.source,
        "base_cell_sha256": cell.sha256,
        "causes": list(causes),
        "parameters": _jsonable(_parameters(model)),
        "lives_in": {e.name: e.lives_in for e in model.effects},
        # a value far outside what the calibration and the shop allow is written only with this flag
        "implausible": {
            name: f"{p['sigmas_from_cell']:.1f} prior sigmas from the cell's value ({p['prior_source']})"
            for name, p in plausibility.items()
            if p["implausible"]
        },
    }
    return replace(ext, provenance=prov)


def check_model(
    dataset_dir: str | os.PathLike,
    cell: Cell,
    out_dir: str | os.PathLike,
    *,
    options: CheckOptions = CheckOptions(),
    catalogue: Sequence[Effect] = CATALOGUE,
    progress: Callable[[str], None] | None = None,
    write: bool = True,
) -> ModelCheckReport:
    """Check ``cell`` against the data set in ``dataset_dir``; write the report and extended cell to ``out_dir``.

    Raises
    ------
    DatasetError
        The data set cannot be used (no truth.csv, missing images, too few images or too few located).
    """
    t0 = time.perf_counter()
    say = progress or (lambda _m: None)
    ds = read_dataset(dataset_dir, cell)
    measured_arris = _has_arris_column(ds)
    say(f"locating {len(ds)} images with the given cell")
    obs_all = observe(ds.images, cell, measured_arris, read_measured_image)
    refused = [{"image": o.item.image, "error": o.refusal} for o in obs_all if not o.ok]
    obs = [o for o in obs_all if o.ok]
    if len(obs) < 12:
        raise too_few_located(len(obs), len(ds), [r["error"] for r in refused])
    errors = np.array([o.error for o in obs])
    sig_locate = np.nanmedian(np.array([o.sigma for o in obs]), axis=0)
    noise = np.sqrt(np.nan_to_num(sig_locate) ** 2 + np.asarray(options.reference_noise) ** 2)
    train, held = _split(len(obs), options.heldout_fraction, options.seed)
    train_obs = [obs[k] for k in train]
    # the training images get their own index space 0..len(train)-1 in the forward models
    say(f"forward models on {len(train)} training images ({len(held)} held out)")
    analytic = AnalyticModel(train_obs, cell, measured_arris)
    candidates = [v for e in catalogue for v in (arris_variants(cell) if e.name == "arris" else (e,))]
    tables = {}
    for e in candidates:
        if e.forward == "relocate":
            say(f"locating the training images again for {e.key}")
            tables[e.key] = RelocateTable(e, train_obs, cell, measured_arris, relocate_grid(e, cell))
    etr = errors[train]
    rows = np.arange(len(train))
    if any(t.effect.name in GREY_REFINED for t in tables.values()):
        say("locating the training images again at the response's own best value")
    pred, grey_refined = _grey_levels_refined(Predictor(analytic, tables), etr, noise, rows)
    priors = priors_for(cell, catalogue)

    def prior_chi2(e: Effect, v: np.ndarray) -> float:
        d = (np.asarray(v, float) - e.nominal(cell)) / np.asarray(priors[e.name].sigma)
        return float(np.sum(d**2))

    say("fitting and selecting effects")
    sel: Selection = select_effects(
        pred, candidates, etr, noise, rows, options.rules, options.folds, prior_penalty=prior_chi2
    )
    model = fit_model(pred, list(sel.chosen.effects), etr, noise, rows)
    model, response_evidence = _with_absorbed_response(model, train_obs, catalogue)
    causes = list(model.names)
    ptrain = (
        pred.predict(list(model.effects), list(model.values), rows) if model.effects else np.zeros_like(etr)
    )
    resid = etr - ptrain
    null_sse = float(np.nansum((etr / noise) ** 2))
    un = structured_residual(resid, _features(train_obs, cell), noise, null_sse, folds=options.folds)
    if un["structured"]:
        causes.append("unexplained")
    say("refining the geometric effects on the training images located again")
    model, refined, ext_errors = _refined_by_relocation(model, cell, train_obs, noise, measured_arris)
    plausibility = _plausibility(model, priors, cell)
    ext = _extended_cell(cell, model, ds, causes, plausibility)
    ext, response_bound = _with_response_bound(
        ext, model, pred, train_obs, noise, rows, measured_arris, ext_errors
    )
    say(f"response bound from the training poses: {response_bound}")
    held_obs = [obs[k] for k in held]
    before = errors[held]
    say(f"locating the {len(held)} held-out images with the extended cell")
    reasons: list[str] = []
    after = locate_errors(held_obs, ext, measured_arris, reasons=reasons) if model.effects else before.copy()
    # an image the extended cell cannot locate counts against it, not as a free pass
    refused_after = [
        o.item.image for o, row in zip(held_obs, after, strict=True) if not np.isfinite(row).all()
    ]
    # one line per kind of refusal (its code), with the first image's message
    refusal_reasons = list({r.split(":", 1)[0]: r for r in reversed(reasons) if r}.values())
    g_before, g_after = _lever_rms(before), _lever_rms(after)
    rep = ModelCheckReport(
        dataset=str(ds.folder),
        cell=str(cell.source),
        causes=causes,
        parameters=_parameters(model),
        heldout_rms_before=_rms(before),
        heldout_rms_after=_rms(after),
        heldout_gain=g_before / g_after if g_after > 0 and not refused_after else float("nan"),
        heldout_images=[o.item.image for o in held_obs],
        train_images=[o.item.image for o in train_obs],
        extended_cell=EXTENDED_CELL_NAME,
        alternatives=sel.alternatives,
        indistinguishable=_indistinguishable(sel, model),
        noise=dict(zip(COMPONENTS, noise.tolist(), strict=True)),
        selection_steps=sel.steps,
        response_measured_by_locate=response_evidence,
        response_bound=response_bound,
        refined_by_relocation=refined,
        grey_levels_refined=grey_refined,
        unexplained_test=un,
        refused=refused,
        elapsed_s=0.0,
        heldout_refused_after=refused_after,
        heldout_refusal_reasons=refusal_reasons,
        plausibility=plausibility,
        considered=sel.considered,
        priors={k: {"sigma": list(p.sigma), "source": p.source} for k, p in priors.items()},
        observations=obs,
        train_prediction=ptrain,
        train_rows=train,
        heldout_rows=held,
        heldout_after=after,
    )
    rep.heldout_rms_before["lever_mm"] = g_before
    rep.heldout_rms_after["lever_mm"] = g_after
    # the cell file says how it fared on the images it was not fitted to, and the verdict on it
    prov = dict(ext.provenance)
    prov["model_check"] = {
        **prov["model_check"],
        "verified": _jsonable(
            {
                "heldout_images": len(held_obs),
                "refused": len(refused_after),
                "gain": rep.heldout_gain,
                "verdict": rep.verdict["status"],
            }
        ),
    }
    ext = replace(ext, provenance=prov)
    if write:
        from doorloc.modelcheck.report import write_report

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        save_cell(ext, out / EXTENDED_CELL_NAME)
        rep.elapsed_s = time.perf_counter() - t0
        write_report(rep, out)
    rep.elapsed_s = time.perf_counter() - t0
    return rep


#: locate measured another camera response than the cell's on at least this share of the training images
#: (and on ABSORBED_MIN_IMAGES at least) before the model check takes it as a cause of its own
ABSORBED_MIN_SHARE = 0.5
ABSORBED_MIN_IMAGES = 6


def _with_absorbed_response(
    model: FittedModel, train_obs: Sequence[Observation], catalogue: Sequence[Effect]
) -> tuple[FittedModel, dict]:
    """``model`` with the camera response that locate measured on the images' plain edges, where it did.

    Locate measures the response on every image whose plain edges show it and, where it differs from the
    cell's, uses its own (``diagnostics.camera_response.absorbed``): those images' poses are right with the
    wrong cell, so the pose errors the selection works on show nothing of it (hidden response 2.39, seed 2038:
    named nothing). The cell is still wrong, and a door whose edges cannot show the response (arrises, a
    door square to the camera) gets the cell's. Where locate measured it on most training images, it is a
    cause: the median of their exponents, with the standard error of that median from their scatter.
    Returns the model and the evidence (``report.json``'s ``response_measured_by_locate``).
    """
    g = np.array([o.response_absorbed for o in train_obs], float)
    g = g[np.isfinite(g)]
    evidence: dict[str, Any] = {"images": int(g.size), "of": len(train_obs)}
    effect = next((e for e in catalogue if e.name == "response_gamma"), None)
    if effect is None or "response_gamma" in model.names:
        return model, evidence
    if "arris" in model.names:
        # locate measured the response on edges of doors whose arris the nominal cell lacked: the profile
        # of an arris it was not told of reads as a response (hidden rounded 0.41 mm arris, linear camera:
        # 1.87 measured, and the extended cell with both refused 6 of 12 held-out images as uncertain).
        # The response's doubt then comes from the training poses (_with_response_bound).
        evidence["skipped"] = "measured with the arris the cell lacked"
        return model, evidence
    if g.size < max(ABSORBED_MIN_IMAGES, ABSORBED_MIN_SHARE * len(train_obs)):
        return model, evidence
    med, se = median_with_error(g)
    se = max(se, 0.01)
    evidence.update(median=med, sigma=se, added=True)
    return (
        replace(
            model,
            effects=(*model.effects, effect),
            values=(*model.values, np.array([med])),
            sigmas=(*model.sigmas, np.array([se])),
        ),
        evidence,
    )


#: times :func:`_grey_levels_refined` locates the training images again at a grey-level effect's fitted value
GREY_REFINE_STEPS = 2

#: the grey-level effects whose tables :func:`_grey_levels_refined` locates again. Not the arris: refined on
#: the pose residuals alone, a hidden 0.41 mm arris went to 0.47 mm (it is read right, 0.41, from the grid):
#: its value is pulled towards what the other pose errors leave, and its own signature (the thickness
#: reading) is what must fix it
GREY_REFINED = ("response_gamma",)


def _grey_levels_refined(
    pred: Predictor, errors: np.ndarray, noise: np.ndarray, rows: np.ndarray
) -> tuple[Predictor, dict]:
    """``pred`` with each table of :data:`GREY_REFINED` also located at its effect's own best value, and the evidence
    (``report.json``'s ``grey_levels_refined``: per table, the fitted value and weighted SSE at each step).

    A grey-level table is exact only at its grid values and interpolated between them, and the pose's
    response to the value is not smooth (locate replaces a cell's camera response by the one it measures
    where they differ): between grid values the table can be far off. Hidden response 1.563 on the grid
    1.5 / 1.8: fitted 1.584 with a weighted SSE of 26 where locating at 1.563 leaves 4.3, and one
    cross-validation fold fell into the table's second minimum at 2.56 (the response's held-out error
    285 of 482): the response was kept only provisionally and focal length +0.012 % took the rest as a
    second cause. So, as the geometric effects are refined by relocation, the response's value
    fitted alone is located at and put into its table, up to :data:`GREY_REFINE_STEPS` times (until the
    value is on the grid), before the selection compares any cause: each then competes with its true
    residual.
    """
    tables = dict(pred.tables)
    evidence: dict[str, list[dict]] = {}
    for key, table in pred.tables.items():
        if table.effect.name not in GREY_REFINED:
            continue
        steps = []
        for _ in range(GREY_REFINE_STEPS + 1):
            m = fit_model(Predictor(pred.analytic, {key: table}), [table.effect], errors, noise, rows)
            v = float(m.values[0][0])
            steps.append({"value": v, "sse": m.sse, "grid_values": int(table.grid.size)})
            tol = 1e-3 * float(table.grid[-1] - table.grid[0])
            if len(steps) > GREY_REFINE_STEPS or float(np.min(np.abs(table.grid - v))) <= tol:
                break
            table = table.with_values([v])
        tables[key] = table
        evidence[key] = steps
    return Predictor(pred.analytic, tables), evidence


#: Gauss-Newton steps of :func:`_refined_by_relocation`
REFINE_STEPS = 2


def _refined_by_relocation(
    model: FittedModel,
    cell: Cell,
    train_obs: Sequence[Observation],
    noise: np.ndarray,
    measured_arris: bool,
) -> tuple[FittedModel, dict, np.ndarray | None]:
    """The geometric (analytic) effects' values refined on the training images located again with the
    cell they make, the evidence (``report.json``'s ``refined_by_relocation``) and the training images'
    errors located with the model returned (None where nothing was refined: no geometric effect).

    The analytic forward model predicts locate's pose from a least-squares line through each edge's
    seen range; locate's own robust fit weighs the points of a bent edge otherwise, so an effect that
    bends the edges is fitted biased (hidden radial k1 0.199, seed 13 of the benchmark: fitted 0.171 +-
    0.002, held-out lever 0.071 mm, where the training images located with 0.1995 are off by 0.007 mm).
    The selection keeps the analytic model (it needs every effect's prediction at once); the chosen
    effects' values then take :data:`REFINE_STEPS` Gauss-Newton steps on the relocated training errors
    (derivatives by differences over each parameter's typical size, the grey-level effects held at
    their values), each kept only where it lowers the relocated cost, and their sigmas come from those
    derivatives.
    """
    ana = [i for i, e in enumerate(model.effects) if e.forward == "analytic"]
    if not ana:
        return model, {}, None
    idx = [(i, j) for i in ana for j in range(len(model.effects[i].params))]
    lo = np.array([model.effects[i].lower[j] for i, j in idx])
    hi = np.array([model.effects[i].upper[j] for i, j in idx])

    def errors(vals: Sequence[np.ndarray]) -> np.ndarray:
        return locate_errors(train_obs, model.apply(cell, vals), measured_arris, gated=False)

    def moved(vals: Sequence[np.ndarray], delta: np.ndarray) -> list[np.ndarray]:
        out = [np.array(v, float) for v in vals]
        for k, (i, j) in enumerate(idx):
            out[i][j] = float(np.clip(out[i][j] + delta[k], lo[k], hi[k]))
        return out

    vals = [np.array(v, float) for v in model.values]
    err = errors(vals)
    r = err / noise
    start_cost = float(np.nansum(r**2))
    sigmas = [np.array(s, float) for s in model.sigmas]
    steps = 0
    for _ in range(REFINE_STEPS):
        step = np.array([model.effects[i].step[j] for i, j in idx])
        cols = [
            (errors(moved(vals, step * np.eye(len(idx))[k])) / noise - r) / step[k] for k in range(len(idx))
        ]
        ok = np.isfinite(r) & np.all([np.isfinite(c) for c in cols], axis=0)
        if ok.sum() <= 2 * len(idx):
            break
        J = np.stack([c[ok] for c in cols], axis=1)
        delta, *_ = np.linalg.lstsq(J, -r[ok], rcond=None)
        trial = moved(vals, delta)
        err_new = errors(trial)
        r_new = err_new / noise
        both = ok & np.isfinite(r_new)
        if not float(np.sum(r_new[both] ** 2)) < float(np.sum(r[both] ** 2)):
            break
        vals, err, r, steps = trial, err_new, r_new, steps + 1
        sse = float(np.sum(r_new[both] ** 2))
        cov = np.linalg.pinv(J.T @ J) * sse / max(int(both.sum()) - len(idx), 1)
        for k, (i, j) in enumerate(idx):
            sigmas[i][j] = float(np.sqrt(max(cov[k, k], 0.0)))
    evidence = {
        "steps": steps,
        "cost_before": round(start_cost, 3),
        "cost_after": round(float(np.nansum(r**2)), 3),
        "values": {
            model.effects[i].name: {"analytic": model.values[i].tolist(), "relocated": vals[i].tolist()}
            for i in ana
        },
    }
    if not steps:
        return model, evidence, err
    return replace(model, values=tuple(vals), sigmas=tuple(sigmas)), evidence, err


#: the training images are located again with the extended cell at its response exponent times and over
#: this factor: the pose's slope in the exponent, image by image
RESPONSE_PROBE_FACTOR = 1.3


def _with_response_bound(
    ext: Cell,
    model: FittedModel,
    pred: Predictor,
    train_obs: Sequence[Observation],
    noise: np.ndarray,
    rows: np.ndarray,
    measured_arris: bool,
    ext_errors: np.ndarray | None = None,
) -> tuple[Cell, dict]:
    """``ext`` with the camera-response doubt that the training poses allow, and the evidence.

    ``ext_errors``: the training images' errors located with ``ext`` where the caller has them.

    A cell whose response was never measured lets locate doubt it over a wide range
    (``locate.response_unmeasured_factor``, 2.2 by default) wherever an image cannot check it itself, and
    with an arris in the cell no edge can: every pose then carries the edge shift of that whole range
    (hidden 0.96 mm arris, seed 1004: 0.14-0.15 mm, held-out images refused ``uncertain`` by the very cell
    that fixed them). The training images carry reference poses, so they measure the response the way
    they measure everything else: located again with the extended cell at its exponent times and over
    :data:`RESPONSE_PROBE_FACTOR`, each pose's slope in the exponent is known; the exponent is then fitted
    to the training errors together with the model's own effects (their slopes from the forward models,
    so an arris and a response that both move the edges share the evidence), and its 1-sigma from that
    joint fit (scaled up by the residual's chi-square where it exceeds the noise, and by the fitted
    exponent's distance from the cell's) becomes ``camera.response_gamma_sigma`` and the factor
    (:func:`doorloc.cell.measured_response_factor`), where it is tighter than the cell's and the fitted
    exponent agrees with the cell's (within 3 sigma; otherwise the evidence says so and the cell keeps
    its doubt). A fitted ``response_gamma`` cause gives its factor from its own sigma.
    """
    cfg = ext.locate
    evidence: dict[str, Any] = {"cell_factor": cfg.response_unmeasured_factor}
    if not model.effects:
        return ext, evidence
    g0 = ext.response_gamma
    if "response_gamma" in model.names:
        k = model.names.index("response_gamma")
        gamma, sigma, offset = g0, float(model.sigmas[k][0]), 0.0
        evidence.update(source="response_gamma cause")
    else:
        k_probe = RESPONSE_PROBE_FACTOR
        hi = locate_errors(train_obs, replace(ext, response_gamma=g0 * k_probe), measured_arris, gated=False)
        lo = locate_errors(train_obs, replace(ext, response_gamma=g0 / k_probe), measured_arris, gated=False)
        at = (
            ext_errors
            if ext_errors is not None
            else locate_errors(train_obs, ext, measured_arris, gated=False)
        )
        slope_g = (hi - lo) / (g0 * k_probe - g0 / k_probe)
        cols = [slope_g]
        for e, v in zip(model.effects, model.values, strict=True):
            for i, step in enumerate(e.step):
                up, down = np.array(v, float), np.array(v, float)
                up[i] += step
                down[i] -= step
                cols.append((pred.predict([e], [up], rows) - pred.predict([e], [down], rows)) / (2 * step))
        # element by element: an image whose thickness cannot be checked still has its x, z and yaw
        ok = np.isfinite(at) & np.all([np.isfinite(c) for c in cols], axis=0)
        if ok.any(axis=1).sum() < 6:
            evidence.update(
                source="relocation", skipped="fewer than 6 training images located at every probe"
            )
            return ext, evidence
        w = np.broadcast_to(1.0 / noise, at.shape)
        A = np.stack([c[ok] * w[ok] for c in cols], axis=1)
        b = -at[ok] * w[ok]
        sol, *_ = np.linalg.lstsq(A, b, rcond=None)
        dof = max(b.size - A.shape[1], 1)
        chi2 = float(np.sum((A @ sol - b) ** 2)) / dof
        cov = np.linalg.pinv(A.T @ A) * max(chi2, 1.0)
        gamma, sigma, offset = g0 + float(sol[0]), float(np.sqrt(max(cov[0, 0], 0.0))), float(sol[0])
        evidence.update(source="relocation", images=int(ok.any(axis=1).sum()), chi2_per_dof=round(chi2, 3))
    bound = float(np.hypot(sigma, offset))
    factor = measured_response_factor(g0, bound)
    evidence.update(gamma=round(gamma, 4), sigma=round(sigma, 4), factor=round(factor, 4))
    if abs(offset) > 3 * sigma:
        evidence["kept_cell_factor"] = "the training poses put the response away from the cell's"
        return ext, evidence
    if factor >= cfg.response_unmeasured_factor:
        return ext, evidence
    evidence["written"] = True
    prov = dict(ext.provenance)
    prov["model_check"] = {**prov["model_check"], "response_bound": _jsonable(evidence)}
    ext = replace(
        ext,
        response_gamma_sigma=round(bound, 4),
        locate=replace(cfg, response_unmeasured_factor=round(factor, 4)),
        provenance=prov,
    )
    return ext, evidence


def _has_arris_column(ds: Dataset) -> bool:
    import csv

    with (ds.folder / "truth.csv").open(newline="", encoding="utf-8") as f:
        header = next(csv.reader(f), [])
    return "arris_mm" in header


def _indistinguishable(sel: Selection, model: FittedModel) -> dict[str, list[str]]:
    """Per cause: what these data cannot tell it from (measured near-ties, and known look-alikes)."""
    out: dict[str, list[str]] = {}
    for e in model.effects:
        names = list(sel.indistinguishable.get(e.name, []))
        if e.looks_like:
            names.append(e.looks_like)
        if names:
            out[e.name] = names
    return out

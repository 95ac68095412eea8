"""Intrinsic calibration from board views: robust fitting, model selection, uncertainties.

The flow (:func:`calibrate_views`):

1. fit a reference model (plumb_bob, free aspect) to every view; reject corners whose residual
   is far beyond the robust noise level and views that fit far worse than the others; refit until
   nothing changes (every rejection is reported);
2. fit each candidate distortion model and choose by **held-out** error: K-fold over views, the
   held-out views' poses re-estimated with the trained intrinsics (``solvePnP``), so a model that
   only fits the training views' noise does not win; among the models whose held-out error is within
   one standard error (paired over views) of the best, the one with fewest parameters is chosen;
3. refit the chosen model on all kept views and report per-view errors, 1-sigma parameter
   uncertainties (from the full Jacobian, extrinsics included) and the projection uncertainty
   across the image, and the radius the data reached (``observed_radius_px``).

Pixels follow OpenCV's convention (origin at the centre of the top-left pixel).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import cv2
import numpy as np

from doorloc.calib.camera import CameraModel, distortion_validity

__all__ = [
    "View",
    "Candidate",
    "CANDIDATES",
    "CANDIDATES_BY_NAME",
    "ModelFit",
    "Rejection",
    "CandidateScore",
    "CalibrationResult",
    "CalibrationError",
    "fit_model",
    "board_pose",
    "held_out_rms",
    "held_out_errors",
    "jackknife_std",
    "calibrate_views",
    "projection_uncertainty",
    "view_information",
    "projection_jacobian",
    "sigma_from_covariance",
    "max_error_quantile",
    "free_param_names",
    "observed_radius",
    "MIN_VIEWS",
    "ProjectionDifference",
    "projection_difference",
    "pixels_within",
]

#: fewest views a calibration is attempted with (after rejection)
MIN_VIEWS = 4
#: a candidate whose held-out error exceeds the best one's by less than this many standard errors
#: (paired over views) counts as equally good; the one with fewest parameters is chosen ("1-SE rule")
SELECTION_STANDARD_ERRORS = 1.0
#: corner rejection: residual above max(CORNER_SIGMAS * robust sigma, CORNER_FLOOR_PX)
CORNER_SIGMAS = 4.0
CORNER_FLOOR_PX = 0.25
#: view rejection: RMS above max(VIEW_FACTOR * median view RMS, VIEW_FLOOR_PX), or too many bad corners
VIEW_FACTOR = 3.0
VIEW_FLOOR_PX = 0.5
VIEW_MAX_BAD_FRACTION = 0.25

_TERM = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)


class CalibrationError(ValueError):
    """The calibration could not be done (too few usable views, degenerate data); the message says why."""


@dataclass(frozen=True)
class View:
    """One image's board corners: object points (board frame, mm) and their pixels.

    ``object_points`` shape (N, 3), ``image_points`` shape (N, 2), ``ids`` shape (N,) (corner ids on
    the board, for reporting rejected corners).
    """

    name: str
    object_points: np.ndarray
    image_points: np.ndarray
    ids: np.ndarray

    def subset(self, mask: np.ndarray) -> View:
        return View(self.name, self.object_points[mask], self.image_points[mask], self.ids[mask])

    @property
    def n(self) -> int:
        return int(len(self.image_points))


@dataclass(frozen=True)
class Candidate:
    """A distortion model and aspect-ratio choice to fit.

    ``flags`` are OpenCV calibration flags; ``n_coeffs`` the coefficients stored (5 or 8);
    ``free_dist`` the indices of the distortion coefficients that are estimated.
    """

    name: str
    flags: int
    n_coeffs: int
    free_dist: tuple[int, ...]
    fixed_aspect: bool = False

    @property
    def n_intrinsics(self) -> int:
        return (1 if self.fixed_aspect else 2) + 2 + len(self.free_dist)

    def with_fixed_aspect(self) -> Candidate:
        return Candidate(
            self.name + "+fixed_aspect",
            self.flags | cv2.CALIB_FIX_ASPECT_RATIO,
            self.n_coeffs,
            self.free_dist,
            True,
        )


_BASE = (
    Candidate("k1k2", cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K3, 5, (0, 1)),
    Candidate("k1k2p1p2", cv2.CALIB_FIX_K3, 5, (0, 1, 2, 3)),
    Candidate("plumb_bob", 0, 5, (0, 1, 2, 3, 4)),
    Candidate("rational", cv2.CALIB_RATIONAL_MODEL, 8, (0, 1, 2, 3, 4, 5, 6, 7)),
)
#: every candidate: the four distortion models, each with free and with fixed (unit) aspect ratio
CANDIDATES: tuple[Candidate, ...] = _BASE + tuple(c.with_fixed_aspect() for c in _BASE)
CANDIDATES_BY_NAME = {c.name: c for c in CANDIDATES}
_REFERENCE = CANDIDATES_BY_NAME["plumb_bob"]


@dataclass(frozen=True)
class ModelFit:
    """A fitted candidate on a set of views.

    ``residuals_px[i]`` is (N_i, 2) observed minus projected pixels of view ``i``; ``rms_px`` over all
    corners; ``per_view_rms_px`` per view; ``rvecs``/``tvecs_mm`` the board poses (board -> camera).
    """

    candidate: Candidate
    camera: CameraModel
    rvecs: list[np.ndarray]
    tvecs_mm: list[np.ndarray]
    residuals_px: list[np.ndarray]
    rms_px: float
    per_view_rms_px: list[float]


@dataclass(frozen=True)
class Rejection:
    """A rejected view (``corner_id`` None) or corner, with its residual and the reason."""

    view: str
    corner_id: int | None
    residual_px: float
    reason: str


@dataclass(frozen=True)
class CandidateScore:
    name: str
    n_params: int
    train_rms_px: float
    held_out_rms_px: float
    chosen: bool = False


@dataclass(frozen=True)
class CalibrationResult:
    """Everything a calibration found; :mod:`doorloc.calib.report` turns it into JSON + PNG.

    Attributes
    ----------
    camera : CameraModel
        The chosen model, with ``observed_radius_px`` set.
    fit : ModelFit
        The final fit on the kept views/corners.
    views : list of View
        The kept views with their kept corners (same order as ``fit.residuals_px``).
    rejections : list of Rejection
    scores : list of CandidateScore
        Training and held-out RMS of every candidate (px).
    std_intrinsics : dict
        1-sigma uncertainties: ``fx, fy, cx, cy`` (px) and the free distortion coefficients by name.
    covariance : ndarray
        Covariance of the free intrinsic parameters (order in ``covariance_names``).
    covariance_names : list of str
    projection_sigma_px : dict
        ``max_observed`` (largest 1-sigma projection uncertainty inside the observed radius),
        ``max_observed_aligned`` (the same after the best small rotation of the camera frame over that
        region is taken out, the figure to compare with :func:`projection_difference`'s ``aligned_max_px``),
        ``max_observed_aligned_95`` (95 % of calibrations with this uncertainty land closer than this
        to the true model everywhere inside the observed radius, after the rotation; see
        :func:`max_error_quantile`),
        ``corners`` (at the four image corners), ``centre``.
    n_folds : int
    std_jackknife : dict
        Delete-a-fold jackknife standard errors (see :func:`jackknife_std`); larger than
        ``std_intrinsics`` when the views disagree more than the corner noise explains.
    excluded_models : dict
        Candidates left out of the selection, with the reason (e.g. the fitted distortion folds
        over inside the region the data cover, or the fit failed).
    """

    camera: CameraModel
    fit: ModelFit
    views: list[View]
    rejections: list[Rejection]
    scores: list[CandidateScore]
    std_intrinsics: dict
    covariance: np.ndarray
    covariance_names: list[str]
    projection_sigma_px: dict
    n_folds: int
    std_jackknife: dict = field(default_factory=dict)
    excluded_models: dict = field(default_factory=dict)


_DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


def _cv_inputs(views: list[View]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    obj = [np.ascontiguousarray(v.object_points, np.float32).reshape(-1, 1, 3) for v in views]
    img = [np.ascontiguousarray(v.image_points, np.float32).reshape(-1, 1, 2) for v in views]
    return obj, img


def _project(camera: CameraModel, rvec, tvec, object_points: np.ndarray) -> np.ndarray:
    p, _ = cv2.projectPoints(
        np.asarray(object_points, float).reshape(-1, 1, 3),
        np.asarray(rvec, float),
        np.asarray(tvec, float),
        camera.camera_matrix,
        camera.dist_coeffs,
    )
    return p.reshape(-1, 2)


def _residuals(camera: CameraModel, views: list[View], rvecs, tvecs) -> list[np.ndarray]:
    return [
        v.image_points - _project(camera, r, t, v.object_points)
        for v, r, t in zip(views, rvecs, tvecs, strict=True)
    ]


def _rms(res: list[np.ndarray]) -> float:
    allr = np.concatenate([r.reshape(-1, 2) for r in res]) if res else np.zeros((0, 2))
    return float(np.sqrt(np.mean(np.sum(allr**2, axis=1)))) if len(allr) else float("nan")


@contextmanager
def _one_opencv_thread() -> Iterator[None]:
    """OpenCV's calibration sums over its worker threads in whatever order they finish, so two runs on the same
    corners differ in the last bits (1e-13 to 1e-10 px on the public board sets), and what is fitted downstream
    of a calibration (the photometric model check) can carry that into different answers. One thread makes a
    calibration repeatable; it costs nothing measurable here (0.9-2.2 s either way on the public sets). The
    count is OpenCV's process-wide setting, put back as it was."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)


def fit_model(views: list[View], image_size: tuple[int, int], candidate: Candidate) -> ModelFit:
    """Fit ``candidate`` to ``views`` with ``cv2.calibrateCamera`` (Levenberg-Marquardt), on one thread so that
    the same views always give the same camera to the last bit.

    Raises :class:`CalibrationError` if OpenCV cannot fit (e.g. degenerate views).
    """
    obj, img = _cv_inputs(views)
    K0 = np.eye(3)
    try:
        with _one_opencv_thread():
            _, K, d, rvecs, tvecs = cv2.calibrateCamera(
                obj, img, tuple(int(s) for s in image_size), K0, None, flags=candidate.flags, criteria=_TERM
            )
    except cv2.error as e:
        raise CalibrationError(f"OpenCV could not fit the {candidate.name} model: {e.err or e}") from None
    d = np.asarray(d, float).ravel()[: candidate.n_coeffs]
    d = np.pad(d, (0, candidate.n_coeffs - d.size))
    if not np.all(np.isfinite(K)) or not np.all(np.isfinite(d)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise CalibrationError(f"the {candidate.name} fit diverged; the views are probably degenerate")
    camera = CameraModel(K, d, image_size)
    rv = [np.asarray(r, float).ravel() for r in rvecs]
    tv = [np.asarray(t, float).ravel() for t in tvecs]
    res = _residuals(camera, views, rv, tv)
    per_view = [float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) for r in res]
    return ModelFit(candidate, camera, rv, tv, res, _rms(res), per_view)


def board_pose(
    camera: CameraModel, object_points: np.ndarray, image_points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Board pose ``(rvec, tvec)`` (board frame -> camera frame, mm) from its points ``object_points`` (N, 3;
    mm) seen at ``image_points`` (N, 2; px) through ``camera`` (planar IPPE start, then Levenberg-Marquardt)."""
    obj = np.asarray(object_points, float).reshape(-1, 1, 3)
    img = np.asarray(image_points, float).reshape(-1, 1, 2)
    planar = np.ptp(obj[:, 0, 2]) < 1e-9
    method = cv2.SOLVEPNP_IPPE if planar else cv2.SOLVEPNP_ITERATIVE
    ok, r, t = cv2.solvePnP(obj, img, camera.camera_matrix, camera.dist_coeffs, flags=method)
    if not ok:
        ok, r, t = cv2.solvePnP(
            obj, img, camera.camera_matrix, camera.dist_coeffs, flags=cv2.SOLVEPNP_ITERATIVE
        )
    r, t = cv2.solvePnPRefineLM(obj, img, camera.camera_matrix, camera.dist_coeffs, r, t)
    return r.ravel(), t.ravel()


def held_out_errors(
    views: list[View],
    image_size: tuple[int, int],
    candidate: Candidate,
    n_folds: int,
    fold_cameras: list[CameraModel] | None = None,
) -> np.ndarray:
    """K-fold held-out squared errors: per view, the mean squared residual (px^2) when it was held out.

    View ``i`` is held out in fold ``i % n_folds``; its pose is re-estimated with the intrinsics
    trained on the other folds. Shape (n_views,); NaN for a view that could not be evaluated.
    If ``fold_cameras`` is a list, the camera trained in each fold is appended to it.
    """
    mse = np.full(len(views), np.nan)
    idx = np.arange(len(views))
    for k in range(n_folds):
        test = idx[idx % n_folds == k]
        train = idx[idx % n_folds != k]
        if len(test) == 0 or len(train) < 2:
            continue
        fit = fit_model([views[i] for i in train], image_size, candidate)
        if fold_cameras is not None:
            fold_cameras.append(fit.camera)
        for i in test:
            r, t = board_pose(fit.camera, views[i].object_points, views[i].image_points)
            res = views[i].image_points - _project(fit.camera, r, t, views[i].object_points)
            mse[i] = float(np.mean(np.sum(res**2, axis=1)))
    return mse


def jackknife_std(fold_cameras: list[CameraModel]) -> dict:
    """Grouped (delete-a-fold) jackknife standard errors of fx, fy, cx, cy and the coefficients, px.

    ``sqrt((K-1)/K * sum_k (theta_k - mean)^2)`` over the K fold fits. Unlike the Jacobian
    sigma, which assumes independent corner noise, this shows how much the answer depends on
    which views were taken (board flatness, detector bias, correlated errors).
    """
    K = len(fold_cameras)
    if K < 2:
        return {}
    th = np.array([[c.fx, c.fy, c.cx, c.cy, *c.dist_coeffs] for c in fold_cameras])
    sd = np.sqrt((K - 1) / K * np.sum((th - th.mean(axis=0)) ** 2, axis=0))
    names = ["fx", "fy", "cx", "cy", *_DIST_NAMES[: th.shape[1] - 4]]
    return dict(zip(names, sd.tolist(), strict=True))


def held_out_rms(views: list[View], image_size: tuple[int, int], candidate: Candidate, n_folds: int) -> float:
    """K-fold held-out RMS (px) over all corners of all views (see :func:`held_out_errors`)."""
    mse = held_out_errors(views, image_size, candidate, n_folds)
    n = np.array([v.n for v in views], float)
    ok = np.isfinite(mse)
    return float(np.sqrt(np.sum(mse[ok] * n[ok]) / np.sum(n[ok]))) if np.any(ok) else float("nan")


def _reject(
    views: list[View], image_size, candidate: Candidate, min_views: int
) -> tuple[list[View], list[Rejection], ModelFit]:
    """Drop outlier views and corners, refitting after each decision.

    A grossly wrong view (a mislabelled detection) bends the whole fit, so views go one at a time,
    worst first, before any corner is judged. A view is bad when more than
    ``VIEW_MAX_BAD_FRACTION`` of its corners are outliers or its remaining corners still fit far
    worse than the other views; otherwise its few outlier corners are dropped instead.
    """
    rejections: list[Rejection] = []
    current = list(views)
    fit = fit_model(current, image_size, candidate)
    for _ in range(len(views) + 5):
        allr = np.concatenate(fit.residuals_px)
        sigma = 1.4826 * float(np.median(np.abs(allr)))
        corner_thr = max(CORNER_SIGMAS * sigma, CORNER_FLOOR_PX)
        norms = [np.linalg.norm(r, axis=1) for r in fit.residuals_px]
        bad_frac = np.array([float(np.mean(n > corner_thr)) for n in norms])
        inlier_rms = np.array(
            [
                float(np.sqrt(np.mean(n[n <= corner_thr] ** 2))) if np.any(n <= corner_thr) else np.inf
                for n in norms
            ]
        )
        view_thr = max(VIEW_FACTOR * float(np.median(inlier_rms)), VIEW_FLOOR_PX)
        badness = np.where(
            (bad_frac > VIEW_MAX_BAD_FRACTION) | (inlier_rms > view_thr), np.array(fit.per_view_rms_px), -1
        )
        worst = int(np.argmax(badness))
        if badness[worst] > 0 and len(current) > min_views:
            why = (
                f"{bad_frac[worst]:.0%} of its corners beyond {corner_thr:.2f} px"
                if bad_frac[worst] > VIEW_MAX_BAD_FRACTION
                else f"view RMS {inlier_rms[worst]:.2f} px > {view_thr:.2f} px"
            )
            rejections.append(Rejection(current[worst].name, None, fit.per_view_rms_px[worst], why))
            current = current[:worst] + current[worst + 1 :]
            fit = fit_model(current, image_size, candidate)
            continue
        changed = False
        new_views: list[View] = []
        for v, n in zip(current, norms, strict=True):
            bad = n > corner_thr
            if np.any(bad) and v.n - int(bad.sum()) >= 6:
                for j in np.flatnonzero(bad):
                    rejections.append(
                        Rejection(
                            v.name,
                            int(v.ids[j]),
                            float(n[j]),
                            f"corner residual {n[j]:.2f} px > {corner_thr:.2f} px",
                        )
                    )
                v = v.subset(~bad)
                changed = True
            new_views.append(v)
        if not changed:
            break
        current = new_views
        fit = fit_model(current, image_size, candidate)
    return current, rejections, fit


def _free_param_names(c: Candidate) -> list[str]:
    return (["f"] if c.fixed_aspect else ["fx", "fy"]) + ["cx", "cy"] + [_DIST_NAMES[i] for i in c.free_dist]


def _intrinsic_jacobian(camera: CameraModel, c: Candidate, jac: np.ndarray) -> np.ndarray:
    """Columns of ``cv2.projectPoints``' Jacobian for the free intrinsics of ``c``. (2N, n_free)."""
    dfx, dfy = jac[:, 6], jac[:, 7]
    cols = [camera.fx / camera.fy * dfx + dfy] if c.fixed_aspect else [dfx, dfy]
    cols += [jac[:, 8], jac[:, 9]]
    cols += [jac[:, 10 + i] for i in c.free_dist]
    return np.stack(cols, axis=1)


def view_information(
    camera: CameraModel, candidate: Candidate, object_points: np.ndarray, rvec, tvec_mm
) -> np.ndarray:
    """Information one board view gives about the free intrinsics of ``candidate``, its pose marginalised.

    With unit corner noise per coordinate: ``J_i^T J_i - J_i^T J_p (J_p^T J_p)^-1 J_p^T J_i`` (the Schur
    complement of the view's 6 pose parameters), ``J_i``/``J_p`` the Jacobians of the view's projected
    corners w.r.t. the intrinsics and the pose. The information of several views is their sum, and its
    inverse times the corner variance is the intrinsics' covariance, so the same function serves the
    covariance of a finished calibration and the design of views before any image is taken
    (:func:`doorloc.calib.coverage.predicted_projection_sigma`). ``object_points`` (N, 3) mm, board frame;
    result shape (n_free, n_free), order :func:`free_param_names`.
    """
    _, jac = cv2.projectPoints(
        np.asarray(object_points, float).reshape(-1, 1, 3),
        np.asarray(rvec, float),
        np.asarray(tvec_mm, float),
        camera.camera_matrix,
        camera.dist_coeffs,
    )
    Ji = _intrinsic_jacobian(camera, candidate, jac)
    Jp = jac[:, :6]
    cross = Ji.T @ Jp
    return Ji.T @ Ji - cross @ np.linalg.pinv(Jp.T @ Jp) @ cross.T


def free_param_names(candidate: Candidate) -> list[str]:
    """Names of the free intrinsics of ``candidate`` in covariance order (``f`` for a fixed aspect ratio)."""
    return _free_param_names(candidate)


def _covariance(fit: ModelFit, views: list[View]) -> tuple[np.ndarray, list[str], float]:
    """Covariance of the free intrinsics from the full Jacobian (intrinsics + all poses).

    Gauss-Newton: ``Cov = s^2 (J^T J)^-1`` with ``s^2`` the residual variance per coordinate; the
    intrinsic block of the inverse is the marginal covariance (pose uncertainty accounted for), computed
    as the inverse of the summed per-view information (:func:`view_information`).
    """
    c, cam = fit.candidate, fit.camera
    info = sum(
        view_information(cam, c, v.object_points, fit.rvecs[k], fit.tvecs_mm[k]) for k, v in enumerate(views)
    )
    n_obs = 2 * sum(v.n for v in views)
    sse = float(sum(np.sum(r**2) for r in fit.residuals_px))
    dof = max(n_obs - c.n_intrinsics - 6 * len(views), 1)
    s2 = sse / dof
    return s2 * np.linalg.pinv(info), _free_param_names(c), math.sqrt(s2)


def projection_uncertainty(
    camera: CameraModel, candidate: Candidate, cov: np.ndarray, pixels: np.ndarray, *, aligned: bool = False
) -> np.ndarray:
    """1-sigma uncertainty (px, major axis) of where a fixed camera-frame ray lands, at each pixel.

    The ray seen at each pixel by ``camera`` is projected again with the intrinsics' covariance
    ``cov`` (free parameters of ``candidate``). Shape ``(N, 2) -> (N,)``; NaN where the model
    cannot undistort the pixel.

    ``aligned=True`` gives the uncertainty left after the best small rotation of the camera frame
    fitted over all of ``pixels`` is taken out (as :func:`projection_difference` does, and as a cell
    calibration with the same intrinsics does): a calibration cannot tell a shift of the principal
    point from a rotation of every board pose, so most of the raw uncertainty near the centre is that
    rotation. The result then depends on the pixel set, which should be the region it is quoted for.
    """
    A = projection_jacobian(camera, candidate, pixels, aligned=aligned)
    return sigma_from_covariance(A, cov)


def projection_jacobian(
    camera: CameraModel, candidate: Candidate, pixels: np.ndarray, *, aligned: bool = False
) -> np.ndarray:
    """How the pixel where a fixed ray lands moves with the free intrinsics of ``candidate``, at each pixel.

    Shape ``(N, 2) -> (N, 2, n_free)`` (NaN rows where ``camera`` cannot undistort the pixel);
    ``aligned`` as in :func:`projection_uncertainty`.
    """
    px = np.asarray(pixels, float).reshape(-1, 2)
    xy = camera.undistort(px)
    n = candidate.n_intrinsics
    out = np.full((len(px), 2, n), np.nan)
    ok = np.all(np.isfinite(xy), axis=1)
    if not np.any(ok):
        return out
    pts = np.concatenate([xy[ok], np.ones((int(ok.sum()), 1))], axis=1).reshape(-1, 1, 3)
    _, jac = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), camera.camera_matrix, camera.dist_coeffs)
    Ji = _intrinsic_jacobian(camera, candidate, jac)  # (2M, n)
    if aligned:
        Jr = jac[:, :3]  # a rotation of the camera frame (rvec at zero)
        Ji = Ji - Jr @ np.linalg.lstsq(Jr, Ji, rcond=None)[0]
    out[ok] = Ji.reshape(-1, 2, n)
    return out


def sigma_from_covariance(jacobian: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Major-axis 1-sigma (px) of ``jacobian`` (N, 2, n) applied to parameter covariance ``cov`` (n, n); (N,)."""
    S = jacobian @ cov @ np.transpose(jacobian, (0, 2, 1))  # (N, 2, 2)
    a, b, c = S[:, 0, 0], S[:, 1, 1], S[:, 0, 1]
    major = 0.5 * (a + b) + np.sqrt(0.25 * (a - b) ** 2 + c**2)  # larger eigenvalue of a symmetric 2x2
    return np.sqrt(np.maximum(major, 0.0))


def max_error_quantile(
    jacobian: np.ndarray, cov: np.ndarray, q: float = 0.95, n_samples: int = 2000, seed: int = 0
) -> float | None:
    """The ``q`` quantile of the largest projection error over a region, px.

    Parameter errors are drawn from N(0, ``cov``) (fixed ``seed``: the figure is reproducible) and
    mapped through ``jacobian`` (N, 2, n) (e.g. :func:`projection_jacobian` with ``aligned=True`` over
    the observed region); for each draw the largest error length over the N pixels is kept. This is
    the figure a "better than X px everywhere in the region" requirement is checked against: the
    largest error is typically 1.5-2.5 times the largest 1-sigma, because the region holds many
    pixels. None when no pixel is usable.
    """
    J = jacobian[np.all(np.isfinite(jacobian), axis=(1, 2))]
    if len(J) == 0:
        return None
    L = np.linalg.cholesky(cov + 1e-18 * np.eye(len(cov)) * max(float(np.trace(cov)), 1e-30))
    draws = np.random.default_rng(seed).standard_normal((n_samples, len(cov))) @ L.T  # (S, n)
    worst = np.concatenate(
        [
            np.sqrt(np.max(np.sum(np.einsum("mkn,sn->smk", J, d) ** 2, axis=2), axis=1))
            for d in np.array_split(draws, max(1, n_samples // 250))
        ]
    )  # chunks bound the memory
    return float(np.quantile(worst, q))


def observed_radius(camera: CameraModel, views: list[View]) -> float:
    """Largest distance (px) of any kept corner from the principal point."""
    c = np.array([camera.cx, camera.cy])
    return float(max(np.max(np.linalg.norm(v.image_points - c, axis=1)) for v in views))


def calibrate_views(
    views: list[View],
    image_size: tuple[int, int],
    *,
    candidates: tuple[Candidate, ...] | list[Candidate] = CANDIDATES,
    n_folds: int = 5,
    min_views: int = MIN_VIEWS,
    reject: bool = True,
) -> CalibrationResult:
    """Calibrate from board views: reject outliers, choose the model by held-out error, fit, report.

    Parameters
    ----------
    views : list of View
        One per image; at least ``min_views`` with six or more corners each.
    image_size : (width, height)
    candidates : the models to choose among (default :data:`CANDIDATES`)
    n_folds : K of the K-fold held-out error (fewer views than K: leave-one-view-out)
    min_views : the least number of views kept

    Raises
    ------
    CalibrationError
        Too few usable views, or no candidate could be fitted.
    """
    views = [v for v in views if v.n >= 6]
    if len(views) < min_views:
        raise CalibrationError(
            f"only {len(views)} usable board view(s); calibration needs at least {min_views} "
            "(more than 10, covering the whole image, gives a trustworthy model)"
        )
    rejections: list[Rejection] = []
    if reject:
        views, rejections, _ = _reject(views, image_size, _REFERENCE, min_views)
    k = min(n_folds, len(views))
    n_pts = np.array([v.n for v in views], float)
    rows: list[tuple[Candidate, ModelFit, np.ndarray]] = []
    folds: dict[str, list[CameraModel]] = {}
    excluded: dict[str, str] = {}
    for cand in candidates:
        cams: list[CameraModel] = []
        try:
            fit = fit_model(views, image_size, cand)
            fold = distortion_validity(fit.camera, n_angles=72, n_radii=600).fold_radius_px
            reach = observed_radius(fit.camera, views)
            if fold is not None and fold < reach:
                # A model that is not one-to-one where the data are cannot be right, however well it fits.
                excluded[cand.name] = (
                    f"folds over at {fold:.0f} px, inside the observed radius {reach:.0f} px"
                )
                continue
            mse = held_out_errors(views, image_size, cand, k, cams)
        except CalibrationError as e:
            excluded[cand.name] = str(e)
            continue
        if np.all(np.isfinite(mse)):
            rows.append((cand, fit, mse))
            folds[cand.name] = cams
    if not rows:
        raise CalibrationError(
            "no distortion model could be fitted to these views ("
            + "; ".join(f"{k2}: {v}" for k2, v in excluded.items())
            + "); check the board size and the images"
        )

    def pooled(mse: np.ndarray) -> float:
        return float(np.sqrt(np.sum(mse * n_pts) / np.sum(n_pts)))

    best_mse = min(rows, key=lambda r: pooled(r[2]))[2]
    eligible = []
    for cand, _, mse in rows:
        d = mse - best_mse
        se = float(np.std(d, ddof=1) / math.sqrt(len(d))) if len(d) > 1 else 0.0
        if np.mean(d) <= SELECTION_STANDARD_ERRORS * se:
            eligible.append(cand)
    chosen = min(eligible, key=lambda c: (c.n_intrinsics, pooled(next(r[2] for r in rows if r[0] is c))))
    scores = [CandidateScore(c.name, c.n_intrinsics, f.rms_px, pooled(m), c is chosen) for c, f, m in rows]
    fits = {c.name: f for c, f, _ in rows}
    fit = fits[chosen.name]
    cov, names, _ = _covariance(fit, views)
    std = dict(zip(names, np.sqrt(np.maximum(np.diag(cov), 0.0)).tolist(), strict=True))
    if "f" in std:
        a = fit.camera.fx / fit.camera.fy
        std = {"fx": std["f"] * a, "fy": std["f"], **{k2: v for k2, v in std.items() if k2 != "f"}}
    radius = observed_radius(fit.camera, views)
    camera = fit.camera.with_observed_radius(radius)
    fit = ModelFit(
        fit.candidate, camera, fit.rvecs, fit.tvecs_mm, fit.residuals_px, fit.rms_px, fit.per_view_rms_px
    )
    w, h = image_size
    corners = camera.image_corners_px() + np.array([[0.5, 0.5], [-0.5, 0.5], [-0.5, -0.5], [0.5, -0.5]])
    gu, gv = np.meshgrid(np.linspace(0, w - 1, 33), np.linspace(0, h - 1, 25))
    grid = np.stack([gu.ravel(), gv.ravel()], axis=1)
    sig_grid = projection_uncertainty(camera, fit.candidate, cov, grid)
    inside = np.linalg.norm(grid - [camera.cx, camera.cy], axis=1) <= radius
    sig_corners = projection_uncertainty(camera, fit.candidate, cov, corners)
    sig_centre = projection_uncertainty(camera, fit.candidate, cov, np.array([[camera.cx, camera.cy]]))
    observed_px = pixels_within(camera, radius, step_px=max(8.0, max(w, h) / 100))
    jac_aligned = projection_jacobian(camera, fit.candidate, observed_px, aligned=True)
    sig_aligned = sigma_from_covariance(jac_aligned, cov)
    proj = {
        "max_observed": float(np.nanmax(sig_grid[inside])) if np.any(inside) else None,
        "max_observed_aligned": float(np.nanmax(sig_aligned)) if np.any(np.isfinite(sig_aligned)) else None,
        "max_observed_aligned_95": max_error_quantile(jac_aligned, cov, 0.95),
        "corners": [None if not np.isfinite(s) else float(s) for s in sig_corners],
        "centre": float(sig_centre[0]),
        "grid_shape": [25, 33],
        "grid": [None if not np.isfinite(s) else float(s) for s in sig_grid],
    }
    return CalibrationResult(
        camera,
        fit,
        views,
        rejections,
        scores,
        std,
        cov,
        names,
        proj,
        k,
        std_jackknife=jackknife_std(folds[chosen.name]),
        excluded_models=excluded,
    )


@dataclass(frozen=True)
class ProjectionDifference:
    """How far two camera models disagree on where rays land, over a set of pixels.

    ``raw_max_px``/``raw_rms_px``: the ray model ``reference`` sees at each pixel, projected by
    ``other``. ``aligned_*``: the same after the best rotation of ``other``'s camera frame
    (``rotation_rad``, Rodrigues): a calibration fixes intrinsics only up to such a small rotation
    traded against the board poses (it moves the principal point), and a cell calibration made
    with the same intrinsics absorbs it.
    """

    raw_max_px: float
    raw_rms_px: float
    aligned_max_px: float
    aligned_rms_px: float
    rotation_rad: np.ndarray
    n_pixels: int


def projection_difference(
    other: CameraModel, reference: CameraModel, pixels: np.ndarray
) -> ProjectionDifference:
    """Compare ``other`` with ``reference`` at ``pixels`` (N, 2) of ``reference``'s image (px).

    Pixels ``reference`` cannot undistort are left out.
    """
    from scipy.optimize import least_squares

    px = np.asarray(pixels, float).reshape(-1, 2)
    xy = reference.undistort(px)
    ok = np.all(np.isfinite(xy), axis=1)
    px, xy = px[ok], xy[ok]
    rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)

    def diff(rv: np.ndarray) -> np.ndarray:
        R = cv2.Rodrigues(np.asarray(rv, float))[0]
        return other.project(rays @ R.T) - px

    d0 = np.linalg.norm(diff(np.zeros(3)), axis=1)
    sol = least_squares(lambda rv: diff(rv).ravel(), np.zeros(3))
    d1 = np.linalg.norm(diff(sol.x), axis=1)
    return ProjectionDifference(
        float(d0.max()),
        float(np.sqrt(np.mean(d0**2))),
        float(d1.max()),
        float(np.sqrt(np.mean(d1**2))),
        sol.x,
        int(len(px)),
    )


def pixels_within(camera: CameraModel, radius_px: float, step_px: float = 8.0) -> np.ndarray:
    """Pixel grid (every ``step_px``) inside the image and within ``radius_px`` of the principal point, (N, 2)."""
    w, h = camera.image_size
    gu, gv = np.meshgrid(np.arange(0, w, step_px), np.arange(0, h, step_px))
    g = np.stack([gu.ravel(), gv.ravel()], axis=1).astype(float)
    return g[np.linalg.norm(g - [camera.cx, camera.cy], axis=1) <= radius_px]

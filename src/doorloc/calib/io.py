"""Calibration files: OpenCV FileStorage YAML and ROS ``camera_info`` YAML (shared/SPEC.md section 5).

Both are read wherever a calibration is accepted; the format is recognised from the content.
OpenCV's ``%YAML:1.0`` header and ``!!opencv-matrix`` tags are not YAML that PyYAML accepts, so the
reader drops the header and gives the tag a constructor. Writers go through :mod:`doorloc.fileio`: a failed write never leaves a
half-written calibration behind.
"""

from __future__ import annotations

import json
import os
import re
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from doorloc.calib.camera import CameraModel
from doorloc.fileio import atomic_write_text

__all__ = [
    "CalibrationFile",
    "CalibrationFileError",
    "load_calibration",
    "parse_calibration",
    "dump_opencv_yaml",
    "dump_ros_yaml",
    "save_calibration",
    "atomic_write_text",
]


class CalibrationFileError(ValueError):
    """A calibration file that cannot be read; the message says which file and what is wrong."""


@dataclass(frozen=True)
class CalibrationFile:
    """A camera model with the quality figures stored beside it.

    ``avg_reprojection_error`` in pixels (RMS over all corners), ``per_view_reprojection_errors`` in
    pixels (RMS per view); ``extra`` keeps any other keys found in the file.

    ``covariance`` is the covariance of the calibration's free intrinsics (``covariance_names`` in its
    order: ``fx``/``fy`` or ``f``, ``cx``, ``cy``, then distortion names ``k1``, ``k2``, ``p1``...; px and
    unitless), saved as ``intrinsics_covariance`` and ``intrinsics_covariance_names`` so that locate can
    carry the calibration's own uncertainty into every answer (as mrcal keeps its optimisation inputs
    with the model). None for a file without it.
    """

    camera: CameraModel
    avg_reprojection_error: float | None = None
    per_view_reprojection_errors: list[float] = field(default_factory=list)
    camera_name: str = "doorloc"
    extra: dict[str, Any] = field(default_factory=dict)
    covariance: np.ndarray | None = None
    covariance_names: tuple[str, ...] = ()
    #: the camera response measured on the calibration photographs (``grey = light ** (1 / gamma)``) and
    #: its 1-sigma (``response_gamma``, ``response_gamma_sigma``; None where not measured): what a cell file's
    #: ``camera.response_gamma`` and ``locate.response_unmeasured_factor`` can be set from
    response_gamma: float | None = None
    response_gamma_sigma: float | None = None
    #: the camera's photometric model (``photometric_model``: parameter name -> value, as
    #: :class:`doorloc.photometric.model.PhotometricModel` names them; None where not measured) and where it
    #: came from (``photometric_model_provenance``: the command, the photographs, the date). Readers older
    #: than the section keep it in ``extra``; the photometric package checks the names where it uses them.
    photometric_model: dict[str, float] | None = None
    photometric_model_provenance: str | None = None
    #: the bits of the camera's levels in its 16-bit images (``stored_bits``: 12 for a 12-bit camera that
    #: stores 0-4095; None where its photographs were 8-bit or used the whole 16 bits), which a cell file's
    #: ``camera.stored_bits`` takes unless it states its own
    stored_bits: int | None = None


def _covariance_from(doc: dict, source: str) -> tuple[np.ndarray | None, tuple[str, ...]]:
    if "intrinsics_covariance" not in doc:
        return None, ()
    try:
        names = tuple(str(n) for n in doc.get("intrinsics_covariance_names") or [])
        cov = np.asarray(_ros_matrix(doc["intrinsics_covariance"], "intrinsics_covariance", source), float)
        cov = cov.reshape(len(names), len(names))
    except (ValueError, TypeError):
        raise CalibrationFileError(
            f"{source}: 'intrinsics_covariance' must be a square matrix with one row per name "
            "in 'intrinsics_covariance_names'"
        ) from None
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0):
        raise CalibrationFileError(f"{source}: 'intrinsics_covariance' has a negative or non-finite variance")
    return cov, names


class _CalibrationLoader(yaml.SafeLoader):
    """PyYAML's safe loader plus OpenCV's ``!!opencv-matrix`` tag (ROS files use it too, rarely)."""


class _OpenCVLoader(_CalibrationLoader):
    """Reads an OpenCV FileStorage file as OpenCV does: its YAML has ints, reals and strings only, so
    ``yes``, ``Null``, ``~`` or a date are strings here too, not YAML 1.1 booleans, nulls or dates."""

    yaml_implicit_resolvers = {
        first: [
            (tag, rx)
            for tag, rx in resolvers
            if tag not in ("tag:yaml.org,2002:bool", "tag:yaml.org,2002:null", "tag:yaml.org,2002:timestamp")
        ]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }


def _opencv_matrix(loader: yaml.SafeLoader, node: yaml.Node) -> np.ndarray:
    if not isinstance(node, yaml.MappingNode):
        raise yaml.constructor.ConstructorError(
            None, None, "an opencv-matrix must be a mapping", node.start_mark
        )
    m = loader.construct_mapping(node, deep=True)
    data = np.asarray(m["data"], dtype=float)
    return data.reshape(int(m["rows"]), int(m["cols"]))


_CalibrationLoader.add_constructor("tag:yaml.org,2002:opencv-matrix", _opencv_matrix)
_CalibrationLoader.add_constructor("!opencv-matrix", _opencv_matrix)


def _ros_matrix(v: Any, name: str, src: str) -> np.ndarray:
    if isinstance(v, dict) and "data" in v:
        data = np.asarray(v["data"], float)
        rows, cols = v.get("rows"), v.get("cols")
        return data.reshape(int(rows), int(cols)) if rows and cols else data
    if isinstance(v, np.ndarray):
        return v
    if isinstance(v, list):
        return np.asarray(v, float)
    raise CalibrationFileError(f"{src}: '{name}' is not a matrix")


#: one backslash escape of OpenCV's double-quoted strings (the backslash and the character it escapes)
_OPENCV_ESCAPE = re.compile(r"\\.")


def _yaml_escape(m: re.Match[str]) -> str:
    """OpenCV's escape as YAML reads it: ``\\'`` (a quote) has no YAML form but the quote itself."""
    return "'" if m.group(0) == "\\'" else m.group(0)


#: characters OpenCV writes raw inside its double-quoted strings (and reads back) that YAML cannot carry
#: raw: DEL and the C1 controls are not printable there, NEL, LS and PS are line breaks (which a quoted
#: string folds into a space), U+FFFE and U+FFFF are no characters
_YAML_UNPRINTABLE = re.compile("[\x7f-\x9f\u2028\u2029\ufffe\uffff]")


def _yaml_char_escape(m: re.Match[str]) -> str:
    """The YAML double-quoted escape of one such character."""
    c = ord(m.group(0))
    return f"\\x{c:02x}" if c <= 0xFF else f"\\u{c:04x}"


def parse_calibration(text: str, source: str = "<calibration>") -> CalibrationFile:
    """Parse OpenCV FileStorage YAML or ROS camera_info YAML text into a :class:`CalibrationFile`."""
    # (split at line feeds only: str.splitlines also splits at the line and paragraph separators, NEL and
    # form feeds that a camera's name may hold inside its quotes)
    lines = text.split("\n")
    loader: type[yaml.SafeLoader] = _CalibrationLoader
    # OpenCV 4 heads its files "%YAML:1.0" (not YAML: dropped), OpenCV 5 "%YAML 1.2"; ROS files have none.
    if lines and lines[0].startswith("%YAML"):
        loader = _OpenCVLoader
        if lines[0].startswith("%YAML:"):
            lines = lines[1:]
        # OpenCV escapes a single quote inside its double-quoted strings as \' , an escape YAML does not
        # have (PyYAML refuses it). Escapes are read in pairs from the left, so that an escaped backslash
        # before a quote (\\' : a backslash, then the quote) keeps its backslash.
        lines = [
            _YAML_UNPRINTABLE.sub(_yaml_char_escape, _OPENCV_ESCAPE.sub(_yaml_escape, ln)) for ln in lines
        ]
    # OpenCV writes "!!opencv-matrix"; PyYAML resolves "!!x" to "tag:yaml.org,2002:x".
    try:
        doc = yaml.load("\n".join(lines), Loader=loader)  # both loaders are SafeLoaders
    except yaml.YAMLError as e:
        raise CalibrationFileError(
            f"{source}: not a YAML calibration file ({e.__class__.__name__}: {e})"
        ) from None
    if not isinstance(doc, dict):
        raise CalibrationFileError(f"{source}: expected a mapping of calibration keys")
    try:
        K = _ros_matrix(doc["camera_matrix"], "camera_matrix", source).reshape(3, 3)
        d = doc.get("distortion_coefficients", doc.get("dist_coeffs", []))
        d = _ros_matrix(d, "distortion_coefficients", source).ravel() if d is not None else np.zeros(0)
        w, h = int(doc["image_width"]), int(doc["image_height"])
    except KeyError as e:
        raise CalibrationFileError(
            f"{source}: missing key {e.args[0]!r}; a calibration needs camera_matrix, distortion_coefficients, "
            "image_width and image_height"
        ) from None
    except (ValueError, TypeError) as e:
        raise CalibrationFileError(f"{source}: malformed calibration values ({e})") from None
    observed = doc.get("observed_radius_px")
    try:
        cam = CameraModel(K, d, (w, h), float(observed) if observed is not None else None)
    except ValueError as e:
        raise CalibrationFileError(f"{source}: {e}") from None
    per_view = doc.get("per_view_reprojection_errors")
    if per_view is not None:
        per_view = np.asarray(per_view, float).ravel().tolist()
    known = {
        "camera_matrix",
        "distortion_coefficients",
        "dist_coeffs",
        "image_width",
        "image_height",
        "avg_reprojection_error",
        "per_view_reprojection_errors",
        "camera_name",
        "observed_radius_px",
        "intrinsics_covariance",
        "intrinsics_covariance_names",
        "response_gamma",
        "response_gamma_sigma",
        "photometric_model",
        "photometric_model_provenance",
        "stored_bits",
    }
    cov, cov_names = _covariance_from(doc, source)
    photometric = _photometric_from(doc, source)
    try:
        response = [
            float(doc[k]) if doc.get(k) is not None else None
            for k in ("response_gamma", "response_gamma_sigma")
        ]
    except (ValueError, TypeError):
        raise CalibrationFileError(
            f"{source}: response_gamma and response_gamma_sigma must be numbers"
        ) from None
    stored_bits = doc.get("stored_bits")
    if stored_bits is not None and (
        isinstance(stored_bits, bool) or not isinstance(stored_bits, int) or not 8 <= stored_bits <= 16
    ):
        raise CalibrationFileError(
            f"{source}: stored_bits must be a whole number of bits from 8 to 16, got {stored_bits!r}"
        )
    extra = {k: v for k, v in doc.items() if k not in known}
    avg = doc.get("avg_reprojection_error")
    return CalibrationFile(
        cam,
        float(avg) if avg is not None else None,
        per_view or [],
        str(doc.get("camera_name", "doorloc")),
        extra,
        cov,
        cov_names,
        response_gamma=response[0],
        response_gamma_sigma=response[1],
        photometric_model=photometric,
        photometric_model_provenance=str(doc["photometric_model_provenance"])
        if doc.get("photometric_model_provenance") is not None
        else None,
        stored_bits=stored_bits,
    )


def _photometric_from(doc: dict, source: str) -> dict[str, float] | None:
    pm = doc.get("photometric_model")
    if pm is None:
        return None
    if not isinstance(pm, dict) or not all(isinstance(k, str) for k in pm):
        raise CalibrationFileError(
            f"{source}: 'photometric_model' must be a mapping of parameter names to numbers"
        )
    out = {}
    for k, v in pm.items():
        try:
            out[k] = float(v)
        except (TypeError, ValueError):
            raise CalibrationFileError(
                f"{source}: photometric_model.{k} must be a number, got {v!r}"
            ) from None
        if not np.isfinite(out[k]):
            raise CalibrationFileError(f"{source}: photometric_model.{k} must be finite")
    return out


def load_calibration(path: str | os.PathLike) -> CalibrationFile:
    """Read a calibration file of either format. Raises :class:`CalibrationFileError` with the path."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise CalibrationFileError(f"cannot read calibration file {p}: {e.strerror or e}") from None
    return parse_calibration(text, str(p))


def _fmt(x: float) -> str:
    return repr(float(x))


def _cv_matrix(name: str, m: np.ndarray) -> str:
    m = np.atleast_2d(np.asarray(m, float))
    data = ", ".join(_fmt(v) for v in m.ravel())
    return f"{name}: !!opencv-matrix\n   rows: {m.shape[0]}\n   cols: {m.shape[1]}\n   dt: d\n   data: [ {data} ]\n"


def _cv_string(name: str, value: str) -> str:
    """A double-quoted scalar that ``cv2.FileStorage`` and PyYAML both read back as ``value``.

    JSON's escapes (``\\"``, ``\\\\``, ``\\n``, ``\\t``, ``\\r``) are the subset both parsers share;
    OpenCV does not understand ``\\uXXXX``, so other control characters cannot be written at all.
    """
    # Zl/Zp: PyYAML folds a raw U+2028/U+2029 inside quotes into a space, and OpenCV cannot escape it
    bad = [
        c
        for c in value
        if (unicodedata.category(c) in ("Cc", "Cs", "Zl", "Zp") and c not in "\t\n\r") or c in "\ufffe\uffff"
    ]
    if bad:
        raise ValueError(
            f"{name} {value!r} holds characters ({', '.join(map(repr, bad))}) "
            "that a calibration file cannot carry"
        )
    return f"{name}: {json.dumps(value, ensure_ascii=False)}"


def dump_opencv_yaml(cal: CalibrationFile) -> str:
    """OpenCV FileStorage YAML text (readable by ``cv2.FileStorage`` and by :func:`parse_calibration`).

    Checked against ``cv2.FileStorage`` both ways by ``tests/core/test_files.py`` (property tests).
    A camera without distortion terms gets no ``distortion_coefficients`` key: OpenCV cannot parse an
    empty ``!!opencv-matrix``, and both readers take a missing key as "no distortion".
    """
    cam = cal.camera
    out = ["%YAML:1.0", "---"]
    out.append(f"image_width: {cam.image_size[0]}")
    out.append(f"image_height: {cam.image_size[1]}")
    out.append(_cv_string("camera_name", cal.camera_name))
    out.append(_cv_matrix("camera_matrix", cam.camera_matrix).rstrip())
    if cam.dist_coeffs.size:
        out.append(_cv_matrix("distortion_coefficients", cam.dist_coeffs.reshape(1, -1)).rstrip())
    if cal.avg_reprojection_error is not None:
        out.append(f"avg_reprojection_error: {_fmt(cal.avg_reprojection_error)}")
    if cal.per_view_reprojection_errors:
        out.append(
            _cv_matrix(
                "per_view_reprojection_errors", np.asarray(cal.per_view_reprojection_errors).reshape(-1, 1)
            ).rstrip()
        )
    if cam.observed_radius_px is not None:
        out.append(f"observed_radius_px: {_fmt(cam.observed_radius_px)}")
    if cal.covariance is not None:
        out.append(_cv_matrix("intrinsics_covariance", cal.covariance).rstrip())
        out.append(
            "intrinsics_covariance_names: [ " + ", ".join(f'"{n}"' for n in cal.covariance_names) + " ]"
        )
    for k in ("response_gamma", "response_gamma_sigma"):
        if getattr(cal, k) is not None:
            out.append(f"{k}: {_fmt(getattr(cal, k))}")
    if cal.stored_bits is not None:
        out.append(f"stored_bits: {int(cal.stored_bits)}")
    if cal.photometric_model is not None:
        # a FileStorage map: cv2.FileStorage and older doorloc readers both take it (the latter into extra)
        out.append("photometric_model:")
        out.extend(f"   {k}: {_fmt(v)}" for k, v in cal.photometric_model.items())
    if cal.photometric_model_provenance is not None:
        out.append(_cv_string("photometric_model_provenance", cal.photometric_model_provenance))
    return "\n".join(out) + "\n"


def dump_ros_yaml(cal: CalibrationFile) -> str:
    """ROS ``camera_info`` YAML text (``rectification_matrix`` identity, ``projection_matrix`` = [K|0])."""
    cam = cal.camera
    P = np.hstack([cam.camera_matrix, np.zeros((3, 1))])

    def mat(m: np.ndarray) -> dict:
        m = np.atleast_2d(m)
        return {"rows": int(m.shape[0]), "cols": int(m.shape[1]), "data": [float(v) for v in m.ravel()]}

    doc = {
        "image_width": cam.image_size[0],
        "image_height": cam.image_size[1],
        "camera_name": cal.camera_name,
        "camera_matrix": mat(cam.camera_matrix),
        "distortion_model": cam.distortion_model,
        "distortion_coefficients": mat(cam.dist_coeffs.reshape(1, -1)),
        "rectification_matrix": mat(np.eye(3)),
        "projection_matrix": mat(P),
    }
    if cal.avg_reprojection_error is not None:
        doc["avg_reprojection_error"] = float(cal.avg_reprojection_error)
    if cal.per_view_reprojection_errors:
        doc["per_view_reprojection_errors"] = [float(v) for v in cal.per_view_reprojection_errors]
    if cam.observed_radius_px is not None:
        doc["observed_radius_px"] = float(cam.observed_radius_px)
    if cal.covariance is not None:
        doc["intrinsics_covariance"] = mat(cal.covariance)
        doc["intrinsics_covariance_names"] = list(cal.covariance_names)
    for k in ("response_gamma", "response_gamma_sigma"):
        if getattr(cal, k) is not None:
            doc[k] = float(getattr(cal, k))
    if cal.stored_bits is not None:
        doc["stored_bits"] = int(cal.stored_bits)
    if cal.photometric_model is not None:
        doc["photometric_model"] = {k: float(v) for k, v in cal.photometric_model.items()}
    if cal.photometric_model_provenance is not None:
        doc["photometric_model_provenance"] = cal.photometric_model_provenance
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def save_calibration(cal: CalibrationFile, path: str | os.PathLike, fmt: str = "opencv") -> None:
    """Write ``cal`` as ``fmt`` = ``"opencv"`` (FileStorage YAML) or ``"ros"`` (camera_info YAML), atomically."""
    if fmt == "opencv":
        text = dump_opencv_yaml(cal)
    elif fmt == "ros":
        text = dump_ros_yaml(cal)
    else:
        raise ValueError(f"unknown calibration format {fmt!r}; use 'opencv' or 'ros'")
    atomic_write_text(path, text)

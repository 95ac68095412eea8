"""Locate over a batch of frames with torch: the coarse search of every frame in one set of tensor operations.

What is vectorised over the batch by the torch finder, on CPU or CUDA with the same code:

- the luminance planes, copied into one ``(B, H, W)`` uint8 tensor on the device (grey frames as they are;
  colour frames converted by OpenCV first at a linear response, see below);
- the coarse step searches (:func:`doorloc.vision.coarse.coarse_edges`): :func:`doorloc.vision.locate.locate_steps`
  is run as a coroutine for every frame, and each round of step searches the frames ask for (reference
  arris, far arris, bottom end) is answered for the whole batch at once by :class:`TorchStepFinder`, whose
  answers are bit for bit those of the one-frame finder (float32 sums of 8-bit grey levels are exact
  integers, and the medians, ties and roundings are taken as numpy takes them; ``tests/vision/test_batched.py``
  checks every answer against the one-frame finder).

On CPU the step searches are answered by the one-frame finder itself, frame by frame
(:class:`PlaneStepFinder`): the searches sample a few thousand pixels of each frame, too little work for
torch's per-operation cost to pay off (measured: torch's batched answers took 1.4-1.7 ms of CPU per frame
where the one-frame finder takes 1.1 ms), and stacking the frames into one CPU tensor alone cost more
than the whole search (a 2 MB copy per 1080p frame, ~5 ms of CPU with its page faults). So the batched
CPU path does the one-frame path's work and no more, each frame's steps to its answer before the next
frame's (taking eight frames' steps in turn only traded the caches' locality), and gains whatever makes the
one-frame functions faster. On CUDA the frames are copied one by one into a device tensor (no stacked copy
on the host).
``locate_batch(..., finder="torch")`` uses the torch finder on CPU too (for comparisons and tests).

What is not (yet): the RANSAC lines, the coarse pose and the **fine sub-pixel stage** (edge points, far-face
fit, robust line fits, quality gate) run through the one-frame code, frame by frame, inside each frame's
coroutine. So the batched answers equal the one-frame answers by construction, and stay equal when the
sub-pixel estimator changes.

Frames the batch cannot take (not 8-bit, colour at a response exponent other than 1, whose luminance is
summed in light at 16 bits, a size other than the batch's, not an array) go through
:func:`doorloc.vision.locate.locate` alone, and their record says so (:attr:`BatchAnswer.fallback`).

kornia is not used: its colour conversion is floating point and differs from OpenCV's fixed-point one by a
grey level on about 0.1-0.3 % of pixels (which would change answers), and the camera projection and
undistortion depend only on the cell, so they are computed once per cell (:meth:`SearchRegion.cached`).

torch is an optional dependency (``pip install doorloc[torch]``); only this module imports it.
"""

from __future__ import annotations

from collections.abc import Generator, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import torch

from doorloc.cell import Cell, DoorSize
from doorloc.vision.coarse import coarse_edges
from doorloc.vision.config import LocateConfig
from doorloc.vision.locate import StepQuery, locate, locate_steps
from doorloc.vision.luminance import LuminancePlane
from doorloc.vision.result import LocateResult

__all__ = ["BatchAnswer", "PlaneStepFinder", "TorchStepFinder", "locate_batch", "resolve_device"]


def resolve_device(device: str) -> torch.device:
    """``"cpu"``, ``"cuda"`` or ``"auto"`` (CUDA when available) as a torch device.

    Raises
    ------
    ValueError
        ``"cuda"`` asked for where torch sees no CUDA device, or an unknown name.
    """
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError("--device cuda: torch sees no CUDA device here; use --device cpu or auto")
    if device not in ("cpu", "cuda"):
        raise ValueError(f"unknown device {device!r}; use cpu, cuda or auto")
    return torch.device(device)


@dataclass
class BatchAnswer:
    """One frame's answer from :func:`locate_batch`.

    ``fallback`` is None when the frame went through the batched path, else why it went through the
    one-frame path instead.
    """

    result: LocateResult
    fallback: str | None = None


Steps = Generator[StepQuery, tuple[np.ndarray, np.ndarray], LocateResult]
StepAnswer = tuple[np.ndarray, np.ndarray]


class StepFinder(Protocol):
    """Answers the step searches of many frames: ``(along, strength)`` per ``(frame index, kwargs)``."""

    def answer(self, queries: Sequence[tuple[int, dict[str, Any]]]) -> list[StepAnswer]: ...


class PlaneStepFinder:
    """The one-frame finder (:func:`doorloc.vision.coarse.coarse_edges`) over each frame's own plane.

    Parameters
    ----------
    planes : sequence of ndarray (H, W) uint8
        The frames' luminance, as the one-frame path reads it.
    """

    def __init__(self, planes: Sequence[np.ndarray]) -> None:
        self.planes = planes

    def answer(self, queries: Sequence[tuple[int, dict[str, Any]]]) -> list[StepAnswer]:
        """``(along, strength)`` for each ``(frame index, coarse_edges keyword arguments)``."""
        return [coarse_edges(self.planes[b], **kw) for b, kw in queries]


class TorchStepFinder:
    """Answers the step searches of many frames at once (:func:`doorloc.vision.coarse.coarse_edges` each).

    Parameters
    ----------
    planes : torch.Tensor, (B, H, W) uint8
        The frames' luminance, on the device that does the work.
    """

    def __init__(self, planes: torch.Tensor) -> None:
        if planes.dtype != torch.uint8 or planes.ndim != 3:
            raise ValueError("TorchStepFinder needs a (B, H, W) uint8 tensor")
        self.planes = planes
        self.flat = planes.reshape(-1)
        self.device = planes.device

    @classmethod
    def from_planes(cls, planes: Sequence[np.ndarray], device: torch.device) -> TorchStepFinder:
        """The frames copied one by one into a ``(B, H, W)`` tensor on ``device`` (no stacked host copy)."""
        out = torch.empty((len(planes), *planes[0].shape), dtype=torch.uint8, device=device)
        for b, plane in enumerate(planes):
            out[b].copy_(torch.from_numpy(np.ascontiguousarray(plane)))
        return cls(out)

    def answer(self, queries: Sequence[tuple[int, dict[str, Any]]]) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(along, strength)`` for each ``(frame index, coarse_edges keyword arguments)``."""
        out: list[Any] = [None] * len(queries)
        groups: dict[tuple, list[int]] = {}
        for i, (_, kw) in enumerate(queries):
            scan = np.asarray(kw["scan"], int)
            half, stride = int(kw.get("half", 3)), int(kw.get("stride", 1))
            length = (
                int(np.max(np.asarray(kw["hi"], int) - np.asarray(kw["lo"], int))) // stride + 2 * half + 1
                if scan.size
                else 0
            )
            if scan.size == 0 or length <= 2 * half + 1:  # nothing to search: as the one-frame finder says
                out[i] = (np.full(scan.size, np.nan), np.zeros(scan.size))
                continue
            groups.setdefault((kw["axis"], half, stride, kw.get("prefer") is not None), []).append(i)
        for (axis, half, stride, with_prefer), idx in groups.items():
            for i, res in zip(
                idx,
                self._answer_group([queries[i] for i in idx], axis, half, stride, with_prefer),
                strict=True,
            ):
                out[i] = res
        return out

    def _answer_group(self, queries, axis: str, half: int, stride: int, with_prefer: bool):
        """``(along, strength)`` for each query of one group (one axis, window ``half``, ``stride`` and
        whether a position is preferred), as :func:`doorloc.vision.coarse.coarse_edges` gives them: the
        responses of every scan line at once, the strongest (or the preferred candidate's) position, px."""
        B, H, W = self.planes.shape
        n_along, pitch_along, pitch_scan = (H, W, 1) if axis == "col" else (W, 1, W)
        dev = self.device
        g = _GroupRows.stack(queries, half, stride, dev)
        resp, ok = self._responses(g, half, stride, n_along, (pitch_along, pitch_scan))
        M = g.L - 2 * half + 1
        i = torch.arange(M, device=dev)
        k = i + half
        r = torch.arange(resp.shape[0], device=dev)
        best = torch.argmax(resp, dim=1)  # the first of equal maxima, as numpy
        if with_prefer:
            best = _preferred(queries, g, resp, ok, best, half, stride)
        strength = resp[r, best]
        along = (g.lo + stride * k[best]).to(torch.float64) - 0.5 * stride
        finite = torch.isfinite(strength)
        along = torch.where(finite, along, torch.tensor(np.nan, dtype=torch.float64, device=dev))
        strength = torch.where(finite, strength, torch.zeros_like(strength))
        along_np, strength_np = along.cpu().numpy(), strength.cpu().numpy()
        out, start = [], 0
        for n in g.rows:
            out.append((along_np[start : start + n].copy(), strength_np[start : start + n].copy()))
            start += n
        return out

    def _responses(
        self, g: _GroupRows, half: int, stride: int, n_along: int, pitch: tuple[int, int]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The step detector's response (R, M) on every row of the group, signed by its polarity and -inf
        where a response is not the row's own (samples outside the image or ``[lo, hi]``), and where it is
        (``ok``); ``pitch`` the flat planes' steps along and across the scan lines."""
        pitch_along, pitch_scan = pitch
        B, H, W = self.planes.shape
        dev = self.device
        lo, hi, length, pol, L = g.lo, g.hi, g.length, g.pol, g.L
        M = L - 2 * half + 1
        j = torch.arange(L, device=dev)
        base = g.frame * (H * W) + g.scan * pitch_scan
        if bool((lo >= 0).all()) and bool((lo + stride * (L - 1) < n_along).all()):
            # every sample of every row inside the image (the usual case): one index per sample
            flat_idx = (base + lo * pitch_along)[:, None] + (stride * pitch_along) * j[None, :]
        else:
            flat_idx = base[:, None] + (lo[:, None] + stride * j[None, :]).clamp(0, n_along - 1) * pitch_along
        # The one-frame finder takes differences of a float32 running sum of 8-bit levels: integers below
        # 2**24, held exactly. Integer window sums give the same numbers with fewer passes.
        v = self.flat[flat_idx].to(torch.int32)
        win = v[:, : L - half + 1].clone()  # win[:, t] = sum of v[:, t:t + half]
        for t in range(1, half):
            win += v[:, t : L - half + 1 + t]
        resp = (win[:, half : half + M] - win[:, :M]).to(torch.float32)
        pols = torch.unique(pol).tolist()
        if len(pols) == 1:  # the usual case: one polarity for the whole group
            resp = (pols[0] * resp if pols[0] else resp.abs()) / half
        else:
            resp = torch.where(pol[:, None] != 0, pol[:, None].to(torch.float32) * resp, resp.abs()) / half
        # Sample j is usable when it lies in the image and in [lo, hi]: an interval [ja, jb] of each row; the
        # detector at k = i + half needs samples i and min(i + 2 half - 1, length - 1), and only the row's
        # own n_resp responses exist.
        n_resp = length - 2 * half + 1
        ja = torch.clamp(-torch.div(lo, stride, rounding_mode="floor"), min=0)
        jb = torch.minimum(
            torch.minimum(
                torch.div(n_along - 1 - lo, stride, rounding_mode="floor"),
                torch.div(hi - lo, stride, rounding_mode="floor"),
            ),
            length - 1,
        )
        ub = torch.minimum(torch.where(jb >= length - 1, jb, jb - 2 * half + 1), n_resp - 1)
        i = torch.arange(M, device=dev)
        ok = (i[None, :] >= ja[:, None]) & (i[None, :] <= ub[:, None])
        neg_inf = torch.tensor(-np.inf, dtype=torch.float32, device=dev)
        return torch.where(ok, resp, neg_inf), ok


@dataclass(frozen=True)
class _GroupRows:
    """One group's step searches stacked scan line by scan line on the device: ``rows`` scan lines per query,
    each row's ``frame``, ``scan`` line, first and last sample ``lo``, ``hi`` along it (px, the window's
    ``half * stride`` included), its own profile ``length`` (samples, as the one-frame finder's, which its
    medians depend on) and ``pol``\arity; ``L`` the longest profile."""

    rows: list[int]
    frame: torch.Tensor
    scan: torch.Tensor
    lo: torch.Tensor
    hi: torch.Tensor
    length: torch.Tensor
    pol: torch.Tensor
    L: int

    @classmethod
    def stack(cls, queries, half: int, stride: int, dev: torch.device) -> _GroupRows:
        """The rows of ``queries`` (``(frame index, coarse_edges keyword arguments)``) on ``dev``."""
        rows = [np.asarray(kw["scan"], int).size for _, kw in queries]
        cat = np.concatenate
        frame = torch.as_tensor(
            cat([np.full(n, b) for n, (b, _) in zip(rows, queries, strict=True)]), device=dev
        )
        scan = torch.as_tensor(cat([np.asarray(kw["scan"], np.int64) for _, kw in queries]), device=dev)
        lo = (
            torch.as_tensor(cat([np.asarray(kw["lo"], np.int64) for _, kw in queries]), device=dev)
            - half * stride
        )
        hi = (
            torch.as_tensor(cat([np.asarray(kw["hi"], np.int64) for _, kw in queries]), device=dev)
            + half * stride
        )
        # each query's own profile length (the one-frame finder's, which its medians depend on)
        q_len = [
            int(np.max(np.asarray(kw["hi"], int) - np.asarray(kw["lo"], int) + 2 * half * stride)) // stride
            + 1
            for _, kw in queries
        ]
        length = torch.as_tensor(cat([np.full(n, L) for n, L in zip(rows, q_len, strict=True)]), device=dev)
        pol = torch.as_tensor(
            cat([np.full(n, int(kw["polarity"])) for n, (_, kw) in zip(rows, queries, strict=True)]),
            device=dev,
        )
        return cls(rows, frame, scan, lo, hi, length, pol, max(q_len))


def _preferred(
    queries, g: _GroupRows, resp: torch.Tensor, ok: torch.Tensor, best: torch.Tensor, half: int, stride: int
) -> torch.Tensor:
    """Each row's response index as :func:`doorloc.vision.coarse.coarse_edges` picks it with ``prefer``: the
    candidate peak (over ``prefer_fraction`` of the row's strongest and 5 robust sigmas of its responses)
    nearest to the preferred position, else ``best`` (the strongest)."""
    dev = resp.device
    rows, lo = g.rows, g.lo
    M = resp.shape[1]
    n_resp = g.length - 2 * half + 1
    r = torch.arange(resp.shape[0], device=dev)
    cat = np.concatenate
    prefer = torch.as_tensor(cat([np.asarray(kw["prefer"], float) for _, kw in queries]), device=dev)
    frac = torch.as_tensor(
        cat(
            [
                np.full(n, float(kw.get("prefer_fraction", 0.3)))
                for n, (_, kw) in zip(rows, queries, strict=True)
            ]
        ),
        device=dev,
    )
    top = resp[r, best]
    peak = torch.zeros_like(ok)
    peak[:, 1:-1] = (resp[:, 1:-1] >= resp[:, :-2]) & (resp[:, 1:-1] > resp[:, 2:])
    peak &= torch.arange(M, device=dev)[None, :] < (n_resp - 1)[:, None]  # not a row's last response
    # numpy's median over each row's own responses (masked ones count as 0): the mean of the two
    # middle values, taken per response count (rows of one query share it; a batch has few counts)
    a = torch.where(ok, resp, torch.zeros_like(resp)).abs()
    floor = torch.empty(resp.shape[0], dtype=torch.float32, device=dev)
    for m in torch.unique(n_resp).tolist():
        sel = n_resp == m
        rows_m = a[sel, :m]
        m_lo = torch.kthvalue(rows_m, (m - 1) // 2 + 1, dim=1).values
        m_hi = torch.kthvalue(rows_m, m // 2 + 1, dim=1).values if m % 2 == 0 else m_lo
        floor[sel] = (m_lo + m_hi) / 2.0
    floor = 1.4826 * floor
    thr = torch.maximum((frac.to(torch.float32) * top), 5.0 * floor)
    cand = peak & (resp >= thr[:, None]) & (resp > 0)
    # the candidate nearest to the preferred position, the first of equally near ones, on the
    # candidates only (as numpy's argmin over the row; NaN wins there, so such a row prefers nothing)
    r_c, i_c = torch.nonzero(cand, as_tuple=True)
    if r_c.numel():
        dist = ((lo[r_c] + stride * (i_c + half)).to(torch.float64) - 0.5 * stride - prefer[r_c]).abs()
        nan_rows = torch.zeros(resp.shape[0], dtype=torch.bool, device=dev)
        nan_rows[r_c[torch.isnan(dist)]] = True
        use = torch.isfinite(dist) & ~nan_rows[r_c]
        r_c, i_c, dist = r_c[use], i_c[use], dist[use]
        inf64 = torch.full((resp.shape[0],), np.inf, dtype=torch.float64, device=dev)
        row_min = inf64.scatter_reduce(0, r_c, dist, reduce="amin")
        big = torch.full((resp.shape[0],), M, dtype=torch.int64, device=dev)
        near = big.scatter_reduce(
            0, r_c, torch.where(dist == row_min[r_c], i_c, torch.full_like(i_c, M)), reduce="amin"
        )
        best = torch.where(near < M, near, best)
    return best


def _stackable(image: np.ndarray, shape: tuple[int, int], gamma: float) -> str | None:
    """Why a frame cannot join a batch of ``shape`` 8-bit planes (None: it can); ``gamma`` the cell's
    response exponent."""
    if not isinstance(image, np.ndarray):
        return "not an array"
    if image.dtype != np.uint8:
        return f"{image.dtype} pixels (the batched path takes 8-bit frames)"
    if image.ndim == 3 and image.shape[2] in (3, 4) and gamma != 1.0:
        return "colour at a response exponent other than 1 (its luminance is summed in light, 16-bit)"
    if image.ndim == 3 and image.shape[2] in (1, 3, 4):
        hw = image.shape[:2]
    elif image.ndim == 2:
        hw = image.shape
    else:
        return f"shape {image.shape}"
    if tuple(hw) != shape:
        return f"{hw[1]}x{hw[0]} px, not the batch's {shape[1]}x{shape[0]}"
    return None


def locate_batch(
    images: Sequence[np.ndarray],
    cell: Cell,
    doors: DoorSize | Sequence[DoorSize | None] | None = None,
    *,
    names: Sequence[str] | None = None,
    config: LocateConfig | None = None,
    device: str | torch.device = "cpu",
    finder: Literal["auto", "torch", "plane"] = "auto",
    jpeg_qualities: Sequence[int] | None = None,
) -> list[BatchAnswer]:
    """:func:`doorloc.vision.locate.locate` over a batch of frames of one cell, the coarse search batched.

    Parameters
    ----------
    images : sequence of ndarray
        Frames as the camera delivered them (see :func:`locate`); 8-bit frames of the camera's size are
        batched, the others go through :func:`locate` alone.
    cell : Cell
    doors : DoorSize or sequence of DoorSize, optional
        One door for all frames, or one per frame (None: the cell's default door).
    names : sequence of str, optional
        ``LocateResult.image`` of each frame.
    config : LocateConfig, optional
    device : str or torch.device
        Where the batched work runs (``"cpu"``, ``"cuda"``, ``"auto"``).
    finder : "auto", "torch" or "plane"
        Who answers the step searches: :class:`TorchStepFinder` on ``device`` or the one-frame finder
        (:class:`PlaneStepFinder`); ``"auto"`` takes torch on CUDA and the one-frame finder on CPU, where
        it is faster (module docstring). The answers are the same.
    jpeg_qualities : sequence of int, optional
        Each frame's file's JPEG quality, 0 where not a JPEG or not known (see :func:`locate`).

    Returns
    -------
    list of BatchAnswer
        In the order of ``images``; each result equals what :func:`locate` gives for that frame.
    """
    dev = resolve_device(device) if isinstance(device, str) else device
    if finder not in ("auto", "torch", "plane"):
        raise ValueError(f"unknown step finder {finder!r}; use auto, torch or plane")
    frames = _Frames.of(images, cell, doors, names, config, jpeg_qualities)
    w, h = cell.camera.image_size
    answers: list[BatchAnswer | None] = [None] * len(images)
    planes: list[np.ndarray] = []
    members: list[int] = []
    for i, img in enumerate(images):
        why = _stackable(img, (h, w), cell.response_gamma)
        if why is not None:
            answers[i] = frames.alone(i, why)
            continue
        planes.append(_grey(img))
        members.append(i)
    if members:
        use_torch = finder == "torch" or (finder == "auto" and dev.type != "cpu")
        finder_impl: StepFinder = (
            TorchStepFinder.from_planes(planes, dev) if use_torch else PlaneStepFinder(planes)
        )
        steps: dict[int, Steps] = {
            b: locate_steps(
                images[i],
                cell,
                frames.doors[i],
                image_name=frames.names[i],
                config=config,
                luminance=LuminancePlane(planes[b], 1.0),
                jpeg_quality=frames.jpeg_qualities[i],
            )
            for b, i in enumerate(members)
        }
        # The one-frame finder answers each frame's searches alone, so nothing is gained by taking the frames'
        # steps in turn, and it cost: each step of eight interleaved frames met another 2 MB frame and its
        # arrays in the caches (batched locate 7.3-8.3 ms a frame against 6.5-7.5 ms one-frame). Without
        # torch each frame runs to its answer.
        for group in [steps] if use_torch else [{b: g} for b, g in steps.items()]:
            _run_group(group, finder_impl, planes, frames, answers, members)
    return [a for a in answers if a is not None]


def _grey(img: np.ndarray) -> np.ndarray:
    """A stackable 8-bit frame's luminance plane (H, W), exactly as the one-frame path takes it."""
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[..., 0]
    if img.ndim == 3:  # OpenCV's fixed-point BT.601 conversion, exactly as the one-frame path
        import cv2

        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    return img


@dataclass(frozen=True)
class _Frames:
    """The batch's frames and what each is located with: the cell, each frame's door and name, the config,
    each frame's file's JPEG quality."""

    images: Sequence[np.ndarray]
    cell: Cell
    doors: list[DoorSize | None]
    names: list[str]
    config: LocateConfig | None
    jpeg_qualities: list[int]

    @classmethod
    def of(
        cls,
        images: Sequence[np.ndarray],
        cell: Cell,
        doors: DoorSize | Sequence[DoorSize | None] | None,
        names: Sequence[str] | None,
        config: LocateConfig | None,
        jpeg_qualities: Sequence[int] | None,
    ) -> _Frames:
        """:func:`locate_batch`'s arguments, one door, name and quality per frame."""
        n = len(images)
        if jpeg_qualities is not None and len(jpeg_qualities) != n:
            raise ValueError(f"{len(jpeg_qualities)} JPEG qualities for {n} frames; give one per frame")
        return cls(
            images,
            cell,
            list(doors) if isinstance(doors, Sequence) else [doors] * n,
            list(names) if names is not None else [""] * n,
            config,
            list(jpeg_qualities) if jpeg_qualities is not None else [0] * n,
        )

    def alone(self, i: int, why: str) -> BatchAnswer:
        """Frame ``i`` through the one-frame path, ``why`` it did not go through the batched one."""
        return BatchAnswer(
            locate(
                self.images[i],
                self.cell,
                self.doors[i],
                image_name=self.names[i],
                config=self.config,
                jpeg_quality=self.jpeg_qualities[i],
            ),
            why,
        )


def _run_group(
    group: dict[int, Steps],
    finder: StepFinder,
    planes: list[np.ndarray],
    frames: _Frames,
    answers: list[BatchAnswer | None],
    members: list[int],
) -> None:
    """The frames of ``group`` (batch index -> its locate coroutine) to their answers, each round of their
    step searches answered together; if the finder fails, the one-frame path answers them.

    The finder holds each frame's own plane (``planes``); a search on another plane (the frame's levels
    mapped through a camera model: a cell's photometric model, or a shoulder's doubt, :mod:`doorloc.vision.
    response_shoulder`) is answered on that plane by the one-frame finder, as :func:`locate` would."""
    pending: dict[int, StepQuery] = {}
    for b, g in group.items():
        _advance(g, None, b, pending, answers, members)
    while pending:
        batch = list(pending.items())
        own = [(b, q.kwargs) for b, q in batch if q.plane is planes[b]]
        try:
            found = iter(finder.answer(own))
        except Exception as e:  # noqa: BLE001 - the one-frame path still answers these frames
            for b, _ in batch:
                i = members[b]
                answers[i] = frames.alone(i, f"batched step search failed ({type(e).__name__}: {e})")
            break
        pending = {}
        for b, q in batch:
            res = next(found) if q.plane is planes[b] else coarse_edges(q.plane, **q.kwargs)
            _advance(group[b], res, b, pending, answers, members)


def _advance(
    g: Steps,
    sent: tuple[np.ndarray, np.ndarray] | None,
    b: int,
    pending: dict[int, StepQuery],
    answers: list[BatchAnswer | None],
    members: list[int],
) -> None:
    """Run frame ``b``'s coroutine to its next step search (kept in ``pending``) or to its answer."""
    try:
        pending[b] = next(g) if sent is None else g.send(sent)
    except StopIteration as done:
        answers[members[b]] = BatchAnswer(done.value)


def numpy_finder(plane: np.ndarray, **kw: Any) -> tuple[np.ndarray, np.ndarray]:
    """The one-frame finder, for comparisons."""
    return coarse_edges(plane, **kw)

"""Real-frame proxy for marker removal: real markerless frames, realistic markers painted on.

Scoring a marker-removal method needs the markerless truth, which a real sensor with markers
never gives. The proxy takes the real markerless presses shipped with Taxim (the ``taxim``
package: GelSight 640x480, 48 presses + a no-contact frame; GelSight Mini, 24 presses, resized
to its usual 320x240), paints markers on them the way real ones look
(:func:`tacswitch.sim.markers.paint_markers`: black pasted dots or soft grey painted dots, fitted
to real GelSight Mini frames) and captures the result as a camera or recorder would
(:mod:`tacswitch.sim.capture`: lossless, MJPEG, H.264). The clean real frame is the truth.

Scores (grey levels, all channels):

- masked MAE and mean signed error over the true marker footprint (every pixel painting changed
  by more than 0.5 grey level): a mask that misses part of it leaves marker pixels in;
- ghost: per marker, the mean of the filled hole minus the mean of the gel ring around it
  (3-6 px out), in luma, minus the same difference on the clean frame; a fill that copies a dark
  ring leaves a visible grey dot (negative ghost). It should stay within +-1 grey level.

Without ground truth, on real frames WITH markers (:func:`heldout_scores`): the marker mask is
shifted by half a pitch onto bare gel, those real pixels are hidden and filled along with the
markers, and the fill is scored there (dense: every shifted hole at once, about half of a GelSight
Mini frame masked, the stress case; sparse, :func:`sparse_heldout_scores`: a quarter of them at a
time, near the real hole density); and the ghost around the real markers
(:func:`ghost_per_marker` with no clean frame).

Images are uint8 BGR, points ``(x, y)`` px. Needs the ``taxim`` package for the presses (the
``test`` extra) and PyAV for H.264 (the ``train`` extra).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.removal import remove_markers
from tacswitch.sim.capture import CaptureProfile
from tacswitch.sim.markers import MarkerStyle

SENSORS: tuple[str, ...] = ("gelsight", "gelsight_mini")
STYLES: tuple[str, ...] = ("pasted", "painted", "crisp")
#: The captures of the proxy: as painted, a webcam MJPEG stream, an H.264 recording (a predicted
#: frame of a 4-frame clip). The real frames already carry their camera's blur and noise; the
#: painted dots carry the blur fitted on real ones, so no further blur or noise is added.
CAPTURES: dict[str, CaptureProfile] = {
    "lossless": CaptureProfile(),
    "mjpeg": CaptureProfile(codec="mjpeg", quality=75),
    "h264": CaptureProfile(codec="h264", quality=26, preset="veryfast", h264_index=3),
}
#: Ghost ring: pixels this far (px, exclusive..inclusive) outside a marker's hole.
GHOST_RING = (3.0, 6.0)

#: A fill under test: (frame with markers, extra pixels to fill or None) -> markerless frame.
#: Methods choose their own marker mask (the point of the proxy); ``extra`` is added to it
#: (held-out gel pixels of the ground-truth-free check).
Fill = Callable[[NDArray[np.uint8], NDArray[np.bool_] | None], NDArray[np.uint8]]


@dataclass(frozen=True)
class ProxyFrame:
    """One proxy frame: ``img`` (painted and captured) and its truth ``clean``.

    Attributes:
        name: ``sensor/press/style/capture``.
        img, clean: ``H x W x 3`` uint8 BGR.
        footprint: ``H x W`` bool, true marker footprint.
        contact: ``H x W`` bool, the press's contact disc (Taxim's annotation).
        reference: the no-contact frame with the same markers and capture (for ``hybrid``).
        centres: ``N x 2`` painted marker centres ``(x, y)``.
    """

    name: str
    img: NDArray[np.uint8]
    clean: NDArray[np.uint8]
    footprint: NDArray[np.bool_]
    contact: NDArray[np.bool_]
    reference: NDArray[np.uint8]
    centres: NDArray[np.float32]


def _taxim_pack(sensor: str) -> Any:
    try:
        import taxim
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("the real-frame proxy needs the taxim package (its real presses): "
                          "pip install 'tacswitch[test]'") from exc
    if sensor not in SENSORS:
        raise ValueError(f"sensor: expected one of {SENSORS}; got {sensor!r}")
    return np.load(Path(taxim.__file__).parent / "calib" / sensor / "dataPack.npz")


def load_presses(sensor: str, n: int | None = None
                 ) -> tuple[NDArray[np.uint8], list[tuple[NDArray[np.uint8], NDArray[np.bool_]]]]:
    """Taxim's real markerless frames of ``sensor``: ``(no_contact, [(press, contact), ...])``.

    GelSight: 640x480; GelSight Mini: resized to 320x240 (area averaging) as it is usually
    streamed. ``n`` presses (default all), taken evenly over the recording. ``contact`` is the
    annotated contact disc.
    """
    import cv2

    pack = _taxim_pack(sensor)
    imgs, centres, radii = pack["imgs"], pack["touch_center"], pack["touch_radius"]
    idx = np.arange(len(imgs)) if n is None else np.linspace(0, len(imgs) - 1, n).round()
    scale = 0.5 if sensor == "gelsight_mini" else 1.0

    def prep(a: NDArray[np.uint8]) -> NDArray[np.uint8]:
        if scale == 1.0:
            return np.ascontiguousarray(a)
        return np.asarray(cv2.resize(a, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA),
                          np.uint8)

    presses = []
    for i in idx.astype(int):
        img = prep(imgs[i])
        h, w = img.shape[:2]
        yy, xx = np.mgrid[0:h, 0:w]
        # Taxim's touch centre is (x, y) px (checked: the centroid of the change from the
        # no-contact frame lies within ~15 px of it on both sensors).
        cx, cy = np.asarray(centres[i], np.float64) * scale
        r = float(radii[i]) * scale
        presses.append((img, (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r))
    return prep(pack["f0"]), presses


#: Presses of the proxy's principal benches (``load_presses(sensor, 4)``, which ``n`` = 1 and 2
#: also pick from) and their neighbours in the recording: never used for training.
HELD_OUT_PRESSES = 4
HELD_OUT_REACH = 1


def held_out_indices(sensor: str) -> frozenset[int]:
    """Indices (into Taxim's presses of ``sensor``) kept out of training: the presses
    ``load_presses(sensor, HELD_OUT_PRESSES)`` scores, each with :data:`HELD_OUT_REACH`
    neighbours on either side (consecutive presses of a recording can be near-repeats)."""
    n = len(_taxim_pack(sensor)["imgs"])
    picks = np.linspace(0, n - 1, HELD_OUT_PRESSES).round().astype(int)
    return frozenset(int(i + d) for i in picks for d in range(-HELD_OUT_REACH, HELD_OUT_REACH + 1)
                     if 0 <= i + d < n)


def training_presses(sensor: str
                     ) -> list[tuple[int, NDArray[np.uint8], NDArray[np.bool_]]]:
    """Taxim's presses of ``sensor`` outside :func:`held_out_indices`, as
    ``(index, frame, contact)`` at the proxy's size (real markerless frames to paint markers on
    for training, :mod:`tacswitch.tacdiff.painted`). Model scores on the proxy with ``n`` other
    than 1, 2 or 4 presses include training presses."""
    _, presses = load_presses(sensor)
    held = held_out_indices(sensor)
    return [(i, f, c) for i, (f, c) in enumerate(presses) if i not in held]


def styles_for(sensor: str) -> dict[str, MarkerStyle]:
    """The marker looks at ``sensor``'s scale: ``"painted"`` (the style fitted to real Mini
    frames), ``"pasted"`` (black dots, the same rim, a fainter halo) and ``"crisp"`` (black
    dots with a 1 px rim and no halo, the case where a wider mask only costs). Diameters scale
    with the frame (11.5 px at 320x240, 23 px at 640x480); rims and halo do not."""
    if sensor not in SENSORS:
        raise ValueError(f"sensor: expected one of {SENSORS}; got {sensor!r}")
    # Dots are twice as wide at 640x480, but their rims and halo are not twice as soft: with the
    # Mini's rim and halo in px, the ring just outside a one-dilation threshold mask of H.264
    # GelSight frames is 3.5 % of the gel (-6 grey levels), as the issue measured on real
    # GelSight H.264 recordings and as real FOTS Mini frames show (-6.1 at their brighter gel).
    s = 2.0 if sensor == "gelsight" else 1.0
    return {
        "painted": MarkerStyle(diameter=11.5 * s, edge_px=1.5, halo_px=1.5),
        "pasted": MarkerStyle(kind="pasted", diameter=11.5 * s, darkness=0.97, edge_px=1.5,
                              halo=0.03, halo_px=1.5, texture=0.0, level_jitter=0.02),
        "crisp": MarkerStyle(kind="pasted", diameter=11.5 * s, darkness=0.95, edge_px=1.0,
                             halo=0.0, texture=0.0, level_jitter=0.0),
    }


def grid_for(sensor: str, rng: np.random.Generator) -> NDArray[np.float32]:
    """The sensor's marker grid (preset pitch) shifted by a random sub-pitch offset, with
    placement jitter; one extra row and column so markers cut by every border occur."""
    from tacswitch.sim.markers import marker_grid
    from tacswitch.sim.presets import get_preset

    p = get_preset(sensor)
    grid = marker_grid(p.height, p.width, p.rows + 1, p.cols + 1, p.pitch, jitter=0.5, seed=rng)
    pts = grid.astype(np.float64) + rng.uniform(-p.pitch / 2, p.pitch / 2, 2)
    r = p.diameter / 2
    keep = ((pts[:, 0] > -r) & (pts[:, 0] < p.width - 1 + r)
            & (pts[:, 1] > -r) & (pts[:, 1] < p.height - 1 + r))
    return pts[keep].astype(np.float32)


def proxy_frames(sensor: str, n: int = 4, *, styles: Sequence[str] = STYLES,
                 captures: Sequence[str] = tuple(CAPTURES), seed: int = 0) -> list[ProxyFrame]:
    """``n`` presses of ``sensor`` x ``styles`` x ``captures`` proxy frames (deterministic
    given ``seed``; the same presses, grid and dots for every capture of a style)."""
    from tacswitch.sim import capture
    from tacswitch.sim.markers import paint_markers

    for s in styles:
        if s not in STYLES:
            raise ValueError(f"styles: expected names from {STYLES}; got {s!r}")
    for c in captures:
        if c not in CAPTURES:
            raise ValueError(f"captures: expected names from {tuple(CAPTURES)}; got {c!r}")
    f0, presses = load_presses(sensor, n)
    looks = styles_for(sensor)
    frames = []
    for i, (clean, contact) in enumerate(presses):
        for si, style in enumerate(styles):
            rng = np.random.default_rng((seed, i, si))
            centres = grid_for(sensor, rng)
            tex_seed = int(rng.integers(2**31))
            img, fp = paint_markers(clean, centres, looks[style], rng=tex_seed)
            ref, _ = paint_markers(f0, centres, looks[style], rng=tex_seed)
            for c in captures:
                prof = CAPTURES[c]
                frames.append(ProxyFrame(
                    f"{sensor}/{i}/{style}/{c}", capture.apply(img, prof, (seed, i, si, 1)),
                    clean, fp, contact, capture.apply(ref, prof, (seed, i, si, 2)), centres))
    return frames


def _luma(img: NDArray[np.uint8]) -> NDArray[np.float32]:
    import cv2

    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32) if img.ndim == 3 else \
        img.astype(np.float32)


def ghost_per_marker(out: NDArray[np.uint8], holes: NDArray[np.bool_],
                     clean: NDArray[np.uint8] | None = None,
                     ring: tuple[float, float] = GHOST_RING) -> NDArray[np.float64]:
    """Per hole (8-connected component of ``holes``): mean luma of ``out`` over the hole minus
    its mean over the gel ring ``ring`` px outside it (other holes excluded), grey levels;
    minus the same difference on ``clean`` when given (so real shading under the hole does not
    count). Holes without a ring (e.g. in a corner) are skipped."""
    import cv2

    if holes.shape != out.shape[:2]:
        raise ValueError(f"holes: expected shape {out.shape[:2]}; got {holes.shape}")
    lo, hi = ring
    y_out = _luma(out)
    y_clean = None if clean is None else _luma(clean)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(holes.astype(np.uint8), connectivity=8)
    h, w = holes.shape
    pad = int(np.ceil(hi)) + 1
    # Pixels near any hole are not gel ring for a neighbour.
    near = cv2.distanceTransform((~holes).astype(np.uint8), cv2.DIST_L2, 5) <= lo
    res = []
    for k in range(1, n):
        x, y, bw, bh = stats[k, :4]
        x0, y0 = max(x - pad, 0), max(y - pad, 0)
        x1, y1 = min(x + bw + pad, w), min(y + bh + pad, h)
        lab = labels[y0:y1, x0:x1] == k
        d = cv2.distanceTransform((~lab).astype(np.uint8), cv2.DIST_L2, 5)
        rg = (d > lo) & (d <= hi) & ~near[y0:y1, x0:x1]
        if rg.sum() < 8:
            continue
        diff = float(y_out[y0:y1, x0:x1][lab].mean() - y_out[y0:y1, x0:x1][rg].mean())
        if y_clean is not None:
            diff -= float(y_clean[y0:y1, x0:x1][lab].mean() - y_clean[y0:y1, x0:x1][rg].mean())
        res.append(diff)
    return np.asarray(res, np.float64)


def radial_profile(img: NDArray[np.uint8], centres: NDArray | None = None, *,
                   radii: int = 14, bg: tuple[float, float] = (10.0, 14.0)
                   ) -> NDArray[np.float64]:
    """Mean marker profile: luma at distance ``[k, k + 1)`` px from each marker centre
    (``k = 0 .. radii - 1``) over the median luma ``bg`` px out, averaged over the markers
    whose window lies inside the frame. ``centres`` default: the extracted markers. Compares
    painted and captured dots with real ones (soft rim, halo, codec ringing)."""
    from tacswitch.markers import extract_markers

    pts = extract_markers(img).centres if centres is None else np.asarray(centres, np.float64)
    y = _luma(img)
    h, w = y.shape
    half = int(np.ceil(max(bg[1], radii))) + 1
    yy, xx = np.mgrid[-half : half + 1, -half : half + 1]
    rows = []
    for cx, cy in pts:
        ix, iy = int(np.rint(cx)), int(np.rint(cy))
        if ix < half or iy < half or ix >= w - half or iy >= h - half:
            continue
        r = np.hypot(xx + (ix - cx), yy + (iy - cy))
        patch = y[iy - half : iy + half + 1, ix - half : ix + half + 1]
        level = float(np.median(patch[(r > bg[0]) & (r < bg[1])]))
        rows.append([patch[(r >= k) & (r < k + 1)].mean() / level for k in range(radii)])
    if not rows:
        raise ValueError("centres: no marker window lies inside the frame")
    return np.asarray(rows, np.float64).mean(axis=0)


@dataclass(frozen=True)
class Score:
    """Scores of one method over a set of frames (grey levels; ms median per frame)."""

    mae: float
    signed: float
    ghost: float
    ghost_abs: float
    ms: float


def score(out: NDArray[np.uint8], frame: ProxyFrame) -> tuple[float, float, NDArray[np.float64]]:
    """``(masked MAE, mean signed error, per-marker ghosts)`` of one fill over the true
    footprint of ``frame``."""
    fp = frame.footprint
    err = out[fp].astype(np.float64) - frame.clean[fp]
    return (float(np.abs(err).mean()), float(err.mean()),
            ghost_per_marker(out, fp, frame.clean))


@dataclass(frozen=True)
class FrameResult:
    """One fill of one proxy frame: error sums over the footprint, ghosts, time (s)."""

    name: str
    abs_sum: float
    signed_sum: float
    count: int
    ghosts: NDArray[np.float64]
    seconds: float


def run(frames: Sequence[ProxyFrame], fill: Fill) -> list[FrameResult]:
    """Runs ``fill`` once on every frame (timed) and keeps what :func:`pool` needs."""
    import time

    res = []
    for f in frames:
        t0 = time.perf_counter()
        out = fill(f.img, None)
        dt = time.perf_counter() - t0
        err = out[f.footprint].astype(np.float64) - f.clean[f.footprint]
        res.append(FrameResult(f.name, float(np.abs(err).sum()), float(err.sum()), int(err.size),
                               ghost_per_marker(out, f.footprint, f.clean), dt))
    return res


def pool(results: Sequence[FrameResult]) -> Score:
    """MAE and signed error pooled over all footprint pixels, ghosts over all markers, median
    time per frame."""
    n = max(sum(r.count for r in results), 1)
    g = np.concatenate([r.ghosts for r in results]) if results else np.zeros(0)
    return Score(sum(r.abs_sum for r in results) / n, sum(r.signed_sum for r in results) / n,
                 float(g.mean()) if g.size else float("nan"),
                 float(np.abs(g).mean()) if g.size else float("nan"),
                 1e3 * float(np.median([r.seconds for r in results])) if results else float("nan"))


def evaluate(frames: Sequence[ProxyFrame], fill: Fill) -> Score:
    """Runs ``fill`` on every frame; MAE and signed error are pooled over all footprint pixels
    of all frames, ghosts over all markers (:func:`run`, :func:`pool`)."""
    return pool(run(frames, fill))


# --- Ground-truth-free check on real frames with markers ------------------------------------

def shifted_holdout(img: NDArray[np.uint8], marker_mask: NDArray[np.bool_] | None = None,
                    *, margin: int = 3) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
    """The marker-offset trick: ``(holdout, hidden)``.

    ``holdout``: bare-gel pixels shaped like the markers, ``marker_mask`` shifted by half the
    marker pitch along x and y (no wrap-around), minus everything within ``margin`` px of a
    marker. ``hidden``: ``img`` with the real markers' pixels copied onto the held-out ones, so
    a method sees a marker there, never the truth (TacDiff reads the pixels under its mask).
    Default ``marker_mask``: the extracted markers dilated twice, border markers kept.
    """
    from tacswitch.markers import dilate_mask, extract_markers

    m = extract_markers(img, exclude_border=False)
    mask = dilate_mask(m.mask, 2) if marker_mask is None else np.asarray(marker_mask, bool)
    if len(m) < 2:
        raise ValueError("img: need at least 2 markers to find the pitch of a held-out shift")
    c = m.centres.astype(np.float64)
    d = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(d, np.inf)
    half = max(round(float(np.median(d.min(axis=1))) / 2), 1)
    h, w = mask.shape
    shifted = np.zeros_like(mask)
    shifted[half:, half:] = mask[: h - half, : w - half]
    holdout = shifted & ~dilate_mask(mask, margin)
    moved = img.copy()
    moved[half:, half:] = img[: h - half, : w - half]
    hidden = img.copy()
    hidden[holdout] = moved[holdout]
    return holdout, hidden


def heldout_scores(img: NDArray[np.uint8], fill: Fill, holdout: NDArray[np.bool_],
                   hidden: NDArray[np.uint8], ghost_holes: NDArray[np.bool_]
                   ) -> tuple[float, float, NDArray[np.float64]]:
    """``(MAE, signed error)`` of ``fill`` over the held-out real gel pixels (``hidden`` is
    ``img`` with markers copied onto ``holdout``, filled together with the real markers), and
    the per-marker ghosts of ``fill(img)`` around the real markers (``ghost_holes``: a generous
    marker mask; no clean frame, so the gel's own shading under a hole is not subtracted)."""
    out = fill(hidden, holdout)
    err = out[holdout].astype(np.float64) - img[holdout]
    return (float(np.abs(err).mean()), float(err.mean()),
            ghost_per_marker(fill(img, None), ghost_holes))


#: Phases of the sparse held-out check per grid axis (:func:`sparse_holdouts`): 2 x 2 = 4 sets,
#: each holding every other held-out hole along x and y.
SPARSE_PHASES = 2


def sparse_holdouts(holdout: NDArray[np.bool_], phases: int = SPARSE_PHASES,
                    pitch: float | None = None) -> list[NDArray[np.bool_]]:
    """The held-out holes of :func:`shifted_holdout` split into ``phases ** 2`` sets, by the
    row and column (modulo ``phases``) of each hole's centre on the grid they form: a set holds
    every ``phases``-th hole along x and y, so filling one set with the markers keeps the
    hole density near the real one (1 + 1 / phases ** 2 holes per marker instead of 2). Sets
    without a hole are left out.

    ``pitch``: grid pitch in px (default: the median distance from each held-out hole's centre
    to its nearest neighbour's; holes cut by the frame border shift their centres a little,
    which the rounding to the nearest grid row absorbs).
    """
    import cv2

    from tacswitch._checks import as_count

    k = as_count(phases, "phases", 1)
    _, labels, _, cen = cv2.connectedComponentsWithStats(holdout.astype(np.uint8),
                                                         connectivity=8)
    c = np.asarray(cen[1:], np.float64)  # (x, y) per hole
    if len(c) == 0:
        return []
    if pitch is None:
        if len(c) < 2:
            return [np.asarray(holdout, bool).copy()]
        d = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
        np.fill_diagonal(d, np.inf)
        pitch = float(np.median(d.min(axis=1)))
    if not pitch > 0:
        raise ValueError(f"pitch: expected a positive grid pitch in px; got {pitch!r}")
    col = np.rint((c[:, 0] - c[:, 0].min()) / pitch).astype(np.int64) % k
    row = np.rint((c[:, 1] - c[:, 1].min()) / pitch).astype(np.int64) % k
    phase = np.concatenate([[-1], row * k + col])
    per_pixel = phase[labels]
    return [m for m in (per_pixel == q for q in range(k * k)) if m.any()]


def sparse_heldout_scores(img: NDArray[np.uint8], fill: Fill, holdout: NDArray[np.bool_],
                          hidden: NDArray[np.uint8], phases: int = SPARSE_PHASES
                          ) -> tuple[float, float]:
    """``(MAE, signed error)`` of ``fill`` over the held-out real gel pixels, held out one set
    of :func:`sparse_holdouts` at a time (``img`` with only that set's markers copied in, filled
    with the real markers) and pooled over all sets: the sparse variant of
    :func:`heldout_scores`, whose masks hold twice the markers (about half a GelSight Mini frame
    masked), a density no marker grid has and the stress case of methods that read the holes'
    surroundings (TacDiff)."""
    errs = []
    for sub in sparse_holdouts(holdout, phases):
        frame = img.copy()
        frame[sub] = hidden[sub]
        out = fill(frame, sub)
        errs.append(out[sub].astype(np.float64) - img[sub])
    err = np.concatenate(errs) if errs else np.zeros(0)
    if err.size == 0:
        return float("nan"), float("nan")
    return float(np.abs(err).mean()), float(err.mean())


# --- The methods compared ---------------------------------------------------------------------

def default_mask(img: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """The mask :func:`tacswitch.remove_markers` builds when given none (markers extracted,
    border-cut ones kept, grown by its default: adaptive growth where the installed version
    has it, else its fixed dilation)."""
    import inspect

    from tacswitch.markers import extract_markers

    grow = inspect.signature(remove_markers).parameters["dilate"].default
    return extract_markers(img, dilate="auto" if grow in (None, "auto") else grow,
                           exclude_border=False).mask


def threshold_mask(img: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """The mask most pipelines use: the thresholded markers dilated once (3x3 cross)."""
    from tacswitch.markers import extract_markers

    return extract_markers(img, dilate=1, exclude_border=False).mask


def _with(mask: NDArray[np.bool_], extra: NDArray[np.bool_] | None) -> NDArray[np.bool_]:
    return mask if extra is None else mask | extra


def own_mask_fill(method: str, **kw: Any) -> Fill:
    """``tacswitch.remove_markers(img, mask, method, **kw)`` on :func:`default_mask`."""
    def fill(img: NDArray[np.uint8], extra: NDArray[np.bool_] | None) -> NDArray[np.uint8]:
        out: NDArray[np.uint8] = remove_markers(img, _with(default_mask(img), extra),
                                                method=method, **kw)  # type: ignore[arg-type]
        return out
    return fill


def opencv_fill(radius: int, flag: str = "telea") -> Fill:
    """``cv2.inpaint`` (TELEA or NS) at ``radius`` on :func:`threshold_mask`."""
    import cv2

    code = cv2.INPAINT_TELEA if flag == "telea" else cv2.INPAINT_NS

    def fill(img: NDArray[np.uint8], extra: NDArray[np.bool_] | None) -> NDArray[np.uint8]:
        m = _with(threshold_mask(img), extra).astype(np.uint8)
        return np.asarray(cv2.inpaint(img, m, radius, code))
    return fill


def prior_fill(kind: str, radius: float | None = None) -> Fill:
    """The classical prior TacDiff refines (:mod:`tacswitch.tacdiff.prior`), on
    :func:`default_mask`, its TELEA at ``radius`` px (default
    :data:`~tacswitch.tacdiff.prior.DEFAULT_PRIOR_RADIUS`, that of the shipped models)."""
    from tacswitch.tacdiff.prior import DEFAULT_PRIOR_RADIUS, check_radius, from_net, prior_planes

    r = check_radius(DEFAULT_PRIOR_RADIUS if radius is None else radius, "radius")

    def fill(img: NDArray[np.uint8], extra: NDArray[np.bool_] | None) -> NDArray[np.uint8]:
        m = _with(default_mask(img), extra)
        out = img.copy()
        out[m] = from_net(prior_planes(img, m, kind, r)[0])[m]
        return out
    return fill


def methods(radii: Sequence[int] = (3, 5, 8, 12), *, models: bool = True,
            priors: Sequence[str] = ()) -> dict[str, Fill]:
    """The proxy's methods: our TELEA default pipeline (:data:`tacswitch.inpaint.DEFAULT_RADIUS`)
    and TELEA at the other ``radii`` (own mask; r=3 was the default before),
    OpenCV TELEA at ``radii`` on a one-dilation threshold mask, NS, the biharmonic fill, the
    ``priors`` named (:mod:`tacswitch.tacdiff.prior` kinds, TELEA at the shipped models'
    radius), and with ``models`` TacDiff
    (default and fast model, K=1, each in its default orientations) and hybrid."""
    from tacswitch.inpaint import DEFAULT_RADIUS

    out: dict[str, Fill] = {
        f"TELEA default r={DEFAULT_RADIUS} (own mask)": own_mask_fill("telea")}
    for r in radii:
        if r != DEFAULT_RADIUS:
            old = ", previous default" if r == 3 else ""
            out[f"TELEA r={r}{old} (own mask)"] = own_mask_fill("telea", radius=r)
    for r in radii:
        out[f"OpenCV TELEA r={r} (1-dilation threshold mask)"] = opencv_fill(r)
    out["NS r=3 (own mask)"] = own_mask_fill("ns")
    out["biharmonic (own mask)"] = own_mask_fill("biharmonic")
    from tacswitch.tacdiff.prior import DEFAULT_PRIOR_RADIUS

    for kind in priors:  # at the shipped models' TELEA radius (r=3 before 0.5's benches)
        out[f"prior {kind} r={DEFAULT_PRIOR_RADIUS} (own mask)"] = prior_fill(kind)
    if models:
        # Each at its default orientations: 4 for the default model, 1 for the fast one.
        out["TacDiff K=1, 4 orientations (own mask)"] = own_mask_fill("tacdiff")
        out["TacDiff fast K=1 (own mask)"] = own_mask_fill("tacdiff", model="fast")
        out["hybrid K=1, 4 orientations (own mask)"] = own_mask_fill("hybrid")
    return out


def grown_biharmonic_fill(px: float | None = None) -> Fill:
    """The biharmonic fill solved on each hole of :func:`default_mask` grown by ``px``
    (default :data:`tacswitch.tacdiff.prior.PRIOR_GROW`; within its Voronoi cell), kept on the
    hole: the biharmonic part of the ``"telea+biharmonic-grown"`` prior."""
    from tacswitch.inpaint import inpaint_biharmonic
    from tacswitch.tacdiff.prior import PRIOR_GROW, grow_holes

    g = PRIOR_GROW if px is None else px

    def fill(img: NDArray[np.uint8], extra: NDArray[np.bool_] | None) -> NDArray[np.uint8]:
        m = _with(default_mask(img), extra)
        out = img.copy()
        out[m] = inpaint_biharmonic(img, grow_holes(m, g))[m]
        return out
    return fill

"""Training-free marker motion: dense optical flow from a reference frame, read at the markers.

The motion of a marker from ``ref`` to ``img`` is the forward flow ``ref -> img`` read
bilinearly at the marker's rest centre (a position in ``ref``): OpenCV's convention is
``ref(y, x) ~ img(y + flow_y, x + flow_x)``, so the flow at a ``ref`` pixel is where that piece of
gel went. Works on whatever moves between the two frames: the contact imprint's shading and edges,
the object's texture, and the coating's fixed-pattern grain and dust (weak on real gels, about
0.3 grey levels under 0.5 of temporal noise on taxim's real presses).

Brightness: both frames are turned into local contrast ``(g - G*g) / G*g`` of their grey level
``g`` (``G*``: a wide Gaussian, sigma ``BG_SIGMA_REL`` of the frame width), which removes a global
gain and any smooth illumination change, then mapped to 8 bits with one shared, compressive scale
(``tanh``) so the faint grain keeps a few grey levels while the strong imprint does not saturate.
Both 8-bit frames are mirror-padded by :data:`PAD_REL` of the width before the flow (the
markers of the outer grid rows sit ~6 px from the edge, where DIS's patches and pyramid lack
support; the padding halved the largest motion a brightness change reports there), and the flow
field is smoothed over about a marker's size (:data:`SMOOTH_REL`) before it is read at the
markers. Identical frames return exactly zero (checked before any flow is computed).

Reference without the contact (``suppress_imprint=True``): against the no-contact frame the
imprint that appears is shading, not motion, and DIS follows it (on taxim's real presses 4-10 px
at GelSight Mini's contact, tens of px at GelSight's, where the gel moves under 1 px). The option
weights the flow by :func:`imprint_weight` (low where the blurred grey level changed by more than
:data:`IMPRINT_CHANGE`, relative, after matching the median gain) and smooths it by normalised
convolution over :data:`IMPRINT_SMOOTH_REL` of the width (instead of :data:`SMOOTH_REL`), so the
field inside the imprint comes from the gel around it. Measured (``benches/
bench_motion_methods.py``, BENCHMARKS.md): it lowers the error from the no-contact frame on the
real-texture proxy, on real presses with a modelled field and on simulated pairs, but it stays
worse than zero motion on the last two (DIS still picks up the imprint's rim), and it costs
accuracy with a reference of the same contact (the imprint is then the best texture), so it is
off by default. Thresholds chosen on every 6th / 3rd real press (seed 0) among 0.01-0.2 and
smoothing 0.04-0.12; blanking the imprint before DIS (a harder mask) and a high-pass (sigma
3-6 px) before DIS were worse on the real-texture proxy.

Algorithms (OpenCV 4.x/5.x, ``opencv-contrib`` for the ``optflow`` ones): ``"dis"`` (DIS, presets
``refined`` (default), ``balanced``, ``ultrafast``/``fast``/``medium``), ``"farneback"``,
``"deepflow"``, ``"pcaflow"``, ``"rlof"`` (dense RLOF).

Presets: OpenCV's ``fast`` and ``ultrafast`` stop at a quarter of the frame's resolution (finest
scale 2), which on the faint texture of a gel away from the contact turns the requantisation of
a brightness change into 0.5-0.9 px of fake motion; ``medium`` works at half resolution with 25
descent and 5 variational-refinement iterations and misses the 100 Hz budget at 320 x 240.
``balanced`` keeps ``medium``'s half resolution with 8 descent and 2 refinement iterations on
8 px patches every 4 px: within the budgets on 2 cores and under the 0.2 px brightness bound
(``benches/bench_motion_methods.py`` has the speed, brightness and real-texture accuracy of
each). On frames at least 480 px wide it works on the pair area-downsampled to about 320 px wide
(:data:`BALANCED_WORK_WIDTH`) at full resolution there: the same flow grid as half resolution
at 640 x 480, with the normalisation, padding and smoothing done on a quarter of the pixels
(a quarter-resolution grid at 640 x 480, as OpenCV's ``fast`` gives, fails the brightness
bound).

``refined`` (the default) is ``balanced`` with 6 descent and 4 refinement iterations: on real
frames fewer patch-descent steps and more variational refinement (a smoothness-regularised fit
of the whole field) trade the patches' isolated errors on faint texture for a smoother field.
Measured (``benches/bench_motion_video_real.py``, BENCHMARKS.md; chosen on the development
objects) on real GelSight Mini videos with the markers removed (tracked truth, 14 held-out
objects): ``MarkerlessTracker`` 0.56x -> 0.53x zero motion, the plain flow from the no-contact
frame 0.66x -> 0.60x; on taxim's truly markerless real presses, GelSight's grain-matched gel
motion 1.81 -> 1.69 px (plain flow) and the false motion of a Mini gel that does not move 0.55
-> 0.47 px; the real FOTS press -> shear pair 0.98 -> 0.93 px. On real texture warped by
modelled fields up to a marker pitch it is worse from a frame of the same contact on the
GelSight (2.69 -> 2.96 px; fewer descent steps follow a large shift less far) and better from
the no-contact frame. It costs 1.17-1.19x ``balanced``'s time. The learned markerless slip
scorer is trained on it too (``balanced`` before 2026-11-30).

``accurate`` is not DIS: OpenCV's DeepFlow (a coarse-to-fine variational flow over a fine
pyramid, no patch search) on the same work-width frames, for offline analysis of recordings
(185 ms a pair, 5 frames/s, on 2 cores: 29x ``refined``'s time at 320 x 240, 10x at 640 x 480).
Measured on real frames (scratch replays, BENCHMARKS.md "An accurate flow for recordings"): on
the real GelSight Mini videos (markers removed, 14 held-out objects, the tracker's suppressed
flow from the no-contact frame, ``anchor="rest"``) 0.533x -> 0.497x zero motion with the default
removal and no clip worse than zero (one before), 0.436x -> 0.443x with the removal for motion,
but 0.73x -> 0.79x under the static-mask control (its smoother field is pulled towards holes
that do not move); the false motion of taxim's real Mini gel, which does not move, 0.47 -> 0.12
px (0.27 -> 0.11 with the imprint suppressed); GelSight's grain-matched gel motion level (1.69 ->
1.68 px plain, 1.69 -> 1.71 suppressed).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ACCURATE",
    "ACCURATE_MIN_SIDE",
    "ALGORITHMS",
    "BALANCED_WORK_WIDTH",
    "DEFAULT_PRESET",
    "DIS_PRESETS",
    "FLOW_PRESETS",
    "IMPRINT_CHANGE",
    "IMPRINT_SIGMA_REL",
    "IMPRINT_SMOOTH_REL",
    "PAD_REL",
    "REFINED",
    "SMOOTH_REL",
    "check_flow_options",
    "dense_flow",
    "flow_motion",
    "imprint_weight",
    "normalise_pair",
    "sample_field",
    "work_factor",
]

#: Flow algorithms accepted by :func:`flow_motion`.
ALGORITHMS = ("dis", "farneback", "deepflow", "pcaflow", "rlof")
#: DIS presets (``preset=``); only DIS has presets. ``refined`` and ``balanced`` are this
#: module's own (see the module doc), the others are OpenCV's.
DIS_PRESETS = ("refined", "balanced", "ultrafast", "fast", "medium")
#: The variational preset for recordings (module doc): OpenCV's DeepFlow, not DIS.
ACCURATE = "accurate"
#: Smallest side (px) of the work frame :data:`ACCURATE` accepts: DeepFlow's coarsest level is
#: 25 px, and a uniform 2 px shift reads 1.2 px at 32 px, 1.9 at 40, 2.0 from 48 up.
ACCURATE_MIN_SIDE = 48
#: Every ``preset=`` of the flow: the DIS presets and :data:`ACCURATE`.
FLOW_PRESETS = (*DIS_PRESETS, ACCURATE)
#: The preset used when none is given.
DEFAULT_PRESET = "refined"
#: ``balanced``: OpenCV's ``fast`` preset with these DIS settings changed: finest scale 1 (half
#: resolution), 8 gradient-descent and 2 variational-refinement iterations.
BALANCED = {"finest_scale": 1, "gradient_descent_iterations": 8,
            "variational_refinement_iterations": 2}
#: ``refined``: ``balanced`` with 6 gradient-descent and 4 variational-refinement iterations
#: (module doc).
REFINED = {**BALANCED, "gradient_descent_iterations": 6,
           "variational_refinement_iterations": 4}
#: Presets on ``balanced``'s working grid (:data:`BALANCED_WORK_WIDTH`, :func:`work_factor`).
_OWN_PRESETS = {"balanced": BALANCED, "refined": REFINED}
#: ``balanced`` and ``refined`` area-downsample frames at least 1.5x this wide by
#: ``round(width / this)`` and compute the flow there at finest scale 0 (see the module doc).
BALANCED_WORK_WIDTH = 320
#: OpenCV's DIS needs the width or the height to be at least this (px).
DIS_MIN_SIDE = 12
#: Smallest side (px, padded) DIS is run on at its ``balanced`` finest scale (two 8 px patches);
#: smaller frames get the full-size flow, and the downsampling never goes below it.
DIS_SMALL_SIDE = 16
#: Mirror padding of both frames before the flow, a fraction of the frame width (16 px at 320).
PAD_REL = 0.05
#: Background blur sigma as a fraction of the frame width (the illumination model's scale).
BG_SIGMA_REL = 1.0 / 24.0
#: Local-contrast value (in units of the reference's robust spread) mapped to ~76 grey levels.
CONTRAST_GAIN = 3.0
#: Gaussian smoothing of the flow field before it is read at the markers, sigma as a fraction of
#: the frame width (12.8 px at 320 wide): a painted dot (0.034-0.036 of the width across on the
#: GelSight and Mini presets) and the tracker's centroid average the gel's motion over its area,
#: and the average removes the flow's pixel-level jitter on weak texture. Chosen among 0, 0.015
#: and 0.03 on a quarter of the real-texture proxy (seed 3): 0.03 was best on all of it (largest
#: motion under a brightness change 0.31 -> 0.13 px at 640 x 480, e_rmse 3-19 % lower); then
#: 0.03 -> 0.04 with the padding, on the same quarter and on simulated grasps of dev seeds (200):
#: e_rmse 1-4 % lower on the proxy (medium), largest motion of held Mini grasps 2.4 -> 2.1 px.
SMOOTH_REL = 0.04
#: ``suppress_imprint``: blur sigma of the grey levels whose change marks an imprint, a
#: fraction of the width (4 px at 320 wide: the imprint's shading, not the grain).
IMPRINT_SIGMA_REL = 1.0 / 80.0
#: ``suppress_imprint``: relative grey-level change at which the flow's weight falls to 1/e.
IMPRINT_CHANGE = 0.04
#: ``suppress_imprint``: the weighted smoothing's sigma, a fraction of the width (2x
#: :data:`SMOOTH_REL`: the fill must reach across an imprint).
IMPRINT_SMOOTH_REL = 0.08
#: Smallest contrast scale: below it the mapping would amplify the camera's noise and the
#: requantisation of a brightness change into fake texture.
MIN_SCALE = 0.0


def _grey(img: NDArray[np.uint8]) -> NDArray[np.float32]:
    import cv2

    if img.ndim == 2:
        return img.astype(np.float32)
    code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
    # Grey from float BGR keeps the sub-grey-level detail the uint8 conversion would round away.
    return np.asarray(cv2.cvtColor(img.astype(np.float32), code), np.float32)


def _background(g: NDArray[np.float32], sigma: float) -> NDArray[np.float32]:
    """Wide Gaussian blur of ``g``: computed at 1/k size (k ~ sigma / 4) and upsampled, ~20x
    cheaper than a full-size blur at this width and equal to it within the smooth field's
    interpolation error."""
    import cv2

    h, w = g.shape
    k = max(1, int(sigma // 4))
    if k == 1:
        return np.asarray(cv2.GaussianBlur(g, (0, 0), sigma, borderType=cv2.BORDER_REFLECT),
                          np.float32)
    small = cv2.resize(g, (max(1, w // k), max(1, h // k)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / k, borderType=cv2.BORDER_REFLECT)
    return np.asarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR), np.float32)


def _local_contrast(g: NDArray[np.float32], sigma: float) -> NDArray[np.float32]:
    bg = _background(g, sigma)
    return np.asarray((g - bg) / np.maximum(bg, 4.0), np.float32)


def _shrink(g: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    """``g`` area-averaged by ``k`` (float: keeps the sub-grey-level detail); ``k = 1``: as is."""
    import cv2

    if k == 1:
        return g
    h, w = g.shape
    return np.asarray(cv2.resize(g, (w // k, h // k), interpolation=cv2.INTER_AREA), np.float32)


def normalise_pair(img: NDArray[np.uint8], ref: NDArray[np.uint8], k: int = 1
                   ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """``(img, ref)`` as 8-bit grey local contrast on one shared scale (see the module doc),
    area-downsampled by the integer ``k`` (``k = 1``: full size).

    The scale is the reference's robust spread (median absolute deviation) of local contrast, so a
    brightness change of ``img`` alone changes neither frame's mapping.
    """
    return _normalise_grey(_shrink(_grey(img), k), _shrink(_grey(ref), k))


def _normalise_grey(gi: NDArray[np.float32], gr: NDArray[np.float32]
                    ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """:func:`normalise_pair` on float grey frames already at the working size."""
    ref8, scale = _normalised_ref(gr)
    return _to8(_local_contrast(gi, _bg_sigma(gi.shape[1])), scale), ref8


def _bg_sigma(width: int) -> float:
    return max(2.0, BG_SIGMA_REL * width)


def _to8(c: NDArray[np.float32], scale: float) -> NDArray[np.uint8]:
    """Local contrast ``c`` mapped to 8 bits on the compressive scale ``scale``."""
    u = 128.0 + 127.0 * np.tanh(c / np.float32(scale))
    return np.clip(np.rint(u), 0, 255).astype(np.uint8)


def _normalised_ref(gr: NDArray[np.float32]) -> tuple[NDArray[np.uint8], float]:
    """The reference's 8-bit local contrast and the shared contrast scale (its robust spread)."""
    cr = _local_contrast(gr, _bg_sigma(gr.shape[1]))
    # The spread from every other pixel in each direction: same statistic, a quarter the work.
    sub = cr[::2, ::2]
    mad = float(np.median(np.abs(sub - np.median(sub))))
    scale = max(CONTRAST_GAIN * 1.4826 * mad, MIN_SCALE, 1e-3)
    return _to8(cr, scale), scale


#: The last reference prepared by :func:`flow_motion`: ``(key, (ref8, scale, grey))``. A video
#: is measured against one reference (the no-contact frame, the grasp start) frame after frame,
#: so its preparation (grey, downsampling, local contrast, spread: ~40 % of the time outside
#: the flow) is done once. The key is the frame's shape, the working factor and a CRC-32 of its
#: bytes (~0.02 ms at 320 x 240), so an array changed in place is prepared again.
_REF_CACHE: list[Any] = [None]


def _prepared_ref(ref: NDArray[np.uint8], k: int
                  ) -> tuple[NDArray[np.uint8], float, NDArray[np.float32]]:
    """``ref``'s 8-bit local contrast, the shared contrast scale and its float grey at the
    working size (for :func:`imprint_weight`), from :data:`_REF_CACHE` when it is the last
    reference seen."""
    import zlib

    key = (ref.shape, ref.dtype.str, k, zlib.crc32(np.ascontiguousarray(ref).data))
    hit = _REF_CACHE[0]
    if hit is not None and hit[0] == key:
        return hit[1]  # type: ignore[no-any-return]
    grey = _shrink(_grey(ref), k)
    out = (*_normalised_ref(grey), grey)
    _REF_CACHE[0] = (key, out)
    return out


def _dis(preset: str, finest_scale: int | None = None) -> Any:
    import cv2 as _cv2

    cv2: Any = _cv2  # OpenCV's stubs lack DIS and type Mat arguments too narrowly

    code = {"ultrafast": cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST,
            "fast": cv2.DISOPTICAL_FLOW_PRESET_FAST,
            "balanced": cv2.DISOPTICAL_FLOW_PRESET_FAST,
            "refined": cv2.DISOPTICAL_FLOW_PRESET_FAST,
            "medium": cv2.DISOPTICAL_FLOW_PRESET_MEDIUM}[preset]
    dis = cv2.DISOpticalFlow_create(code)
    own = _OWN_PRESETS.get(preset)
    if own is not None:
        dis.setFinestScale(own["finest_scale"] if finest_scale is None else finest_scale)
        dis.setGradientDescentIterations(own["gradient_descent_iterations"])
        dis.setVariationalRefinementIterations(own["variational_refinement_iterations"])
    return dis


def dense_flow(ref8: NDArray[np.uint8], img8: NDArray[np.uint8], algorithm: str = "dis",
               preset: str = DEFAULT_PRESET, pad: int = 0, finest_scale: int | None = None
               ) -> NDArray[np.float32]:
    """Forward flow ``ref8 -> img8`` (``H x W x 2`` float32, ``(dx, dy)`` px at ``ref8``'s
    pixels) between two 8-bit grey frames of the same size, computed on both frames
    mirror-padded by ``pad`` px (the padding is cropped off the result). ``finest_scale``
    overrides the ``balanced`` / ``refined`` presets' (pyramid level where DIS stops; 0 = full
    size). ``algorithm="dis"`` with ``preset="accurate"`` runs DeepFlow."""
    import cv2 as _cv2

    cv2: Any = _cv2  # OpenCV's stubs reject None as the flow argument

    if pad > 0:
        ref8 = cv2.copyMakeBorder(ref8, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
        img8 = cv2.copyMakeBorder(img8, pad, pad, pad, pad, cv2.BORDER_REFLECT_101)
    if algorithm == "dis" and preset != ACCURATE:
        flow = _dis(preset, finest_scale).calc(ref8, img8, None)
    elif algorithm == "farneback":
        # A 15 px Gaussian window, 5 levels: smooth gel fields, motions up to a marker pitch.
        flow = cv2.calcOpticalFlowFarneback(ref8, img8, None, 0.5, 5, 15, 5, 7, 1.5,
                                            cv2.OPTFLOW_FARNEBACK_GAUSSIAN)
    elif algorithm in ("deepflow", "dis"):  # "dis" here: the accurate preset, DeepFlow
        flow = cv2.optflow.createOptFlow_DeepFlow().calc(ref8, img8, None)
    elif algorithm == "pcaflow":
        flow = cv2.optflow.createOptFlow_PCAFlow().calc(ref8, img8, None)
    elif algorithm == "rlof":
        # Dense RLOF's default support region needs 3-channel input.
        flow = cv2.optflow.calcOpticalFlowDenseRLOF(cv2.cvtColor(ref8, cv2.COLOR_GRAY2BGR),
                                                    cv2.cvtColor(img8, cv2.COLOR_GRAY2BGR), None)
    else:
        raise ValueError(f"algorithm: unknown {algorithm!r}; choose from {list(ALGORITHMS)}")
    if pad > 0:
        flow = flow[pad:-pad, pad:-pad]
    return np.ascontiguousarray(flow, np.float32)


def _smooth(field: NDArray[np.float32], sigma: float) -> NDArray[np.float32]:
    """Gaussian smoothing of an ``H x W x 2`` field, computed at half size for wide kernels (the
    smoothed field is smooth at that scale: within ~0.03 px of the full-size blur at the markers
    of a real 640 x 480 pair, ~4x cheaper)."""
    import cv2

    h, w = field.shape[:2]
    if sigma < 8:
        return np.asarray(cv2.GaussianBlur(field, (0, 0), sigma,
                                           borderType=cv2.BORDER_REPLICATE), np.float32)
    k = 2
    small = cv2.resize(field, (max(1, w // k), max(1, h // k)), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / k, borderType=cv2.BORDER_REPLICATE)
    return np.asarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR), np.float32)


def _smooth_wide(field: NDArray[np.float32], sigma: float) -> NDArray[np.float32]:
    """Gaussian smoothing of an ``H x W x C`` field (C <= 4) computed at 1/k size, k ~ sigma / 6
    (the result is smooth at that scale, see :func:`_smooth`)."""
    import cv2

    h, w = field.shape[:2]
    k = max(1, int(sigma // 6))
    small = cv2.resize(np.ascontiguousarray(field, np.float32), (max(1, w // k), max(1, h // k)),
                       interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma / k, borderType=cv2.BORDER_REPLICATE)
    return np.asarray(cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR), np.float32)


#: Longest side cv2.remap takes for its source and maps (SHRT_MAX, exclusive).
_REMAP_MAX_SIDE = 32767
#: Points per row of the maps :func:`sample_field` hands to cv2.remap.
_REMAP_ROW = 16384


def sample_field(field: NDArray[np.float32], pts: NDArray[np.float32]) -> NDArray[np.float32]:
    """Bilinear samples of an ``H x W x 2`` field at ``N x 2`` points ``(x, y)`` (pixel centres at
    integers); points outside take the nearest border value."""
    import cv2

    n = len(pts)
    if n == 0:
        return np.zeros((0, 2), np.float32)
    if max(field.shape[:2]) >= _REMAP_MAX_SIDE:
        raise ValueError(f"img: a {field.shape[0]} x {field.shape[1]} px field is too large to "
                         f"sample (OpenCV's remap takes sides below {_REMAP_MAX_SIDE} px)")
    # cv2.remap needs each side of its maps below SHRT_MAX: the points are laid out as rows of
    # at most _REMAP_ROW points (padded with the last one), one remap call per block of rows.
    cols = min(n, _REMAP_ROW)
    rows = -(-n // cols)
    flat = np.empty((rows * cols, 2), np.float32)
    flat[:n] = pts
    flat[n:] = pts[n - 1]
    mx = np.ascontiguousarray(flat[:, 0].reshape(rows, cols))
    my = np.ascontiguousarray(flat[:, 1].reshape(rows, cols))
    out = np.empty((rows, cols, field.shape[2]), np.float32)
    for r0 in range(0, rows, _REMAP_ROW):
        r1 = min(rows, r0 + _REMAP_ROW)
        out[r0:r1] = np.asarray(cv2.remap(field, mx[r0:r1], my[r0:r1], cv2.INTER_LINEAR,
                                          borderMode=cv2.BORDER_REPLICATE),
                                np.float32).reshape(r1 - r0, cols, -1)
    return out.reshape(-1, field.shape[2])[:n]


def flow_motion(img: NDArray[np.uint8], ref: NDArray[np.uint8], centres: NDArray[np.float32], *,
                algorithm: str = "dis", preset: str = DEFAULT_PRESET,
                suppress_imprint: bool = False, coarse: bool = False) -> NDArray[np.float32]:
    """Motion ``N x 2`` float32 ``(dx, dy)`` px of markers at rest ``centres`` (``(x, y)`` px in
    ``ref``) from ``ref`` to ``img`` (validated uint8 frames of one shape, BGR or grey).

    Exactly zero for identical frames. ``preset`` applies to ``algorithm="dis"`` only
    (:data:`FLOW_PRESETS`; ``"accurate"`` runs DeepFlow in DIS's place, module doc).
    ``suppress_imprint``: for a reference without the contact (the no-contact frame), trust the
    flow less where an imprint appeared (:func:`imprint_weight`) and fill it from the
    surrounding gel, smoothing over :data:`IMPRINT_SMOOTH_REL` of the width (see the module doc).
    ``coarse``: with the ``balanced`` and ``refined`` presets on a frame downsampled for the
    flow (:func:`work_factor` > 1), DIS stops one pyramid level above the work size, as it
    does on frames at the work width, at a quarter of the cost: the flow's grid is then the
    same in pixels of the work frame whatever the input width (frames at the work width or
    smaller: the same flow). ``MarkerlessTracker(frame_to_frame=...)`` reads every flow so:
    on real GelSight Mini videos upsampled to 640 x 480 its motion then stays closer to the
    motion it reads at the videos' own 320 x 240 (0.29 against 0.44 px RMS apart, every slip
    decision the same) and is as accurate against the tracked markers (markerless-motion notes).
    """
    check_flow_options(algorithm, preset, suppress_imprint)
    if len(centres) == 0 or np.array_equal(img, ref):
        return np.zeros((len(centres), 2), np.float32)
    k = work_factor(img.shape[1], algorithm, preset, height=img.shape[0])
    if preset == ACCURATE and min(img.shape[:2]) // k < ACCURATE_MIN_SIDE:
        # DeepFlow's pyramid stops at 25 px: on smaller work frames it under-reads the motion.
        raise ValueError(f"preset: {ACCURATE!r} needs frames at least {ACCURATE_MIN_SIDE * k} px "
                         f"a side here; got {img.shape[1]} x {img.shape[0]} (use 'refined')")
    gi = _shrink(_grey(img), k)
    ref8, scale, gr = _prepared_ref(ref, k)
    img8 = _to8(_local_contrast(gi, _bg_sigma(gi.shape[1])), scale)
    h, w = img8.shape
    # Mirror padding needs pad < each side (a frame may be as small as 8 px a side); DIS refuses
    # frames with no side of at least DIS_MIN_SIDE px, which the padding also provides.
    pad = min(round(PAD_REL * w), min(h, w) - 1)
    pad = max(pad, (DIS_MIN_SIDE - max(h, w) + 1) // 2)
    # DIS stopping at half size crashes (OpenCV 5.0) on frames under 2 patches (16 px) high
    # once padded; such small frames are cheap at full size.
    full = (k > 1 and not coarse) or min(h, w) + 2 * pad < DIS_SMALL_SIDE
    flow = dense_flow(ref8, img8, algorithm, preset, pad=pad, finest_scale=0 if full else None)
    if suppress_imprint:
        # Normalised convolution: the weighted mean of the flow over a wide Gaussian, so inside
        # an imprint that appeared the field comes from the gel around it.
        wt = imprint_weight(gi, gr)
        packed = np.empty((*wt.shape, 3), np.float32)
        np.multiply(flow, wt[..., None], out=packed[..., :2])
        packed[..., 2] = wt
        both = _smooth_wide(packed, IMPRINT_SMOOTH_REL * w)
        flow = np.asarray(both[..., :2] / np.maximum(both[..., 2:], 1e-3), np.float32)
    elif SMOOTH_REL > 0:
        flow = np.asarray(_smooth(flow, SMOOTH_REL * w), np.float32)
    # Pixel centres at integers: x_small = (x + 0.5) / k - 0.5.
    pts = centres if k == 1 else ((centres + 0.5) / k - 0.5).astype(np.float32)
    out = sample_field(flow, pts) * np.float32(k)
    return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)


def check_flow_options(algorithm: Any, preset: Any, suppress_imprint: Any) -> None:
    """``TypeError`` / ``ValueError`` naming the argument unless the options of
    :func:`flow_motion` are valid."""
    if not isinstance(suppress_imprint, (bool, np.bool_)):
        raise TypeError(f"suppress_imprint: expected a bool, got {type(suppress_imprint).__name__}")
    if algorithm not in ALGORITHMS:
        raise ValueError(f"algorithm: unknown {algorithm!r}; choose from {list(ALGORITHMS)}")
    if preset not in FLOW_PRESETS:
        raise ValueError(f"preset: unknown {preset!r}; choose from {list(FLOW_PRESETS)}")
    if preset == ACCURATE and algorithm != "dis":
        raise ValueError(f"preset: {ACCURATE!r} is its own flow (DeepFlow); it goes with "
                         f"algorithm='dis' (the default), not {algorithm!r}")


def imprint_weight(gi: NDArray[np.float32], gr: NDArray[np.float32]) -> NDArray[np.float32]:
    """Confidence ``H x W`` float32 in (0, 1] of the flow ``gr -> gi`` (float grey frames of one
    shape): ``exp(-(d / IMPRINT_CHANGE)^2)`` with ``d`` the relative change of the grey level
    blurred over :data:`IMPRINT_SIGMA_REL` of the width, after matching the frames' median
    gain. ``d`` is large where a contact's imprint appeared (shading, not motion) and ~0.001-0.01
    on untouched gel of taxim's real presses."""
    import cv2

    h, w = gi.shape
    s = max(2.0, IMPRINT_SIGMA_REL * w)
    # At half size (the blurred frames are smooth at that scale): a quarter of the work.
    k = 2 if s >= 4 and min(h, w) >= 16 else 1
    bi, br = (cv2.GaussianBlur(_shrink(g, k), (0, 0), s / k, borderType=cv2.BORDER_REFLECT)
              for g in (gi, gr))
    gain = float(np.median(bi)) / max(float(np.median(br)), 1.0)
    d = np.abs(bi / max(gain, 1e-3) - br) / np.maximum(br, 4.0)
    wt = np.exp(-np.square(d / IMPRINT_CHANGE)).astype(np.float32)
    if k > 1:
        wt = cv2.resize(wt, (w, h), interpolation=cv2.INTER_LINEAR)
    return np.asarray(wt, np.float32)


def work_factor(width: int, algorithm: str = "dis", preset: str = DEFAULT_PRESET, *,
                height: int | None = None) -> int:
    """Integer area-downsampling factor :func:`flow_motion` applies to a frame ``width`` px wide
    before the flow (1 = none): ``round(width / BALANCED_WORK_WIDTH)`` for the ``balanced``,
    ``refined`` and ``accurate`` presets on frames at least 1.5x that wide, lowered so that a
    frame ``height`` px high keeps at least :data:`DIS_SMALL_SIDE` px a side."""
    if (algorithm != "dis" or (preset not in _OWN_PRESETS and preset != ACCURATE)
            or width < 1.5 * BALANCED_WORK_WIDTH):
        return 1
    k = max(1, round(width / BALANCED_WORK_WIDTH))
    if height is not None:
        k = max(1, min(k, height // DIS_SMALL_SIDE))
    return k

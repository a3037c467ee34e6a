"""Speed/accuracy trade-off of marker-removal methods: every knob on both axes, one table.

Frames come with the truth, so quality is the error against the true pixels under the marker
mask, overall and where the gel is in contact (where texture and edges make inpainting hard):
simulated pairs (:func:`simulated_frames`), or the real-frame proxy (:func:`proxy_frames`: real
markerless presses with realistic markers painted on and captured lossless, MJPEG or H.264).
Time is the median per 640x480 frame on one thread, measured alternately with the other methods.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.inpaint import inpaint_biharmonic, inpaint_telea
from tacswitch.metrics import masked_mae, masked_psnr

#: A method under test: (frame with markers, uint8 mask, the paired frame) -> markerless frame.
#: The paired frame is passed for methods that use more than the image (hybrid's reference).
Inpaint = Callable[[NDArray[np.uint8], NDArray[np.uint8], "PairedFrame"], NDArray[Any]]


@dataclass(frozen=True)
class PairedFrame:
    """A frame with markers, its true markerless image, the mask to fill and the contact mask;
    ``score`` is where errors are measured (default: the mask; for an extracted mask, the union
    with the true marker footprint, so a rim the mask misses counts against it)."""

    with_markers: NDArray[np.uint8]
    truth: NDArray[np.uint8]
    mask: NDArray[np.bool_]
    contact: NDArray[np.bool_]
    reference: NDArray[np.uint8] | None = None  # no-contact frame of the same scene
    score: NDArray[np.bool_] | None = None
    source: str = ""  # what the frame is: "simulated ... contacts", "real ... frames ..."

    @property
    def scored(self) -> NDArray[np.bool_]:
        """The pixels errors are measured on."""
        return self.mask if self.score is None else self.score


@dataclass(frozen=True)
class Row:
    """One method at one setting: quality and time."""

    method: str
    knob: str
    ms: float
    mae: float
    mae_contact: float
    psnr: float
    #: What the row was measured on (e.g. "simulated gelsight contacts"), for the plot's title.
    source: str = ""


def default_methods(radii: Sequence[int] = (3, 5, 8, 12), opencv: bool = True
                    ) -> dict[tuple[str, str], Inpaint]:
    """TELEA (ours) at each radius (``remove_markers``' default radius marked ``(default)``),
    our biharmonic fill (no knob), and OpenCV's TELEA and NS at the same radii."""
    import cv2

    from tacswitch.inpaint import DEFAULT_RADIUS

    def ours(r: int) -> Inpaint:
        return lambda img, m, f: inpaint_telea(img, m, r)

    def opencv_inpaint(r: int, flag: int) -> Inpaint:
        return lambda img, m, f: np.asarray(cv2.inpaint(img, m, r, flag))

    methods: dict[tuple[str, str], Inpaint] = {}
    for r in radii:
        knob = f"r={r} (default)" if r == DEFAULT_RADIUS else f"r={r}"
        methods[("TELEA (tacswitch)", knob)] = ours(r)
    methods[("biharmonic (tacswitch)", "-")] = lambda img, m, f: inpaint_biharmonic(img, m)
    if opencv:
        for r in radii:
            methods[("TELEA (OpenCV)", f"r={r}")] = opencv_inpaint(r, cv2.INPAINT_TELEA)
            methods[("NS (OpenCV)", f"r={r}")] = opencv_inpaint(r, cv2.INPAINT_NS)
    return methods


def tacdiff_methods(steps: Sequence[int] = (1, 2, 4, 8, 20), hybrid_steps: Sequence[int] = (2,),
                    model: str | None = None) -> dict[tuple[str, str], Inpaint]:
    """TacDiff (onnxruntime, all cores) at each step count K (in the default orientations;
    K = 1 also in one orientation), the hybrid mode (TacDiff near
    the contact, found against the reference frame or from texture; TELEA at
    :data:`tacswitch.inpaint.DEFAULT_RADIUS` elsewhere), and
    the model's classical prior alone (what the network starts from), so the table shows what
    the learned part adds."""
    from tacswitch.tacdiff import inpaint_hybrid, inpaint_tacdiff
    from tacswitch.tacdiff.infer import default_orientations, load_model, model_path
    from tacswitch.tacdiff.prior import from_net, prior_planes

    net = load_model(model)
    kind = net.prior
    n_default = default_orientations(net)

    def prior_only(img: NDArray[np.uint8], m: NDArray[np.uint8], f: PairedFrame
                   ) -> NDArray[np.uint8]:
        return from_net(prior_planes(img, m.astype(bool), kind)[0])

    def diffusion(k: int) -> Inpaint:
        return lambda img, m, f: inpaint_tacdiff(img, m, k, model=model)

    def hybrid(k: int, use_ref: bool) -> Inpaint:
        return lambda img, m, f: inpaint_hybrid(img, m, f.reference if use_ref else None,
                                                steps=k, model=model)[0]

    methods: dict[tuple[str, str], Inpaint] = {("TacDiff prior (no network)", kind): prior_only}
    tag = f", {n_default} orientation{'s' if n_default > 1 else ''}"
    for k in steps:
        methods[("TacDiff", f"K={k}{tag}")] = diffusion(k)
    if 1 in steps and n_default > 1:
        # The default averages several orientations; one is the speed knob.
        methods[("TacDiff", "K=1, 1 orientation")] = \
            lambda img, m, f: inpaint_tacdiff(img, m, 1, model=model, orientations=1)
    for k in hybrid_steps:
        methods[("Hybrid (reference)", f"K={k}")] = hybrid(k, True)
        methods[("Hybrid (texture)", f"K={k}")] = hybrid(k, False)
    if model is None and model_path("fast").is_file():
        # The shipped narrow model: the model-width knob, at its fastest setting.
        methods[("TacDiff fast", "K=1, 1 orientation")] = \
            lambda img, m, f: inpaint_tacdiff(img, m, 1, model="fast")
        methods[("TacDiff fast", "K=1, 4 orientations")] = \
            lambda img, m, f: inpaint_tacdiff(img, m, 1, model="fast", orientations=4)
        methods[("Hybrid fast (reference)", "K=1")] = \
            lambda img, m, f: inpaint_hybrid(img, m, f.reference, steps=1, model="fast")[0]
    return methods


def simulated_frames(n: int, preset: str = "gelsight", seed: int = 0,
                     mask: str = "true") -> list[PairedFrame]:
    """``n`` simulated contacts. ``mask="true"``: the fill mask is the true marker mask dilated
    once, as in the paper (a known mask); ``"extracted"``: the mask
    :func:`tacswitch.remove_markers` would use (markers extracted from the frame, dilated
    ``DEFAULT_DILATE`` times), scored on its union with the true footprint."""
    from tacswitch.inpaint import DEFAULT_DILATE
    from tacswitch.markers import dilate_mask, extract_markers
    from tacswitch.sim.scene import render_sample

    if mask not in ("true", "extracted"):
        raise ValueError(f"mask: expected 'true' or 'extracted'; got {mask!r}")
    frames = []
    source = f"simulated {preset} contacts"
    for i in range(n):
        s = render_sample(preset, (seed, i))
        true = dilate_mask(s.marker_mask)
        if mask == "true":
            frames.append(PairedFrame(s.image_markers, s.image, true, s.contact_mask,
                                      s.reference, source=source))
            continue
        fill = extract_markers(s.image_markers, dilate=DEFAULT_DILATE,
                               exclude_border=False).mask
        frames.append(PairedFrame(s.image_markers, s.image, fill, s.contact_mask, s.reference,
                                  score=fill | true, source=source))
    return frames


#: Style/capture cases of the real-frame proxy rows (:mod:`tacswitch.realproxy`): crisp black
#: dots as painted, and soft dots (black pasted, grey painted) as MJPEG and H.264 deliver them.
PROXY_CASES: tuple[tuple[str, str], ...] = (
    ("crisp", "lossless"), ("pasted", "lossless"), ("painted", "lossless"),
    ("pasted", "mjpeg"), ("painted", "mjpeg"), ("pasted", "h264"), ("painted", "h264"))
#: The cases ``--quick`` keeps: crisp, and soft grey dots through H.264.
PROXY_QUICK_CASES: tuple[tuple[str, str], ...] = (("crisp", "lossless"), ("painted", "h264"))


def proxy_frames(n: int, sensor: str = "gelsight", *,
                 cases: Sequence[tuple[str, str]] = PROXY_CASES, seed: int = 0
                 ) -> list[PairedFrame]:
    """The real-frame proxy as paired frames: ``n`` of Taxim's real markerless presses of
    ``sensor`` with markers painted and captured as ``cases`` say (style, capture;
    :mod:`tacswitch.realproxy`). The fill mask is the one :func:`tacswitch.remove_markers`
    builds from the frame (adaptive growth); errors are measured over the true marker
    footprint, so whatever the mask misses counts. Needs the ``taxim`` package (and PyAV for
    H.264)."""
    from tacswitch import realproxy

    styles = tuple(dict.fromkeys(s for s, _ in cases))
    captures = tuple(dict.fromkeys(c for _, c in cases))
    want = {f"{s}/{c}" for s, c in cases}
    frames = []
    for f in realproxy.proxy_frames(sensor, n, styles=styles, captures=captures, seed=seed):
        if "/".join(f.name.split("/")[2:]) not in want:
            continue
        frames.append(PairedFrame(f.img, f.clean, realproxy.default_mask(f.img), f.contact,
                                  f.reference, score=f.footprint,
                                  source=f"real {sensor} frames, painted markers"))
    return frames


def evaluate(frames: Sequence[PairedFrame], methods: dict[tuple[str, str], Inpaint],
             rounds: int = 3) -> list[Row]:
    """Runs every method on every frame ``rounds`` times (alternating), returns one row each."""
    times: dict[tuple[str, str], list[float]] = {k: [] for k in methods}
    outputs: dict[tuple[str, str], list[NDArray[np.uint8]]] = {k: [] for k in methods}
    for rnd in range(rounds):
        for f in frames:
            m8 = f.mask.view(np.uint8)
            for key, fn in methods.items():
                t0 = time.perf_counter()
                out = fn(f.with_markers, m8, f)
                times[key].append(time.perf_counter() - t0)
                if rnd == 0:
                    outputs[key].append(out)
    rows = []
    for key in methods:
        outs = outputs[key]
        mae = float(np.mean([masked_mae(o, f.truth, f.scored) for o, f in zip(outs, frames,
                                                                             strict=True)]))
        contact = [masked_mae(o, f.truth, f.scored & f.contact)
                   for o, f in zip(outs, frames, strict=True) if (f.scored & f.contact).any()]
        psnr = float(np.mean([masked_psnr(o, f.truth, f.scored) for o, f in zip(outs, frames,
                                                                             strict=True)]))
        rows.append(Row(key[0], key[1], 1e3 * float(np.median(times[key])), mae,
                        float(np.mean(contact)) if contact else float("nan"), psnr,
                        source=" + ".join(dict.fromkeys(f.source for f in frames if f.source))))
    return rows


def markdown(rows: Sequence[Row]) -> str:
    """The table, fastest first, with the Pareto-optimal settings marked."""
    front = pareto(rows)
    lines = ["| method | setting | ms / frame | masked MAE | MAE in contact | masked PSNR dB "
             "| Pareto |", "|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: r.ms):
        lines.append(f"| {r.method} | {r.knob} | {r.ms:.2f} | {r.mae:.3f} | {r.mae_contact:.3f} "
                     f"| {r.psnr:.2f} | {'yes' if r in front else ''} |")
    return "\n".join(lines)


def pareto(rows: Sequence[Row]) -> list[Row]:
    """Rows no other row beats on both time and masked MAE."""
    return [r for r in rows
            if not any(o.ms <= r.ms and o.mae <= r.mae and (o.ms < r.ms or o.mae < r.mae)
                       for o in rows)]


def plot_title(rows: Sequence[Row]) -> str:
    """The plot's title: what the rows were measured on (:attr:`Row.source`), so the simulated
    and the real-frame plots are told apart."""
    sources = list(dict.fromkeys(r.source for r in rows if r.source))
    on = f" on {' + '.join(sources)}" if sources else ""
    return f"Marker removal{on}: time vs masked error"


#: Text scale of the plot's tick labels, point labels and legend (Hershey simplex).
_SMALL = 0.42


def _text_box(text: str, org: tuple[int, int], scale: float = _SMALL
              ) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)`` of ``text`` drawn with its baseline at ``org``."""
    import cv2

    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
    return org[0], org[1] - th - 1, org[0] + tw, org[1] + base


def _overlap(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> int:
    return max(0, min(a[2], b[2]) - max(a[0], b[0])) * max(0, min(a[3], b[3]) - max(a[1], b[1]))


def _place_label(text: str, p: tuple[int, int], taken: list[tuple[int, int, int, int]],
                 box: tuple[int, int, int, int]) -> tuple[int, int]:
    """Baseline origin of a point's label near ``p``: the first place (eight around it, then
    the same a line, two and three lines farther up or down) that stays inside ``box`` and
    overlaps nothing ``taken``, else the one that overlaps least."""
    x0, y0, x1, _ = _text_box(text, (0, 0))
    tw, th = x1 - x0, -y0
    ring = [(p[0] + 8, p[1] - 4), (p[0] + 8, p[1] + th + 4), (p[0] - 8 - tw, p[1] - 4),
            (p[0] - 8 - tw, p[1] + th + 4), (p[0] - tw // 2, p[1] - 9),
            (p[0] - tw // 2, p[1] + th + 9), (p[0] + 8, p[1] + th // 2),
            (p[0] - 8 - tw, p[1] + th // 2)]
    cands = ring + [(x, y + sign * k * (th + 6)) for k in (1, 2, 3) for sign in (-1, 1)
                    for x, y in ring]
    best, best_cost = cands[0], None
    for org in cands:
        r = _text_box(text, org)
        outside = (max(0, box[0] - r[0]) + max(0, r[2] - box[2]) + max(0, box[1] - r[1])
                   + max(0, r[3] - box[3]))
        cost = 10_000 * outside + sum(_overlap(r, t) for t in taken)
        if best_cost is None or cost < best_cost:
            best, best_cost = org, cost
        if cost == 0:
            break
    return best


def plot(rows: Sequence[Row], size: tuple[int, int] = (480, 720), *,
         title: str | None = None) -> NDArray[np.uint8]:
    """Time (log scale) against masked MAE, one colour and shape per method
    (:func:`tacswitch.viz.series_style`: 20 colours, 40 styles), the Pareto front joined.

    The legend sits right of the plot box, which shrinks (or the image widens) to fit it;
    each point's setting is labelled beside it where it overlaps no other label or point and
    stays inside the plot box. ``title``: default :func:`plot_title`. ``size``: ``(height,
    width)`` px at least.
    """
    import cv2

    from tacswitch.viz import draw_point, series_style

    font, black = cv2.FONT_HERSHEY_SIMPLEX, (0, 0, 0)
    methods = list(dict.fromkeys(r.method for r in rows))
    legend_w = 34 + max((_text_box(m, (0, 0))[2] for m in methods), default=0)
    line = 20
    left, top, bottom = 70, 64, 50
    h = max(size[0], top + bottom + line * len(methods) + 8)
    w = max(size[1], left + 320 + legend_w + 16)
    right = legend_w + 16  # the legend column, outside the plot box
    img = np.full((h, w, 3), 255, np.uint8)
    xs = np.log10([r.ms for r in rows])
    ys = np.array([r.mae for r in rows])
    x0, x1 = xs.min() - 0.1, xs.max() + 0.1
    y0, y1 = ys.min() * 0.95, ys.max() * 1.05
    bx0, by0, bx1, by1 = left, top, w - right, h - bottom  # plot box

    def px(lx: float, y: float) -> tuple[int, int]:
        return (round(bx0 + (bx1 - bx0) * (lx - x0) / (x1 - x0)),
                round(by1 - (by1 - by0) * (y - y0) / max(y1 - y0, 1e-9)))

    cv2.rectangle(img, (bx0, by0), (bx1, by1), black, 1)
    for dec in range(int(np.floor(x0)), int(np.ceil(x1)) + 1):
        for mult in (1, 2, 5):
            lx = dec + np.log10(mult)
            if x0 <= lx <= x1:
                x, _ = px(lx, y0)
                cv2.line(img, (x, by1), (x, by1 + 4), black, 1)
                text = f"{10 ** lx:g}"
                tw = _text_box(text, (0, 0))[2]
                cv2.putText(img, text, (x - tw // 2, by1 + 18), font, 0.4, black, 1, cv2.LINE_AA)
    for frac in np.linspace(0, 1, 5):
        y = y0 + frac * (y1 - y0)
        _, py = px(x0, y)
        cv2.putText(img, f"{y:.2f}", (8, py + 4), font, 0.4, black, 1, cv2.LINE_AA)
    xlabel = "ms per 640x480 frame (log)"
    cv2.putText(img, xlabel, ((bx0 + bx1 - _text_box(xlabel, (0, 0), 0.45)[2]) // 2, h - 12),
                font, 0.45, black, 1, cv2.LINE_AA)
    cv2.putText(img, "masked MAE (grey levels), lower is better", (bx0, by0 - 10), font, 0.45,
                black, 1, cv2.LINE_AA)
    cv2.putText(img, plot_title(rows) if title is None else title, (8, 24), font, 0.6, black, 1,
                cv2.LINE_AA)
    front = sorted(pareto(rows), key=lambda r: r.ms)
    for a, b in itertools.pairwise(front):
        cv2.line(img, px(np.log10(a.ms), a.mae), px(np.log10(b.ms), b.mae), (160, 160, 160), 1,
                 cv2.LINE_AA)
    points = [px(np.log10(r.ms), r.mae) for r in rows]
    # Points first, then their labels, each placed clear of every point and earlier label.
    taken = [(p[0] - 7, p[1] - 7, p[0] + 7, p[1] + 7) for p in points]
    for r, p in zip(rows, points, strict=True):
        colour, shape = series_style(methods.index(r.method))
        draw_point(img, p, colour, shape)
    box = (bx0 + 2, by0 + 2, bx1 - 2, by1 - 2)
    for r, p in zip(rows, points, strict=True):
        if not r.knob or r.knob == "-":
            continue
        colour, _ = series_style(methods.index(r.method))
        org = _place_label(r.knob, p, taken, box)
        taken.append(_text_box(r.knob, org))
        cv2.putText(img, r.knob, org, font, _SMALL, colour, 1, cv2.LINE_AA)
    lx = bx1 + 16
    for i, m in enumerate(methods):
        colour, shape = series_style(i)
        cy = by0 + 10 + line * i
        draw_point(img, (lx + 6, cy), colour, shape)
        cv2.putText(img, m, (lx + 18, cy + 5), font, _SMALL, black, 1, cv2.LINE_AA)
    return img

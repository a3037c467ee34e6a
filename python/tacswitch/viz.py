"""Drawing helpers (OpenCV): marker overlays, motion arrows, simple line plots. BGR uint8."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import cast

import numpy as np
from numpy.typing import NDArray


def draw_markers(img: NDArray[np.uint8], centres: NDArray, colour=(0, 200, 255)) -> NDArray:
    """Copy of ``img`` (BGR) with a small cross on every centre ``(x, y)``."""
    import cv2

    out = img.copy() if img.ndim == 3 else cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    for x, y in np.asarray(centres, np.float64):
        cv2.drawMarker(out, (round(x), round(y)), colour, cv2.MARKER_CROSS, 7, 1, cv2.LINE_AA)
    return out


def draw_motion(
    img: NDArray[np.uint8],
    points: NDArray,
    motion: NDArray,
    valid: NDArray | None = None,
    *,
    scale: float = 3.0,
    colour=(0, 0, 255),
) -> NDArray:
    """Copy of ``img`` with an arrow from each point along its motion times ``scale``.

    A note in the corner states the scale, so arrows read as pixels. Invalid markers get a grey dot.
    """
    import cv2

    out = img.copy() if img.ndim == 3 else cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    pts = np.asarray(points, np.float64)
    mv = np.asarray(motion, np.float64)
    ok = (cast("NDArray[np.bool_]", np.isfinite(mv).all(axis=1)) if valid is None
          else np.asarray(valid, bool))
    for (x, y), (dx, dy), good in zip(pts, mv, ok, strict=True):
        start = (round(x), round(y))
        if not good:
            cv2.circle(out, start, 2, (128, 128, 128), -1, cv2.LINE_AA)
            continue
        end = (round(x + scale * dx), round(y + scale * dy))
        cv2.arrowedLine(out, start, end, colour, 1, cv2.LINE_AA, tipLength=0.25)
    cv2.putText(out, f"arrows x{scale:g}", (6, out.shape[0] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.55,
                (255, 255, 255), 1, cv2.LINE_AA)
    return out


#: Series colours (BGR) of the plots: matplotlib's tab20, its ten dark shades first (tab10:
#: ten distinct hues), then their light shades.
SERIES_COLOURS: tuple[tuple[int, int, int], ...] = tuple(
    (int(h[4:6], 16), int(h[2:4], 16), int(h[0:2], 16)) for h in (
        "1f77b4", "ff7f0e", "2ca02c", "d62728", "9467bd", "8c564b", "e377c2", "7f7f7f",
        "bcbd22", "17becf", "aec7e8", "ffbb78", "98df8a", "ff9896", "c5b0d5", "c49c94",
        "f7b6d2", "c7c7c7", "dbdb8d", "9edae5"))
#: Point shapes of the plots, changing every ten series (so a light shade differs from its dark
#: one in shape too, and 40 series differ in colour or shape).
SERIES_MARKERS = ("circle", "square", "triangle", "diamond")


def series_style(i: int) -> tuple[tuple[int, int, int], str]:
    """Colour (BGR) and point shape of series ``i`` (0-based) in a plot: 20 distinct colours,
    40 distinct (colour, shape) pairs."""
    return SERIES_COLOURS[i % len(SERIES_COLOURS)], SERIES_MARKERS[(i // 10) % len(SERIES_MARKERS)]


def draw_point(img: NDArray[np.uint8], centre: tuple[int, int], colour: tuple[int, int, int],
               shape: str, radius: int = 5) -> None:
    """A filled point of ``shape`` (:data:`SERIES_MARKERS`) at ``centre``, in place."""
    import cv2

    x, y = centre
    r = radius
    if shape == "circle":
        cv2.circle(img, centre, r, colour, -1, cv2.LINE_AA)
        return
    if shape == "square":
        poly = [(x - r + 1, y - r + 1), (x + r - 1, y - r + 1), (x + r - 1, y + r - 1),
                (x - r + 1, y + r - 1)]
    elif shape == "triangle":
        poly = [(x, y - r - 1), (x + r + 1, y + r), (x - r - 1, y + r)]
    else:  # diamond
        poly = [(x, y - r - 1), (x + r + 1, y), (x, y + r + 1), (x - r - 1, y)]
    cv2.fillPoly(img, [np.array(poly, np.int32)], colour, cv2.LINE_AA)


def difference_panel(result: NDArray[np.uint8], truth: NDArray[np.uint8],
                     floor: float = 1.0) -> tuple[NDArray[np.uint8], float]:
    """A visible picture of ``|result - truth|`` (uint8 images of one shape): the truth,
    dimmed and grey, for context, under a heat map (black, red, yellow, white) of the error
    amplified so that its 99th percentile over the changed pixels is white.

    Errors of a few grey levels under small markers are otherwise an almost black image.
    ``floor``: smallest error (grey levels) mapped to white (caps the gain where errors are
    tiny). Returns ``(panel BGR uint8, gain)``: the heat map shows ``gain x`` the error.
    """
    import cv2

    err = np.abs(result.astype(np.int16) - truth.astype(np.int16))
    err = err.max(axis=2) if err.ndim == 3 else err
    changed = err[err > 0]
    top = max(float(np.percentile(changed, 99)) if changed.size else 0.0, floor)
    gain = 255.0 / top
    heat = cv2.applyColorMap(np.clip(err * gain, 0, 255).astype(np.uint8), cv2.COLORMAP_HOT)
    grey = truth if truth.ndim == 2 else cv2.cvtColor(
        truth if truth.shape[2] == 3 else truth[..., :3], cv2.COLOR_BGR2GRAY)
    context = (np.asarray(grey, np.float32) * 0.4).astype(np.uint8)
    return np.maximum(np.asarray(heat), context[..., None]), gain


#: Caption and plot text: Hershey simplex at this scale draws capitals about 14 px high.
TEXT_SCALE = 0.62
_FONT = 0  # cv2.FONT_HERSHEY_SIMPLEX


def _text_width(text: str, scale: float, thickness: int = 1) -> int:
    import cv2

    return int(cv2.getTextSize(text, _FONT, scale, thickness)[0][0])


def _wrap(text: str, width: int, scale: float) -> list[str]:
    """``text`` broken at spaces into lines at most ``width`` px wide (a longer word stays)."""
    lines: list[str] = []
    for word in text.split():
        if lines and _text_width(f"{lines[-1]} {word}", scale) <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


def _put(img: NDArray[np.uint8], text: str, org: tuple[int, int], colour=(0, 0, 0),
         scale: float = TEXT_SCALE, thickness: int = 1) -> None:
    import cv2

    cv2.putText(img, text, org, _FONT, scale, colour, thickness, cv2.LINE_AA)


def line_plot(
    series: dict[str, NDArray],
    size: tuple[int, int] = (240, 640),
    *,
    hline: float | None = None,
    hline_label: str | None = None,
    marks: NDArray | None = None,
    marks_label: str | None = None,
    spans: Sequence[tuple[float, float, str]] | None = None,
    events: Sequence[tuple[float, str, int]] | None = None,
    title: str = "",
    xlabel: str = "",
    ylabel: str = "",
) -> NDArray[np.uint8]:
    """A line plot (white background, BGR uint8) of named series against their index.

    Axes have ticks and labels (``xlabel`` under the x axis, ``ylabel`` above the y axis);
    the legend names each series in its colour.

    Args:
        series: name -> values (NaN: not drawn).
        size: ``(height, width)`` in pixels.
        hline: a dashed horizontal line (e.g. a threshold), named ``hline_label``.
        marks: bool per index: those samples are shaded red, named ``marks_label``.
        spans: ``(first, last, text)`` index ranges shaded grey with ``text`` inside (e.g. a
            phase where the series is not defined).
        events: ``(index, text, series number)``: a vertical line in that series' colour
            with ``text`` beside it (e.g. a detection).
    """
    import cv2

    h, w = size
    img = np.full((h, w, 3), 255, np.uint8)
    small = 0.9 * TEXT_SCALE
    left, right, top, bottom = 64, 16, 84, 50
    n = max(len(v) for v in series.values())
    values = np.concatenate([np.asarray(v, np.float64) for v in series.values()])
    finite = values[np.isfinite(values)]
    ymax = float(max(finite.max() if finite.size else 0.0, hline or 0.0, 1e-6)) * 1.1
    x0, x1, y0, y1 = left, w - right, h - bottom, top  # plot box (y grows downwards)

    def px(i: float, v: float) -> tuple[int, int]:
        x = x0 + (x1 - x0) * (i + 0.5) / max(n, 1)
        y = y0 - (y0 - y1) * v / ymax
        return round(x), round(y)

    for first, last, text in spans or []:
        a, b = px(first - 0.5, 0)[0], px(last + 0.5, 0)[0]
        cv2.rectangle(img, (a, y1), (b, y0), (232, 232, 232), -1)
        for k, line in enumerate(_wrap(text, b - a - 12, small)):
            _put(img, line, (a + 6, y1 + 22 + 20 * k), (90, 90, 90), small)
    if marks is not None:
        for j in np.flatnonzero(np.asarray(marks, bool)).tolist():
            cv2.rectangle(img, (px(j - 0.5, 0)[0], y1), (px(j + 0.5, 0)[0], y0),
                          (215, 215, 255), -1)
    # Axes, ticks and labels.
    cv2.line(img, (x0, y0), (x1, y0), (0, 0, 0), 1)
    cv2.line(img, (x0, y1), (x0, y0), (0, 0, 0), 1)
    for frac in (0.0, 0.25, 0.5, 0.75, 1.0):
        tick = ymax / 1.1 * frac
        _, y = px(0, tick)
        cv2.line(img, (x0 - 5, y), (x0, y), (0, 0, 0), 1)
        text = f"{tick:.1f}" if ymax < 20 else f"{tick:.0f}"
        _put(img, text, (x0 - 9 - _text_width(text, small), y + 6), scale=small)
    step = max(1, int(np.ceil(n / 10 / 5)) * 5) if n > 10 else 1
    for tick_i in range(0, n, step):
        x, _ = px(tick_i, 0)
        cv2.line(img, (x, y0), (x, y0 + 5), (0, 0, 0), 1)
        _put(img, str(tick_i), (x - _text_width(str(tick_i), small) // 2, y0 + 24), scale=small)
    if xlabel:
        _put(img, xlabel, ((x0 + x1 - _text_width(xlabel, small)) // 2, h - 6), scale=small)
    if ylabel:
        _put(img, ylabel, (8, y1 - 12), scale=small)
    if hline is not None:
        _, y = px(0, hline)
        for x in range(x0, x1, 12):
            cv2.line(img, (x, y), (min(x + 6, x1), y), (0, 0, 200), 1)
        if hline_label:
            _put(img, hline_label, (x1 - _text_width(hline_label, small) - 4, y - 6),
                 (0, 0, 200), small)
    # Four colours of their own, then the shared series colours but the four hues they are
    # (blue, green, red, purple): 20 distinct colours.
    palette = [(200, 80, 0), (0, 150, 0), (0, 0, 200), (120, 0, 120),
               *(c for i, c in enumerate(SERIES_COLOURS) if i not in (0, 2, 3, 4))]
    for k, (_name, v) in enumerate(series.items()):
        pts = [px(i, val) for i, val in enumerate(np.asarray(v, np.float64)) if np.isfinite(val)]
        for p, q in itertools.pairwise(pts):
            cv2.line(img, p, q, palette[k % len(palette)], 2, cv2.LINE_AA)
    for at, text, k in events or []:
        x, _ = px(at, 0)
        colour = palette[k % len(palette)]
        for y in range(y1, y0, 8):
            cv2.line(img, (x, y), (x, min(y + 4, y0)), colour, 2)
        cv2.drawMarker(img, (x, y0), colour, cv2.MARKER_TRIANGLE_UP, 14, 2)
        tw = _text_width(text, small)
        tx = x + 6 if x + 6 + tw < x1 else x - 6 - tw
        _put(img, text, (tx, y1 + 22 + 22 * (k + 1)), colour, small)
    # Legend and title on the top band.
    x = x0
    entries = [(name, palette[k % len(palette)]) for k, name in enumerate(series)]
    if marks_label:
        entries.append((marks_label, (150, 150, 255)))
    for name, colour in entries:
        cv2.rectangle(img, (x, 40), (x + 14, 50), colour, -1)
        _put(img, name, (x + 20, 50), (0, 0, 0), small)
        x += 20 + _text_width(name, small) + 24
    if title:
        _put(img, title, (x0, 24))
    return img


def label(img: NDArray[np.uint8], text: str, scale: float = TEXT_SCALE) -> NDArray[np.uint8]:
    """Copy of ``img`` (grey images become BGR) with a caption bar on top: white text at
    ``scale`` (:data:`TEXT_SCALE`: capitals ~14 px), wrapped onto more lines if it is wider
    than the image."""
    bar_line = round(36 * scale / TEXT_SCALE)
    lines = _wrap(text, img.shape[1] - 12, scale)
    bar = np.full((bar_line * len(lines) + 6, img.shape[1], 3), 40, np.uint8)
    for k, line in enumerate(lines):
        _put(bar, line, (6, bar_line * (k + 1) - 8), (255, 255, 255), scale)
    body = img if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2)
    return np.vstack([bar, body])

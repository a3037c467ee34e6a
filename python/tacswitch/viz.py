"""Drawing helpers (OpenCV): marker overlays, motion arrows, simple line plots. BGR uint8."""

from __future__ import annotations

import itertools
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
    cv2.putText(out, f"arrows x{scale:g}", (6, out.shape[0] - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                (255, 255, 255), 1, cv2.LINE_AA)
    return out


def line_plot(
    series: dict[str, NDArray],
    size: tuple[int, int] = (240, 640),
    *,
    hline: float | None = None,
    marks: NDArray | None = None,
    title: str = "",
) -> NDArray[np.uint8]:
    """A small line plot (white background) of named series against their index.

    ``hline`` draws a dashed threshold; ``marks`` (bool per index) shades those samples.
    """
    import cv2

    h, w = size
    img = np.full((h, w, 3), 255, np.uint8)
    left, right, top, bottom = 50, 10, 24, 24
    n = max(len(v) for v in series.values())
    values = np.concatenate([np.asarray(v, np.float64) for v in series.values()])
    ymax = float(np.nanmax(np.append(values[np.isfinite(values)], [hline or 0.0, 1e-6])))
    ymax *= 1.1

    def to_px(i: float, v: float) -> tuple[int, int]:
        x = left + (w - left - right) * i / max(n - 1, 1)
        y = h - bottom - (h - top - bottom) * v / ymax
        return round(x), round(y)

    if marks is not None:
        for i in np.flatnonzero(np.asarray(marks, bool)):
            x0, _ = to_px(i - 0.5, 0)
            x1, _ = to_px(i + 0.5, 0)
            cv2.rectangle(img, (x0, top), (x1, h - bottom), (220, 220, 255), -1)
    cv2.line(img, (left, h - bottom), (w - right, h - bottom), (0, 0, 0), 1)
    cv2.line(img, (left, top), (left, h - bottom), (0, 0, 0), 1)
    for frac in (0.0, 0.5, 1.0):
        tick = ymax * frac / 1.1
        _, y = to_px(0, tick)
        cv2.putText(img, f"{tick:.1f}", (4, y + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 1)
    if hline is not None:
        _, y = to_px(0, hline)
        for x in range(left, w - right, 12):
            cv2.line(img, (x, y), (min(x + 6, w - right), y), (0, 0, 200), 1)
    palette = [(200, 80, 0), (0, 150, 0), (0, 0, 200), (120, 0, 120)]
    for k, (name, v) in enumerate(series.items()):
        v = np.asarray(v, np.float64)
        pts = [to_px(i, val) for i, val in enumerate(v) if np.isfinite(val)]
        colour = palette[k % len(palette)]
        for a, b in itertools.pairwise(pts):
            cv2.line(img, a, b, colour, 2, cv2.LINE_AA)
        cv2.putText(img, name, (left + 8 + 160 * k, top - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    colour, 1, cv2.LINE_AA)
    if title:
        cv2.putText(img, title, (w - 8 - 7 * len(title), top - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    (0, 0, 0), 1, cv2.LINE_AA)
    return img


def label(img: NDArray[np.uint8], text: str) -> NDArray[np.uint8]:
    """Copy of ``img`` with a caption bar on top."""
    import cv2

    bar = np.full((22, img.shape[1], 3), 40, np.uint8)
    cv2.putText(bar, text, (6, 15), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    body = img if img.ndim == 3 else np.repeat(img[:, :, None], 3, axis=2)
    return np.vstack([bar, body])

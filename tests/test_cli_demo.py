"""The demo report's drawing helpers: readable captions, plots with axes, phases and events."""

from __future__ import annotations

import numpy as np

from tacswitch import viz


def text_rows(img: np.ndarray, threshold: int = 128) -> int:
    """Height in px of the bright text drawn on a dark caption bar."""
    rows = np.flatnonzero((img.max(axis=2) > threshold).any(axis=1))
    return int(rows[-1] - rows[0] + 1) if rows.size else 0


def test_captions_are_at_least_14_px_and_wrap() -> None:
    body = np.zeros((50, 300, 3), np.uint8)
    out = viz.label(body, "Ag")
    bar = out[: out.shape[0] - 50]
    assert text_rows(bar) >= 14  # capitals ~14 px, descenders below
    long = viz.label(body, "a caption much longer than the panel is wide, so it must wrap "
                           "onto more lines instead of running off the edge")
    assert long.shape[1] == 300 and long.shape[0] > out.shape[0] + 30
    assert (long[: long.shape[0] - 50, -3:] < 128).all()  # nothing runs off the right edge


def test_line_plot_has_axes_phases_and_events() -> None:
    h, w = 300, 800
    n = 40
    values = np.full(n, np.nan)
    values[20:] = np.linspace(0, 10, 20)
    plot = viz.line_plot({"a": values}, size=(h, w), hline=3.0, hline_label="threshold",
                         marks=np.arange(n) >= 22, marks_label="true",
                         spans=[(0, 19, "loading phase")], events=[(25, "detected", 0)],
                         xlabel="frame", ylabel="px", title="t")
    assert plot.shape == (h, w, 3) and plot.dtype == np.uint8
    grey = (plot[h - 50 - 3] == 232).all(axis=1)  # a row just above the x axis
    cols = np.flatnonzero(grey)
    # The span covers the first half of the x axis (frames 0..19 of 40).
    left, right = 64, w - 16
    assert abs(cols[0] - left) <= 3 and abs(cols[-1] - (left + (right - left) * 20 / n)) <= 3
    # The event: a dashed vertical line in the series colour at frame 25.
    x = round(left + (right - left) * 25.5 / n)
    blue = (plot[:, x - 1:x + 2] == (200, 80, 0)).all(axis=2).any(axis=1)
    assert blue.sum() > 0.3 * (h - 84 - 50)
    # Tick labels below the x axis and a label under it: dark pixels in the bottom band.
    assert (plot[h - 48:, left:right].max(axis=2) < 100).sum() > 200


def test_demo_rows_keep_captions_readable_when_panels_shrink() -> None:
    from tacswitch.cli.demo import _row

    big = np.full((480, 640, 3), 90, np.uint8)
    one = _row([(big, "A panel")], 640)
    four = _row([(big, "A panel")] * 4, 640)  # each panel shrunk 4x
    bar_one = one[: one.shape[0] - 480]
    bar_four = four[: four.shape[0] - 120]
    assert bar_one.shape[0] == bar_four.shape[0]
    assert text_rows(bar_four) == text_rows(bar_one) >= 12
    titled = _row([(big, "A panel")] * 2, 640, "Row title")
    assert titled.shape[0] > _row([(big, "A panel")] * 2, 640).shape[0]

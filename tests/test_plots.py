"""Issue 32, item 10: bench plots whose series can be told apart, labels that neither overlap
nor run off the image, titles that say what was measured, and a visible removal diff panel."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from tacswitch import tradeoff, viz
from tacswitch.tradeoff import Row

#: What `tacswitch bench` plots (ten series, as in the issue; settings as it names them, times
#: and errors in the ranges it measures), plus two more series.
SPECS: list[tuple[str, list[str], float, float]] = [
    ("TELEA (tacswitch)", ["r=3", "r=12 (default)"], 3, 3.4),
    ("biharmonic (tacswitch)", ["-"], 8, 3.6),
    ("TELEA (OpenCV)", ["r=3", "r=12"], 5, 3.45),
    ("NS (OpenCV)", ["r=3", "r=12"], 6, 3.5),
    ("TacDiff prior (no network)", ["telea"], 4, 3.7),
    ("TacDiff", ["K=1, 4 orientations", "K=2, 4 orientations", "K=1, 1 orientation"], 400, 3.0),
    ("Hybrid (reference)", ["K=2"], 200, 3.1),
    ("Hybrid (texture)", ["K=2"], 210, 3.12),
    ("TacDiff fast", ["K=1, 1 orientation", "K=1, 4 orientations"], 90, 3.2),
    ("Hybrid fast (reference)", ["K=1"], 60, 3.15),
    ("extra one", ["a", "b"], 20, 3.3),
    ("extra two", ["c"], 30, 3.35)]
METHODS = [m for m, *_ in SPECS]


def _rows(source: str) -> list[Row]:
    rows = []
    for m, knobs, ms, mae in SPECS:
        for j, k in enumerate(knobs):
            rows.append(Row(m, k, ms * (1 + 0.3 * j), mae + 0.02 * j, mae, 30.0, source=source))
    return rows


def test_series_styles_are_distinct() -> None:
    colours = [viz.series_style(i)[0] for i in range(20)]
    assert len(set(colours)) == 20
    # The first ten (what a ten-series plot uses) are distinct hues, not shades of a few.
    c10 = np.array(colours[:10], float)
    gaps = [np.linalg.norm(a - b) for a, b in itertools.combinations(c10, 2)]
    assert min(gaps) > 60
    assert len({viz.series_style(i) for i in range(40)}) == 40


def test_bench_plot_draws_every_series_in_its_own_colour() -> None:
    img = tradeoff.plot(_rows("simulated gelsight contacts"))
    for i in range(len(METHODS)):
        colour, _ = viz.series_style(i)
        hits = (img == np.array(colour, np.uint8)).all(axis=2).sum()
        assert hits >= 20, f"series {i} ({METHODS[i]}): colour {colour} drawn on {hits} px"


def test_bench_plot_labels_do_not_overlap_or_leave_the_image(monkeypatch: Any) -> None:
    import cv2

    drawn: list[tuple[str, tuple[int, int], float]] = []
    put = cv2.putText

    def record(img: np.ndarray, text: str, org: tuple[int, int], font: int, scale: float,
               *args: Any, **kwargs: Any) -> Any:
        drawn.append((text, tuple(org), scale))
        return put(img, text, org, font, scale, *args, **kwargs)

    monkeypatch.setattr(cv2, "putText", record)
    rows = _rows("simulated gelsight contacts")
    img = tradeoff.plot(rows)
    h, w = img.shape[:2]
    knobs = {r.knob for r in rows} - {"-"}
    boxes = [tradeoff._text_box(t, o, s) for t, o, s in drawn if t in knobs]
    assert len(boxes) == sum(r.knob != "-" for r in rows)
    for a, b in itertools.combinations(boxes, 2):
        assert tradeoff._overlap(a, b) == 0, (a, b)
    every = [tradeoff._text_box(t, o, s) for t, o, s in drawn]
    for x0, y0, x1, y1 in every:
        assert 0 <= x0 and x1 <= w and 0 <= y0 and y1 <= h, (x0, y0, x1, y1)
    # Nothing drawn in the last columns: the legend is not clipped at the right edge.
    assert (img[:, -4:] == 255).all()


def test_simulated_and_real_plots_have_different_titles() -> None:
    sim_rows = _rows("simulated gelsight contacts")
    real_rows = _rows("real gelsight frames, painted markers")
    t_sim, t_real = tradeoff.plot_title(sim_rows), tradeoff.plot_title(real_rows)
    assert t_sim != t_real and "simulated" in t_sim and "real" in t_real
    a, b = tradeoff.plot(sim_rows), tradeoff.plot(real_rows)
    assert a.shape == b.shape and not np.array_equal(a[:34], b[:34])  # the title band
    assert tradeoff.plot(sim_rows, title="mine").shape == a.shape


def test_rows_carry_their_frames_source() -> None:
    frames = tradeoff.simulated_frames(1, "gelsight_mini")
    rows = tradeoff.evaluate(frames, tradeoff.default_methods((3,), opencv=False), rounds=1)
    assert {r.source for r in rows} == {"simulated gelsight_mini contacts"}


@pytest.fixture(scope="module")
def removal() -> tuple[np.ndarray, np.ndarray]:
    import tacswitch as ts
    from tacswitch.sim.scene import render_sample

    s = render_sample("gelsight", 0)
    return ts.remove_markers(s.image_markers), s.image


def test_demo_diff_panel_is_visible(removal: tuple[np.ndarray, np.ndarray]) -> None:
    """The old panel (|TacDiff - truth| x4) had a mean brightness of ~1 grey level."""
    from tacswitch.cli.demo import _error_panel

    result, truth = removal
    panel, caption = _error_panel(result, truth, "TELEA")
    assert panel.shape == truth.shape and panel.dtype == np.uint8
    grey = panel.max(axis=2)
    assert grey.mean() > 25, grey.mean()
    err = np.abs(result.astype(int) - truth.astype(int)).max(axis=2)
    assert np.percentile(grey[err > 0], 90) > 100
    gain = float(caption.split(" x")[1].split()[0])
    assert gain > 1 and "truth" in caption  # the caption says how much it is amplified


def test_difference_panel_of_identical_frames_shows_the_dimmed_frame() -> None:
    truth = np.full((20, 30, 3), 200, np.uint8)
    panel, gain = viz.difference_panel(truth, truth)
    assert gain == 255.0 and (panel == 80).all()
    result = truth.copy()
    result[5, 5] = 202  # a 2 grey-level error: white
    panel, gain = viz.difference_panel(result, truth)
    assert gain == pytest.approx(127.5) and (panel[5, 5] == 255).all()

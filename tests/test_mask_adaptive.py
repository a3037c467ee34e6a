"""Adaptive marker masks (``dilate="auto"``), border-cut markers, bounded dilation, large frames."""

from __future__ import annotations

import subprocess
import sys
from typing import Literal

import cv2
import numpy as np
import pytest

import tacswitch as ts
from conftest import disc_mask

NOISE = 1.5


def soft_dots(shape: tuple[int, int], centres: np.ndarray, radius: float, *, level: float = 40.0,
              edge: float = 0.0, bg: float | np.ndarray = 180.0) -> np.ndarray:
    """Grey float frame: dots of luma ``level`` on ``bg``, antialiased (8x8 supersampling), with
    a Gaussian edge blur of ``edge`` px (0: crisp)."""
    h, w = shape
    cover: np.ndarray = np.zeros(shape, np.float32)
    ss = (np.arange(8) + 0.5) / 8 - 0.5
    for cx, cy in centres:
        x0, x1 = max(int(cx - radius - 2), 0), min(int(cx + radius + 3), w)
        y0, y1 = max(int(cy - radius - 2), 0), min(int(cy + radius + 3), h)
        if x0 >= x1 or y0 >= y1:
            continue
        yy = np.arange(y0, y1)[:, None, None, None] + ss[None, None, :, None]
        xx = np.arange(x0, x1)[None, :, None, None] + ss[None, None, None, :]
        inside = ((xx - cx) ** 2 + (yy - cy) ** 2 <= radius * radius).mean(axis=(2, 3))
        np.maximum(cover[y0:y1, x0:x1], inside, out=cover[y0:y1, x0:x1])
    if edge > 0:
        cover = cv2.GaussianBlur(cover, (0, 0), edge)
    base = np.broadcast_to(np.asarray(bg, np.float32), shape)
    return base + (level - base) * cover


def capture(frame: np.ndarray, seed: int, *, noise: float = NOISE, jpeg: int | None = None
            ) -> np.ndarray:
    """Sensor noise, rounding and optionally a JPEG round trip (BGR uint8)."""
    rng = np.random.default_rng(seed)
    img = np.clip(np.rint(frame + rng.normal(0, noise, frame.shape)), 0, 255).astype(np.uint8)
    bgr: np.ndarray = np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
    if jpeg is not None:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, jpeg])
        assert ok
        decoded = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        assert decoded is not None
        bgr = decoded
    return bgr


def grid(shape: tuple[int, int], pitch: float, offset: float) -> np.ndarray:
    ys, xs = np.mgrid[offset : shape[0] - offset + 1 : pitch,
                      offset : shape[1] - offset + 1 : pitch]
    rng = np.random.default_rng(3)
    return np.stack([xs.ravel(), ys.ravel()], 1) + rng.uniform(-0.5, 0.5, (xs.size, 2))


def luma(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)


@pytest.fixture(scope="module")
def soft_jpeg() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(captured frame with soft markers (noise, JPEG q70), the marker-caused darkening of the
    capture (noise-free captures with and without markers, grey levels), clean frame BGR, true
    footprint: pixels the markers change by more than half a grey level)."""
    shape = (240, 320)
    pts = grid(shape, 40.0, 20.0)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    bg = 150.0 + 0.08 * xx + 0.05 * yy
    clean = soft_dots(shape, pts[:0], 6.0, bg=bg)
    dots = soft_dots(shape, pts, 6.0, level=45.0, edge=1.3, bg=bg)
    img = capture(dots, seed=1, jpeg=70)
    darkening = luma(capture(clean, 1, noise=0, jpeg=70)) - luma(capture(dots, 1, noise=0, jpeg=70))
    foot = np.abs(dots - clean) > 0.5
    return img, darkening, np.repeat(clean[:, :, None], 3, axis=2), foot


def test_adaptive_mask_covers_everything_a_marker_darkens(soft_jpeg) -> None:
    img, darkening, _, _ = soft_jpeg
    dark = darkening > 2 * NOISE
    auto = ts.extract_markers(img, dilate="auto")
    one = ts.extract_markers(img, dilate=1).mask
    assert len(auto) == 48

    def rim(mask: np.ndarray) -> float:
        """Mean darkening of the one-pixel ring just outside the mask."""
        return float(darkening[ts.dilate_mask(mask, 1) & ~mask].mean())

    # The soft edge and the codec's ring are inside: what is left just outside is darkened by
    # less than half a noise sigma on average; a fixed single dilation leaves a dark rim.
    assert abs(rim(auto.mask)) < 0.5 * NOISE, rim(auto.mask)
    assert rim(one) > 3 * NOISE
    # Pixel by pixel: all but the JPEG block noise a few pixels out (< 5 %) is covered.
    missed = (dark & ~auto.mask).sum()
    assert missed < 0.05 * dark.sum(), f"{missed} of {dark.sum()} dark pixels left"
    assert (dark & ~one).sum() > 0.3 * dark.sum()
    # ...and the growth stops: the mask is not much larger than what is darkened.
    assert auto.mask.sum() < 1.5 * dark.sum()
    assert auto.grow_rings.shape == (48,) and auto.grow_rings.dtype == np.uint16


def test_remove_markers_defaults_to_the_adaptive_mask(soft_jpeg) -> None:
    img, _, clean, foot = soft_jpeg
    out = ts.remove_markers(img)
    np.testing.assert_array_equal(out, ts.remove_markers(img, dilate="auto"))

    def mae(x: np.ndarray) -> float:
        return float(np.abs(x.astype(np.float32) - clean)[foot].mean())

    assert mae(out) < 0.8 * mae(ts.remove_markers(img, dilate=1))
    assert mae(out) < mae(ts.remove_markers(img, dilate=2))


def test_crisp_markers_stay_tight() -> None:
    shape = (240, 320)
    pts = grid(shape, 40.0, 20.0)
    frame = soft_dots(shape, pts, 6.3)
    img = capture(frame, seed=2, noise=0.0)
    exact = luma(img) < 179.5  # every pixel a dot touches
    m = ts.extract_markers(img, dilate="auto")
    assert len(m) == 48
    assert (m.mask & ~ts.dilate_mask(exact, 1)).sum() == 0
    assert (exact & ~m.mask).sum() == 0
    assert m.grow_rings.max() <= 1
    # With camera noise the mask stays within one pixel of the dots too.
    noisy = ts.extract_markers(capture(frame, seed=4), dilate="auto")
    assert np.median(noisy.grow_rings) == 1
    assert (noisy.mask & ~ts.dilate_mask(exact, 1)).sum() <= 0.03 * exact.sum()


def test_growth_does_not_run_away_on_shading() -> None:
    shape = (240, 320)
    pts = grid(shape, 40.0, 20.0)
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    # Strong contact-like shading: a steep ramp plus a bright bump around the centre.
    bg = 110.0 + 0.3 * xx + 60.0 * np.exp(-((xx - 160) ** 2 + (yy - 120) ** 2) / (2 * 35.0 ** 2))
    img = capture(soft_dots(shape, pts, 6.0, level=30.0, edge=0.5, bg=bg), seed=5)
    m = ts.extract_markers(img, dilate="auto")
    assert len(m) == 48
    assert np.median(m.grow_rings) <= 2
    # The cap (1.5 radii, half the gap to the next marker) holds for every marker.
    assert m.grow_rings.max() <= 9



@pytest.mark.parametrize("press", [1, 2])
def test_contact_markers_stop_at_their_rim_on_real_presses(press: int) -> None:
    """Real GelSight Mini presses (Taxim) with painted markers: contact shading is not planar
    around a marker (curvature, the imprint's edge), which made contact markers grow to their
    cap (2.7x and 3.2x the one-dilation mask inside the contact disc of these two presses).
    The grown mask stays within 2x there."""
    pytest.importorskip("taxim")
    from tacswitch import realproxy

    frame = realproxy.proxy_frames("gelsight_mini", 4, styles=("painted",),
                                   captures=("lossless",))[press]
    auto = ts.extract_markers(frame.img, dilate="auto", exclude_border=False).mask
    one = ts.extract_markers(frame.img, dilate=1, exclude_border=False).mask
    inside = (one & frame.contact).sum()
    assert inside > 50
    assert (auto & frame.contact).sum() <= 2.0 * inside
    # Every painted pixel darker than the gel by a third is still inside the mask.
    dark = luma(frame.clean) - luma(frame.img) > 60
    assert (dark & ~auto).sum() == 0

def border_frame() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interior grid plus markers cut deeply by each of the four borders (centres outside)."""
    shape = (240, 320)
    r = 7.0
    inner = grid(shape, 40.0, 40.0)
    cut = np.array([[-3.5, 100.0], [322.5, 140.0], [180.0, -4.0], [90.0, 243.0],
                    [-2.0, -2.5], [160.0, -1.0]])
    frame = soft_dots(shape, np.concatenate([inner, cut]), r, level=25.0, edge=0.6)
    return capture(frame, seed=6), inner, cut


def test_border_slivers_masked_on_all_four_borders() -> None:
    img, inner, cut = border_frame()
    cases: tuple[tuple[int | Literal["auto"], int], ...] = ((0, 60), (1, 100), ("auto", 150))
    for dilate, level in cases:
        dark = luma(img) < level  # marker pixels (the gel is at 180, dots at 25)
        m = ts.extract_markers(img, dilate=dilate)
        assert not (dark & ~m.mask).any(), f"dilate={dilate}: {(dark & ~m.mask).sum()} px left"
        # Tracking users get only markers whose centre is in the frame, [0, W-1] x [0, H-1]
        # (issue 32: the one centred at y = -1 is no longer listed).
        assert len(m) == len(inner)
        h, w = img.shape[:2]
        assert m.centres.min() >= 0
        assert m.centres[:, 0].max() <= w - 1 and m.centres[:, 1].max() <= h - 1
    reported = ts.extract_markers(img, exclude_border=False)
    assert len(reported) == len(inner) + len(cut)
    out = ts.remove_markers(img)
    assert luma(out).min() > 150


def test_border_shading_is_not_a_marker() -> None:
    img, _, _ = border_frame()
    g = luma(img)
    # A dark band along the left border and a dark corner, as vignetting or the gel edge give.
    g[:, :4] -= 90
    g[200:, 280:] -= np.linspace(0, 80, 40)[None, :] * np.linspace(0, 1, 40)[:, None]
    band = np.ascontiguousarray(np.repeat(np.clip(g, 0, 255).astype(np.uint8)[:, :, None], 3, 2))
    m = ts.extract_markers(band, dilate="auto", exclude_border=False)
    assert m.mask[5:235, :3].mean() < 0.2
    assert not m.mask[225:, 305:].any()


def test_bounded_dilation_returns_and_matches_a_full_mask() -> None:
    img, _, _ = border_frame()
    code = (
        "import numpy as np, tacswitch as ts, sys\n"
        "img = np.load(sys.argv[1])\n"
        "m = ts.extract_markers(img, dilate=10**9).mask\n"
        "assert m.all()\n"
        "small = np.zeros((7, 9), bool); small[3, 4] = True\n"
        "assert ts.dilate_mask(small, 10**9).all()\n"
        "assert not ts.dilate_mask(np.zeros((7, 9), bool), 10**9).any()\n"
        "try:\n"
        "    ts.remove_markers(img, dilate=10**9)\n"
        "except ValueError as e:\n"
        "    assert 'mask' in str(e)\n"
        "print('ok')\n"
    )
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "img.npy"
        np.save(path, img)
        res = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True,
                             text=True, timeout=120)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr
    small = np.zeros((7, 9), bool)
    small[0, 0] = True
    # A cross needs H + W - 2 steps to fill from a corner; more change nothing.
    assert not ts.dilate_mask(small, 13).all()
    np.testing.assert_array_equal(ts.dilate_mask(small, 14), np.ones((7, 9), bool))


def test_large_frames_find_small_markers() -> None:
    # 3200 x 3200 with 23-px markers: the old default min_area (5e-5 H W = 512 px) exceeded
    # the markers' 415 px.
    n = 3200
    img = np.full((n, n), 180, np.uint8)
    pts = []
    yy, xx = np.mgrid[-12:13, -12:13]
    disc = (xx ** 2 + yy ** 2 <= 11.5 ** 2)
    for cy in range(200, n - 100, 400):
        for cx in range(200, n - 100, 400):
            img[cy - 12 : cy + 13, cx - 12 : cx + 13][disc] = 40
            pts.append((cx, cy))
    m = ts.extract_markers(img)
    assert len(m) == len(pts) == 64
    # Specks (dust) do not become markers: the typical size is weighted by area.
    rng = np.random.default_rng(0)
    for y, x in rng.integers(50, n - 50, (40, 2)):
        img[y : y + 3, x : x + 3] = 60
    assert len(ts.extract_markers(img)) == 64


def test_dilate_argument_errors() -> None:
    img, _, _ = border_frame()
    with pytest.raises(ValueError, match="dilate"):
        ts.extract_markers(img, dilate="wide")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="dilate"):
        ts.extract_markers(img, dilate=-1)
    with pytest.raises(TypeError, match="dilate"):
        ts.extract_markers(img, dilate=True)
    with pytest.raises(TypeError, match="dilate"):
        ts.remove_markers(img, dilate="wide")  # type: ignore[arg-type]
    m = disc_mask((20, 30), [(10.0, 10.0)], 3.0)
    np.testing.assert_array_equal(ts.dilate_mask(m, 10**30), np.ones((20, 30), bool))

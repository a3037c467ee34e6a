"""The simulator's press law, calibrated on real presses (sim.presets), and the grain matcher
that measured it (motion.grainmatch)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from tacswitch.motion import grainmatch as gm
from tacswitch.sim import presets
from tacswitch.sim.motion import ball_press, contact_displacement, sample_field


def _rings(preset: str, a_px: float, qs: tuple[float, ...], dilation: float,
           centre: tuple[float, float] | None = None) -> NDArray[np.float64]:
    """Mean outward motion (px) on the rings ``q a`` (their points inside the frame) of a ball
    pressed at ``centre`` (default the frame centre) to contact radius ``a_px``, the ball of
    taxim's real presses (``proxy.REAL_BALL_RADIUS_MM``, the one the calibration used)."""
    from proxies.motion_proxy import REAL_BALL_RADIUS_MM

    p = presets.get_preset(preset)
    c = ((p.width - 1) / 2, (p.height - 1) / 2) if centre is None else centre
    ang = np.arange(32) * 2 * np.pi / 32
    unit = np.stack([np.cos(ang), np.sin(ang)], 1)
    out = np.zeros(len(qs))
    fld, _, _, st = ball_press(p, c, a_px, REAL_BALL_RADIUS_MM[preset], dilation)
    for j, q in enumerate(qs):
        pts = np.asarray(c) + q * a_px * unit
        ok = ((pts >= 2) & (pts < np.array([p.width - 2, p.height - 2]))).all(1)
        v = sample_field(fld, st, pts[ok] + (0.5 - 0.5 * st))[0]
        out[j] = float((v * unit[ok]).sum(1).mean())
    return out


def test_presets_carry_the_measured_press_law() -> None:
    g = presets.get_preset("gelsight")
    m = presets.get_preset("gelsight_mini")
    assert g.press_dilation == presets.GELSIGHT_PRESS_DILATION
    assert g.press_decay_mm == presets.GELSIGHT_PRESS_DECAY_MM
    assert m.press_dilation == presets.MINI_PRESS_DILATION
    assert m.press_decay_mm == presets.MINI_PRESS_DECAY_MM
    # Not measured: the old law (one gel thickness).
    assert presets.get_preset("digit").press_decay_mm is None


def test_simulated_gelsight_press_moves_the_gel_as_the_real_one() -> None:
    """Real GelSight presses moved the gel outward by ~2.4-2.6 px at 2 a, ~3 px at 3 a and
    ~0.6-0.7 px at 6 a (640 x 480; BENCHMARKS.md, held-out odd presses); the old law gave 0.05 px
    at 3 a. The simulator's law (taxim's ball, mid gain) at taxim's recorded contacts, averaged
    (with the 4 mm ball the depth, and so the motion, grows steeply with a: pressed at the frame
    centre, 1.8 px at 2 a for a = 62 px, 2.7 px for 66 px)."""
    pytest.importorskip("taxim")
    from proxies.motion_proxy import load_real_presses

    real = load_real_presses("gelsight")
    mid = float(np.mean(presets.GELSIGHT_PRESS_DILATION))
    at2, at3, at5 = np.mean([_rings("gelsight", float(a), (2.0, 3.0, 5.0), mid,
                                    (float(c[0]), float(c[1])))
                             for c, a in zip(real.centres, real.radii, strict=True)], 0)
    assert 1.8 < at2 < 3.2
    assert 1.8 < at3 < 3.8
    assert 0.4 < at5 < 2.0 and at5 < at3  # (5 a leaves the frame: read at its border)
    # The law is linear in its gain.
    at2_once = _rings("gelsight", 63.0, (2.0,), mid)[0]
    assert _rings("gelsight", 63.0, (2.0,), 2 * mid)[0] == pytest.approx(2 * at2_once, rel=1e-4)


def test_simulated_mini_press_barely_moves_the_gel() -> None:
    """Real GelSight Mini presses: under 0.15 px (320 x 240) at every ring 1.5-6 a."""
    hi = presets.MINI_PRESS_DILATION[1]
    assert np.abs(_rings("gelsight_mini", 23.0, (1.5, 2.0, 3.0, 5.0), hi)).max() < 0.15


def test_scene_draws_the_preset_gain() -> None:
    from tacswitch.sim.scene import Scene

    for k in range(3):
        s = Scene("gelsight", np.random.default_rng([5, k]), label="sphere")
        lo, hi = presets.GELSIGHT_PRESS_DILATION
        assert lo <= s.dilation <= hi


def test_decay_widens_the_press_field() -> None:
    """A longer reach moves the gel farther from the contact (same gain)."""
    gh = gw = 64
    yy, xx = np.mgrid[0:gh, 0:gw]
    gel = np.maximum(0.3 - 0.01 * ((xx - 32.0) ** 2 + (yy - 32.0) ** 2), -0.0).astype(np.float32)
    pres = np.maximum(gel, 0)
    kw = dict(centre=(32 * 4.0, 32 * 4.0), dilation=1.0, gel=gel)
    near, _ = contact_displacement(pres, 4.0, 0.05, 2.0, **kw)
    far, _ = contact_displacement(pres, 4.0, 0.05, 2.0, decay_mm=5.0, **kw)
    same, _ = contact_displacement(pres, 4.0, 0.05, 2.0, decay_mm=2.0, **kw)
    assert np.array_equal(near, same)
    # Outward on the x axis; 20 cells = 4 mm from the centre (the indentation ends at ~1 mm):
    # the 2 mm law has mostly died out there, the 5 mm one carries more of its motion.
    rn = near[32, 52, 0] / np.abs(near[32, 32:, 0]).max()
    rf = far[32, 52, 0] / np.abs(far[32, 32:, 0]).max()
    assert far[32, 52, 0] > 0 and rf > 1.4 * rn


def test_grain_matcher_recovers_a_shift_on_a_real_frame() -> None:
    """taxim's real GelSight no-contact frame against itself moved by (1.3, -0.7) px plus fresh
    noise of the real temporal level: the weak grain alone locates the patches."""
    import cv2

    proxy = pytest.importorskip("proxies.motion_proxy")
    f0 = proxy.load_real_presses("gelsight").f0
    m = np.array([[1, 0, 1.3], [0, 1, -0.7]], np.float32)
    moved = cv2.warpAffine(f0, m, (f0.shape[1], f0.shape[0]), flags=cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REFLECT)
    rng = np.random.default_rng(0)
    noisy = np.clip(moved + rng.normal(0, 0.5, moved.shape), 0, 255).astype(np.uint8)
    ys, xs = np.mgrid[80:400:40, 80:560:40]
    pts = np.stack([xs.ravel(), ys.ravel()], 1).astype(np.float64)
    d, pk = gm.match_patches(gm.highpass(f0), gm.highpass(noisy), pts)
    ok = pk > 0.08
    assert ok.mean() > 0.8
    assert np.median(d[ok], 0) == pytest.approx([1.3, -0.7], abs=0.15)
    sim = gm.fit_similarity(pts[ok], d[ok], (319.5, 239.5))
    assert sim[:2] == pytest.approx([1.3, -0.7], abs=0.15) and abs(sim[2]) < 1e-3
    with pytest.raises(ValueError, match="patch"):
        gm.match_patches(gm.highpass(f0), gm.highpass(f0), pts, patch=4)

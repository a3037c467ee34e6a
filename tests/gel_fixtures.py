"""Generated markerless gel frames with a known motion, for the motion tests (no shared data)."""

from __future__ import annotations

import numpy as np


def _gel(seed: int = 0, shape: tuple[int, int] = (240, 320), grain_sd: float = 6.0
         ) -> np.ndarray:
    """A generated markerless gel frame: smooth shading plus a faint grain of standard deviation
    ``grain_sd`` grey levels (BGR uint8)."""
    import cv2

    rng = np.random.default_rng(seed)
    h, w = shape
    grain = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.5)
    grain *= grain_sd / grain.std()
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    shade = 120 + 30 * np.exp(-((xx - 0.4 * w) ** 2 + (yy - 0.5 * h) ** 2) / (0.3 * w) ** 2)
    g = np.clip(shade + grain, 0, 255)
    return np.dstack([g, 0.9 * g, 0.8 * g]).round().astype(np.uint8)


def _pressed_and_sheared(img: np.ndarray, amp: float) -> tuple[np.ndarray, np.ndarray]:
    """``img`` warped by a smooth press (outward) + shear field of about ``amp`` px, with the
    contact's imprint (a shaded disc the no-contact frame lacks) on it, and the field
    ``H x W x 2`` (forward: the gel at p goes to p + field(p))."""
    import cv2

    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    cx, cy, r = 0.5 * w, 0.5 * h, 0.25 * w
    d2 = ((xx - cx) ** 2 + (yy - cy) ** 2) / r ** 2
    bump = np.exp(-d2).astype(np.float32)
    fx = amp * (0.6 * bump + 0.4 * (xx - cx) / r * bump)
    fy = amp * (0.3 * bump + 0.4 * (yy - cy) / r * bump)
    # Backward map by one fixed-point step (the field is smooth and small).
    mx, my = xx - fx, yy - fy
    warped = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    # The imprint: a shading dome over the contact, deeper with the press.
    dome = ((30.0 + 4.0 * amp) * np.exp(-((d2 / 0.4) ** 2)))[..., None]
    out = np.clip(warped.astype(np.float32) + dome * np.array([1.0, 0.6, 0.3], np.float32),
                  0, 255)
    return out.round().astype(np.uint8), np.dstack([fx, fy]).astype(np.float32)


def _moved(img: np.ndarray, shift: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """``img`` (gel and imprint alike: a stuck contact) moved by a smooth field that is
    ``shift`` ``(dx, dy)`` px at the frame's centre and fades towards its border, and that field
    ``H x W x 2`` (forward, as :func:`_pressed_and_sheared`)."""
    import cv2

    h, w = img.shape[:2]
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    bump = np.exp(-(((xx - 0.5 * w) / (0.35 * w)) ** 2 + ((yy - 0.5 * h) / (0.35 * h)) ** 2))
    fx, fy = (np.float32(s) * bump.astype(np.float32) for s in shift)
    moved = cv2.remap(img, xx - fx, yy - fy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return moved, np.dstack([fx, fy]).astype(np.float32)

"""Re-compressing the fine-tune's transplanted frames like the source recording.

On a compressed recording the 8 x 8 transform blocks that hold a dark marker are quantised
around it: the gel texture in those blocks, just outside the marker's mask, is distorted by the
marker's edges. A marker transplanted onto gel that was compressed *without* a marker lacks that
distortion, so a fine-tune on such frames learns holes framed by clean gel and meets distorted
gel at inference. Measured on real + painted GelSight frames captured as MJPEG q75
(``benches/bench_finetune_real.py``; 600 steps from the shipped default): without re-compression
the fine-tune improved its own validation by 4.6 % and made the held-out frames 2.5 % worse
(1.387 -> 1.421), at any learning rate or pseudo-fill radius tried; with each transplanted frame
re-compressed as JPEG q75 it made them 1.9 % better (1.387 -> 1.361), its validation agreeing.
On lossless frames the fine-tune helped without it (1.153 -> 1.129).

Spec (``tacswitch finetune --recompress``): ``"auto"`` (default) recognises a JPEG/MJPEG source
by its quality (:func:`jpeg_quality`) and re-compresses at it, otherwise leaves the frames as they
are; ``"none"``; ``"jpeg:Q"`` (quality 1..100); ``"h264:CRF"`` (libx264, CRF 0..51, needs PyAV,
the ``train`` extra). Frames are ``H x W x 3`` uint8 BGR.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = ["Recompress", "jpeg_quality", "recompressor"]

#: A function re-compressing one BGR frame.
Recompress = Callable[[NDArray[np.uint8]], NDArray[np.uint8]]
#: Qualities :func:`jpeg_quality` tries.
QUALITIES = range(20, 100)
#: A JPEG-decoded frame re-encoded at its own quality changes by at most this many grey levels
#: on average (libjpeg is near idempotent there: 0.00-0.01 on real proxy frames at q75), and by
#: less than a third of what qualities :data:`PLATEAU` away change it (neighbouring qualities
#: can round to the same quantisation tables, so the nearest ones may match as well).
IDEMPOTENT_MAE, DIP_RATIO, PLATEAU = 0.1, 1.0 / 3.0, 3


def jpeg_quality(frame: NDArray[np.uint8]) -> int | None:
    """The JPEG quality ``frame`` was decoded from (or one with the same quantisation tables),
    or None (lossless, a video codec, another encoder's tables, or above about quality 93,
    where a re-compression changes little and the neighbours' round trips are as small): the
    quality whose JPEG round trip leaves it nearly unchanged while qualities a few steps away
    do not (a round trip at the source's own tables is close to idempotent; at other tables it
    re-quantises)."""
    from tacswitch.sim.capture import jpeg_roundtrip

    f = np.asarray(frame)
    err = {q: float(np.abs(jpeg_roundtrip(f, q).astype(np.int16) - f).mean()) for q in QUALITIES}
    q = min(err, key=lambda k: err[k])
    if q - PLATEAU not in err or q + PLATEAU not in err or err[q] > IDEMPOTENT_MAE:
        return None
    if err[q] > DIP_RATIO * min(err[q - PLATEAU], err[q + PLATEAU]):
        return None
    return q


def recompressor(spec: str, frames: Sequence[NDArray[np.uint8]]) -> tuple[Recompress | None,
                                                                          str]:
    """``(function or None, description)`` for ``spec`` (module doc); ``"auto"`` looks at the
    first of ``frames``. ``ValueError`` naming ``recompress`` for a bad spec."""
    from tacswitch.sim import capture

    text = str(spec).strip().lower()
    if text == "none":
        return None, "none"
    if text == "auto":
        q = jpeg_quality(frames[0]) if len(frames) else None
        if q is None:
            return None, ("none (no JPEG source recognised; frames from a compressed video: "
                          "pass h264:CRF)")
        text = f"jpeg:{q}"
    kind, _, value = text.partition(":")
    try:
        level = int(value)
    except ValueError:
        raise ValueError(f"recompress: expected 'auto', 'none', 'jpeg:Q' or 'h264:CRF'; got "
                         f"{spec!r}") from None
    if kind == "jpeg" and 1 <= level <= 100:
        return (lambda img: capture.jpeg_roundtrip(img, level)), f"jpeg:{level}"
    if kind == "h264" and 0 <= level <= 51:
        return (lambda img: capture.h264_roundtrip([img], level)[0]), f"h264:{level}"
    raise ValueError(f"recompress: expected 'jpeg:Q' (Q 1..100) or 'h264:CRF' (CRF 0..51); "
                     f"got {spec!r}")

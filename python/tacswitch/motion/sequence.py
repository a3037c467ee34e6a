"""Marker motion from rest over a markerless video: the no-contact frame, then the contact.

One pair cannot have it both ways: against the no-contact frame the imprint *appears* and optical
flow turns its shading into false motion, so the contact-mechanics rule is the better estimate
there (:mod:`tacswitch.motion.reference`), but that rule sees only the press, never the shear or
twist that drags a stuck contact sideways; against a frame of the same contact flow follows that
lateral motion well (real texture: cosine 0.97). A video has both frames.
:class:`MarkerlessTracker` anchors on the first frame that shows a contact the no-contact frame
lacks, takes the press part of the motion there from the mechanics rule against the no-contact
frame, and from then on adds the flow from the anchor (read at the markers' anchored positions):

    motion(t) = m_rule(anchor vs no-contact) + flow(anchor -> frame t) at (centres + m_rule)

Before the first contact (and after the contact is released) it returns the flow from the
no-contact frame, which for a frame without contact is texture motion only (exactly zero for an
identical frame). Measured in ``benches/bench_motion_sequence.py`` (BENCHMARKS.md "Markerless
motion over a sequence") and on real GelSight Mini videos with tracked markers
(``benches/bench_motion_video_real.py``, 29 objects, markers removed): there it ties with the
direct flow from the no-contact frame (development objects: e_rmse 1.36 vs 1.35 px, zero 1.72;
held-out objects with the ghost control 0.82 vs 0.81 px, zero 1.54, cosine 0.91 for both), while
anchoring at the first contact with the flow instead of the rule (1.38) and re-anchoring
whenever the motion from the anchor passes 0-5 px (2.5-3.5: every link adds its error) were
worse; on simulated GelSight grasps and real frames with the modelled press field the rule at
the anchor is far better than the direct flow (0.96 vs 1.51 px, 1.25 vs 4.9 px), so it stays.

A video that starts in contact has no no-contact frame (``no_contact=None``): the first frame
is the anchor and the mechanics rule runs on it alone (single frame; ``predict_motion(img)``
runs the ensemble, rule + learned model, instead); the contact cannot be seen to end, so the
anchor stays until :meth:`~MarkerlessTracker.reset`. Checked on real marker motion: the two
FOTS GelSight Mini frames (a press, then the same contact sheared), markers removed,
``benches/bench_motion_fots.py``.

Units and conventions: frames ``H x W x 3`` uint8 BGR of one size, centres and motion ``(x, y)``
px with pixel centres at integers.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["MarkerlessTracker"]


class MarkerlessTracker:
    """Marker motion from rest over a markerless video (module doc).

    Args:
        no_contact: markerless frame of the sensor without contact, ``H x W x 3`` uint8 BGR, or
            None when the video starts in contact (the first frame is then the anchor, see the
            module doc).
        centres: ``N x 2`` float32 marker rest centres ``(x, y)`` px (default: the shipped motion
            model's grid scaled to the frame, as :func:`tacswitch.predict_motion`).
        gain: the mechanics rule's press gain (a sensor name or a number >= 0, as
            :func:`tacswitch.predict_motion` takes it; default: the rule's).
        model: motion model path, used only for the default centres.

    Attributes:
        centres: the rest centres used (None until the first frame when both ``no_contact``
        and ``centres`` were None); ``anchor_index``: index (0-based count of :meth:`update`
        calls since the last reset) of the current anchor frame, or None.
    """

    def __init__(self, no_contact: Any = None, centres: Any = None, *,
                 gain: float | str | None = None,
                 model: str | os.PathLike[str] | None = None) -> None:
        from tacswitch._checks import as_points
        from tacswitch.motion.infer import _bgr, _rule_gain
        from tacswitch.motion.mechanics import MECHANICS_GAIN

        self._model = model
        self.no_contact: NDArray[np.uint8] | None = None
        self.centres: NDArray[np.float32] | None = (
            None if centres is None else as_points(centres, "centres").copy())
        # The frame shape every update must have, and what fixed it (for the error message).
        self._shape: tuple[int, ...] | None = None
        self._shape_of = ""
        if no_contact is not None:
            self.no_contact = self._checked(_bgr(no_contact, "no_contact"), "no_contact",
                                            "no_contact").copy()
        self.gain = MECHANICS_GAIN if gain is None else _rule_gain("mechanics", gain)
        self.reset()

    def _checked(self, img: NDArray[np.uint8], name: str, what: str) -> NDArray[np.uint8]:
        """``img`` (argument ``name``) after the size check; fixes the frame shape (``what``
        fixed it, for later errors) and the default centres from the first frame seen."""
        from tacswitch._checks import check_downsampled_size
        from tacswitch.motion.infer import MIN_IMAGE_SIDE_PX, load_model

        check_downsampled_size(img.shape, 1, MIN_IMAGE_SIDE_PX, name)
        if self.centres is None:
            self.centres = load_model(self._model).centres_for(*img.shape[:2])
        self._shape, self._shape_of = img.shape, what
        return img

    def reset(self) -> None:
        """Forgets the anchor: the next frame is judged against the no-contact frame again
        (without one, the next frame becomes the new anchor)."""
        # (anchor frame, its motion from rest by the rule), from the first frame of a contact.
        self._anchor: tuple[NDArray[np.uint8], NDArray[np.float32]] | None = None
        self.anchor_index: int | None = None
        self._count = 0

    def update(self, frame: Any) -> NDArray[np.float32]:
        """Motion ``N x 2`` float32 ``(dx, dy)`` px of every marker from rest to ``frame``."""
        from tacswitch.motion.flow import flow_motion
        from tacswitch.motion.infer import _bgr
        from tacswitch.motion.mechanics import mechanics_motion
        from tacswitch.motion.reference import is_new_contact

        img = _bgr(frame, "frame")
        if self._shape is None:
            self._checked(img, "frame", "the first frame")
        elif img.shape != self._shape:
            raise ValueError(f"frame: shape {img.shape} does not match {self._shape_of} "
                             f"{self._shape}")
        index = self._count
        self._count += 1
        c = self.centres
        assert c is not None  # set by _checked at construction or on the first frame
        if len(c) == 0:
            return np.zeros((0, 2), np.float32)
        if self.no_contact is None:
            # Starts in contact: the first frame is the anchor, the rule on it alone.
            if self._anchor is None:
                self._anchor = (img.copy(), mechanics_motion(img, None, c, gain=self.gain))
                self.anchor_index = index
                return self._anchor[1].copy()
        elif not is_new_contact(img, self.no_contact):
            # No contact (yet, or any more): texture motion against the no-contact frame.
            self._anchor = self.anchor_index = None
            return flow_motion(img, self.no_contact, c)
        if self._anchor is None:
            self._anchor = (img.copy(), mechanics_motion(img, self.no_contact, c, gain=self.gain))
            self.anchor_index = index
            return self._anchor[1].copy()
        anchor, pressed = self._anchor
        at = (c + pressed).astype(np.float32)
        return (pressed + flow_motion(img, anchor, at)).astype(np.float32)

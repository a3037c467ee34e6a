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
motion over a sequence").

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
        no_contact: markerless frame of the sensor without contact, ``H x W x 3`` uint8 BGR.
        centres: ``N x 2`` float32 marker rest centres ``(x, y)`` px (default: the shipped motion
            model's grid scaled to the frame, as :func:`tacswitch.predict_motion`).
        gain: the mechanics rule's press gain (a sensor name or a number >= 0, as
            :func:`tacswitch.predict_motion` takes it; default: the rule's).
        model: motion model path, used only for the default centres.

    Attributes:
        centres: the rest centres used; ``anchor_index``: index (0-based count of
        :meth:`update` calls since the last reset) of the current anchor frame, or None.
    """

    def __init__(self, no_contact: Any, centres: Any = None, *, gain: float | str | None = None,
                 model: str | os.PathLike[str] | None = None) -> None:
        from tacswitch._checks import as_points, check_downsampled_size
        from tacswitch.motion.infer import MIN_IMAGE_SIDE_PX, _bgr, _rule_gain, load_model
        from tacswitch.motion.mechanics import MECHANICS_GAIN

        self.no_contact = _bgr(no_contact, "no_contact").copy()
        check_downsampled_size(self.no_contact.shape, 1, MIN_IMAGE_SIDE_PX, "no_contact")
        h, w = self.no_contact.shape[:2]
        self.centres = (load_model(model).centres_for(h, w) if centres is None
                        else as_points(centres, "centres").copy())
        self.gain = MECHANICS_GAIN if gain is None else _rule_gain("mechanics", gain)
        self.reset()

    def reset(self) -> None:
        """Forgets the anchor: the next frame is judged against the no-contact frame again."""
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
        if img.shape != self.no_contact.shape:
            raise ValueError(f"frame: shape {img.shape} does not match no_contact "
                             f"{self.no_contact.shape}")
        index = self._count
        self._count += 1
        c = self.centres
        if len(c) == 0:
            return np.zeros((0, 2), np.float32)
        if not is_new_contact(img, self.no_contact):
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

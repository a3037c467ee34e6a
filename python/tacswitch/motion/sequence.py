"""Marker motion from rest over a markerless video: the no-contact frame, then the contact.

With the no-contact frame, a frame's motion is the optical flow from that frame (every frame's
with ``anchor="rest"``; with the default ``anchor="contact"`` while no contact or a new one
shows, see below), read at the rest centres (:func:`tacswitch.motion.flow.flow_motion`;
exactly zero for an identical frame), with the imprint suppressed (``suppress_imprint=True``,
the default): the shading of a contact the no-contact frame lacks is not motion, so the flow is
trusted less where an imprint appeared and filled there from the gel around it. Measured on
real GelSight Mini videos with tracked markers (29 objects, markers removed,
``benches/bench_motion_video_real.py``, BENCHMARKS.md "Markerless motion on real GelSight Mini
videos"), the direct flow from the no-contact frame beat every chained estimate tried on the
development objects: e_rmse 1.35 px (zero 1.72) against 1.38 for anchoring at the first contact
and adding the flow from there, 2.5-3.5 for re-anchoring whenever the motion from the anchor
passes 0-5 px (every link adds its own error; drift grows with the chain), and 1.36 for the
earlier design (the mechanics rule at the first frame with a new contact, then the flow from
it). Where it matters — the frames showing a contact the no-contact frame lacks — the earlier
design lost the press: over all 29 objects, ghost control, e_rmse 1.44 px, cosine 0.31,
magnitude ratio 0.50, against the direct flow's 1.25 / 0.62 / 0.90 (zero 1.14; the rule
predicts little press motion on these gels, which move several px). On the simulator's grasps
and on real frames with the modelled press field (the rule's own physics) the earlier design
was better (``benches/bench_motion_sequence.py``); the real markers decided.

Suppressing the imprint then lowered the error on the 14 held-out objects under every
removal: 0.67x -> 0.57x zero motion with the default removal, 0.51x -> 0.47x with the mask grown
by 4 px, 0.78x -> 0.74x with one mask per clip (cosine 0.84 -> 0.90, 0.92 -> 0.94, 0.68 -> 0.77;
magnitude ratio 0.93 -> 0.80), as it did on real texture warped by known fields and on truly
markerless real presses (a Mini gel that does not move: 0.55 -> 0.29 px of false motion). The
flow's DIS preset ``refined`` (the default since 2026-11-30, :mod:`tacswitch.motion.flow`) then
took the held-out default removal from 0.56x to 0.53x.

Within a steady contact (``anchor="contact"``, the default since 2026-11-30) the motion is read
from the frame where the contact settled instead:

    motion(t) = motion(anchor) + flow(anchor -> frame t) at (centres + motion(anchor))

A frame that shows a contact the no-contact frame lacks (:func:`~tacswitch.motion.reference.
is_new_contact`) anchors the tracker when there is no anchor yet or when its contact changed
against the anchor's (it shows a contact the anchor lacks, or the anchor one it lacks: the
contact grew or receded; its changed shading is read by the direct flow above, and the anchor
moves to it); a frame without a contact drops the anchor. Both
frames of the anchored flow show the imprint, which moves with the gel while the contact
sticks, so the flow follows the contact's shear in full, where the flow from the no-contact
frame smooths the imprint away. On real GelSight texture warped by a stuck shear (taxim's
presses as one recording of a press, then a shear, ``benches/bench_motion_sequence.py``)
the motion since the full press is 0.38 px off against 1.22 px with ``anchor="rest"`` and 0.72
for zero motion (cosine 0.65 against 0.37); on simulated GelSight grasps 0.90 px against 1.20
(zero 2.59; held contacts 0.90 against 1.90). Its cost: a contact that slides over the gel (a
slip) moves the imprint without the gel, and the anchored flow follows the object: simulated
GelSight slips 1.89 px against 0.79 (zero 2.17), and on the real GelSight Mini videos the frames
with a new contact, mostly in clips that slip, 0.84x zero motion against 0.76x (markers removed
for motion; over all scored frames of the 14 held-out objects 0.44x both). Where the gel barely
moves under its noise (taxim's real Mini presses, the simulator's Mini) both are above zero
motion, the anchored flow more so. ``anchor="rest"`` keeps the direct flow from the no-contact
frame on every frame; both run one flow a frame, the anchor adds up to three contact tests of
about 1 ms at 640 x 480.

The no-contact frame's noise (``rest_frames``, off by default): every frame's flow is read
against one frame, so that frame's camera noise is a fixed error of every motion. With
``rest_frames=n > 1`` the frames fed after it are averaged into it while nothing changes
against it (no contact, no imprint: :func:`~tacswitch.motion.reference.is_unchanged`), each
once :data:`REST_CONFIRM` more such frames have followed it, up to ``n`` in all; the first
change ends the averaging for good (:meth:`reset` does not restart it). Measured (scratch
replays of the real GelSight Mini videos, fed at 12.5 frames/s, markers removed for motion;
x zero motion, held-out / development objects): with 4 grey levels of added camera noise 0.548x /
0.677x -> 0.527x / 0.622x at ``n = 16``; as recorded (MPEG-4, noise about 0.3 grey levels)
0.437x / 0.525x -> 0.437x / 0.503x. Its risk is a contact whose shading does not show at
first: on the simulator's GelSight grasps, which start pressing at their first frame with a
faint imprint, the press was averaged in (0.90 -> 1.08 px, zero 2.59). Averaging only frames
whose motion from the no-contact frame stayed under 0.5-1 px removed that risk and, under
noise, most of the gain (0.545x / 0.658x at 1 px): not the default. Use it with a noisy camera
and untouched frames before the grasp.

The frame-to-frame path (``frame_to_frame=w``, off by default): each frame's motion becomes

    motion(t) = w * (motion(t-1) + flow(frame t-1 -> frame t) at (centres + motion(t-1)))
                + (1 - w) * motion read as above

a complementary filter. The step from the last frame is small and is read steadily where the
flow from rest, across a large motion or a changed contact, reads each frame anew; the term read
from rest or the anchor bounds the drift the chained steps would gather. On the 300 real GelSight
Mini slip videos (markers removed for motion, the first settled frame as the anchor; scored
against the tracked markers) the error of the velocity a frame falls from 0.95 to 0.48 px RMS at
``w = 0.8`` (true velocities 0.73 px RMS), and that of the motion from 4.59 to 4.49 px. A slip
detector reads the velocity, and the markerless slip scorer is trained on this path
(:data:`tacswitch.grasp.detector.SCORER_FRAME_TO_FRAME`). On the motion from rest it changes
little (held-out objects, markers removed: 0.53x -> 0.55x zero motion with the default removal,
0.44x both with the removal for motion; markerless-motion notes), so it is off by default. It
costs a second flow a frame, the step's. With the path on, every flow of the tracker stops one
pyramid level above the flow's work size (:func:`~tacswitch.motion.flow.flow_motion` with
``coarse=True``): on frames wider than the work width (640 x 480) each flow then costs a quarter
and reads on the grid the slip scorer learned at 320 x 240 (the slip loop at 640 x 480 on one
thread: 26 -> 51 frames/s, against 34 without the path; BENCHMARKS.md); at 320 x 240 the flows
are the same.

A video that starts in contact has no no-contact frame (``no_contact=None``): the first frame
is the anchor and the mechanics rule runs on it alone (single frame; ``predict_motion(img)``
runs the ensemble, rule + learned model, instead); every later frame adds the flow from the
anchor, read at the markers' anchored positions:

    motion(t) = m_rule(anchor) + flow(anchor -> frame t) at (centres + m_rule)

The contact cannot be seen to end, so the anchor stays until :meth:`~MarkerlessTracker.reset`.
Checked on real marker motion: the two FOTS GelSight Mini frames (a press, then the same contact
sheared), markers removed, ``benches/studies/bench_motion_fots.py``.

Units and conventions: frames ``H x W x 3`` uint8 BGR of one size, centres and motion ``(x, y)``
px with pixel centres at integers.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["ANCHORS", "REST_CONFIRM", "MarkerlessTracker"]

#: ``MarkerlessTracker(anchor=...)`` with a no-contact frame: ``"contact"`` (default) reads a
#: steady contact's motion as the flow from the frame where it settled; ``"rest"`` reads every
#: frame's motion as the flow from the no-contact frame (module doc).
ANCHORS = ("contact", "rest")
#: ``MarkerlessTracker(rest_frames=...)``: a still frame is averaged into the no-contact frame
#: only once this many more still frames have followed it (the frames just before a contact
#: shows may already carry its first motion; module doc).
REST_CONFIRM = 2


class MarkerlessTracker:
    """Marker motion from rest over a markerless video (module doc).

    Args:
        no_contact: markerless frame of the sensor without contact, ``H x W x 3`` uint8 BGR, or
            None when the video starts in contact (the first frame is then the anchor, see the
            module doc).
        centres: ``N x 2`` float32 marker rest centres ``(x, y)`` px (default: the shipped motion
            model's grid scaled to the frame, as :func:`tacswitch.predict_motion`).
        gain: the mechanics rule's press gain on the first frame of a video that starts in
            contact (``no_contact=None``; a sensor name or a number >= 0, as
            :func:`tacswitch.predict_motion` takes it; default: the rule's). Unused with a
            no-contact frame.
        model: motion model path, used only for the default centres.
        suppress_imprint: with a no-contact frame, suppress the imprint's shading in the flow
            (default True; module doc). False gives the plain flow, which is what the
            markerless slip scorer was trained on (``tacswitch slip --markerless --ref``).
            Unused without a no-contact frame (the anchor may be in contact).
        preset: the flow's preset (:data:`tacswitch.motion.flow.FLOW_PRESETS`; None: the
            default, ``"refined"``), which the markerless slip scorer was trained on too.
            ``"accurate"`` (DeepFlow, 5 frames/s: 10-30x slower) is for recordings: on the
            real Mini videos (markers removed, measured with ``anchor="rest"``) no held-out
            clip is worse than zero motion with the removals whose fills move, and on a still
            real Mini gel it reads 0.11 px of false motion against 0.27
            (:mod:`tacswitch.motion.flow`).
        anchor: with a no-contact frame, ``"contact"`` (default) reads a steady contact's
            motion from the frame where it settled, ``"rest"`` every frame's from the
            no-contact frame (:data:`ANCHORS`, module doc). Unused without a no-contact frame.
        rest_frames: with a no-contact frame, how many frames (it included, an int >= 1) may
            be averaged into it: the frames fed before anything changes against it (no
            contact, no imprint: :func:`~tacswitch.motion.reference.is_unchanged`), each once
            :data:`REST_CONFIRM` more such frames have followed it. This averages the camera's
            noise out of the reference every frame's flow is read from (module doc: it helps
            a noisy camera, and a contact whose shading does not show at first can be averaged
            in). 1 (default): the no-contact frame as given.
        frame_to_frame: weight ``w`` in [0, 1] of the frame-to-frame path (module doc): each
            frame's motion becomes ``w * (last motion + flow(last frame -> frame)) + (1 - w) *
            motion read as above``, a complementary filter: the increment carries the motion
            from frame to frame without lag, the motion read from rest or the anchor bounds
            the drift. 0 (default): off. It steadies the velocity a slip detector reads (the
            markerless slip scorer is trained on it: :data:`tacswitch.grasp.detector.
            SCORER_FRAME_TO_FRAME`) and costs a second flow a frame (on frames wider than
            the flow's work width every flow is then read a pyramid level coarser, at a
            quarter of the cost: module doc).

    Attributes:
        centres: the rest centres used (None until the first frame when both ``no_contact``
            and ``centres`` were None).
        anchor: the ``anchor`` option.
        anchor_index: index (0-based count of :meth:`update` calls since the last reset) of the
            anchor frame: the first frame of a video that starts in contact, or with a
            no-contact frame and ``anchor="contact"`` the frame where the current contact
            settled; None while there is none.
        no_contact: the no-contact frame in use (with ``rest_frames > 1``, the average of
            ``rest_count`` frames), or None.
        rest_count: how many frames the no-contact frame in use averages (1: as given).
    """

    def __init__(self, no_contact: Any = None, centres: Any = None, *,
                 gain: float | str | None = None,
                 model: str | os.PathLike[str] | None = None,
                 suppress_imprint: bool = True, preset: str | None = None,
                 anchor: str = "contact", rest_frames: int = 1,
                 frame_to_frame: float = 0.0) -> None:
        from tacswitch._checks import as_count, as_number, as_points, check_model_arg
        from tacswitch.motion.flow import DEFAULT_PRESET, check_flow_options
        from tacswitch.motion.infer import _bgr, _rule_gain
        from tacswitch.motion.mechanics import MECHANICS_GAIN

        # Checked now: it is first used at the first update (for the default centres).
        check_model_arg(model)
        self.preset = DEFAULT_PRESET if preset is None else preset
        check_flow_options("dis", self.preset, suppress_imprint)
        if not isinstance(anchor, str) or anchor not in ANCHORS:
            raise ValueError(f"anchor: unknown {anchor!r}; choose from {list(ANCHORS)}")
        self.anchor = anchor
        self.rest_frames = as_count(rest_frames, "rest_frames", 1)
        self.frame_to_frame = as_number(frame_to_frame, "frame_to_frame", 0.0, 1.0)
        self.suppress_imprint = bool(suppress_imprint)
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
        # The running sum of the averaged no-contact frames (None once closed: something
        # changed, or rest_frames were taken) and their count.
        self._rest_sum: NDArray[np.float32] | None = (
            None if self.no_contact is None or self.rest_frames == 1
            else self.no_contact.astype(np.float32))
        self.rest_count = 1
        self._rest_waiting: list[NDArray[np.uint8]] = []  # still frames not yet confirmed
        self.gain = MECHANICS_GAIN if gain is None else _rule_gain("mechanics", gain)
        self.reset()

    @property
    def _coarse(self) -> bool:
        """Whether the flows stop a pyramid level above the work size on frames downsampled
        for the flow (``flow_motion(coarse=True)``): with the frame-to-frame path (module doc)."""
        return self.frame_to_frame > 0

    def _checked(self, img: NDArray[np.uint8], name: str, what: str) -> NDArray[np.uint8]:
        """``img`` (argument ``name``) after the size check; fixes the frame shape (``what``
        fixed it, for later errors) and the default centres from the first frame seen."""
        from tacswitch._checks import check_downsampled_size, check_points_in_frame
        from tacswitch.motion.infer import MIN_IMAGE_SIDE_PX, load_model

        check_downsampled_size(img.shape, 1, MIN_IMAGE_SIDE_PX, name)
        if self.centres is None:
            self.centres = load_model(self._model).centres_for(*img.shape[:2])
        else:
            check_points_in_frame(self.centres, img.shape[0], img.shape[1], "centres")
        self._shape, self._shape_of = img.shape, what
        return img

    def reset(self) -> None:
        """Forgets the anchor: the next frame is judged against the no-contact frame again
        (without one, the next frame becomes the new anchor). The no-contact frame stays as
        averaged so far (``rest_frames``), and an averaging still open goes on."""
        # (anchor frame, its motion from rest): by the rule on the first frame of a video that
        # starts in contact, else by the direct flow where the contact settled.
        self._anchor: tuple[NDArray[np.uint8], NDArray[np.float32]] | None = None
        self.anchor_index: int | None = None
        self._count = 0
        # The last frame fed and its motion, for the frame-to-frame path.
        self._last: tuple[NDArray[np.uint8], NDArray[np.float32]] | None = None

    def update(self, frame: Any) -> NDArray[np.float32]:
        """Motion ``N x 2`` float32 ``(dx, dy)`` px of every marker from rest to ``frame``."""
        from tacswitch.motion.flow import flow_motion
        from tacswitch.motion.infer import _bgr

        img = _bgr(frame, "frame")
        motion = self._read(img)
        w = self.frame_to_frame
        if w > 0 and len(motion):
            if self._last is not None:
                last, moved = self._last
                assert self.centres is not None  # set by the first frame's _read
                at = (self.centres + moved).astype(np.float32)
                step = flow_motion(img, last, at, preset=self.preset, coarse=True)
                motion = (w * (moved + step) + (1.0 - w) * motion).astype(np.float32)
            self._last = (img.copy(), motion.copy())
        return motion

    def _read(self, img: NDArray[np.uint8]) -> NDArray[np.float32]:
        """The motion of a validated frame from rest or the anchor (module doc), before the
        frame-to-frame path."""
        from tacswitch.motion.flow import flow_motion
        from tacswitch.motion.mechanics import mechanics_motion

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
        if self.no_contact is not None:
            return self._from_rest(img, c, index)
        if self._anchor is None:
            # Starts in contact: the first frame is the anchor, the rule on it alone.
            self._anchor = (img.copy(), mechanics_motion(img, None, c, gain=self.gain))
            self.anchor_index = index
            return self._anchor[1].copy()
        anchor, pressed = self._anchor
        at = (c + pressed).astype(np.float32)
        return (pressed + flow_motion(img, anchor, at, preset=self.preset,
                                       coarse=self._coarse)).astype(np.float32)

    def _fold_rest(self, img: NDArray[np.uint8]) -> bool:
        """Averages ``img`` into the no-contact frame once :data:`REST_CONFIRM` more frames
        have followed it with nothing changed against the no-contact frame (module doc). The
        first change drops the frames still waiting and ends the averaging, as does the last
        of ``rest_frames``. Returns whether nothing changed (then ``img`` shows no contact)."""
        from tacswitch.motion.reference import is_unchanged

        rest, total = self.no_contact, self._rest_sum
        assert rest is not None and total is not None
        if np.array_equal(img, rest):
            return True  # the no-contact frame fed again (often the video's first frame)
        if not is_unchanged(img, rest):
            self._rest_sum, self._rest_waiting = None, []
            return False
        self._rest_waiting.append(img.copy())
        if len(self._rest_waiting) <= REST_CONFIRM:
            return True
        total += self._rest_waiting.pop(0)
        self.rest_count += 1
        self.no_contact = np.rint(total / np.float32(self.rest_count)).astype(np.uint8)
        if self.rest_count >= self.rest_frames:
            self._rest_sum, self._rest_waiting = None, []
        return True

    def _from_rest(self, img: NDArray[np.uint8], c: NDArray[np.float32],
                   index: int) -> NDArray[np.float32]:
        """Motion from rest with a no-contact frame (module doc): the direct flow from it, or,
        with ``anchor="contact"`` inside a steady contact, the motion at the frame where the
        contact last grew plus the flow from that frame."""
        from tacswitch.motion.flow import flow_motion
        from tacswitch.motion.reference import contact_changed, is_new_contact

        rest = self.no_contact
        assert rest is not None
        # While averaging, a frame with nothing changed shows no contact (is_new_contact's own
        # region test), so the contact test is not run again. The frame is read against the
        # no-contact frame before the fold.
        still = self._rest_sum is not None and self._fold_rest(img)

        def direct() -> NDArray[np.float32]:
            return flow_motion(img, rest, c, preset=self.preset,
                               suppress_imprint=self.suppress_imprint, coarse=self._coarse)

        if self.anchor == "rest" or still or not is_new_contact(img, rest):
            # No contact (or not asked for): nothing to anchor on.
            self._anchor, self.anchor_index = None, None
            return direct()
        if self._anchor is None or contact_changed(img, self._anchor[0]):
            # A contact appeared, grew or receded: its shading changed, so read it from rest
            # and anchor here.
            motion = direct()
            self._anchor, self.anchor_index = (img.copy(), motion), index
            return motion.copy()
        # Both frames show the contact: the flow follows the imprint and the gel under it.
        anchor, at_anchor = self._anchor
        at = (c + at_anchor).astype(np.float32)
        return (at_anchor + flow_motion(img, anchor, at, preset=self.preset,
                                          coarse=self._coarse)).astype(np.float32)

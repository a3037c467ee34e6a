"""The live node's processing: one tactile image message in, the result messages out.

:class:`TactileProcessor` takes the messages of an image topic one at a time, as a ROS 2
subscription delivers them (``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage``, as the
``rosbags`` message dataclasses :mod:`tacswitch.bags` reads; the node converts rclpy's messages
to them, :mod:`tacswitch.ros.convert`), and returns :class:`Output` items holding the result
messages, built by the bag writer's own builders (:class:`tacswitch.bags.BagSink`), so a live
run publishes exactly what ``--out-bag`` records:

- ``markerless``: ``sensor_msgs/Image`` ``bgr8``, the frame through
  :func:`tacswitch.remove_markers` (``method``);
- ``motion``: ``sensor_msgs/PointCloud2``, every marker's rest position ``x, y`` px and motion
  ``dx, dy`` px from the reference frame (NaN where lost) and ``valid``: tracked markers
  (:class:`tacswitch.MarkerTracker`, ``motion="markers"``) or the motion of a markerless
  sensor's frames (:class:`tacswitch.MarkerlessTracker` from the reference frame, the
  no-contact frame, ``motion="markerless"``);
- ``slip``: ``diagnostic_msgs/DiagnosticArray``, :class:`tacswitch.GraspSlipDetector` on that
  motion (``rule``, thresholds).

Every result message carries the input message's header (stamp and frame_id).

The reference frame (``reference``):

- ``"first"``: the first usable frame. With markers, the first ``look_ahead`` readable frames
  are held and the reference is the first of them, after the camera settled (exposure still
  changing, stale frames ended by a jump: :func:`tacswitch.tracking.settled_index`), showing
  at least half the most markers any of them shows (a blank frame while the camera settles,
  or a blurred one, is skipped): the
  rule of ``tacswitch slip`` and ``track`` (:mod:`tacswitch.cli.rest_frame`), applied to
  frames pushed one at a time, since a subscription cannot be read ahead and replayed, and a
  library module does not import the CLI. The held frames are then processed at once, so the
  motion and slip of the first ``look_ahead`` frames come out together, late by up to
  ``look_ahead`` frames (one second at 30 frames/s; ``look_ahead=1``: no delay, the first
  frame showing a marker). With ``motion="markerless"`` the first readable frame.
- ``"frame"``: readable frame ``reference_frame`` (0-based, counted from the start or the
  last reset); with markers, the first from there that shows a marker.
- ``"service"``: none until :meth:`TactileProcessor.recapture` (the node's ``~/recapture``
  service) is called.

:meth:`~TactileProcessor.recapture` works in every mode: the next readable frame (with
markers: the next showing a marker) becomes the reference and the slip detector restarts.
Frames before the reference get a markerless image but no motion or slip.

What the stream may do:

- a compressed message that does not decode: no output, counted (``stats["undecodable"]``);
- a frame size change (a reconfigured camera): a reset, with a warning: the reference is
  dropped and captured again as ``reference`` says (with ``"service"``: wait for a recapture),
  since motion against a reference of another size means nothing;
- header stamps going back (a bag played in a loop, a restarted driver): a reset, as above;
- dropped frames: processing goes on; a gap above 1.5 times the median of the last frame
  intervals is counted (``stats["dropped"]``, the frames missing). The marker tracker's
  per-frame gate is half the marker pitch, so a fast press across a gap may lose markers for
  a frame or two (it re-acquires them); the learned slip rule reads motion per frame and was
  trained at camera rate.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tacswitch.bags import (
    COMPRESSED_TYPE,
    IMAGE_TYPE,
    IMAGE_TYPES,
    MARKERLESS,
    MOTION,
    SLIP,
    BagFrame,
    BagSink,
    decode_image,
    header_stamp_ns,
)
from tacswitch.grasp.timebase import check_fps, fps_from_intervals
from tacswitch.motion.sequence import ANCHORS
from tacswitch.tracking import (
    REST_LOOK_AHEAD,
    REST_USABLE_FRACTION,
    lattice_irregularity,
    rest_thumbnail,
    settled_index,
    usable_rest_frame,
)

MOTION_MODES = ("markers", "markerless")
REFERENCE_MODES = ("first", "frame", "service")
RULES = ("learned", "paper")
#: ``ProcessorConfig.anchor``: ``"auto"`` and :data:`tacswitch.motion.sequence.ANCHORS`.
ANCHOR_MODES = ("auto", *ANCHORS)
REMOVAL_METHODS = ("telea", "biharmonic", "ns", "tacdiff", "hybrid")
OUTPUTS = ("markerless", "motion", "slip")
#: The rest-frame rule of ``tacswitch track`` / ``slip``
#: (:func:`tacswitch.tracking.usable_rest_frame`).
LOOK_AHEAD = REST_LOOK_AHEAD
USABLE_FRACTION = REST_USABLE_FRACTION
#: The paper rule's moving average on a markerless sensor (as ``tacswitch slip --markerless``).
MARKERLESS_SMOOTH_FRAMES = 2
#: A stamp gap above this many median frame intervals counts as dropped frames.
GAP_FACTOR = 1.5
#: Frame intervals the median is taken over.
INTERVALS = 30

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ProcessorConfig:
    """The processor's parameters (the node's ROS parameters have the same names).

    Attributes:
        motion: ``"markers"`` (track the markers) or ``"markerless"`` (a markerless sensor:
            :class:`tacswitch.MarkerlessTracker` from the reference frame; with the learned
            ``slip`` output, without its imprint suppression, as the markerless slip scorer
            was trained).
        method: marker removal for the ``markerless`` output (:func:`tacswitch.remove_markers`).
        anchor: ``motion="markerless"``: :class:`tacswitch.MarkerlessTracker`'s ``anchor``,
            ``"contact"`` (a steady contact read from the frame where it settled) or ``"rest"``
            (the flow from the reference frame on every frame); ``"auto"`` (default):
            ``"rest"`` with the ``slip`` output (what the slip rules read), else
            ``"contact"``.
        rest_frames: ``motion="markerless"``: :class:`tacswitch.MarkerlessTracker`'s
            ``rest_frames``, how many frames (the reference included) the reference frame may
            average: the still frames after it, until anything changes, to average a noisy
            camera's noise out (1, default: the frame as given; not with the ``slip`` output,
            whose figures were measured from the frame as given).
        reference: ``"first"``, ``"frame"`` or ``"service"`` (module doc).
        reference_frame: ``reference="frame"``: the readable frame (0-based).
        look_ahead: ``reference="first"`` with markers: frames held to choose it (1-300).
        rule: the slip rule, ``"learned"`` or ``"paper"``.
        score_threshold: learned rule: logit above which a committee member fires (None: the
            model's).
        fps: learned rule: the camera's frame rate, frames/s (None: the rate the header stamps
            showed before the reference, else the scorer's; above 1.25x the scorer's rate the
            motion is resampled to it, :class:`tacswitch.GraspSlipDetector`).
        threshold_px: paper rule: displacement threshold, px (None: 3.25 px at 640 wide,
            scaled to the frame width).
        outputs: which results to publish, a subset of ``("markerless", "motion", "slip")``.
        device: ``"auto"``, ``"cpu"`` or ``"cuda"`` for the model methods (``tacdiff``,
            ``hybrid``).
    """

    motion: str = "markers"
    method: str = "telea"
    anchor: str = "auto"
    rest_frames: int = 1
    reference: str = "first"
    reference_frame: int = 0
    look_ahead: int = LOOK_AHEAD
    rule: str = "learned"
    score_threshold: float | None = None
    fps: float | None = None
    threshold_px: float | None = None
    outputs: tuple[str, ...] = OUTPUTS
    device: str = "auto"

    def __post_init__(self) -> None:
        def one_of(name: str, value: Any, allowed: tuple[str, ...]) -> None:
            if value not in allowed:
                raise ValueError(f"{name}: one of {', '.join(allowed)}; got {value!r}")

        one_of("motion", self.motion, MOTION_MODES)
        one_of("method", self.method, REMOVAL_METHODS)
        one_of("reference", self.reference, REFERENCE_MODES)
        one_of("rule", self.rule, RULES)
        one_of("anchor", self.anchor, ANCHOR_MODES)
        if self.anchor != "auto" and self.motion != "markerless":
            raise ValueError("anchor: applies to motion 'markerless' only")
        one_of("device", self.device, ("auto", "cpu", "cuda"))
        _integer("reference_frame", self.reference_frame, 0, 1_000_000)
        _integer("look_ahead", self.look_ahead, 1, 300)
        _integer("rest_frames", self.rest_frames, 1, 1000)
        if self.rest_frames != 1 and self.motion != "markerless":
            raise ValueError("rest_frames: applies to motion 'markerless' only")
        outs = self.outputs
        if isinstance(outs, str) or not all(isinstance(o, str) for o in outs):
            raise ValueError(f"outputs: a list of names from {', '.join(OUTPUTS)}; got {outs!r}")
        for o in outs:
            one_of("outputs", o, OUTPUTS)
        if not outs:
            raise ValueError(f"outputs: name at least one of {', '.join(OUTPUTS)}")
        object.__setattr__(self, "outputs", tuple(dict.fromkeys(outs)))
        if self.anchor == "contact" and "slip" in self.outputs:
            raise ValueError("anchor: the slip output reads the motion from the reference on "
                             "every frame (anchor 'rest'); use 'auto' or 'rest', or drop slip "
                             "from outputs")
        if self.rest_frames != 1 and "slip" in self.outputs:
            raise ValueError("rest_frames: the slip output reads the motion from the reference "
                             "frame as given (1); drop slip from outputs or set 1")
        if self.score_threshold is not None:
            if self.rule != "learned":
                raise ValueError("score_threshold: applies to rule 'learned' only")
            if not _real(self.score_threshold) or not math.isfinite(self.score_threshold):
                raise ValueError(f"score_threshold: must be a finite number; "
                                 f"got {self.score_threshold!r}")
        if self.fps is not None:
            if self.rule != "learned":
                raise ValueError("fps: applies to rule 'learned' only")
            try:
                check_fps(self.fps)
            except TypeError as exc:  # the config's errors are all ValueErrors
                raise ValueError(str(exc)) from None
        if self.threshold_px is not None:
            if self.rule != "paper":
                raise ValueError("threshold_px: applies to rule 'paper' only")
            if not _real(self.threshold_px) or not self.threshold_px > 0 \
                    or not math.isfinite(self.threshold_px):
                raise ValueError(f"threshold_px: must be > 0 px; got {self.threshold_px!r}")
        if self.reference != "frame" and self.reference_frame != 0:
            raise ValueError("reference_frame: applies to reference 'frame' only")


def _real(v: Any) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


def _integer(name: str, v: Any, lo: int, hi: int) -> None:
    if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or not lo <= v <= hi:
        raise ValueError(f"{name}: an integer in [{lo}, {hi}]; got {v!r}")


@dataclass(frozen=True)
class Output:
    """One result message.

    Attributes:
        name: ``"markerless"``, ``"motion"`` or ``"slip"``.
        suffix: its topic under the image topic (``markerless``, ``marker_motion``, ``slip``:
            the bag writer's).
        msgtype: ``sensor_msgs/msg/Image``, ``sensor_msgs/msg/PointCloud2`` or
            ``diagnostic_msgs/msg/DiagnosticArray``.
        msg: the ``rosbags`` message dataclass (ROS 2 Humble definitions).
        stamp_ns: the input frame's header stamp, ns (the message's own header stamp).
    """

    name: str
    suffix: str
    msgtype: str
    msg: Any
    stamp_ns: int


_NAMES = {MARKERLESS: "markerless", MOTION: "motion", SLIP: "slip"}


class _Builder(BagSink):
    """The bag writer's message builders (:meth:`BagSink.image`, :meth:`~BagSink.points`,
    :meth:`~BagSink.slip`) without a bag: what they would write is collected instead, so the
    node publishes the very messages ``--out-bag`` records."""

    def __init__(self, store: Any) -> None:  # no bag is opened: BagSink.__init__ is not run
        self.store, self.kind, self.topic = store, "ros2", ""
        self.built: list[Output] = []

    def _write(self, suffix: str, msgtype: str, msg: Any, at: BagFrame) -> None:
        self.built.append(Output(_NAMES[suffix], suffix, msgtype, msg, at.stamp_ns))

    def take(self) -> list[Output]:
        out, self.built = self.built, []
        return out


@dataclass
class _Held:
    """A frame held for the look-ahead: the frame, where it came from, its marker count and
    the lattice's irregularity (:func:`tacswitch.tracking.lattice_irregularity`)."""

    frame: NDArray[np.uint8]
    at: BagFrame
    markers: int = 0
    irregularity: float = float("nan")


@dataclass
class _Stats:
    frames: int = 0
    undecodable: int = 0
    dropped: int = 0
    resets: int = 0
    before_reference: int = 0
    intervals: list[int] = field(default_factory=list)


class TactileProcessor:
    """One image message in, its result messages out (module doc).

    Args:
        config: the parameters (:class:`ProcessorConfig`); or give them as keywords.
        warn: where warnings go (a size change, a reset, no markers on a reference); default
            this module's logger. The node passes its ROS logger.
        slip_model: the learned rule's scorer (a path or a callable, as
            :class:`tacswitch.GraspSlipDetector` takes ``model``); default the shipped one
            for the motion mode.
        **params: :class:`ProcessorConfig` fields, when ``config`` is not given.

    Raises:
        ValueError: a bad parameter (one line naming it).
        ImportError: ``rosbags`` is missing (names ``pip install "tacswitch[ros]"``).
    """

    def __init__(self, config: ProcessorConfig | None = None, *,
                 warn: Callable[[str], None] | None = None, slip_model: Any = None,
                 **params: Any) -> None:
        if config is not None and params:
            raise TypeError("TactileProcessor: give config or keyword parameters, not both")
        if config is None:
            known = {f.name for f in fields(ProcessorConfig)}
            unknown = sorted(set(params) - known)
            if unknown:
                raise ValueError(f"{unknown[0]}: not a parameter; the parameters are "
                                 f"{', '.join(sorted(known))}")
            if "outputs" in params and not isinstance(params["outputs"], str):
                params["outputs"] = tuple(params["outputs"])
            config = ProcessorConfig(**params)
        self.config = config
        self.warn = warn or log.warning
        self.slip_model = slip_model
        try:
            from rosbags.typesys import Stores, get_typestore
        except ImportError:
            from tacswitch.bags import INSTALL_HINT

            raise ImportError("tacswitch.ros: the result messages need the rosbags package: "
                              f"{INSTALL_HINT}") from None
        self._builder = _Builder(get_typestore(Stores.ROS2_HUMBLE))
        #: The ``rosbags`` type store of the messages (ROS 2 Humble definitions).
        self.store = self._builder.store
        self._stats = _Stats()
        self._last_stamp: int | None = None
        self._start()

    # --- state -------------------------------------------------------------------------------

    def _start(self) -> None:
        """Forgets the reference and the frame size (the start of a stream, or a reset)."""
        self.tracker: Any = None
        self.detector: Any = None
        self.reference_stamp_ns: int | None = None
        self._shape: tuple[int, ...] | None = None
        self._held: list[_Held] = []
        self._readable = 0  # readable frames since the start or the last reset
        self._recapture = False

    def recapture(self) -> None:
        """The next readable frame (with markers: the next that shows one) becomes the
        reference; the motion and the slip detector start again from it."""
        self._recapture = True

    def reset(self, why: str | None = None) -> None:
        """Drops the reference and the frame size; it is captured again as ``reference``
        says. ``why``: warned, with what happens next."""
        self._stats.resets += 1
        if why:
            again = ("waiting for a recapture" if self.config.reference == "service"
                     else f"capturing it again ({self.config.reference!r})")
            self.warn(f"tacswitch: {why}: reference dropped, {again}")
        self._start()

    @property
    def stats(self) -> dict[str, int]:
        """Counts since construction: ``frames`` (messages), ``undecodable``, ``dropped``
        (frames missing from stamp gaps), ``resets``, ``before_reference`` (readable frames
        with no motion or slip)."""
        s = self._stats
        return {"frames": s.frames, "undecodable": s.undecodable, "dropped": s.dropped,
                "resets": s.resets, "before_reference": s.before_reference}

    @property
    def waiting(self) -> bool:
        """Whether motion and slip are waiting for a reference frame."""
        return self.tracker is None

    # --- processing --------------------------------------------------------------------------

    def process(self, msg: Any, msgtype: str | None = None) -> list[Output]:
        """Processes one image message; returns the result messages it completes, in order
        (usually this frame's; after a look-ahead, those of every frame held).

        Args:
            msg: a ``sensor_msgs/Image`` or ``CompressedImage`` message (a ``rosbags``
                dataclass, or anything with the same fields).
            msgtype: ``sensor_msgs/msg/Image`` or ``sensor_msgs/msg/CompressedImage``;
                default the message's own ``__msgtype__``.

        Raises:
            ValueError: an encoding tacswitch does not read, or a message that does not
                hold its pixels (one line naming ``msg``).
        """
        kind = msgtype or getattr(msg, "__msgtype__", None)
        if kind not in IMAGE_TYPES:
            raise ValueError(f"msgtype: one of {IMAGE_TYPE}, {COMPRESSED_TYPE}; got {kind!r}")
        self._stats.frames += 1
        frame = decode_image(msg, kind, "msg")
        if frame is None:
            self._stats.undecodable += 1
            return []
        stamp = header_stamp_ns(msg)
        self._check_time(stamp)
        at = BagFrame(stamp, stamp, msg.header)
        if self._shape is not None and frame.shape != self._shape:
            old, new = self._shape, frame.shape
            self.reset(f"frame size changed from {old[1]}x{old[0]} to {new[1]}x{new[0]}")
        self._shape = frame.shape
        if "markerless" in self.config.outputs:
            img = _remove(frame, self.config)
            self._builder.image(at, img)
        self._readable += 1
        if self.tracker is not None and not self._recapture:
            self._step(frame, at)
        else:
            self._wait(frame, at)
        return self._builder.take()

    def flush(self) -> list[Output]:
        """Chooses the reference among the frames held for the look-ahead now (the end of a
        recording shorter than it) and returns their results."""
        if self._held:
            self._choose()
        return self._builder.take()

    def stamp_fps(self) -> float | None:
        """The stream's frame rate (frames/s) from the header stamps' typical interval so far;
        None before 5 intervals (dropped frames do not count)."""
        return fps_from_intervals(self._stats.intervals)

    def _check_time(self, stamp: int) -> None:
        s = self._stats
        last, self._last_stamp = self._last_stamp, stamp
        if last is None:
            return
        if stamp < last:
            s.intervals.clear()
            self.reset(f"header stamps went back by {(last - stamp) / 1e9:.3f} s")
            return
        gap = stamp - last
        if gap <= 0:
            return  # an unset or repeated stamp: no timing to judge
        if len(s.intervals) >= 5:
            typical = float(np.median(s.intervals))
            if gap > GAP_FACTOR * typical:
                s.dropped += max(round(gap / typical) - 1, 1)
                return  # a gap is not a frame interval
        s.intervals.append(gap)
        del s.intervals[:-INTERVALS]

    def _wait(self, frame: NDArray[np.uint8], at: BagFrame) -> None:
        """A frame while there is no reference (or a recapture is asked for)."""
        cfg = self.config
        markers = cfg.motion == "markers"
        if self._recapture or (cfg.reference == "frame" and self._readable > cfg.reference_frame):
            if markers and _count(frame) == 0:
                self._stats.before_reference += 1
                self.warn(f"tacswitch: frame at {at.stamp_ns} ns shows no markers; the "
                          "reference is the next frame that does")
                return
            self._begin(frame, at)
            return
        if cfg.reference == "first":
            if not markers or cfg.look_ahead == 1:
                if not markers or _count(frame) > 0:
                    self._begin(frame, at)
                    return
                self._stats.before_reference += 1
                return
            centres = _centres(frame)
            self._held.append(_Held(frame, at, len(centres), lattice_irregularity(centres)))
            if len(self._held) >= cfg.look_ahead:
                self._choose()
            return
        self._stats.before_reference += 1

    def _choose(self) -> None:
        """The reference among the frames held: the first showing at least
        :data:`USABLE_FRACTION` of the most markers any of them shows (module doc)."""
        held, self._held = self._held, []
        settled = settled_index([rest_thumbnail(h.frame) for h in held],
                                [h.irregularity for h in held])
        index = usable_rest_frame([h.markers for h in held], USABLE_FRACTION, settled)
        if index is None:
            self._stats.before_reference += len(held)
            self.warn(f"tacswitch: none of {len(held)} frames shows a marker (a blank or "
                      "markerless stream? set motion to 'markerless'); looking again")
            return
        best = max(h.markers for h in held)
        if index and 0 < settled <= index:
            self.warn(f"tacswitch: frames before {settled} come before the camera settled "
                      "(exposure changing, or frames left from before: a jump of the whole "
                      f"image, or a deformed gel relaxing), so frame {index} "
                      f"of the first {len(held)} is the reference ({held[index].markers} "
                      "markers); frames before it get no motion or slip")
        elif index:
            self.warn(f"tacswitch: frame 0 shows {held[0].markers} markers, so frame {index} "
                      f"of the first {len(held)} is the reference ({held[index].markers}; the "
                      f"most is {best}); frames before it get no motion or slip")
        self._stats.before_reference += index
        self._begin(held[index].frame, held[index].at)
        for h in held[index + 1:]:
            self._step(h.frame, h.at)

    def _begin(self, frame: NDArray[np.uint8], at: BagFrame) -> None:
        """Makes ``frame`` the reference and processes it (its motion: zero)."""
        from tacswitch.grasp.detector import SCORER_FLOW_PRESET, GraspSlipDetector
        from tacswitch.motion.sequence import MarkerlessTracker
        from tacswitch.tracking import MarkerTracker

        cfg = self.config
        self._recapture = False
        self._held = []
        if cfg.motion == "markers":
            self.tracker = MarkerTracker(frame)
            points = self.tracker.reference
        else:
            # The learned markerless scorer was trained on the plain flow of one preset: keep
            # its inputs so. Slip (either rule) reads the flow from rest on every frame: the
            # contact anchor follows an object that slides over the gel.
            scorer = "slip" in cfg.outputs and cfg.rule == "learned"
            anchor = cfg.anchor if cfg.anchor != "auto" else (
                "rest" if "slip" in cfg.outputs else "contact")
            # ... and with the frame-to-frame weight its file records.
            weight = 0.0
            if scorer:
                from tacswitch.grasp.detector import scorer_frame_to_frame

                weight = scorer_frame_to_frame(self.slip_model or "markerless")
            self.tracker = MarkerlessTracker(
                frame, suppress_imprint=not scorer,
                preset=SCORER_FLOW_PRESET if scorer else None, anchor=anchor,
                rest_frames=cfg.rest_frames, frame_to_frame=weight)
            points = self.tracker.centres
        self.points = np.asarray(points, np.float32)
        self.detector = None
        if "slip" in cfg.outputs:
            if cfg.rule == "learned":
                model = self.slip_model or ("markers" if cfg.motion == "markers"
                                            else "markerless")
                # Unset: the rate the header stamps have shown so far (None: the scorer's).
                fps = cfg.fps if cfg.fps is not None else self.stamp_fps()
                self.detector = GraspSlipDetector(self.points, image_width=frame.shape[1],
                                                     model=model,
                                                     threshold=cfg.score_threshold, fps=fps)
            else:
                smooth = 1 if cfg.motion == "markers" else MARKERLESS_SMOOTH_FRAMES
                self.detector = GraspSlipDetector(self.points, image_width=frame.shape[1],
                                                     rule="paper",
                                                     threshold_px=cfg.threshold_px,
                                                     smooth_frames=smooth)
        self.reference_stamp_ns = at.stamp_ns
        self._step(frame, at)

    def _step(self, frame: NDArray[np.uint8], at: BagFrame) -> None:
        """Motion (and slip) of one frame against the reference."""
        if self.config.motion == "markers":
            motion, valid = self.tracker.update(frame)
        else:
            motion = self.tracker.update(frame)
            valid = np.ones(len(motion), bool)
        motion = np.asarray(motion, np.float32)
        valid = np.asarray(valid, bool)
        if "motion" in self.config.outputs:
            self._builder.points(at, motion_fields(self.points, motion, valid))
        if self.detector is not None:
            st = self.detector.update(motion, valid)
            self._builder.slip(at, bool(st.slip), str(st.phase), float(st.score))


def motion_fields(points: Any, motion: Any, valid: Any) -> dict[str, NDArray[np.float32]]:
    """The ``PointCloud2`` fields of a motion field: rest ``x, y`` px, ``dx, dy`` px (NaN
    where not ``valid``) and ``valid`` (the fields ``--out-bag`` writes; the CLI's helper
    lives in the CLI layer, which a library module does not import)."""
    pts = np.asarray(points, np.float32).reshape(-1, 2)
    mot = np.asarray(motion, np.float32).reshape(-1, 2)
    ok = np.asarray(valid, bool)
    return {"x": pts[:, 0], "y": pts[:, 1], "dx": np.where(ok, mot[:, 0], np.nan),
            "dy": np.where(ok, mot[:, 1], np.nan), "valid": ok.astype(np.float32)}


def _centres(frame: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Centres ``N x 2`` of the markers found on a frame (the default extraction, as the
    trackers use)."""
    from tacswitch.markers import extract_markers

    return np.asarray(extract_markers(frame).centres, np.float32)


def _count(frame: NDArray[np.uint8]) -> int:
    """Markers found on a frame (the default extraction, as the trackers use)."""
    return len(_centres(frame))


def _remove(frame: NDArray[np.uint8], cfg: ProcessorConfig) -> NDArray[np.uint8]:
    # remove_markers moves from tacswitch.inpaint to tacswitch.removal with issue 33's
    # one-way imports (a module below the front door imports the module defining a name).
    try:
        from tacswitch.removal import remove_markers  # type: ignore[import-not-found, unused-ignore]
    except ImportError:
        from tacswitch.inpaint import remove_markers  # type: ignore[attr-defined, no-redef, unused-ignore]

    method: Any = cfg.method  # checked against REMOVAL_METHODS by ProcessorConfig
    if method in ("tacdiff", "hybrid"):
        return remove_markers(frame, method=method, device=cfg.device)
    return remove_markers(frame, method=method)


def process_all(processor: TactileProcessor, messages: Iterable[Any]) -> list[Output]:
    """Every message through ``processor``, then :meth:`~TactileProcessor.flush`: the
    outputs in order (for recordings and tests)."""
    out: list[Output] = []
    for msg in messages:
        out += processor.process(msg)
    return out + processor.flush()


"""One rendered contact: paired marker/markerless images with exact ground truth.

A :class:`Scene` fixes everything that does not change during a grasp (sensor background, the
painted marker grid with its flaws, dust, the object and the camera's noise level);
:meth:`Scene.render` renders one frame for an object pose and load. :func:`render_sample` draws a
random scene and load and renders it once.

Pipeline of a frame: object surface -> gel deformation (:mod:`~tacswitch.sim.deform`) -> colour
(:mod:`~tacswitch.sim.optics`, real Taxim tables or Phong) -> marker motion (elastic fields,
:mod:`~tacswitch.sim.motion`) -> the gel-attached layer (coating grain with the real grain's
contrast and spectrum, dust and fibres; :mod:`~tacswitch.sim.grain`) carried by the same
displacement field as the markers -> markers painted as transmittance (:func:`marker_layer`) ->
the same camera noise added to both images. Hence ``I_w == I_wo`` wherever ``marker_mask`` is
False.

``appearance="random"`` draws the look of a different sensor for every scene (exposure, white
balance, shading strength, illumination gradient, the gel background, camera noise): real sensors
differ far more than the presets.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import NDArray

from tacswitch._checks import as_jpeg_quality
from tacswitch.sim import deform
from tacswitch.sim.deform import deform_gel
from tacswitch.sim.grain import (
    GRAIN_STD_RANGE,
    REAL_RADIAL_PSD,
    dense_field,
    grain_texture,
    warp_layer,
)
from tacswitch.sim.indenters import CLASSES, ObjectSpec, depth_range, random_object
from tacswitch.sim.markers import gel_background, marker_layer
from tacswitch.sim.motion import contact_displacement, sample_field
from tacswitch.sim.optics import (
    CALIBRATIONS,
    Calibration,
    background_image,
    load_calibration,
    shade_phong,
    shade_taxim,
)
from tacswitch.sim.presets import SensorPreset, as_preset

Optics = Literal["auto", "taxim", "phong"]
Appearance = Literal["preset", "random"]

#: Marker grids (rows, cols) a scene may draw with ``vary_grid=True``: 6x8 to 10x14.
GRIDS: tuple[tuple[int, int], ...] = ((6, 8), (7, 9), (8, 10), (9, 11), (10, 14))
#: Camera temporal noise, grey levels per channel (real sensors: 1.3-2.1).
NOISE_SIGMA_RANGE = (1.3, 2.1)
#: ... with ``appearance="random"``: taxim's real presses have 0.7-1.4 (FOTS Mini frames more).
RANDOM_NOISE_SIGMA_RANGE = (0.6, 1.8)
#: Background blur, mm: removes the real background frame's own grain (fixed in that frame, not
#: attached to the simulated gel); the moving grain layer replaces it.
BACKGROUND_DEGRAIN_MM = 0.09
#: Transmittance at a marker's centre (real dots keep 0.25-0.30 of the background).
CENTRE_TRANSMITTANCE = (0.22, 0.32)
#: Principal stretches a marker may take from the gel's local strain.
STRAIN_LIMITS = (0.8, 1.3)


@dataclass
class Frame:
    """One rendered frame. Images are uint8 BGR ``H x W x 3``; masks ``H x W`` bool.

    Attributes:
        image: markerless image ``I_wo``.
        image_markers: the same contact and noise with markers ``I_w``.
        marker_mask: True where a marker (or its soft edge) changes the image.
        contact_mask: True where the object touches the gel.
        displacement: ``N x 2`` true marker displacement ``(dx, dy)`` px from ``Scene.rest``.
        stick_fraction: stuck share of the contact area (1 = all stuck, 0 = sliding).
    """

    image: NDArray[np.uint8]
    image_markers: NDArray[np.uint8]
    marker_mask: NDArray[np.bool_]
    contact_mask: NDArray[np.bool_]
    displacement: NDArray[np.float32]
    stick_fraction: float
    #: ``H x W x 2`` lateral displacement (dx, dy) px of the gel point at rest at each pixel
    #: (what moves the markers and the gel-attached grain and dust).
    field: NDArray[np.float32] | None = None


@dataclass
class Sample(Frame):
    """A :class:`Frame` with its scene's reference and labels (one dataset sample).

    Attributes:
        reference: no-contact frame with markers at rest (its own noise draw).
        rest: ``N x 2`` marker centres at rest ``(x, y)`` px.
        present: ``N`` bool, False for a marker missing from the painting.
        merged: ``N`` bool, True for a marker painted with a touching satellite blob.
        label: object class (one of :data:`~tacswitch.sim.indenters.CLASSES`).
        params: sensor, scene and load parameters (JSON-serialisable).
    """

    reference: NDArray[np.uint8] = field(default_factory=lambda: np.zeros(0, np.uint8))
    rest: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    present: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    merged: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    label: str = "none"
    params: dict[str, Any] = field(default_factory=dict)


def _as_rng(seed: int | np.random.Generator | np.random.SeedSequence | None
            ) -> np.random.Generator:
    from tacswitch._checks import as_rng

    return as_rng(seed, "seed")


class Scene:
    """Sensor, markers, dirt, object and camera of one contact (see the module docstring).

    Args:
        preset: sensor preset or its name.
        seed: randomness of the scene.
        label: object class; random (uniform over :data:`CLASSES`) if None.
        optics: ``"taxim"`` (real calibration; needs ``preset.calib``), ``"phong"``, or
            ``"auto"`` (Taxim when the preset has a calibration).
        vary_grid: draw the marker grid from :data:`GRIDS` (pitch fitted to the frame) instead of
            the preset's.
        jpeg_quality: JPEG-compress frames at this quality (None: lossless).
        appearance: ``"preset"`` (the calibration's look) or ``"random"`` (see the module
            docstring).
        grain: render the gel-attached grain (False: only dust and fibres, as before it).
    """

    def __init__(self, preset: str | SensorPreset = "gelsight", seed: Any = None, *,
                 label: str | None = None, optics: Optics = "auto", vary_grid: bool = False,
                 jpeg_quality: int | None = None, appearance: Appearance = "preset",
                 grain: bool = True) -> None:
        p = as_preset(preset)
        rng = _as_rng(seed)
        jpeg_quality = as_jpeg_quality(jpeg_quality)
        self.preset = p
        h, w = p.height, p.width
        if optics not in ("auto", "taxim", "phong"):
            raise ValueError(f"optics: must be 'auto', 'taxim' or 'phong'; got {optics!r}")
        if appearance not in ("preset", "random"):
            raise ValueError(f"appearance: must be 'preset' or 'random'; got {appearance!r}")
        if optics == "taxim" and p.calib is None:
            raise ValueError(f"optics: preset {p.name!r} has no Taxim calibration; use 'phong'")
        self.optics = "taxim" if (optics != "phong" and p.calib is not None) else "phong"
        if self.optics == "taxim":
            assert p.calib is not None
            self.calib: Calibration | None = load_calibration(p.calib)
            self.background = background_image(self.calib, h, w)
        else:
            self.calib = None
            self.background = gel_background(h, w, seed=rng, base=(150.0, 150.0, 150.0))
        # --- marker grid -----------------------------------------------------------------
        rows, cols, pitch = p.rows, p.cols, p.pitch
        if vary_grid:
            rows, cols = GRIDS[int(rng.integers(len(GRIDS)))]
            pitch = float(min(0.92 * w / cols, 0.92 * h / rows))
        diam0 = p.diameter * pitch / p.pitch
        xs = (w - 1) / 2 + (np.arange(cols) - (cols - 1) / 2) * pitch
        ys = (h - 1) / 2 + (np.arange(rows) - (rows - 1) / 2) * pitch
        gx, gy = np.meshgrid(xs, ys)
        n = rows * cols
        rest = np.stack([gx.ravel(), gy.ravel()], 1) + rng.normal(0, rng.uniform(0.2, 0.6), (n, 2))
        self.rows, self.cols, self.pitch = rows, cols, pitch
        self.rest = rest.astype(np.float32)
        self.diameters = diam0 * rng.normal(1.0, 0.06, n).clip(0.85, 1.15)
        # Painted dots are slightly elliptical at random orientations.
        asp = rng.uniform(1.0, 1.12, n)
        th = rng.uniform(0, np.pi, n)
        c, s = np.cos(th), np.sin(th)
        rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
        self.shapes = rot @ (np.eye(2) * np.stack([asp, 1 / asp], -1)[:, None, :])
        base_dark = 1.0 - rng.uniform(*CENTRE_TRANSMITTANCE)
        self.darkness = (base_dark + rng.normal(0, 0.02, n)).clip(0.6, 0.85)
        self.edge_px = float(rng.uniform(2.0, 3.0)) * min(1.0, pitch / 28.5 + 0.3)
        self.present = rng.random(n) > 0.01
        self.merged = (rng.random(n) < 0.01) & self.present
        ang = rng.uniform(0, 2 * np.pi, n)
        self.satellite = (0.55 * self.diameters)[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
        # --- dust and fibres on the gel (seen in both images: they are not markers) ---------
        self.dirt = self._dirt(h, w, rng)
        # --- object and load --------------------------------------------------------------
        self.label = label if label is not None else CLASSES[int(rng.integers(len(CLASSES)))]
        self.object: ObjectSpec = random_object(self.label, rng)
        self.centre = (float(rng.uniform(0.3, 0.7) * w), float(rng.uniform(0.3, 0.7) * h))
        self.angle = float(rng.uniform(0, np.pi))
        self.depth = float(rng.uniform(*depth_range(self.label)))
        # Press law per preset, measured on real presses (sim.presets: press_dilation / _decay_mm).
        self.dilation = float(rng.uniform(*p.press_dilation))
        self.noise_sigma = rng.uniform(*NOISE_SIGMA_RANGE, 3)
        self.jpeg_quality = jpeg_quality
        self.step = max(2, round(w / 80))
        # --- drawn last, so the draws above (and existing seeds' scenes) stay as they were ---
        self.appearance = appearance
        self.look = self._draw_look(rng) if appearance == "random" else {}
        if self.look:
            self.noise_sigma = rng.uniform(*RANDOM_NOISE_SIGMA_RANGE, 3)
            self.background = self._look_background(rng)
        if self.calib is not None:
            # The real background frame carries its own gel's grain, fixed in the image.
            self.background = deform.gaussian_blur(
                np.ascontiguousarray(self.background, np.float32),
                BACKGROUND_DEGRAIN_MM / p.mm_per_px)
        self.grain_std = float(rng.uniform(*GRAIN_STD_RANGE)) if grain else 0.0
        self.grain_profile = str(rng.choice(sorted(REAL_RADIAL_PSD)))
        self.grain = grain_texture(h, w, p.mm_per_px, rng, std_grey=self.grain_std,
                                   mean_grey=float(self.background.mean()),
                                   profile=self.grain_profile) if grain else \
            np.zeros((h, w), np.float32)

    @staticmethod
    def _draw_look(rng: np.random.Generator) -> dict[str, Any]:
        """Exposure, white balance, shading gain, illumination gradient of a random sensor."""
        return {"exposure": float(rng.uniform(0.7, 1.3)),
                "white_balance": rng.uniform(0.85, 1.15, 3).tolist(),
                "shade_gain": float(rng.uniform(0.6, 1.4)),
                "gradient": rng.uniform(-0.15, 0.15, 2).tolist(),
                "vignette": float(rng.uniform(0.0, 0.25)),
                "background": str(rng.choice(["own", "own", "other", "synthetic"]))}

    def _look_background(self, rng: np.random.Generator) -> NDArray[np.float32]:
        """The background of a random look: the preset's, another sensor's real one, or a
        synthetic gel; then exposure, white balance and the illumination gradient."""
        h, w = self.preset.height, self.preset.width
        kind = self.look["background"]
        bg = self.background
        if kind == "other" or (kind == "own" and self.calib is None):
            names = [c for c in CALIBRATIONS if self.calib is None or c != self.calib.name]
            bg = background_image(load_calibration(names[int(rng.integers(len(names)))]), h, w)
        elif kind == "synthetic":
            base = tuple(float(v) for v in rng.uniform(80, 190, 3))
            bg = gel_background(h, w, seed=rng, base=base)  # type: ignore[arg-type]
        return np.asarray(bg, np.float32) * self._illumination()

    def _illumination(self) -> NDArray[np.float32]:
        """``H x W x 3`` gain: exposure x white balance x a linear gradient x a vignette."""
        h, w = self.preset.height, self.preset.width
        lk = self.look
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        u, v = (xx - w / 2) / w, (yy - h / 2) / h
        g = 1.0 + lk["gradient"][0] * 2 * u + lk["gradient"][1] * 2 * v \
            - lk["vignette"] * (u * u + v * v) * 2
        wb = np.asarray(lk["white_balance"], np.float32) * lk["exposure"]
        return (g[..., None] * wb).astype(np.float32)

    @staticmethod
    def _dirt(h: int, w: int, rng: np.random.Generator) -> NDArray[np.float32]:
        import cv2

        dirt = np.ones((h, w), np.float32)
        for _ in range(int(rng.poisson(6))):
            x, y = int(rng.integers(w)), int(rng.integers(h))
            cv2.circle(dirt, (x, y), int(rng.integers(0, 2)), float(rng.uniform(0.7, 0.9)), -1,
                       cv2.LINE_AA)
        for _ in range(int(rng.poisson(0.7))):
            n = 6
            pts = np.cumsum(rng.normal(0, 6, (n, 2)), 0) + rng.uniform([0, 0], [w, h])
            cv2.polylines(dirt, [pts.astype(np.int32)], False, float(rng.uniform(0.8, 0.92)), 1,
                          cv2.LINE_AA)
        return cast("NDArray[np.float32]", cv2.GaussianBlur(dirt, (3, 3), 0.6))  # keeps float32

    # ------------------------------------------------------------------------------------
    def render(self, rng: Any = None, *, offset: tuple[float, float] | None = None,
               depth: float | None = None, shear_px: tuple[float, float] = (0.0, 0.0),
               load_ratio: float = 0.5, twist_rad: float = 0.0,
               marker_shear_px: tuple[float, float] | None = None,
               markers: bool = True) -> Frame:
        """Renders one frame.

        Args:
            rng: randomness of the camera noise.
            offset: object displacement from its rest pose ``(dx, dy)`` px; default
                ``shear_px`` (a stuck object carries the gel with it).
            depth: press depth, mm (default the scene's).
            shear_px: displacement of the stuck zone of the gel, px.
            load_ratio: ``Q / (mu P)`` (partial slip; 1 = sliding).
            twist_rad: rotation of the object and of the stuck zone, rad.
            marker_shear_px: override the gel's shear (slip: the markers stay saturated while
                the object moves on by ``offset``).
            markers: paint the markers (False: ``image_markers`` is the markerless image and
                ``marker_mask`` is empty; saves the marker rendering when only ``I_wo`` is
                needed). The noise draws are the same either way.
        """
        import cv2

        rng = _as_rng(rng)
        p = self.preset
        h, w = p.height, p.width
        d = self.depth if depth is None else depth
        off = shear_px if offset is None else offset
        centre = (self.centre[0] + off[0], self.centre[1] + off[1])
        if self.label == "none" or d <= 0:
            z = np.full((h, w), -np.inf, np.float32)
        else:
            z = self.object.surface(h, w, p.mm_per_px, centre, self.angle + twist_rad, d)
        gel, contact = deform_gel(z, p.mm_per_px)
        if self.calib is not None:
            shade = shade_taxim(gel, p.mm_per_px, self.calib)
        else:
            shade = shade_phong(gel, p.mm_per_px)
        if self.look:
            shade = shade * self._illumination() * np.float32(self.look["shade_gain"])
        # --- marker motion on the coarse grid --------------------------------------------
        st = self.step
        gh, gw = -(-h // st), -(-w // st)
        pen = np.where(contact, np.maximum(gel, 0), 0).astype(np.float32)
        pres = cv2.resize(pen, (gw, gh), interpolation=cv2.INTER_AREA)
        gel_c = cv2.resize(gel, (gw, gh), interpolation=cv2.INTER_AREA)
        ms = shear_px if marker_shear_px is None else marker_shear_px
        fld, stick = contact_displacement(
            pres, st, p.mm_per_px, p.gel_thickness_mm, centre=centre, shear_px=ms,
            load_ratio=load_ratio, twist_rad=twist_rad, dilation=self.dilation, gel=gel_c,
            decay_mm=p.press_decay_mm)
        # Coarse cell (i, j) covers pixels [j*st, (j+1)*st): its centre is at (j + 0.5) st - 0.5.
        disp, jac = sample_field(fld, st, self.rest + (0.5 - 0.5 * st))
        # The grain, dust and fibres are on the gel: the same field carries them.
        dense = dense_field(fld, st, h, w)
        layer = warp_layer((1.0 + self.grain) * self.dirt, dense, border=1.0)
        clean = (self.background + shade) * layer[..., None]
        pos = self.rest + disp
        strain = np.eye(2, dtype=np.float32) + jac
        # The coarse field's gradient overstates strain at a contact's rim; painted dots on real
        # gels stretch by tens of percent, not into slivers.
        u, sv, vt = np.linalg.svd(strain)
        strain = (u * np.clip(sv, *STRAIN_LIMITS)[:, None, :]) @ vt
        shapes = strain @ self.shapes
        cen, dia, dark, shp = [pos[self.present]], [self.diameters[self.present]], \
            [self.darkness[self.present]], [shapes[self.present]]
        if self.merged.any():
            sat = pos[self.merged] + np.einsum("nij,nj->ni", strain[self.merged],
                                              self.satellite[self.merged])
            cen.append(sat)
            dia.append(0.8 * self.diameters[self.merged])
            dark.append(self.darkness[self.merged])
            shp.append(shapes[self.merged])
        trans = marker_layer(h, w, np.concatenate(cen), np.concatenate(dia),
                             np.concatenate(dark), edge_px=self.edge_px,
                             shape=np.concatenate(shp)) if markers else \
            np.ones((h, w), np.float32)
        mask = trans < 1.0
        i_wo, i_w = self._camera(clean, trans, mask, rng)
        n_contact = max(int((pres > 0).sum()), 1)
        return Frame(i_wo, i_w, mask, contact, disp.astype(np.float32),
                     float(stick.sum() / n_contact) if (pres > 0).any() else 1.0, dense)

    def _camera(self, clean: NDArray, trans: NDArray, mask: NDArray, rng: np.random.Generator
                ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """The same temporal noise and per-frame offset in both images; JPEG confined so the
        images still differ only under ``mask``."""
        import cv2

        noise = rng.standard_normal(clean.shape, np.float32) * self.noise_sigma.astype(np.float32)
        noise += rng.normal(0, 0.7, 3).astype(np.float32)
        i_wo = np.clip(np.rint(clean + noise), 0, 255).astype(np.uint8)
        i_w = np.clip(np.rint(clean * trans[..., None] + noise), 0, 255).astype(np.uint8)
        if self.jpeg_quality is not None:
            q = [int(cv2.IMWRITE_JPEG_QUALITY), int(self.jpeg_quality)]
            # Decoding a buffer cv2 just encoded cannot fail; IMREAD_COLOR gives uint8 BGR.
            i_wo = cast("NDArray[np.uint8]",
                        cv2.imdecode(cv2.imencode(".jpg", i_wo, q)[1], cv2.IMREAD_COLOR))
            i_w = np.where(mask[..., None],
                           cast("NDArray[np.uint8]",
                                cv2.imdecode(cv2.imencode(".jpg", i_w, q)[1], cv2.IMREAD_COLOR)),
                           i_wo)
        return i_wo, i_w

    def reference(self, rng: Any = None) -> NDArray[np.uint8]:
        """No-contact frame with markers at rest (its own noise draw), uint8 BGR."""
        f = self.render(rng, depth=0.0)
        return f.image_markers

    def describe(self) -> dict[str, Any]:
        """Sensor and scene parameters, JSON-serialisable."""
        p = self.preset
        return {
            "preset": p.name, "height": p.height, "width": p.width, "mm_per_px": p.mm_per_px,
            "optics": self.optics, "grid": [self.rows, self.cols], "pitch": round(self.pitch, 3),
            "marker_diameter": round(float(np.mean(self.diameters)), 3),
            "marker_edge_px": round(self.edge_px, 3),
            "noise_sigma": [round(float(s), 3) for s in self.noise_sigma],
            "jpeg_quality": self.jpeg_quality, "object": self.object.params,
            "centre": [round(c, 3) for c in self.centre], "angle": round(self.angle, 4),
            "depth_mm": round(self.depth, 4), "dilation": round(self.dilation, 4),
            "appearance": self.appearance, "look": self.look,
            "grain_std": round(self.grain_std, 4), "grain_profile": self.grain_profile,
        }


def render_sample(preset: str | SensorPreset = "gelsight", seed: Any = None, *,
                  label: str | None = None, optics: Optics = "auto", vary_grid: bool = False,
                  jpeg_quality: int | None = None, appearance: Appearance = "preset") -> Sample:
    """A random scene under a random load, rendered once (one dataset sample).

    Load: stuck-zone shear up to 0.9 marker pitch in a random direction, load ratio
    ``Q / (mu P)`` in [0, 0.95], twist within +-0.08 rad. Deterministic given ``seed``.
    """
    rng = _as_rng(seed)
    scene = Scene(preset, rng, label=label, optics=optics, vary_grid=vary_grid,
                  jpeg_quality=jpeg_quality, appearance=appearance)
    mag = scene.pitch * rng.uniform(0.0, 0.9) ** 1.5
    ang = rng.uniform(0, 2 * np.pi)
    shear = (float(mag * np.cos(ang)), float(mag * np.sin(ang)))
    load = float(rng.uniform(0.0, 0.95))
    twist = float(rng.uniform(-0.08, 0.08))
    ref = scene.reference(rng)
    f = scene.render(rng, shear_px=shear, load_ratio=load, twist_rad=twist)
    params = scene.describe() | {"shear_px": [round(v, 4) for v in shear], "load_ratio":
                                 round(load, 4), "twist_rad": round(twist, 5),
                                 "stick_fraction": round(f.stick_fraction, 4)}
    return Sample(f.image, f.image_markers, f.marker_mask, f.contact_mask, f.displacement,
                  f.stick_fraction, reference=ref, rest=scene.rest, present=scene.present,
                  merged=scene.merged, label=scene.label, params=params)

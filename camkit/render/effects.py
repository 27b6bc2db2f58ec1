"""Physical effects on top of the geometric render: motion blur, defocus, lateral chromatic
aberration, exposure and the sensor (noise, colour filter mosaic, demosaicing)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camkit._kernels import render as render_kernels
from camkit._validate import as_matrix, as_positive_float, as_positive_int, check_choice
from camkit.errors import ParameterError
from camkit.geometry.pose import Pose
from camkit.lens.base import CameraModel
from camkit.lens.chromatic import LateralChromaticAberration
from camkit.optics.thin_lens import circle_of_confusion
from camkit.render.target import RenderTruth, _render_board, camera_rays, render_target
from camkit.resample.chromatic import apply_chromatic
from camkit.sensor.cfa import PATTERNS, mosaic
from camkit.sensor.demosaic import DEMOSAIC_METHODS, demosaic
from camkit.sensor.noise import EMVA1288Sensor
from camkit.target import Target

__all__ = ["Defocus", "Effects", "Exposure", "Motion", "render_view"]


@dataclass(frozen=True, slots=True, kw_only=True)
class Defocus:
    """Thin-lens defocus: each pixel is blurred by the circle of confusion of the depth it
    sees (``camkit.optics.circle_of_confusion``), converted to pixels with the pixel pitch.
    Metres."""

    focal_length: float
    f_number: float
    focus_distance: float
    pixel_pitch: float

    def __post_init__(self) -> None:
        for name in ("focal_length", "f_number", "focus_distance", "pixel_pitch"):
            object.__setattr__(self, name, as_positive_float(getattr(self, name), name))
        if self.focus_distance <= self.focal_length:
            raise ParameterError("focus_distance: expected more than the focal length")

    def blur_diameter_px(self, depth: np.ndarray) -> np.ndarray:
        """Blur-spot diameter in pixels for camera-frame depths (NaN or <= f -> 0)."""
        ok = np.isfinite(depth) & (depth > self.focal_length)
        d = np.where(ok, depth, self.focus_distance)
        c = circle_of_confusion(self.focal_length, self.f_number, self.focus_distance, d)
        return np.where(ok, np.asarray(c) / self.pixel_pitch, 0.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class Motion:
    """The camera moves during the exposure with constant velocities in its own frame:
    ``cam_from_target(tau) = Pose.from_rvec(w tau, v tau) @ cam_from_target`` for ``tau`` in
    ``[-T/2, T/2]``, averaged over ``samples`` instants (odd, so the middle one is the pose
    the ground truth reports)."""

    linear_velocity: Any = (0.0, 0.0, 0.0)
    angular_velocity: Any = (0.0, 0.0, 0.0)
    exposure_time: float = 0.01
    samples: int = 9

    def __post_init__(self) -> None:
        for name in ("linear_velocity", "angular_velocity"):
            object.__setattr__(self, name, as_matrix(getattr(self, name), (3,), name))
        object.__setattr__(self, "exposure_time", as_positive_float(self.exposure_time, "exposure_time"))
        n = as_positive_int(self.samples, "samples")
        if n % 2 == 0:
            raise ParameterError(
                f"samples: expected an odd number (the middle one is the reported pose), got {n}"
            )
        object.__setattr__(self, "samples", n)

    def poses(self, cam_from_target: Pose) -> list[Pose]:
        taus = (np.arange(self.samples) + 0.5) / self.samples - 0.5
        return [Pose.from_rvec(self.angular_velocity * tau * self.exposure_time,
                               self.linear_velocity * tau * self.exposure_time) @ cam_from_target
                for tau in taus]


@dataclass(frozen=True, slots=True, kw_only=True)
class Exposure:
    """Light reaching the sensor: ``photons = reflectance * photons_at_white`` per pixel and
    colour channel during ``exposure_time`` (see ``camkit.sensor.photons_from_irradiance`` and
    ``camkit.optics.exposure_value`` to derive it from a scene and an aperture)."""

    photons_at_white: float
    exposure_time: float

    def __post_init__(self) -> None:
        for name in ("photons_at_white", "exposure_time"):
            object.__setattr__(self, name, as_positive_float(getattr(self, name), name))


@dataclass(frozen=True, slots=True, kw_only=True)
class Effects:
    """Which effects to apply; every one is off by default (a pure-geometry render).

    ``sensor`` needs ``exposure``. ``cfa`` (a Bayer pattern) puts a colour filter mosaic in
    front of the sensor; ``demosaic`` then names the method, or ``None`` to return the raw
    mosaic. Without ``cfa`` a colour render is a three-layer capture.
    """

    chromatic: LateralChromaticAberration | None = None
    defocus: Defocus | None = None
    motion: Motion | None = None
    exposure: Exposure | None = None
    sensor: EMVA1288Sensor | None = None
    cfa: str | None = None
    demosaic: str | None = "menon"
    colour: bool = field(default=False)

    def __post_init__(self) -> None:
        if self.cfa is not None:
            check_choice(self.cfa, PATTERNS, "cfa")
        if self.demosaic is not None:
            check_choice(self.demosaic, DEMOSAIC_METHODS, "demosaic")
        if self.sensor is not None and self.exposure is None:
            raise ParameterError(
                "sensor: needs exposure (how many photons reach it); give Effects(exposure=...)"
            )

    @property
    def rgb(self) -> bool:
        return self.colour or self.chromatic is not None or self.cfa is not None


def render_view(camera: CameraModel, cam_from_target: Pose, board: Target,
                effects: Effects | None = None, *, rng: np.random.Generator | None = None,
                supersample: int = 16) -> tuple[np.ndarray, RenderTruth]:
    """Render a view of a target (a checkerboard or any registered target) with the chosen
    physical effects, in the order light meets them: motion during the exposure, defocus,
    lateral chromatic aberration, exposure, then the sensor (colour filter mosaic, noise, ADC,
    demosaicing).

    Returns
    -------
    image : ndarray
        Without a sensor: float64 reflectance, (H, W), or (H, W, 3) for colour. With a sensor:
        uint16 digital numbers, (H, W) raw mosaic (``demosaic=None``) or (H, W, 3).
    truth : RenderTruth
        For the pose at the middle of the exposure.
    """
    fx = Effects() if effects is None else effects
    if not isinstance(fx, Effects):
        raise ParameterError(f"effects: expected an Effects, got {type(fx).__name__}")
    if fx.sensor is not None and not isinstance(rng, np.random.Generator):
        raise ParameterError(
            f"rng: expected a numpy.random.Generator (the sensor is noisy), got {type(rng).__name__}"
        )
    if fx.motion is None:
        img, truth = render_target(camera, cam_from_target, board, supersample=supersample)
    else:
        poses = fx.motion.poses(cam_from_target)
        rays = camera_rays(camera)
        acc = None
        for k, pose in enumerate(poses):
            im, tr = _render_board(camera, pose, board, supersample, 0.05, 0.95, 0.5, rays)
            acc = im if acc is None else acc + im
            if k == len(poses) // 2:
                truth = tr
        img = acc / len(poses)
    img3 = np.ascontiguousarray(img[:, :, None])
    if fx.defocus is not None:
        radius = np.ascontiguousarray(fx.defocus.blur_diameter_px(truth.depth) / 2.0)
        out = np.empty_like(img3)
        render_kernels.disc_blur(img3, radius, out)
        img3 = out
    if fx.rgb:
        img3 = np.repeat(img3, 3, axis=2)
    if fx.chromatic is not None:
        img3 = apply_chromatic(img3, fx.chromatic)
    image = img3 if fx.rgb else img3[:, :, 0]
    if fx.exposure is None:
        return image, truth
    # Resampling (chromatic aberration) can overshoot below 0 next to edges; light cannot.
    photons = np.maximum(image, 0.0) * fx.exposure.photons_at_white
    if fx.sensor is None:
        return photons, truth
    t = fx.exposure.exposure_time
    if fx.cfa is not None:
        raw = fx.sensor.simulate(mosaic(photons, fx.cfa), exposure_time=t, rng=rng)
        if fx.demosaic is None:
            return raw, truth
        return demosaic(raw, fx.cfa, fx.demosaic), truth
    return fx.sensor.simulate(photons, exposure_time=t, rng=rng), truth

"""The contract every camera model keeps, and the registry of models by name.

A model is a frozen, slotted, keyword-only dataclass with named parameters. It maps camera
coordinates (x right, y down, z forward) to pixels, and pixels back to unit rays.
Subclasses implement three row kernels on contiguous float64 arrays:

- ``_project_rows(points (N, 3)) -> pixels (N, 2)``, NaN rows where not projectable;
- ``_unproject_rows(pixels (N, 2)) -> rays (N, 3)``, unit rays, NaN where not invertible;
- ``_jacobian_rows(points (N, 3)) -> (pixels, d_pixels_d_points (N, 2, 3),
  d_pixels_d_params (N, 2, n_params))``.

Everything else (validation, broadcasting, depth, field of view, parameters, registry) lives
here once.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any, ClassVar, NamedTuple, Self, TypeVar

import numpy as np

from camkit._registry import Registry
from camkit._validate import (
    as_finite_float,
    as_matrix,
    as_points,
    as_positive_float,
    as_positive_int,
    as_real_array,
)
from camkit.errors import ParameterError, ShapeError

__all__ = [
    "MODELS",
    "CameraModel",
    "FieldOfView",
    "get_model",
    "model_from_params",
    "register_model",
]

MODELS: Registry = Registry("model")  # name -> CameraModel subclass

_M = TypeVar("_M", bound="type[CameraModel]")


def register_model(cls: _M) -> _M:
    """Class decorator: add a model to :data:`MODELS` under its ``name``."""
    return MODELS.register(cls)


def get_model(name: str) -> type[CameraModel]:
    """The model class registered as ``name`` (for example ``"brown-conrady"``)."""
    return MODELS.lookup(name)


def model_from_params(name: str, params: Any, *, width: int, height: int) -> CameraModel:
    """Build the model registered as ``name`` from its parameter vector."""
    return get_model(name).from_params(params, width=width, height=height)


class FieldOfView(NamedTuple):
    """Full angles of view in degrees, from edge to edge through the principal point."""

    horizontal_deg: float
    vertical_deg: float
    diagonal_deg: float


class CameraModel(abc.ABC):
    """Base of every camera model; see the module docstring for the contract.

    Every model has ``fx, fy, cx, cy, skew`` (pixels) and ``width, height`` (pixels), and
    the class attributes ``name``, ``param_names`` and ``param_groups``.
    """

    __slots__ = ()

    name: ClassVar[str]
    param_names: ClassVar[tuple[str, ...]]
    param_groups: ClassVar[dict[str, tuple[str, ...]]]
    #: Parameters calibration holds at their start value unless the caller frees them.
    default_fixed: ClassVar[tuple[str, ...]] = ("skew",)
    #: Parameters a linear least-squares step can start from a pinhole fit (Zhang 2000, eq.
    #: 13: radial terms that multiply the ideal offset by powers of r^2); none by default.
    linear_start_terms: ClassVar[tuple[str, ...]] = ()
    #: True where ``project`` is ``K (x/z, y/z, 1)`` exactly: a resampling map into such a
    #: model is one matrix product per pixel.
    is_pinhole: ClassVar[bool] = False

    fx: float
    fy: float
    cx: float
    cy: float
    skew: float
    width: int
    height: int

    # -- validation ---------------------------------------------------------------------
    def __post_init__(self) -> None:
        set_ = object.__setattr__
        for pname in self.param_names:
            set_(self, pname, as_finite_float(getattr(self, pname), pname))
        for pname in ("fx", "fy"):
            as_positive_float(getattr(self, pname), pname)
        set_(self, "width", as_positive_int(self.width, "width"))
        set_(self, "height", as_positive_int(self.height, "height"))
        self._check()

    def _check(self) -> None:  # noqa: B027 - an optional hook, empty by design
        """Model-specific checks of the parameters; models with constraints override it."""

    # -- parameters ---------------------------------------------------------------------
    def params(self) -> np.ndarray:
        """The parameter vector, in the order of ``param_names``."""
        return np.array([getattr(self, p) for p in self.param_names], dtype=np.float64)

    @classmethod
    def from_params(cls, params: Any, *, width: int, height: int) -> Self:
        """Build a model from a parameter vector in the order of ``param_names``."""
        p = as_real_array(params, "params")
        if p.shape != (len(cls.param_names),):
            raise ShapeError(
                f"params: expected shape ({len(cls.param_names)},) for {cls.name} "
                f"({', '.join(cls.param_names)}), got {p.shape}"
            )
        return cls(**dict(zip(cls.param_names, p.tolist(), strict=True)), width=width, height=height)

    @classmethod
    def held_parameters(cls, fix: Any = (), free: Any = ()) -> tuple[str, ...]:
        """The parameters calibration holds: :attr:`default_fixed`, plus ``fix``, less ``free``.

        ``fix`` and ``free`` take parameter names or group names of the model (``"k3"``,
        ``"tangential"``); a name the model does not have is an error, whatever the model (a
        pinhole has no ``k6``). Returns the held names in the model's parameter order.
        """
        sets = []
        for arg, label in ((fix, "fix"), (free, "free")):
            if arg is None:
                arg = ()
            if isinstance(arg, str) or not all(isinstance(f, str) for f in arg):
                raise ParameterError(f"{label}: expected a tuple of parameter or group names, got {arg!r}")
            unknown = [f for f in arg if f not in cls.param_names and f not in cls.param_groups]
            if unknown:
                raise ParameterError(f"{label}: {unknown} are not parameters of the {cls.name} model; expected "
                                     f"names from {cls.param_names} or groups {tuple(cls.param_groups)}")
            sets.append({cls.param_names[i] for i in cls.param_indices(tuple(arg))} if arg else set())
        both = sets[0] & sets[1]
        if both:
            raise ParameterError(f"fix, free: {sorted(both)} named in both")
        held = (set(cls.default_fixed) | sets[0]) - sets[1]
        return tuple(n for n in cls.param_names if n in held)

    @classmethod
    def start_projection(cls) -> str:
        """The closed-form start calibration uses for this model: ``"perspective"`` (Zhang's,
        from homographies of the pinhole image) or ``"equidistant"`` (``r = f theta``, for
        fisheye lenses whose corners no homography explains)."""
        return "perspective"

    @classmethod
    def initial_guess(cls, K: Any, *, width: int, height: int) -> Self:
        """The model a closed-form start gives: intrinsics from the 3x3 ``K``, every
        distortion parameter at its neutral value."""
        k = as_real_array(K, "K")
        if k.shape != (3, 3):
            raise ShapeError(f"K: expected shape (3, 3), got {k.shape}")
        return cls(fx=float(k[0, 0]), fy=float(k[1, 1]), cx=float(k[0, 2]), cy=float(k[1, 2]),  # type: ignore[call-arg]
                   skew=float(k[0, 1]), width=width, height=height)

    @classmethod
    @abc.abstractmethod
    def example(cls) -> Self:
        """A realistic instance: 1280x960, 4.8 um pixels behind a 4.8 mm lens (fx = 1000 px)
        or a fisheye; what the command line, the demo and the contract tests use."""

    def for_points(self, points_cam: Any) -> Self:
        """This model, for an optimiser's trial evaluations at camera points ``(N, 3)``: a model
        whose valid region must be searched (Brown-Conrady) establishes it only as far out as
        these points reach, a cheaper scan. The model itself is unchanged; the returned one
        serves these points only (a model to keep is built fresh)."""
        as_points(points_cam, 3, "points_cam", finite=False)
        return self

    def map_from_rays(self, M: Any, out: np.ndarray) -> bool:
        """Fill ``out`` (H, W, 2; float32 or float64, C-contiguous) with this model's pixels
        for the rays ``M @ (u, v, 1)`` of every output pixel ``(u, v)``, in one fused kernel,
        and return True; False where the model has no such kernel (a resampling map then
        projects row bands through :meth:`project`)."""
        m = as_matrix(M, (3, 3), "M")
        if not (isinstance(out, np.ndarray) and out.ndim == 3 and out.shape[2] == 2
                and out.dtype in (np.float32, np.float64) and out.flags.c_contiguous and out.flags.writeable):
            got = f"{out.dtype} {out.shape}" if isinstance(out, np.ndarray) else type(out).__name__
            raise ShapeError(f"out: expected a writeable C-contiguous float32 or float64 array (H, W, 2), got {got}")
        return self._map_from_rays(m, out)

    def _map_from_rays(self, M: np.ndarray, out: np.ndarray) -> bool:
        """The fused kernel of :meth:`map_from_rays` (arguments checked); models with one override it."""
        return False

    def to_dict(self) -> dict[str, Any]:
        """``{"type": name, "width", "height", and every parameter by name}``."""
        out: dict[str, Any] = {"type": self.name, "width": self.width, "height": self.height}
        out.update({n: float(getattr(self, n)) for n in self.param_names})
        return out

    def replace(self, **changes: Any) -> Self:
        """A copy with some fields changed (``dataclasses.replace``); the model is immutable."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    @classmethod
    def param_indices(cls, names: Any) -> list[int]:
        """Indices into ``params()`` of parameter or group names (``"focal"``, ``"k3"``)."""
        if isinstance(names, str):
            names = (names,)
        out: list[int] = []
        for n in names:
            if n in cls.param_groups:
                members = cls.param_groups[n]
            elif n in cls.param_names:
                members = (n,)
            else:
                valid = sorted(cls.param_groups) + list(cls.param_names)
                raise ParameterError(
                    f"names: expected parameter or group names of {cls.name} "
                    f"({', '.join(valid)}), got {n!r}"
                )
            out.extend(cls.param_names.index(m) for m in members if cls.param_names.index(m) not in out)
        return out

    def _intr(self) -> np.ndarray:
        """``fx fy cx cy skew`` as one array, the layout every kernel takes."""
        return np.array([self.fx, self.fy, self.cx, self.cy, self.skew])

    def _jacobian_buffers(self, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Outputs of a Jacobian kernel for n points: pixels, d/d points, d/d params (zeroed)."""
        return np.empty((n, 2)), np.empty((n, 2, 3)), np.zeros((n, 2, len(self.param_names)))

    @property
    def K(self) -> np.ndarray:
        """The 3x3 intrinsic matrix ``[[fx, skew, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, self.skew, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        """``(width, height)`` in pixels."""
        return (self.width, self.height)

    # -- mapping ------------------------------------------------------------------------
    def project(self, points_cam: Any) -> np.ndarray:
        """Pixels of camera-frame points.

        Parameters
        ----------
        points_cam : array_like, (..., 3)
            Points in the camera frame (x right, y down, z forward), any real dtype.

        Returns
        -------
        ndarray, (..., 2), float64
            ``(x, y)`` = (column, row), pixel (0, 0) at the centre of the top-left pixel.
            NaN rows for points the model cannot image (behind a pinhole camera, outside
            the lens model's valid region).
        """
        p = as_points(points_cam, 3, "points_cam", nan_rows=True)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        return self._project_rows(flat).reshape((*p.shape[:-1], 2))

    def unproject(self, pixels: Any) -> np.ndarray:
        """Unit rays in the camera frame through pixels.

        A pixel records light arriving along one ray; every point on that ray images to the
        same pixel, so a pixel alone determines a direction, never a point. Give a depth
        (:meth:`unproject_depth`) or intersect with known geometry to get a point.

        Parameters
        ----------
        pixels : array_like, (..., 2)

        Returns
        -------
        ndarray, (..., 3), float64
            Unit vectors; NaN rows where the model is not invertible.
        """
        p = as_points(pixels, 2, "pixels", nan_rows=True)
        flat = np.ascontiguousarray(p.reshape(-1, 2))
        return self._unproject_rows(flat).reshape((*p.shape[:-1], 3))

    def unproject_depth(self, pixels: Any, depth: Any) -> np.ndarray:
        """Camera-frame points at a given depth (z, along the optical axis) through pixels.

        ``X = ray * depth / ray_z``. Depth is the z coordinate, not the distance along the
        ray. Rays with ``ray_z <= 0`` (beyond 90 degrees off-axis) give NaN.

        Parameters
        ----------
        pixels : array_like, (..., 2)
        depth : array_like, broadcastable with ``pixels[..., 0]``, > 0

        Returns
        -------
        ndarray, (..., 3)
        """
        rays = self.unproject(pixels)
        d = as_real_array(depth, "depth")
        if not np.isfinite(d).all() or (d <= 0).any():
            raise ParameterError("depth: expected finite values > 0")
        try:
            d = np.broadcast_to(d, rays.shape[:-1])
        except ValueError:
            raise ShapeError(
                f"depth: expected a shape broadcastable to {rays.shape[:-1]}, got {d.shape}"
            ) from None
        rz = rays[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(rz > 0, d / rz, np.nan)
        return rays * scale[..., None]

    def project_with_jacobian(self, points_cam: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixels and their analytic derivatives.

        Parameters
        ----------
        points_cam : array_like, (..., 3)

        Returns
        -------
        pixels : ndarray, (..., 2)
        d_pixels_d_points : ndarray, (..., 2, 3)
        d_pixels_d_params : ndarray, (..., 2, n_params)
            Columns in the order of ``param_names``.
        """
        p = as_points(points_cam, 3, "points_cam", nan_rows=True)
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        uv, dp, dk = self._jacobian_rows(flat)
        lead = p.shape[:-1]
        return (uv.reshape((*lead, 2)), dp.reshape((*lead, 2, 3)),
                dk.reshape((*lead, 2, len(self.param_names))))

    # -- derived quantities ---------------------------------------------------------------
    def fov_deg(self) -> FieldOfView:
        """Full horizontal, vertical and diagonal angles of view, in degrees.

        Each is the angle off-axis of the ray through one edge (or corner) plus that of the
        opposite one, measured through the principal point; for a centred pinhole this is
        ``2 atan(d / 2f)`` with ``d`` the image size in pixels. Edges are the outer borders
        of the border pixels (``-0.5`` and ``width - 0.5``).

        Examples
        --------
        >>> from camkit.lens import Pinhole
        >>> cam = Pinhole.from_physical(focal_length=0.050, pixel_pitch=6e-6,
        ...                             width=6000, height=4000)
        >>> [round(a, 2) for a in cam.fov_deg()]
        [39.6, 26.99, 46.79]
        """
        w, h = self.width - 0.5, self.height - 0.5
        edges = np.array([
            [-0.5, self.cy], [w, self.cy],
            [self.cx, -0.5], [self.cx, h],
            [-0.5, -0.5], [w, h],
        ])
        rays = self.unproject(edges)
        off_axis = np.degrees(np.arctan2(np.hypot(rays[:, 0], rays[:, 1]), rays[:, 2]))
        pairs = off_axis.reshape(3, 2).sum(axis=1)
        return FieldOfView(float(pairs[0]), float(pairs[1]), float(pairs[2]))

    def vanishing_point(self, direction_world: Any, cam_from_world: Any) -> np.ndarray:
        """Where images of parallel 3-D lines with a given direction meet.

        A line ``X0 + s d`` images, as ``s -> +-infinity``, to the projection of the direction
        ``d_cam = R d`` itself (translation does not matter). Lines in direction ``d`` and
        ``-d`` are the same lines, so the direction with positive z is projected. For a
        direction parallel to the image plane (``|d_cam_z| <= 1e-12 |d|``) the images of the
        lines are parallel and meet at infinity: the result is a NaN row.

        Parameters
        ----------
        direction_world : array_like, (..., 3)
            Non-zero directions in the world frame.
        cam_from_world : Pose

        Returns
        -------
        ndarray, (..., 2)
        """
        from camkit.geometry.pose import Pose

        if not isinstance(cam_from_world, Pose):
            raise ParameterError(
                f"cam_from_world: expected a camkit.geometry.Pose, got {type(cam_from_world).__name__}"
            )
        d = as_points(direction_world, 3, "direction_world")
        n = np.linalg.norm(d, axis=-1)
        if (n == 0).any():
            raise ParameterError("direction_world: expected non-zero directions, got a zero vector")
        dc = d @ cam_from_world.R.T
        z = dc[..., 2]
        parallel = np.abs(z) <= 1e-12 * n
        dc = np.where((z < 0)[..., None], -dc, dc)
        dc[parallel] = (0.0, 0.0, 1.0)  # placeholder; these rows become NaN below
        out = self.project(dc)
        out[parallel] = np.nan
        return out

    # -- to implement ---------------------------------------------------------------------
    @abc.abstractmethod
    def _project_rows(self, pts: np.ndarray) -> np.ndarray:
        """Pixels (N, 2) of points (N, 3); NaN rows where not projectable."""

    @abc.abstractmethod
    def _unproject_rows(self, px: np.ndarray) -> np.ndarray:
        """Unit rays (N, 3) through pixels (N, 2); NaN rows where not invertible."""

    @abc.abstractmethod
    def _jacobian_rows(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixels (N, 2), d/d points (N, 2, 3), d/d params (N, 2, n_params)."""

"""Calibrated pinhole cameras with OpenCV lens distortion, and rigs of synchronised views.

Convention (OpenCV): a world point X (metres) maps to camera coordinates
``x_cam = R X + t``; the camera looks along +z_cam, x_cam to the right of the image and y_cam
down. Normalised coordinates ``(x, y) = x_cam[:2] / x_cam[2]`` are distorted with
``(k1, k2, p1, p2, k3)``:

    r2 = x^2 + y^2,  c = 1 + k1 r2 + k2 r2^2 + k3 r2^3
    x' = x c + 2 p1 x y + p2 (r2 + 2 x^2),   y' = y c + p1 (r2 + 2 y^2) + 2 p2 x y

and mapped to pixels by ``K``: ``u = fx x' + s y' + cx``, ``v = fy y' + cy``. Pixel centres
sit at integer coordinates; column u, row v.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Bool, Float
from .._validation import as_float_array

NEAR_PLANE = 1e-2  # metres: points closer to the camera plane than this count as behind it


class CameraRig(eqx.Module):
    """Several synchronised calibrated cameras, stacked along a leading ``views`` axis.

    Attributes:
        K: (C, 3, 3) intrinsics, pixels.
        R: (C, 3, 3) world-to-camera rotations.
        t: (C, 3) world-to-camera translations, metres.
        dist: (C, 5) OpenCV distortion (k1, k2, p1, p2, k3).
        image_size: (C, 2) (width, height) in pixels; static, as it fixes image shapes.
        names: (C,) camera names.
    """

    K: Float[Array, "views 3 3"]
    R: Float[Array, "views 3 3"]
    t: Float[Array, "views 3"]
    dist: Float[Array, "views 5"]
    image_size: tuple[tuple[int, int], ...] = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    def __check_init__(self):
        C = len(self.names)
        for name, arr, shape in (
            ("K", self.K, (C, 3, 3)),
            ("R", self.R, (C, 3, 3)),
            ("t", self.t, (C, 3)),
            ("dist", self.dist, (C, 5)),
        ):
            if arr.shape != shape:
                raise ValueError(f"camera {name} must have shape {shape}, got {arr.shape}")
        if len(self.image_size) != C:
            raise ValueError(f"image_size has {len(self.image_size)} entries for {C} cameras")

    @property
    def num_views(self) -> int:
        return len(self.names)

    @property
    def centers(self) -> Float[Array, "views 3"]:
        """Camera centres in world coordinates, metres: ``-R^T t``."""
        return -jnp.einsum("cji,cj->ci", self.R, self.t)

    def view(self, index: int) -> CameraRig:
        """A one-camera rig holding camera ``index``."""
        return CameraRig(
            K=self.K[index : index + 1],
            R=self.R[index : index + 1],
            t=self.t[index : index + 1],
            dist=self.dist[index : index + 1],
            image_size=(self.image_size[index],),
            names=(self.names[index],),
        )

    def resized(self, width: int, height: int) -> CameraRig:
        """The same rig seen at another image resolution (intrinsics scaled per axis)."""
        K = np.array(self.K, dtype=np.float64)
        for c, (w, h) in enumerate(self.image_size):
            sx, sy = width / w, height / h
            # Pixel centres at integer coordinates: scale about the -0.5 pixel corner.
            K[c, 0, :] *= sx
            K[c, 1, :] *= sy
            K[c, 0, 2] = (self.K[c, 0, 2] + 0.5) * sx - 0.5
            K[c, 1, 2] = (self.K[c, 1, 2] + 0.5) * sy - 0.5
        return CameraRig(
            K=jnp.asarray(K, self.K.dtype),
            R=self.R,
            t=self.t,
            dist=self.dist,
            image_size=tuple((int(width), int(height)) for _ in self.image_size),
            names=self.names,
        )


def make_rig(
    K,
    R,
    t,
    image_size,
    dist=None,
    names: Sequence[str] | None = None,
    dtype=jnp.float32,
) -> CameraRig:
    """Build and validate a rig from per-camera arrays.

    Args:
        K: (C, 3, 3) intrinsics with positive focal lengths and ``K[2] = (0, 0, 1)``.
        R: (C, 3, 3) rotation matrices (orthonormal, determinant +1).
        t: (C, 3) translations, metres.
        image_size: (C, 2) (width, height) in pixels.
        dist: (C, 5) distortion, zeros if omitted.
        names: camera names; ``cam0, cam1, ...`` if omitted.

    Raises:
        ValueError: on wrong shapes, non-finite values, a non-rotation R or a bad K.
    """
    K = as_float_array(K, "camera K", ndim=3, last=(3, 3))
    C = K.shape[0]
    R = as_float_array(R, "camera R", ndim=3, last=(3, 3))
    t = as_float_array(t, "camera t", ndim=2, last=(3,))
    dist = np.zeros((C, 5)) if dist is None else as_float_array(dist, "camera dist", ndim=2, last=(5,))
    sizes = np.asarray(image_size)
    if sizes.shape != (C, 2) or not np.issubdtype(sizes.dtype, np.number):
        raise ValueError(f"image_size must have shape ({C}, 2) as (width, height), got {sizes.shape}")
    if np.any(sizes < 1) or np.any(sizes != np.round(sizes)):
        raise ValueError(f"image_size must hold positive integers, got {sizes.tolist()}")
    for name, arr in (("R", R), ("t", t), ("dist", dist)):
        if arr.shape[0] != C:
            raise ValueError(f"camera {name} has {arr.shape[0]} cameras, K has {C}")
    for c in range(C):
        if not np.allclose(R[c] @ R[c].T, np.eye(3), atol=1e-5) or np.linalg.det(R[c]) < 0:
            raise ValueError(f"camera R[{c}] is not a rotation matrix (orthonormal, det +1)")
        if K[c, 0, 0] <= 0 or K[c, 1, 1] <= 0 or not np.allclose(K[c, 2], [0, 0, 1]) or K[c, 1, 0] != 0:
            raise ValueError(f"camera K[{c}] must be upper triangular with positive fx, fy and K[2] = (0, 0, 1)")
    if names is None:
        names = tuple(f"cam{c}" for c in range(C))
    if len(names) != C:
        raise ValueError(f"{len(names)} camera names for {C} cameras")
    return CameraRig(
        K=jnp.asarray(K, dtype),
        R=jnp.asarray(R, dtype),
        t=jnp.asarray(t, dtype),
        dist=jnp.asarray(dist, dtype),
        image_size=tuple((int(w), int(h)) for w, h in sizes),
        names=tuple(str(n) for n in names),
    )


def decompose_projection_matrix(P) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split a 3x4 projection matrix ``P ~ K [R | t]`` by RQ decomposition.

    Returns ``(K, R, t)`` with ``K[2, 2] = 1``, positive focal lengths and ``det R = +1``
    (the overall sign and scale of P are free and are removed).
    """
    P = as_float_array(P, "projection matrix", ndim=2, last=(3, 4))
    M = P[:, :3]
    if abs(np.linalg.det(M)) < 1e-12 * max(1.0, np.abs(M).max() ** 3):
        raise ValueError("projection matrix has a singular left 3x3 block")
    # RQ of M from QR of the row-reversed transpose.
    flip = np.eye(3)[::-1]
    q, r = np.linalg.qr((flip @ M).T)
    K = flip @ r.T @ flip
    R = flip @ q.T
    signs = np.diag(np.sign(np.diag(K)))
    K, R = K @ signs, signs @ R
    scale = K[2, 2]
    t = np.linalg.solve(K, P[:, 3])
    if np.linalg.det(R) < 0:  # P was given up to a negative scale
        R, t = -R, -t
    return K / scale, R, t


def rig_from_projection_matrices(
    P, image_size, dist=None, names=None, dtype=jnp.float32
) -> CameraRig:
    """A rig from (C, 3, 4) projection matrices (see ``decompose_projection_matrix``)."""
    P = as_float_array(P, "projection matrices", ndim=3, last=(3, 4))
    parts = [decompose_projection_matrix(p) for p in P]
    return make_rig(
        np.stack([k for k, _, _ in parts]),
        np.stack([r for _, r, _ in parts]),
        np.stack([t for _, _, t in parts]),
        image_size,
        dist=dist,
        names=names,
        dtype=dtype,
    )


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``(R, t)`` of a camera at ``eye`` looking at ``target`` (OpenCV axes)."""
    eye, target, up = (np.asarray(v, np.float64) for v in (eye, target, up))
    forward = target - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-9:
        raise ValueError("look_at: viewing direction is parallel to the up vector")
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])
    return R, -R @ eye


def default_rig(
    width: int = 80,
    height: int = 60,
    *,
    num_views: int = 4,
    distance: float = 6.0,
    camera_height: float = 2.0,
    target_height: float = 0.9,
    focal_ratio: float = 1.2,
    dist=None,
    azimuth: float | Sequence[float] = 45.0,
    dtype=jnp.float32,
) -> CameraRig:
    """A HumanEva-like rig: cameras evenly around a 4 m capture area, looking at its centre.

    Args:
        width, height: image size in pixels.
        num_views: number of cameras, placed at equal angles starting at ``azimuth``, or at
            the ``azimuth`` given for each.
        distance: horizontal distance of each camera from the area's centre, metres.
        camera_height, target_height: heights of the cameras and of the point they look at, metres.
        focal_ratio: focal length as a multiple of the image width.
        dist: optional (5,) or (C, 5) distortion applied to every camera.
        azimuth: the first camera's direction from the area's centre, degrees from the world's
            x axis towards its y axis (the others follow at ``360 / num_views`` apart), or one
            direction per camera (``num_views`` of them).
    """
    if isinstance(num_views, bool) or not isinstance(num_views, (int, np.integer)) or num_views < 1:
        raise ValueError(f"num_views must be a positive integer, got {num_views!r}")
    if not (np.isfinite(distance) and distance > 0):
        raise ValueError(f"distance must be a positive number of metres, got {distance!r}")
    azimuths = _camera_azimuths(azimuth, int(num_views))
    f = focal_ratio * width
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    Rs, ts = [], []
    for c in range(num_views):
        angle = azimuths[c]
        eye = [distance * np.cos(angle), distance * np.sin(angle), camera_height]
        R, t = look_at(eye, [0.0, 0.0, target_height])
        Rs.append(R)
        ts.append(t)
    if dist is not None:
        dist = np.broadcast_to(np.asarray(dist, np.float64), (num_views, 5))
    return make_rig(
        np.repeat(K[None], num_views, 0),
        np.stack(Rs),
        np.stack(ts),
        [(width, height)] * num_views,
        dist=dist,
        names=[f"C{c + 1}" for c in range(num_views)],
        dtype=dtype,
    )


def _camera_azimuths(azimuth, num_views: int) -> list[float]:
    """Each camera's direction in radians: ``azimuth`` degrees and equal steps after it, or the
    ``num_views`` directions given."""
    values = list(np.ravel(np.asarray(azimuth, dtype=object)))
    if not values or any(isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not np.isfinite(v)
                         for v in values):
        raise ValueError(f"azimuth must be a finite number of degrees or one per camera, got {azimuth!r}")
    if len(values) == 1:
        return [np.deg2rad(float(values[0])) + 2 * np.pi * c / num_views for c in range(num_views)]
    if len(values) != num_views:
        raise ValueError(f"azimuth gives {len(values)} directions for {num_views} cameras")
    return [float(np.deg2rad(float(v))) for v in values]


def world_to_camera(rig: CameraRig, points: Float[Array, "*batch 3"]) -> Float[Array, "*batch views 3"]:
    """Camera-frame coordinates (metres) of world points in every view."""
    return jnp.einsum("cij,...j->...ci", rig.R, points) + rig.t


def distort(dist: Float[Array, "*#batch 5"], xy: Float[Array, "*#batch 2"]) -> Float[Array, ...]:
    """Apply OpenCV radial/tangential distortion to normalised image coordinates.

    ``dist`` (k1, k2, p1, p2, k3) and ``xy`` broadcast against each other.
    """
    k1, k2, p1, p2, k3 = (dist[..., i] for i in range(5))
    x, y = xy[..., 0], xy[..., 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return jnp.stack([xd, yd], axis=-1)


def project_points(
    rig: CameraRig, points: Float[Array, "*batch 3"]
) -> tuple[Float[Array, "*batch views 2"], Float[Array, "*batch views"], Bool[Array, "*batch views"]]:
    """Project world points into every view.

    Args:
        rig: the cameras.
        points: world points, metres.

    Returns:
        ``(uv, depth, in_front)``: pixel coordinates (u = column, v = row), the depth z_cam in
        metres, and whether the point lies in front of the camera (``depth > NEAR_PLANE``).
        Points behind a camera are flagged, never silently projected: their ``uv`` is computed
        from a depth clamped to the near plane and must be masked with ``in_front``.
    """
    cam = world_to_camera(rig, points)
    depth = cam[..., 2]
    in_front = depth > NEAR_PLANE
    safe_depth = jnp.where(in_front, depth, NEAR_PLANE)
    xy = cam[..., :2] / safe_depth[..., None]
    xy = distort(rig.dist, xy)
    K = rig.K
    u = K[:, 0, 0] * xy[..., 0] + K[:, 0, 1] * xy[..., 1] + K[:, 0, 2]
    v = K[:, 1, 1] * xy[..., 1] + K[:, 1, 2]
    return jnp.stack([u, v], axis=-1), depth, in_front


def check_in_front(rig: CameraRig, points, what: str = "the body") -> None:
    """Raise ``ValueError`` naming the camera when any of ``points`` (…, 3) is behind a camera.

    Call before jitting, e.g. with the joints of a sequence's poses.
    """
    points = np.asarray(points, np.float64).reshape(-1, 3)
    depth = np.einsum("cij,nj->nc", np.asarray(rig.R, np.float64), points) + np.asarray(rig.t, np.float64)[:, 2]
    bad = depth <= NEAR_PLANE
    if bad.any():
        n, c = np.argwhere(bad)[0]
        raise ValueError(
            f"camera {rig.names[c]!r} is behind {what}: point {n} at {points[n].round(3).tolist()} m "
            f"has depth {depth[n, c]:.3f} m (must be > {NEAR_PLANE} m)"
        )


def check_in_view(rig: CameraRig, points, what: str = "the body") -> None:
    """Raise ``ValueError`` naming the camera when ``points`` (…, 3) are behind it
    (``check_in_front``) or all project outside its image: a view that cannot see the body
    gives every particle the same likelihood, and the filter would track blind."""
    check_in_front(rig, points, what)
    points = np.asarray(points, np.float64).reshape(-1, 3)
    uv = np.asarray(project_points(rig, jnp.asarray(points, rig.K.dtype))[0], np.float64)  # (N, views, 2)
    size = np.asarray(rig.image_size, np.float64)  # (views, 2): width, height
    inside = np.all((uv >= 0) & (uv <= size[None]), axis=-1)  # (N, views)
    for c in np.flatnonzero(~inside.any(axis=0)):
        w, h = (int(v) for v in size[c])
        raise ValueError(f"camera {rig.names[c]!r} does not see {what}: all {len(points)} points project outside its "
                         f"{w}x{h} image")


def focal_lengths(rig: CameraRig) -> Float[Array, " views"]:
    """Mean focal length (fx + fy) / 2 of each camera, pixels."""
    return 0.5 * (rig.K[:, 0, 0] + rig.K[:, 1, 1])


def image_shape(rig: CameraRig) -> tuple[int, int]:
    """Common (height, width) of the rig's images; raises if the views differ in size."""
    sizes = set(rig.image_size)
    if len(sizes) != 1:
        raise ValueError(f"the views have different image sizes {rig.image_size}; resize them to one")
    w, h = sizes.pop()
    return h, w


def pixel_grid(height: int, width: int, dtype=jnp.float32) -> tuple[Float[Array, "height width"], ...]:
    """Row and column coordinates of every pixel centre."""
    v, u = jnp.meshgrid(jnp.arange(height, dtype=dtype), jnp.arange(width, dtype=dtype), indexing="ij")
    return v, u


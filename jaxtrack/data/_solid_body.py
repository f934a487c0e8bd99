"""A second body and renderer for test scenes: ellipsoids ray-cast exactly, never the tracker's
capsules.

A tracker whose body model rendered its own test data is graded on its own assumptions. This
body differs from ``body.BodyModel`` where real people do: an elliptical torso (wider than deep)
and a pelvis, tapered limbs (each an ellipsoid spanning its bone, overlapping the joints), feet
that reach forward from the ankles, hands, and an egg-shaped head. Each solid is an ellipsoid
fixed in one bone's frame (``body.global_rotation_matrices``); a pixel is foreground when the
ray through it meets any ellipsoid in front of the camera (an exact quadratic test, supersampled
3 x 3 per pixel and kept at half coverage). Cameras with lens distortion are refused: the rays
are cast through undistorted pixels.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..body import Skeleton, forward_kinematics, global_rotation_matrices
from ..camera import CameraRig, image_shape

# (name, frame joint, from joint, to joint, centre fraction along from->to, extra offset in the
#  frame (x forward, y left, z up; metres), semi-axes (x, y, z) in the frame, metres, None: that
#  semi-axis is half the from->to distance times 1.1)
_SOLIDS = (
    ("pelvis", "pelvis", "pelvis", "pelvis", 0.0, (0.0, 0.0, 0.03), (0.11, 0.16, 0.12)),
    ("torso", "thorax", "pelvis", "thorax", 0.55, (0.0, 0.0, 0.0), (0.115, 0.165, None)),
    ("neck", "head", "thorax", "head", 0.3, (0.0, 0.0, 0.0), (0.055, 0.055, 0.08)),
    ("head", "head", "head", "head", 0.0, (0.01, 0.0, 0.02), (0.1, 0.085, 0.12)),
    ("lupper_arm", "lelbow", "lshoulder", "lelbow", 0.5, (0.0, 0.0, 0.0), (0.055, 0.05, None)),
    ("lforearm", "lwrist", "lelbow", "lwrist", 0.5, (0.0, 0.0, 0.0), (0.045, 0.04, None)),
    ("lhand", "lwrist", "lwrist", "lwrist", 0.0, (0.0, 0.0, -0.08), (0.03, 0.045, 0.09)),
    ("rupper_arm", "relbow", "rshoulder", "relbow", 0.5, (0.0, 0.0, 0.0), (0.055, 0.05, None)),
    ("rforearm", "rwrist", "relbow", "rwrist", 0.5, (0.0, 0.0, 0.0), (0.045, 0.04, None)),
    ("rhand", "rwrist", "rwrist", "rwrist", 0.0, (0.0, 0.0, -0.08), (0.03, 0.045, 0.09)),
    ("lthigh", "lknee", "lhip", "lknee", 0.5, (0.0, 0.0, 0.0), (0.085, 0.08, None)),
    ("lshin", "lankle", "lknee", "lankle", 0.5, (0.0, 0.0, 0.0), (0.06, 0.055, None)),
    ("lfoot", "lankle", "lankle", "lankle", 0.0, (0.07, 0.0, -0.045), (0.13, 0.05, 0.045)),
    ("rthigh", "rknee", "rhip", "rknee", 0.5, (0.0, 0.0, 0.0), (0.085, 0.08, None)),
    ("rshin", "rankle", "rknee", "rankle", 0.5, (0.0, 0.0, 0.0), (0.06, 0.055, None)),
    ("rfoot", "rankle", "rankle", "rankle", 0.0, (0.07, 0.0, -0.045), (0.13, 0.05, 0.045)),
)

# The masses round the joints a person has and the ellipsoids above lack (``SolidBody(joints=True)``):
# the shoulder girdle across the top of the chest (clavicles, trapezius), the deltoids over the
# shoulders, the knees and the elbows. Breadths from adult anthropometry: the knee about 10 cm
# across (0.6 of the thigh's breadth, 0.85 of the calf's), the elbow about 7.5 cm (0.7 of the
# upper arm's); the girdle's ends reach the deltoids.
_JOINT_SOLIDS = (
    ("girdle", "thorax", "rshoulder", "lshoulder", 0.5, (-0.01, 0.0, -0.035), (0.075, None, 0.065)),
    ("ldeltoid", "lelbow", "lshoulder", "lelbow", 0.12, (0.0, 0.0, 0.0), (0.06, 0.055, 0.075)),
    ("rdeltoid", "relbow", "rshoulder", "relbow", 0.12, (0.0, 0.0, 0.0), (0.06, 0.055, 0.075)),
    ("lelbow", "lwrist", "lelbow", "lelbow", 0.0, (0.0, 0.0, 0.0), (0.038, 0.036, 0.045)),
    ("relbow", "rwrist", "relbow", "relbow", 0.0, (0.0, 0.0, 0.0), (0.038, 0.036, 0.045)),
    ("lknee", "lankle", "lknee", "lknee", 0.0, (0.0, 0.0, 0.0), (0.052, 0.05, 0.06)),
    ("rknee", "rankle", "rknee", "rknee", 0.0, (0.0, 0.0, 0.0), (0.052, 0.05, 0.06)),
)


@dataclasses.dataclass(frozen=True)
class SolidBody:
    """Ellipsoids attached to a skeleton's bones (module docstring).

    Attributes:
        skeleton: the kinematic tree the solids follow.
        girth: multiplies every semi-axis across a bone (x and y), a build factor.
        joints: add the masses round the joints (``_JOINT_SOLIDS``: shoulder girdle, deltoids,
            elbows, knees). Without them each limb's silhouette narrows to about 40 % of its
            width at the knee and the elbow, where a person's narrows to 60-90 %.
    """

    skeleton: Skeleton
    girth: float = 1.0
    joints: bool = False

    @property
    def solids(self) -> tuple:
        return _SOLIDS + (_JOINT_SOLIDS if self.joints else ())

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s[0] for s in self.solids)

    def ellipsoids(self, pose) -> tuple[jax.Array, jax.Array]:
        """``(centres (E, 3), axes (E, 3, 3))`` in the world: each ellipsoid is the set of points
        ``c + A u`` with ``|u| <= 1`` (``A`` = the frame's rotation times its semi-axes)."""
        joints = forward_kinematics(self.skeleton, pose)
        frames = global_rotation_matrices(self.skeleton, pose)
        index = self.skeleton.joint_index
        centres, axes = [], []
        for _, frame, a, b, fraction, offset, semi in self.solids:
            R = frames[index(frame)]
            pa, pb = joints[index(a)], joints[index(b)]
            span = 0.55 * jnp.linalg.norm(pb - pa)
            girth = (self.girth, self.girth, 1.0)
            scales = jnp.stack([jnp.asarray(span if s is None else s * g, pose.dtype) for s, g in zip(semi, girth)])
            centres.append(pa + fraction * (pb - pa) + R @ jnp.asarray(offset, pose.dtype))
            axes.append(R * scales[None, :])
        return jnp.stack(centres), jnp.stack(axes)


def _rays(rig: CameraRig, height: int, width: int, samples: int):
    """Per view: the camera centre (3,) and the world direction (H, W, s*s, 3) of each sub-pixel ray."""
    dtype = rig.K.dtype
    offsets = (jnp.arange(samples, dtype=dtype) + 0.5) / samples - 0.5
    dv, du = jnp.meshgrid(offsets, offsets, indexing="ij")
    v, u = jnp.meshgrid(jnp.arange(height, dtype=dtype), jnp.arange(width, dtype=dtype), indexing="ij")
    u = u[..., None] + du.ravel()
    v = v[..., None] + dv.ravel()
    pixels = jnp.stack([u, v, jnp.ones_like(u)], axis=-1)  # (H, W, s*s, 3)
    k_inv = jnp.linalg.inv(rig.K)  # (C, 3, 3)
    camera_dirs = jnp.einsum("cij,hwsj->chwsi", k_inv, pixels)
    world_dirs = jnp.einsum("cji,chwsj->chwsi", rig.R, camera_dirs)  # R^T d
    centres = -jnp.einsum("cji,cj->ci", rig.R, rig.t)
    return centres, world_dirs


def _hits(origin, directions, centre, axes):
    """Whether rays from ``origin`` along ``directions`` (..., 3) meet the ellipsoid in front."""
    inv = jnp.linalg.inv(axes)
    o = inv @ (origin - centre)
    d = jnp.einsum("ij,...j->...i", inv, directions)
    a = jnp.sum(d * d, axis=-1)
    b = jnp.sum(d * o, axis=-1)
    c = jnp.dot(o, o) - 1.0
    disc = b * b - a * c
    far = (-b + jnp.sqrt(jnp.maximum(disc, 0.0))) / a
    return (disc >= 0) & (far > 0)


def _render(centres, axes, origins, directions):
    def view(origin, dirs):
        hit = jax.vmap(lambda c, A: _hits(origin, dirs, c, A))(centres, axes)  # (E, H, W, s*s)
        return jnp.mean(jnp.any(hit, axis=0), axis=-1) >= 0.5

    return jax.vmap(view)(origins, directions)


def render_solid_silhouettes(solid: SolidBody, rig: CameraRig, poses, *, samples: int = 3) -> np.ndarray:
    """Binary silhouettes (T, C, H, W) of the solid body at each pose (T, D), one view per camera.

    Raises:
        ValueError: for a rig with lens distortion (the rays are cast through undistorted pixels).
    """
    if np.any(np.asarray(rig.dist) != 0):
        raise ValueError("render_solid_silhouettes casts rays through undistorted pixels: give it a rig without lens distortion")
    height, width = image_shape(rig)
    origins, directions = _rays(rig, height, width, samples)
    poses = jnp.asarray(poses, rig.K.dtype)
    frame = jax.jit(lambda pose: _render(*solid.ellipsoids(pose), origins, directions))
    return np.stack([np.asarray(frame(pose)) for pose in poses])

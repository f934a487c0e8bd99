"""A pose read off one frame's 15 joint positions by geometry alone: the starting point that keeps
inverse kinematics out of the wrong basin.

Gauss-Newton from the previous frame's pose follows whatever basin the first frame fell into: a
leg twisted half a turn with its knee bent backwards against the limit, an arm turned inside out,
stays so for the whole take (a residual of 30-120 mm on every frame). This pose depends on the
frame alone. Each joint's angles come from its bone's direction in its parent's frame, walking
down the tree:

- the root: the hips' line gives the lateral axis, the world's up the rest (pelvis pitch zero,
  which these joints cannot see); its position is the pelvis;
- a joint of two or three angles whose first two axes are perpendicular to its bone (spine, neck,
  clavicles, shoulders, hips): the two swing angles that turn the rest bone onto the bone; the
  third (a twist about the bone) turns the child's hinge plane onto the child's bone (shoulder ->
  elbow, hip -> knee) or, for the spine, the shoulders' line onto the lateral axis;
- a hinge (elbow, knee): the angle between its rest bone and the bone, about its axis.

Angles may land outside the joint limits; the least squares that follows pulls them in. Where a
hinge is straight, its parent's twist is undetermined and set to zero.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import ArrayLike, Float
from ._skeleton import Skeleton

STRAIGHT = 0.02  # sine of a hinge's bend below which its parent's twist is left at zero

# joint -> the child whose hinge plane fixes its twist
_TWIST_FROM = {"lelbow": "lwrist", "relbow": "rwrist", "lknee": "lankle", "rknee": "rankle"}


class _Geometry:
    """Batched vector helpers over leading axes, in NumPy or in JAX (``xp``)."""

    def __init__(self, xp):
        self.xp = xp

    def dot(self, a, b):
        return self.xp.sum(a * b, axis=-1)

    def cross(self, a, b):
        return self.xp.cross(a, b)

    def unit(self, v):
        return v / self.xp.maximum(self.xp.linalg.norm(v, axis=-1, keepdims=True), 1e-12)

    def rotation(self, axis: np.ndarray, angle):
        """Rotation matrices (..., 3, 3) by ``angle`` (...) about the static unit ``axis`` (Rodrigues)."""
        x, y, z = axis
        cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
        angle = angle[..., None, None]
        return np.eye(3) + self.xp.sin(angle) * cross + (1.0 - self.xp.cos(angle)) * (cross @ cross)

    def compose(self, a, b):
        """``a @ b`` over leading axes, as a sum of products (no dot for XLA to compile, as ``_kinematics``)."""
        return self.xp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)

    def in_frame(self, frame, v):
        """``frame.T @ v``: world vectors in the frames' coordinates."""
        return self.xp.sum(frame * v[..., :, None], axis=-2)

    def signed_angle(self, axis, a, b):
        """Angle about ``axis`` that turns ``a`` towards ``b`` (both projected off the axis)."""
        return self.xp.arctan2(self.dot(self.cross(a, b), axis), self.dot(a, b) - self.dot(a, axis) * self.dot(b, axis))

    def swing(self, a1, a2, u0, d):
        """Angles (t1, t2) with ``R(a1, t1) R(a2, t2) u0 = d`` for unit ``d``, where ``a1``, ``a2``
        and ``u0`` are mutually perpendicular unit vectors (coordinate axes up to sign)."""
        xp = self.xp
        side = self.dot(self.cross(a2, u0), a1)  # +-1
        t2 = xp.arcsin(xp.clip(self.dot(d, a1) * side, -1.0, 1.0))
        v = xp.cos(t2)[..., None] * u0 + xp.sin(t2)[..., None] * self.cross(a2, u0)
        return self.signed_angle(a1, v, d), t2


def _dofs_of(skeleton: Skeleton, joint: int) -> list[int]:
    return [k for k, j in enumerate(skeleton.dof_joint) if j == joint]


def geometric_pose(skeleton: Skeleton, joints: Float[ArrayLike, "*batch joints 3"]) -> Float[ArrayLike, "*batch dofs"]:
    """The poses (..., D) that geometry reads off HumanEva joints (..., 15, 3), metres, Z up
    (module docstring).

    NumPy in, NumPy out (no compilation: what ``inverse_kinematics`` uses); JAX arrays (or
    tracers) in, JAX out, under jit and vmap. Bone directions are matched, not lengths: where the
    skeleton's lengths are the joints', the joints of this pose are the targets up to the joint
    limits, the pelvis pitch and the twists that straight limbs leave undetermined.
    """
    xp = jnp if isinstance(joints, jax.Array) else np
    g = _Geometry(xp)
    index = skeleton.joint_index
    axes = np.asarray(skeleton.dof_axes, np.float64)
    offsets = skeleton.offsets if xp is jnp else np.asarray(skeleton.offsets, np.float64)
    rest = g.unit(offsets.astype(joints.dtype))  # unit rest bones (the root's row unused)
    zero = xp.zeros(joints.shape[:-2], joints.dtype)
    angles = [zero] * len(skeleton.dof_names)

    # The root: the hips' line lateral, pitch zero; intrinsic yaw (Z), pitch (Y), roll (X).
    lateral = g.unit(joints[..., index("lhip"), :] - joints[..., index("rhip"), :])
    forward = g.unit(g.cross(lateral, np.array([0.0, 0.0, 1.0])))
    up = g.cross(forward, lateral)
    root = xp.stack([forward, lateral, up], axis=-1)
    yaw = xp.arctan2(root[..., 1, 0], root[..., 0, 0])
    pitch = xp.arcsin(xp.clip(-root[..., 2, 0], -1.0, 1.0))
    roll = xp.arctan2(root[..., 2, 1], root[..., 2, 2])
    world = {0: root}
    for k, angle in zip(_dofs_of(skeleton, 0), (yaw, pitch, roll)):
        angles[k] = angle

    children = {j: [c for c, p in enumerate(skeleton.parents) if p == j] for j in range(skeleton.num_joints)}
    for j in range(1, skeleton.num_joints):
        parent = skeleton.parents[j]
        frame = world[parent]
        dofs = _dofs_of(skeleton, j)
        if not dofs:  # a joint fixed to its parent (the hips)
            world[j] = frame
            continue
        u0 = rest[j]
        d = g.unit(g.in_frame(frame, joints[..., j, :] - joints[..., parent, :]))
        if len(dofs) == 1:  # a hinge
            t = (g.signed_angle(axes[dofs[0]], u0, d),)
        else:
            t1, t2 = g.swing(axes[dofs[0]], axes[dofs[1]], u0, d)
            t = (t1, t2)
            if len(dofs) == 3:
                swung = g.compose(frame, g.compose(g.rotation(axes[dofs[0]], t1), g.rotation(axes[dofs[1]], t2)))
                twist_axis = axes[dofs[2]]
                name = skeleton.joint_names[j]
                if name in _TWIST_FROM:  # turn the child's hinge plane onto the child's bone
                    child = index(_TWIST_FROM[name])
                    bend = g.cross(axes[_dofs_of(skeleton, child)[0]], rest[child])
                    w = g.in_frame(swung, joints[..., child, :] - joints[..., j, :])
                    off_axis = w - g.dot(w, twist_axis)[..., None] * twist_axis
                    straight = xp.linalg.norm(off_axis, axis=-1) < STRAIGHT * xp.linalg.norm(w, axis=-1)
                    t3 = xp.where(straight, 0.0, g.signed_angle(twist_axis, bend, w))
                elif len(children[j]) > 1:  # the spine: the shoulders' line onto the lateral axis
                    left, right = (index(n) for n in ("lshoulder", "rshoulder"))
                    w = g.in_frame(swung, joints[..., left, :] - joints[..., right, :])
                    t3 = g.signed_angle(twist_axis, rest[left], w)
                else:  # the neck: nothing sees its twist
                    t3 = zero
                t = (t1, t2, t3)
        world[j] = frame
        for k, angle in zip(dofs, t):
            angles[k] = angle
            world[j] = g.compose(world[j], g.rotation(axes[k], angle))
    return xp.concatenate([joints[..., 0, :], xp.stack(angles, axis=-1)], axis=-1)

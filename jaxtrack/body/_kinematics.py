"""Forward kinematics: pose vectors -> 3-D joint positions (docs/papers.md)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, Shaped
from ._skeleton import Skeleton


def _dof_generators(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per rotational dof, the norm of its axis, and the cross-product matrix [a]x of its unit
    axis and its square (static NumPy arrays): Rodrigues' formula for all dofs at once."""
    axes = np.asarray(skeleton.dof_axes, np.float64).reshape(-1, 3)
    norms = np.linalg.norm(axes, axis=1)
    unit = axes / np.where(norms > 0, norms, 1.0)[:, None]
    x, y, z = unit.T
    zero = np.zeros_like(x)
    cross = np.stack([np.stack([zero, -z, y], -1), np.stack([z, zero, -x], -1), np.stack([-y, x, zero], -1)], -2)
    return norms, cross, cross @ cross


def _dof_slots(skeleton: Skeleton) -> np.ndarray:
    """(J, S) the dofs of each joint in pose order, padded with K (the identity's index)."""
    per_joint = [[k for k, joint in enumerate(skeleton.dof_joint) if joint == j] for j in range(skeleton.num_joints)]
    width = max(1, max(len(d) for d in per_joint))
    identity = len(skeleton.dof_joint)
    return np.asarray([d + [identity] * (width - len(d)) for d in per_joint], np.int32).reshape(skeleton.num_joints, width)


def _compose(a: Float[Array, "*batch 3 3"], b: Float[Array, "*batch 3 3"]) -> Float[Array, "*batch 3 3"]:
    """``a @ b`` for stacks of 3x3 matrices, as a sum of elementwise products: no dot product
    for XLA to rewrite (its CPU compiler mis-shaped the batched 3x3 dot under ``vmap``: an HLO
    verifier error in the batched-runs tests), and as cheap at this size."""
    return jnp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


def joint_local_rotations(skeleton: Skeleton, pose: Float[Array, "*batch dofs"]) -> Float[Array, "*batch joints 3 3"]:
    """Local rotation matrix of every joint's bone (the identity for a joint without dofs).

    The dofs of a joint are applied in the order they appear in the pose layout (intrinsic
    rotations: the first dof is outermost). Each dof is a rotation by its angle about its axis
    (Rodrigues' formula, all dofs in one vectorised expression: a short program to compile).
    """
    norms, cross, cross2 = _dof_generators(skeleton)
    theta = pose[..., 3:] * jnp.asarray(norms, pose.dtype)  # (*batch, K)
    sin, one_minus_cos = jnp.sin(theta)[..., None, None], (1.0 - jnp.cos(theta))[..., None, None]
    eye = jnp.eye(3, dtype=pose.dtype)
    dofs = eye + sin * jnp.asarray(cross, pose.dtype) + one_minus_cos * jnp.asarray(cross2, pose.dtype)  # (*batch, K, 3, 3)
    dofs = jnp.concatenate([dofs, jnp.broadcast_to(eye, dofs.shape[:-3] + (1, 3, 3))], axis=-3)
    slots = _dof_slots(skeleton)
    local = dofs[..., slots[:, 0], :, :]
    for s in range(1, slots.shape[1]):
        local = _compose(local, dofs[..., slots[:, s], :, :])
    return local


def global_rotation_matrices(
    skeleton: Skeleton, pose: Float[Array, "*batch dofs"]
) -> Float[Array, "*batch joints 3 3"]:
    """World orientation of every joint's bone frame as rotation matrices."""
    local = joint_local_rotations(skeleton, pose)
    moved = set(skeleton.dof_joint)
    world = [None] * skeleton.num_joints
    for j, parent in enumerate(skeleton.parents):
        if parent < 0:
            world[j] = local[..., j, :, :]
        elif j not in moved:
            world[j] = world[parent]
        else:
            world[j] = _compose(world[parent], local[..., j, :, :])
    return jnp.stack(world, axis=-3)


def forward_kinematics(
    skeleton: Skeleton, pose: Shaped[Array, "*batch dofs"]
) -> Float[Array, "*batch joints 3"]:
    """3-D joint positions (metres, world frame, Z up) of a pose or a batch of poses.

    Args:
        skeleton: the kinematic tree and its rest offsets.
        pose: pose vector(s) laid out as ``skeleton.pose_layout``; any leading batch axes
            (frames, particles) are kept. Integer poses are computed in the default float type.

    Returns:
        Joint positions, root first, in ``skeleton.joint_names`` order.
    """
    if pose.shape[-1] != skeleton.num_dofs:
        raise ValueError(
            f"pose has {pose.shape[-1]} entries per vector, the skeleton needs {skeleton.num_dofs}"
        )
    pose = jnp.asarray(pose)
    if not jnp.issubdtype(pose.dtype, jnp.floating):  # integer poses: the offsets must not be truncated
        pose = pose.astype(jnp.result_type(float))
    rotations = global_rotation_matrices(skeleton, pose)
    offsets = skeleton.offsets.astype(pose.dtype)
    positions = [None] * skeleton.num_joints
    for j, parent in enumerate(skeleton.parents):
        if parent < 0:
            positions[j] = pose[..., :3]
        else:
            positions[j] = positions[parent] + jnp.einsum("...ij,j->...i", rotations[..., j, :, :], offsets[j])
    return jnp.stack(positions, axis=-2)

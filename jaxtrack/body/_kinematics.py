"""Forward kinematics: pose vectors -> 3-D joint positions (docs/papers.md)."""

from __future__ import annotations

import jax.numpy as jnp
import jaxlie

from .._custom_types import Array, Float
from ._skeleton import Skeleton


def joint_local_rotations(skeleton: Skeleton, pose: Float[Array, "*batch dofs"]) -> list:
    """Local rotation of every joint's bone: J ``jaxlie.SO3`` with batch axes ``*batch``, or None.

    The dofs of a joint are applied in the order they appear in the pose layout
    (intrinsic rotations: the first dof is outermost).
    """
    local = [None] * skeleton.num_joints  # None: a joint without dofs (identity)
    for k, (joint, axis) in enumerate(zip(skeleton.dof_joint, skeleton.dof_axes)):
        tangent = pose[..., 3 + k, None] * jnp.asarray(axis, pose.dtype)
        rotation = jaxlie.SO3.exp(tangent)
        local[joint] = rotation if local[joint] is None else local[joint] @ rotation
    return local


def global_rotation_matrices(
    skeleton: Skeleton, pose: Float[Array, "*batch dofs"]
) -> Float[Array, "*batch joints 3 3"]:
    """World orientation of every joint's bone frame as rotation matrices."""
    local = joint_local_rotations(skeleton, pose)
    world = [None] * skeleton.num_joints
    for j, parent in enumerate(skeleton.parents):
        if parent < 0:
            world[j] = local[j].as_matrix() if local[j] is not None else _eye_like(pose)
        elif local[j] is None:
            world[j] = world[parent]
        else:
            world[j] = world[parent] @ local[j].as_matrix()
    return jnp.stack(world, axis=-3)


def _eye_like(pose):
    return jnp.broadcast_to(jnp.eye(3, dtype=pose.dtype), pose.shape[:-1] + (3, 3))


def forward_kinematics(
    skeleton: Skeleton, pose: Float[Array, "*batch dofs"]
) -> Float[Array, "*batch joints 3"]:
    """3-D joint positions (metres, world frame, Z up) of a pose or a batch of poses.

    Args:
        skeleton: the kinematic tree and its rest offsets.
        pose: pose vector(s) laid out as ``skeleton.pose_layout``; any leading batch axes
            (frames, particles) are kept.

    Returns:
        Joint positions, root first, in ``skeleton.joint_names`` order.
    """
    if pose.shape[-1] != skeleton.num_dofs:
        raise ValueError(
            f"pose has {pose.shape[-1]} entries per vector, the skeleton needs {skeleton.num_dofs}"
        )
    rotations = global_rotation_matrices(skeleton, pose)
    offsets = skeleton.offsets.astype(pose.dtype)
    positions = [None] * skeleton.num_joints
    for j, parent in enumerate(skeleton.parents):
        if parent < 0:
            positions[j] = pose[..., :3]
        else:
            positions[j] = positions[parent] + jnp.einsum("...ij,j->...i", rotations[..., j, :, :], offsets[j])
    return jnp.stack(positions, axis=-2)

"""Body shape: one capsule per limb with per-part radii (docs/papers.md)."""

from __future__ import annotations

from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._kinematics import forward_kinematics
from ._skeleton import Skeleton, humaneva_skeleton

# (name, joint a, joint b, start fraction, end fraction, radius in metres, part group).
# A capsule's axis runs from p_a + s0 (p_b - p_a) to p_a + s1 (p_b - p_a).
_HUMANEVA_CAPSULES = (
    ("torso", "pelvis", "thorax", 0.0, 1.0, 0.13, "torso"),
    ("lclavicle", "thorax", "lshoulder", 0.0, 1.0, 0.05, "torso"),
    ("rclavicle", "thorax", "rshoulder", 0.0, 1.0, 0.05, "torso"),
    ("lupper_arm", "lshoulder", "lelbow", 0.0, 1.0, 0.05, "arms"),
    ("lforearm", "lelbow", "lwrist", 0.0, 1.0, 0.04, "arms"),
    ("rupper_arm", "rshoulder", "relbow", 0.0, 1.0, 0.05, "arms"),
    ("rforearm", "relbow", "rwrist", 0.0, 1.0, 0.04, "arms"),
    ("lpelvis", "pelvis", "lhip", 0.0, 1.0, 0.09, "torso"),
    ("rpelvis", "pelvis", "rhip", 0.0, 1.0, 0.09, "torso"),
    ("lthigh", "lhip", "lknee", 0.0, 1.0, 0.075, "legs"),
    ("lshin", "lknee", "lankle", 0.0, 1.0, 0.055, "legs"),
    ("rthigh", "rhip", "rknee", 0.0, 1.0, 0.075, "legs"),
    ("rshin", "rknee", "rankle", 0.0, 1.0, 0.055, "legs"),
    ("neck", "thorax", "head", 0.0, 0.45, 0.05, "head"),
    ("head", "thorax", "head", 0.62, 1.05, 0.10, "head"),
)


class BodyModel(eqx.Module):
    """A skeleton dressed with capsules: what the renderer and the likelihood see.

    Attributes:
        skeleton: the kinematic tree.
        capsule_names: (K,) capsule names.
        capsule_joints: (K, 2) joint indices (a, b) spanning each capsule's axis.
        capsule_span: (K, 2) start and end fractions of the axis along a -> b.
        capsule_groups: (K,) body-part group of each capsule (torso, head, arms, legs).
        radii: (K,) capsule radii, metres.
    """

    skeleton: Skeleton
    capsule_names: tuple[str, ...] = eqx.field(static=True)
    capsule_joints: tuple[tuple[int, int], ...] = eqx.field(static=True)
    capsule_span: tuple[tuple[float, float], ...] = eqx.field(static=True)
    capsule_groups: tuple[str, ...] = eqx.field(static=True)
    radii: Float[Array, " capsules"]

    def __check_init__(self):
        K = len(self.capsule_names)
        if not (len(self.capsule_joints) == len(self.capsule_span) == len(self.capsule_groups) == K):
            raise ValueError("capsule_names, capsule_joints, capsule_span and capsule_groups differ in length")
        if self.radii.shape != (K,):
            raise ValueError(f"radii must have shape ({K},), got {self.radii.shape}")

    @property
    def num_capsules(self) -> int:
        return len(self.capsule_names)

    def capsules(
        self, pose: Float[Array, "*batch dofs"]
    ) -> tuple[Float[Array, "*batch capsules 3"], Float[Array, "*batch capsules 3"]]:
        """World end points (metres) of every capsule's axis for a pose or a batch of poses."""
        joints = forward_kinematics(self.skeleton, pose)
        return self.capsules_from_joints(joints)

    def capsules_from_joints(
        self, joints: Float[Array, "*batch joints 3"]
    ) -> tuple[Float[Array, "*batch capsules 3"], Float[Array, "*batch capsules 3"]]:
        """Capsule axis end points from joint positions."""
        ia = jnp.asarray([a for a, _ in self.capsule_joints])
        ib = jnp.asarray([b for _, b in self.capsule_joints])
        s0 = jnp.asarray([s for s, _ in self.capsule_span], joints.dtype)[:, None]
        s1 = jnp.asarray([s for _, s in self.capsule_span], joints.dtype)[:, None]
        pa = joints[..., ia, :]
        pb = joints[..., ib, :]
        return pa + s0 * (pb - pa), pa + s1 * (pb - pa)


def humaneva_body(
    limb_lengths: Mapping[str, float] | None = None,
    radius_scale: float | Mapping[str, float] = 1.0,
    dtype=jnp.float32,
) -> BodyModel:
    """The default 15-joint, 15-capsule body.

    Args:
        limb_lengths: per-subject limb lengths (see ``DEFAULT_LIMB_LENGTHS``), metres.
        radius_scale: one factor for every capsule radius, or a mapping from capsule name or
            part group (torso, head, arms, legs) to a factor.
        dtype: floating dtype of the array fields.
    """
    skeleton = humaneva_skeleton(limb_lengths, dtype=dtype)
    radii = []
    for name, _, _, _, _, r, group in _HUMANEVA_CAPSULES:
        if isinstance(radius_scale, Mapping):
            factor = radius_scale.get(name, radius_scale.get(group, 1.0))
        else:
            factor = radius_scale
        if not factor > 0:
            raise ValueError(f"radius scale for capsule {name!r} must be positive, got {factor}")
        radii.append(r * factor)
    return BodyModel(
        skeleton=skeleton,
        capsule_names=tuple(c[0] for c in _HUMANEVA_CAPSULES),
        capsule_joints=tuple((skeleton.joint_index(c[1]), skeleton.joint_index(c[2])) for c in _HUMANEVA_CAPSULES),
        capsule_span=tuple((c[3], c[4]) for c in _HUMANEVA_CAPSULES),
        capsule_groups=tuple(c[6] for c in _HUMANEVA_CAPSULES),
        radii=jnp.asarray(radii, dtype),
    )

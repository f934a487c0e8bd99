"""Kinematic tree, pose-vector layout and joint limits (docs/papers.md).

Convention. World frame: metres, Z up. Body frame at rest: x forward, y to the body's left,
z up; the rest pose stands upright with the arms hanging down. Each joint ``j`` owns the
bone from its parent to itself: its rotational degrees of freedom rotate that bone about
axes fixed in the parent's frame, so

$$R_j = R_{\\mathrm{parent}(j)} \\prod_k \\exp(\\theta_k [a_k]_\\times), \\qquad
  p_j = p_{\\mathrm{parent}(j)} + R_j\\, o_j,$$

with $o_j$ the rest offset of ``j`` from its parent. The root owns the global orientation
(yaw about z, pitch about y, roll about x) and the pose vector starts with the root position.
A degree of freedom is named after the anatomical joint it moves (``lhip_flex`` rotates the
bone ``lhip -> lknee``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float

HUMANEVA_JOINTS: tuple[str, ...] = (
    "pelvis",
    "thorax",
    "lshoulder",
    "lelbow",
    "lwrist",
    "rshoulder",
    "relbow",
    "rwrist",
    "lhip",
    "lknee",
    "lankle",
    "rhip",
    "rknee",
    "rankle",
    "head",
)
HUMANEVA_PARENTS: tuple[int, ...] = (-1, 0, 1, 2, 3, 1, 5, 6, 0, 8, 9, 0, 11, 12, 1)

# Body-part groups of paper 000 Table 2, by joint.
HUMANEVA_PART_GROUPS: dict[str, tuple[str, ...]] = {
    "torso": ("pelvis", "thorax", "lshoulder", "rshoulder", "lhip", "rhip"),
    "head": ("head",),
    "arms": ("lelbow", "lwrist", "relbow", "rwrist"),
    "legs": ("lknee", "lankle", "rknee", "rankle"),
}

# Limb lengths of the default (about 1.75 m) subject, metres.
DEFAULT_LIMB_LENGTHS: dict[str, float] = {
    "spine": 0.50,  # pelvis -> thorax
    "neck": 0.22,  # thorax -> head (centre of the head)
    "shoulder": 0.18,  # thorax -> shoulder, half the shoulder width
    "upper_arm": 0.29,
    "forearm": 0.26,
    "hip": 0.10,  # pelvis -> hip, half the hip width
    "thigh": 0.44,
    "shin": 0.43,
}

_X, _Y, _Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _neg(axis):
    return tuple(-a for a in axis)


# (dof name, joint whose bone it rotates, axis in the parent frame, lower, upper); radians.
# Signs are chosen so that a positive flexion moves the limb forward (knee and elbow: bend).
_INF = math.inf
_HUMANEVA_DOFS: tuple[tuple[str, str, tuple[float, float, float], float, float], ...] = (
    ("root_yaw", "pelvis", _Z, -_INF, _INF),
    ("root_pitch", "pelvis", _Y, -1.2, 1.2),
    ("root_roll", "pelvis", _X, -1.2, 1.2),
    ("spine_flex", "thorax", _Y, -0.5, 1.2),
    ("spine_bend", "thorax", _X, -0.5, 0.5),
    ("spine_twist", "thorax", _Z, -0.8, 0.8),
    ("lclavicle_elev", "lshoulder", _X, -0.3, 0.6),
    ("lclavicle_prot", "lshoulder", _neg(_Z), -0.4, 0.4),
    ("lshoulder_flex", "lelbow", _neg(_Y), -1.2, 3.0),
    ("lshoulder_abd", "lelbow", _X, -0.6, 2.6),
    ("lshoulder_twist", "lelbow", _Z, -1.5, 1.5),
    ("lelbow_flex", "lwrist", _neg(_Y), 0.0, 2.6),
    ("rclavicle_elev", "rshoulder", _neg(_X), -0.3, 0.6),
    ("rclavicle_prot", "rshoulder", _Z, -0.4, 0.4),
    ("rshoulder_flex", "relbow", _neg(_Y), -1.2, 3.0),
    ("rshoulder_abd", "relbow", _neg(_X), -0.6, 2.6),
    ("rshoulder_twist", "relbow", _neg(_Z), -1.5, 1.5),
    ("relbow_flex", "rwrist", _neg(_Y), 0.0, 2.6),
    ("lhip_flex", "lknee", _neg(_Y), -0.6, 2.2),
    ("lhip_abd", "lknee", _X, -0.5, 0.9),
    ("lhip_twist", "lknee", _Z, -0.8, 0.8),
    ("lknee_flex", "lankle", _Y, 0.0, 2.6),
    ("rhip_flex", "rknee", _neg(_Y), -0.6, 2.2),
    ("rhip_abd", "rknee", _neg(_X), -0.5, 0.9),
    ("rhip_twist", "rknee", _neg(_Z), -0.8, 0.8),
    ("rknee_flex", "rankle", _Y, 0.0, 2.6),
    ("neck_flex", "head", _Y, -0.6, 0.9),
    ("neck_bend", "head", _X, -0.5, 0.5),
    ("neck_twist", "head", _Z, -1.2, 1.2),
)
ROOT_TRANSLATION_DOFS: tuple[str, ...] = ("root_x", "root_y", "root_z")
GLOBAL_DOFS = 6
"""Leading entries of every pose vector that place the body in the world (root position x, y, z
in metres, then root yaw, pitch, roll in radians); the rest are joint angles, which is what the
pose manifolds model (001 sec. 5)."""


def joint_angles(poses):
    """The joint-angle part ``poses[..., GLOBAL_DOFS:]`` of pose vectors (..., D)."""
    return poses[..., GLOBAL_DOFS:]


def humaneva_offsets(limb_lengths: Mapping[str, float] | None = None) -> np.ndarray:
    """Rest offsets (15, 3) of the HumanEva joints from their parents, metres, body frame.

    Args:
        limb_lengths: overrides of ``DEFAULT_LIMB_LENGTHS`` (keys: spine, neck, shoulder,
            upper_arm, forearm, hip, thigh, shin), metres.
    """
    lengths = dict(DEFAULT_LIMB_LENGTHS)
    if limb_lengths is not None:
        unknown = set(limb_lengths) - set(lengths)
        if unknown:
            raise ValueError(
                f"unknown limb-length names {sorted(unknown)}; expected some of {sorted(lengths)}"
            )
        lengths.update({k: float(v) for k, v in limb_lengths.items()})
    for name, value in lengths.items():
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"limb length {name!r} must be a positive number of metres, got {value}")
    L = lengths
    return np.array(
        [
            [0, 0, 0],  # pelvis (root)
            [0, 0, L["spine"]],  # thorax
            [0, L["shoulder"], 0],  # lshoulder
            [0, 0, -L["upper_arm"]],  # lelbow
            [0, 0, -L["forearm"]],  # lwrist
            [0, -L["shoulder"], 0],  # rshoulder
            [0, 0, -L["upper_arm"]],  # relbow
            [0, 0, -L["forearm"]],  # rwrist
            [0, L["hip"], 0],  # lhip
            [0, 0, -L["thigh"]],  # lknee
            [0, 0, -L["shin"]],  # lankle
            [0, -L["hip"], 0],  # rhip
            [0, 0, -L["thigh"]],  # rknee
            [0, 0, -L["shin"]],  # rankle
            [0, 0, L["neck"]],  # head
        ],
        dtype=np.float64,
    )


class Skeleton(eqx.Module):
    """A kinematic tree with per-joint rotational degrees of freedom and joint limits.

    The pose vector (``dofs`` numbers) is ``[root_x, root_y, root_z]`` (metres) followed by
    one angle (radians) per entry of ``dof_names``.

    Attributes:
        joint_names: (J,) names, root first.
        parents: (J,) parent index of each joint, -1 for the root; parents precede children.
        dof_joint: for each rotational dof, the joint whose bone it rotates.
        dof_axes: for each rotational dof, its unit axis in the parent's frame.
        dof_names: names of the rotational dofs.
        offsets: (J, 3) rest offset of each joint from its parent in metres (root row unused).
        lower, upper: (D,) joint limits of the full pose vector (root translation unbounded).
        part_groups: body-part groups (name -> joint names) used for per-part errors.
    """

    joint_names: tuple[str, ...] = eqx.field(static=True)
    parents: tuple[int, ...] = eqx.field(static=True)
    dof_joint: tuple[int, ...] = eqx.field(static=True)
    dof_axes: tuple[tuple[float, float, float], ...] = eqx.field(static=True)
    dof_names: tuple[str, ...] = eqx.field(static=True)
    part_groups: tuple[tuple[str, tuple[str, ...]], ...] = eqx.field(static=True)
    offsets: Float[Array, "joints 3"]
    lower: Float[Array, " dofs"]
    upper: Float[Array, " dofs"]

    def __check_init__(self):
        J = len(self.joint_names)
        if len(self.parents) != J:
            raise ValueError(f"parents has {len(self.parents)} entries for {J} joints")
        if self.parents[0] != -1 or any(p == -1 for p in self.parents[1:]):
            raise ValueError("the root must be the first joint and the only one with parent -1")
        if any(not (0 <= p < j) for j, p in enumerate(self.parents) if j > 0):
            raise ValueError("every parent must precede its child in the joint order")
        if self.offsets.shape != (J, 3):
            raise ValueError(f"offsets must have shape ({J}, 3), got {self.offsets.shape}")
        n = len(self.dof_names)
        if len(self.dof_joint) != n or len(self.dof_axes) != n:
            raise ValueError("dof_names, dof_joint and dof_axes must have the same length")
        if self.lower.shape != (3 + n,) or self.upper.shape != (3 + n,):
            raise ValueError(f"joint limits must have shape ({3 + n},)")

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    @property
    def num_dofs(self) -> int:
        """Length D of a pose vector (3 root-translation numbers + rotational dofs)."""
        return 3 + len(self.dof_names)

    @property
    def pose_layout(self) -> tuple[str, ...]:
        """Names of the D pose-vector entries, in order (stored as ``pose_layout`` in files)."""
        return ROOT_TRANSLATION_DOFS + self.dof_names

    def joint_index(self, name: str) -> int:
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise ValueError(f"unknown joint {name!r}; joints are {self.joint_names}") from None

    def dof_index(self, name: str) -> int:
        """Index of a named entry in the pose vector."""
        try:
            return self.pose_layout.index(name)
        except ValueError:
            raise ValueError(f"unknown pose entry {name!r}; layout is {self.pose_layout}") from None

    def bone_lengths(self) -> Float[Array, " joints"]:
        """Length of the bone ending at each joint (0 for the root), metres."""
        return jnp.linalg.norm(self.offsets, axis=-1)

    def zero_pose(self) -> Float[Array, " dofs"]:
        """The rest pose at the origin (pelvis at the world origin, facing +x)."""
        return jnp.zeros(self.num_dofs, self.offsets.dtype)

    def clip_to_limits(self, pose: Float[Array, "*batch dofs"]) -> Float[Array, "*batch dofs"]:
        """Clamp a pose (or a batch) to the joint limits."""
        return jnp.clip(pose, self.lower, self.upper)

    def limit_violation(self, pose: Float[Array, "*batch dofs"]) -> Float[Array, "*batch"]:
        """Largest amount (radians or metres) by which a pose exceeds a joint limit; 0 inside."""
        over = jnp.maximum(pose - self.upper, 0.0)
        under = jnp.maximum(self.lower - pose, 0.0)
        return jnp.max(jnp.maximum(over, under), axis=-1)


def humaneva_skeleton(limb_lengths: Mapping[str, float] | None = None, dtype=jnp.float32) -> Skeleton:
    """The default 15-joint HumanEva skeleton with 32 pose numbers (3 + 29 angles).

    Args:
        limb_lengths: per-subject limb lengths in metres (see ``DEFAULT_LIMB_LENGTHS``).
        dtype: floating dtype of the array fields.
    """
    names = HUMANEVA_JOINTS
    dof_names = tuple(d[0] for d in _HUMANEVA_DOFS)
    dof_joint = tuple(names.index(d[1]) for d in _HUMANEVA_DOFS)
    dof_axes = tuple(tuple(float(a) for a in d[2]) for d in _HUMANEVA_DOFS)
    lower = [-_INF] * 3 + [d[3] for d in _HUMANEVA_DOFS]
    upper = [_INF] * 3 + [d[4] for d in _HUMANEVA_DOFS]
    return Skeleton(
        joint_names=names,
        parents=HUMANEVA_PARENTS,
        dof_joint=dof_joint,
        dof_axes=dof_axes,
        dof_names=dof_names,
        part_groups=tuple((k, v) for k, v in HUMANEVA_PART_GROUPS.items()),
        offsets=jnp.asarray(humaneva_offsets(limb_lengths), dtype),
        lower=jnp.asarray(lower, dtype),
        upper=jnp.asarray(upper, dtype),
    )


def with_offsets(skeleton: Skeleton, offsets) -> Skeleton:
    """A copy of ``skeleton`` with new rest offsets (J, 3), e.g. another subject's limb lengths."""
    offsets = jnp.asarray(offsets, skeleton.offsets.dtype)
    return eqx.tree_at(lambda s: s.offsets, skeleton, offsets)


def part_group_indices(skeleton: Skeleton) -> dict[str, tuple[int, ...]]:
    """Body-part group name -> joint indices."""
    return {g: tuple(skeleton.joint_index(n) for n in names) for g, names in skeleton.part_groups}


def mirrored_groups(names: Sequence[str]) -> np.ndarray:
    """One group id per name, numbered in order of first appearance; a left entry
    (``"l" + rest``) and its mirror (``"r" + rest``) share one when both are named, every
    other name has its own. E.g. the joint angles ``skeleton.dof_names[3:]`` of the HumanEva
    skeleton give 16 groups for 26 angles (the clavicles, shoulders, elbows, hips and knees
    paired)."""
    names = list(names)
    present = set(names)
    ids: dict[str, int] = {}
    groups = []
    for name in names:
        side, rest = name[:1], name[1:]
        mirror = {"l": "r", "r": "l"}.get(side)
        key = "mirrored:" + rest if mirror is not None and mirror + rest in present else name
        groups.append(ids.setdefault(key, len(ids)))
    return np.asarray(groups, dtype=np.int64)


def check_joint_names(names: Sequence[str], expected: Sequence[str], what: str) -> None:
    """Raise a clear ``ValueError`` when two joint sets differ."""
    if tuple(names) != tuple(expected):
        missing = [n for n in expected if n not in names]
        extra = [n for n in names if n not in expected]
        raise ValueError(
            f"{what}: joint set differs from the skeleton's (missing {missing}, unexpected {extra}, "
            f"or a different order)"
        )


def check_poses(skeleton: Skeleton, poses, name: str = "poses") -> np.ndarray:
    """Validate pose vectors (..., D) before jitting; returns them as a float NumPy array.

    Raises:
        ValueError: on a wrong last dimension, or a NaN/inf entry (naming its index and the
            pose entry, e.g. ``lknee_flex``).
    """
    arr = np.asarray(poses)
    if arr.dtype == object or not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    arr = arr.astype(np.float64) if not np.issubdtype(arr.dtype, np.floating) else arr
    if arr.ndim < 1 or arr.shape[-1] != skeleton.num_dofs:
        raise ValueError(
            f"{name} must have {skeleton.num_dofs} numbers per pose (layout {skeleton.pose_layout[:4]}...), got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(arr))[0])
        raise ValueError(f"{name} contain a non-finite value at index {bad} (pose entry {skeleton.pose_layout[bad[-1]]!r})")
    return arr

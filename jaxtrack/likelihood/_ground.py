"""The ground plane as a pose prior: the feet do not go through the floor.

``ln p(x) = -1/2 sum_{a in ankles} max(0, c - (z_a(x) - h))^2 / sigma^2``

with ``z_a(x)`` the ankle heights of pose ``x`` (forward kinematics, metres, world frame Z up),
``h`` the floor's height (0: the world frames of HumanEva, of ``jaxtrack convert`` and of the
synthetic scenes put the floor at z = 0), ``c`` the ankle's clearance (the lowest an ankle gets
above the floor: the foot below it), and ``sigma`` how far a foot may sink before it costs half
a nat: a tolerance for another person's foot, whose clearance the motion it was fitted on does
not know exactly. Above the clearance the prior is flat: it says nothing about a foot in the air.

Why: background-subtraction noise and shadows widen a silhouette's lower edge, and the
silhouette likelihood then prefers the whole body lower than it is (on the demo's walk by about
15 mm, with the feet in the floor). A tracker whose root walks freely follows that preference
frame by frame. The floor is known in a calibrated capture; this prior makes the trackers use it.

The prior ignores the observation, so it composes with any likelihood by ``+``
(``SumLikelihood``): every filter weighs by the product, and gradient-refined moves target it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, ArrayLike, Float
from ..body import Skeleton, forward_kinematics
from ._base import AbstractLikelihood

ANKLES = ("lankle", "rankle")
DEFAULT_TOLERANCE = 0.01  # m: sigma; the clearance of CMU subject 35's takes spans 60-73 mm
DEFAULT_PERCENTILE = 1.0  # the clearance: this percentile of each frame's lowest ankle height


class GroundPlanePrior(AbstractLikelihood):
    """``ln p(x)`` of the module docstring for a batch of poses; the observation is ignored.

    Attributes:
        skeleton: the tracked body's skeleton (its forward kinematics gives the ankles).
        clearance: ``c``, metres above the floor.
        tolerance: ``sigma``, metres.
        floor_height: ``h``, the floor's world z, metres.
    """

    reads_observation: ClassVar[bool] = False

    skeleton: Skeleton
    clearance: Float[Array, ""]
    tolerance: Float[Array, ""]
    floor_height: Float[Array, ""]
    ankles: tuple[int, ...] = eqx.field(static=True, default=())

    def __check_init__(self):
        if not self.ankles:
            raise ValueError("GroundPlanePrior needs the ankle joints' indices; build it with make_ground_prior")

    def log_likelihood(self, poses, observation):
        del observation
        heights = forward_kinematics(self.skeleton, poses)[:, jnp.asarray(self.ankles), 2] - self.floor_height
        depth = jnp.maximum(self.clearance - heights, 0.0) / self.tolerance
        return -0.5 * jnp.sum(jnp.square(depth), axis=1)

    def lowest_ankle(self, pose: Float[ArrayLike, " dofs"]) -> float:
        """The lowest ankle of one pose, metres above the floor."""
        joints = np.asarray(forward_kinematics(self.skeleton, jnp.asarray(pose, self.skeleton.offsets.dtype)))
        return float(joints[list(self.ankles), 2].min() - float(self.floor_height))

    def allowing(self, pose: Float[ArrayLike, " dofs"]) -> GroundPlanePrior:
        """The prior with its clearance lowered, where needed, to ``pose``'s lowest ankle: a pose
        known to be right (the initial one) is never penalised."""
        clearance = min(float(self.clearance), self.lowest_ankle(pose))
        return eqx.tree_at(lambda p: p.clearance, self, jnp.asarray(clearance, self.clearance.dtype))


def ankle_indices(skeleton: Skeleton) -> tuple[int, ...]:
    """The indices of the skeleton's ankle joints; ``ValueError`` if it has none."""
    missing = [name for name in ANKLES if name not in skeleton.joint_names]
    if missing:
        raise ValueError(f"the ground prior needs the joints {ANKLES}; the skeleton lacks {missing} "
                         f"(it has {list(skeleton.joint_names)})")
    return tuple(skeleton.joint_index(name) for name in ANKLES)


def ground_clearance(motions: Sequence[Float[ArrayLike, "t joints 3"]], joint_names: Sequence[str], *,
                     floor_height: float = 0.0, percentile: float = DEFAULT_PERCENTILE) -> float:
    """The ankle's clearance above the floor in recorded motion, metres: the ``percentile`` of
    each frame's lowest ankle height (a low percentile, not the minimum, so that one bad marker
    frame does not set it).

    Args:
        motions: (T, J, 3) joint positions (metres, world frame, Z up), one array per sequence.
        joint_names: the J joint names, with "lankle" and "rankle".
        floor_height: the floor's world z in these motions.
        percentile: in [0, 100].

    Raises:
        ValueError: with no frames, joints of the wrong shape or not finite, or no ankles.
    """
    if not 0 <= percentile <= 100:
        raise ValueError(f"percentile must be in [0, 100], got {percentile}")
    names = list(joint_names)
    missing = [name for name in ANKLES if name not in names]
    if missing:
        raise ValueError(f"the ground clearance needs the joints {ANKLES}; the motion lacks {missing}")
    index = [names.index(name) for name in ANKLES]
    lowest = []
    for i, joints in enumerate(motions):
        joints = np.asarray(joints, np.float64)
        if joints.ndim != 3 or joints.shape[1:] != (len(names), 3):
            raise ValueError(f"motion {i}: joints must be (T, {len(names)}, 3), got shape {joints.shape}")
        if not np.all(np.isfinite(joints)):
            raise ValueError(f"motion {i}: joints contain NaN or inf (frame {int(np.argwhere(~np.isfinite(joints))[0, 0])})")
        lowest.append(joints[:, index, 2].min(axis=1) - floor_height)
    frames = np.concatenate(lowest) if lowest else np.zeros(0)
    if frames.size == 0:
        raise ValueError("the ground clearance needs at least one frame of motion")
    return float(np.percentile(frames, percentile))


def make_ground_prior(skeleton: Skeleton, clearance: float, *, tolerance: float = DEFAULT_TOLERANCE,
                      floor_height: float = 0.0) -> GroundPlanePrior:
    """A ``GroundPlanePrior`` for ``skeleton`` (in its dtype); lengths in metres."""
    if not (np.isfinite(clearance) and np.isfinite(floor_height)):
        raise ValueError(f"clearance and floor_height must be finite, got {clearance} and {floor_height}")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"the ground prior's tolerance must be a positive length in metres, got {tolerance}")
    dtype = skeleton.offsets.dtype
    return GroundPlanePrior(skeleton=skeleton, clearance=jnp.asarray(clearance, dtype), tolerance=jnp.asarray(tolerance, dtype),
                            floor_height=jnp.asarray(floor_height, dtype), ankles=ankle_indices(skeleton))

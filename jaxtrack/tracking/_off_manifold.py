"""How far a tracker starts from the pose it is given: the latent trackers' projection onto
their manifold.

A tracker whose pose is decoded from a latent point starts at ``decode(encode(pose))``, the
given pose's projection onto its manifold. For a person or a capture the manifold was not
trained on, that projection can be several centimetres from the given pose (the issue's jogs:
GPAPF 139 mm at frame 0 where the start was given to the millimetre). Where it is more than
``OFF_MANIFOLD_START_MM`` away, a tracker that carries no pose residual is given the fading
start instead (``FADING_START``: it starts at the given pose, with the latent point that decodes
nearest to it, and fades onto its manifold over 20-30 frames), and says so.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..body import Skeleton, forward_kinematics

OFF_MANIFOLD_START_MM = 30.0
"""Frame 0's given pose further than this (mean over the joints) from where a tracker's dynamics
put it: the tracker starts from the given pose instead (module docstring)."""


def start_off_manifold_mm(dynamics, pose, skeleton: Skeleton, key) -> float:
    """Mean distance over the joints (mm) between ``pose`` (D,) and the pose ``dynamics`` starts a
    particle at (``init`` then ``to_pose``): 0 for a pose-space dynamics, the projection's
    distance for one that decodes its pose from a latent point."""
    pose = jnp.asarray(pose)
    started = dynamics.to_pose(dynamics.init(key, pose, 1))[0].astype(pose.dtype)
    joints = forward_kinematics(skeleton, jnp.stack([pose, started]).astype(skeleton.offsets.dtype))
    return float(1000.0 * np.mean(np.linalg.norm(np.asarray(joints[1] - joints[0], np.float64), axis=-1)))

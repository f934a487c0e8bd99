"""Inverse kinematics: a subject's limb lengths and every frame's pose from 3-D joint positions.

1. Limb lengths, once per subject: the median over frames of each segment's length (left and
   right averaged), which is the least-squares estimate for a rigid segment.
2. Poses: for each frame, Gauss-Newton least squares (optimistix) on the joint-position residuals
   plus a penalty on joint-limit violation, in one ``lax.scan``. Each frame is solved from two
   starts, the previous frame's solution and the pose geometry reads off the frame's own joints
   (``geometric_pose``), and the better is kept: warm starts keep the angles continuous (no
   wrapping: the yaw is unbounded), the geometric start keeps a wrong basin from being handed on
   (undamped Gauss-Newton from a rest pose diverged on the first frame of mid-stride jogs, and
   every later frame inherited the wrong limb: 20-120 mm on every frame). Poses are finally
   clamped to the limits. The pelvis pitch, which these 15 joints cannot see, is held at zero by
   a weak prior.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

from .._custom_types import Array, Float
from .._tree import cast_floating
from ._geometric_pose import geometric_pose
from ._kinematics import forward_kinematics
from ._skeleton import HUMANEVA_JOINTS, Skeleton, humaneva_skeleton

PITCH_PRIOR = 0.05  # metres of residual per radian of pelvis pitch

LIMB_SEGMENTS: dict[str, list[tuple[str, str]]] = {  # limb -> its (parent joint, joint) bones, left and right tied
    "spine": [("pelvis", "thorax")],
    "neck": [("thorax", "head")],
    "shoulder": [("thorax", "lshoulder"), ("thorax", "rshoulder")],
    "upper_arm": [("lshoulder", "lelbow"), ("rshoulder", "relbow")],
    "forearm": [("lelbow", "lwrist"), ("relbow", "rwrist")],
    "hip": [("pelvis", "lhip"), ("pelvis", "rhip")],
    "thigh": [("lhip", "lknee"), ("rhip", "rknee")],
    "shin": [("lknee", "lankle"), ("rknee", "rankle")],
}


def fit_limb_lengths(joints) -> dict[str, float]:
    """Limb lengths (metres) of the HumanEva skeleton from (T, 15, 3) joint positions."""
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (15, 3):
        raise ValueError(f"joints must be (T, 15, 3) HumanEva joint positions, got {joints.shape}")
    index = {n: i for i, n in enumerate(HUMANEVA_JOINTS)}
    lengths = {}
    for limb, pairs in LIMB_SEGMENTS.items():
        values = [np.linalg.norm(joints[:, index[b]] - joints[:, index[a]], axis=-1) for a, b in pairs]
        lengths[limb] = float(np.median(np.concatenate(values)))
        if not lengths[limb] > 1e-3:
            raise ValueError(f"limb {limb!r} has zero length in the data: are two joints mapped to one source joint?")
    return lengths


class IKResult(NamedTuple):
    """Inverse-kinematics output.

    Attributes:
        skeleton: the subject's skeleton (fitted limb lengths).
        pose: (T, D) pose vectors inside the joint limits.
        joints: (T, 15, 3) forward kinematics of ``pose``, metres.
        residual_mm: (T, 15) distance between fitted and target joints, millimetres.
    """

    skeleton: Skeleton
    pose: Float[Array, "frames dofs"]
    joints: Float[Array, "frames joints 3"]
    residual_mm: Float[Array, "frames joints"]


def _residuals(pose, args):
    skeleton, target, limit_weight, previous, smooth_weight = args
    joints = forward_kinematics(skeleton, pose)
    finite_low = jnp.isfinite(skeleton.lower)
    finite_high = jnp.isfinite(skeleton.upper)
    low = jnp.where(finite_low, skeleton.lower, 0.0)
    high = jnp.where(finite_high, skeleton.upper, 0.0)
    violation = jnp.where(finite_low, jnp.maximum(low - pose, 0.0), 0.0) + jnp.where(
        finite_high, jnp.maximum(pose - high, 0.0), 0.0
    )
    # A weak pull towards the previous frame's angles keeps dofs the joints cannot see
    # (an arm's twist when the elbow is straight) from jumping between frames.
    smooth = smooth_weight * (pose[3:] - previous[3:])
    # The pelvis pitch is invisible to these joints (the hips lie on its axis): it trades
    # exactly against spine and hip flexion. A weak prior holds it at zero, making IK unique.
    pitch = PITCH_PRIOR * pose[skeleton.dof_index("root_pitch")]
    return jnp.concatenate([(joints - target).ravel(), limit_weight * violation, smooth, pitch[None]])


def _solve(skeleton, target, pose0, previous, limit_weight, smooth_weight, max_steps):
    """Gauss-Newton from ``pose0``, pulled weakly towards ``previous``: (pose, cost)."""
    # Gauss-Newton with a QR solve: as accurate here as Levenberg-Marquardt (warm starts keep
    # every frame close to its solution) and it compiles in half the time.
    solver = optx.GaussNewton(rtol=1e-9, atol=1e-9, linear_solver=lx.QR())
    args = (skeleton, target, limit_weight, previous, smooth_weight)
    solution = optx.least_squares(_residuals, solver, pose0, args=args, max_steps=max_steps, throw=False)
    pose = solution.value
    cost = jnp.sum(_residuals(pose, args) ** 2)
    return pose, jnp.where(jnp.isfinite(cost), cost, jnp.inf)


def _near_yaw(pose, reference, skeleton):
    """``pose`` with its root yaw moved by whole turns to within half a turn of ``reference``'s
    (the warm-started yaw is unwrapped; a geometric one is in (-pi, pi])."""
    k = skeleton.dof_index("root_yaw")
    turns = jnp.round((pose[k] - reference[k]) / (2 * jnp.pi))
    return pose.at[k].add(-2 * jnp.pi * turns)


@eqx.filter_jit
def solve_poses(
    skeleton: Skeleton,
    targets: Float[Array, "frames joints 3"],
    pose0: Float[Array, " dofs"],
    limit_weight=1.0,
    smooth_weight=0.01,
    *,
    max_steps: int = 100,
    starts: Float[Array, "frames dofs"] | None = None,
) -> Float[Array, "frames dofs"]:
    """Per-frame IK in one ``lax.scan`` (poses not yet clamped).

    Every frame is solved twice, from the previous frame's pose (``pose0`` for the first) and
    from ``starts`` (default: the pose geometry reads off the frame's own joints,
    ``geometric_pose``), and the solution of lower cost is kept: a frame that fell into a wrong
    basin does not hand it on. The weights are traced (changing them does not recompile); the
    number of frames is a shape, so ``inverse_kinematics`` pads sequences to a power of two and
    passes ``starts`` computed in NumPy (no geometry to compile).
    """
    limit_weight = jnp.asarray(limit_weight, targets.dtype)
    smooth_weight = jnp.asarray(smooth_weight, targets.dtype)
    if starts is None:
        starts = jax.vmap(lambda target: geometric_pose(skeleton, target))(targets)

    def step(previous, inputs):
        target, fresh = inputs
        candidates = jnp.stack([previous, _near_yaw(fresh, previous, skeleton)])
        poses, costs = jax.vmap(lambda start: _solve(skeleton, target, start, previous, limit_weight, smooth_weight,
                                                     max_steps))(candidates)
        best = jnp.argmin(costs)
        # Neither solve finite (a diverged step): keep the previous pose rather than hand on NaNs.
        pose = jnp.where(jnp.isfinite(costs[best]) & jnp.all(jnp.isfinite(poses[best])), poses[best], previous)
        return pose, pose

    _, poses = jax.lax.scan(step, pose0, (targets, jnp.asarray(starts, targets.dtype)))
    return poses


def _padded(targets, frames):
    """Repeat the last frame up to ``frames`` frames."""
    extra = frames - targets.shape[0]
    return jnp.concatenate([targets, jnp.repeat(targets[-1:], extra, axis=0)]) if extra > 0 else targets


def inverse_kinematics(
    joints,
    *,
    skeleton: Skeleton | None = None,
    limit_weight: float = 1.0,
    smooth_weight: float = 0.01,
    max_steps: int = 100,
    restarts: int = 4,
    key=None,
    dtype=None,
) -> IKResult:
    """Fit limb lengths and the pose of every frame to HumanEva joint positions.

    Args:
        joints: (T, 15, 3) target joint positions, metres, Z up.
        skeleton: a skeleton whose limb lengths to keep; fitted from the data if omitted.
        limit_weight: weight of the joint-limit penalty (metres of residual per radian).
        smooth_weight: weight of the pull towards the previous frame's angles (metres per
            radian); small, so it only decides what the joints leave undetermined.
        max_steps: Gauss-Newton steps per frame.
        restarts: random restarts for the first frame (the rest are warm-started);
            needs ``key`` when > 0.
        key: PRNG key for the restarts.
        dtype: floating dtype of the result (default: JAX's default float, float64 under x64).
            The fit itself always runs in float64: its Gauss-Newton tolerances are below float32's
            resolution, and in float32 the first frame of a Bandai run (``run_normal_006``) landed
            at a pelvis pitch of 0.81 rad with the spine bent back to match (8.6 mm from its
            joints), a pose the next frame left by a 0.7 rad jump.

    Returns:
        An ``IKResult``; ``residual_mm`` reports the fit per joint.
    """
    dtype = jnp.result_type(float) if dtype is None else dtype
    joints = _checked_joints(joints)
    if restarts > 0 and key is None:
        raise ValueError("inverse_kinematics with restarts > 0 needs a PRNG key")
    with jax.enable_x64(True):
        result = _fit(joints, None if skeleton is None else cast_floating(skeleton, jnp.float64), limit_weight, smooth_weight,
                      max_steps, restarts, key)
        return cast_floating(result, dtype)


def _checked_joints(joints) -> np.ndarray:
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (15, 3):
        raise ValueError(f"joints must be (T, 15, 3) HumanEva joint positions, got {joints.shape}")
    if joints.shape[0] < 1:
        raise ValueError("joints has no frames")
    if not np.all(np.isfinite(joints)):
        bad = np.argwhere(~np.isfinite(joints))[0]
        raise ValueError(f"joints contains a non-finite value at frame {bad[0]}, joint {HUMANEVA_JOINTS[bad[1]]}")
    return joints


def _fit(joints, skeleton, limit_weight, smooth_weight, max_steps, restarts, key) -> IKResult:
    """``inverse_kinematics`` on checked joints, in float64 (inside ``jax.enable_x64``)."""
    dtype = jnp.float64
    if skeleton is None:
        skeleton = humaneva_skeleton(fit_limb_lengths(joints), dtype=dtype)
    targets = jnp.asarray(joints, dtype)
    T = targets.shape[0]
    bucket = max(16, 1 << (T - 1).bit_length())  # one compile per power-of-two length

    # First frame: the best of the geometric pose and a few random ones about it, each solved by
    # warm-starting on the first frame repeated (the same compiled function as the sequence itself).
    first_frame = jnp.repeat(targets[:1], bucket, axis=0)
    padded = _padded(targets, bucket)
    geometric = geometric_pose(skeleton, np.asarray(padded))  # NumPy: nothing to compile
    start = jnp.asarray(geometric[0])
    candidates = [start]
    if restarts > 0:
        noise = 0.4 * jax.random.normal(key, (restarts, skeleton.num_dofs), dtype)
        candidates += list(skeleton.clip_to_limits(start + noise.at[:, :3].set(0.0)))
    best, best_cost = None, np.inf
    for candidate in candidates:
        pose = solve_poses(skeleton, first_frame, candidate, limit_weight, 0.0, max_steps=max_steps,
                           starts=np.repeat(geometric[:1], bucket, axis=0))[-1]
        cost = float(jnp.sum(_residuals(pose, (skeleton, targets[0], limit_weight, pose, 0.0)) ** 2))
        if cost < best_cost:
            best, best_cost = pose, cost

    poses = solve_poses(skeleton, padded, best, limit_weight, smooth_weight, max_steps=max_steps, starts=geometric)[:T]
    poses = skeleton.clip_to_limits(poses)
    fitted = forward_kinematics(skeleton, poses)
    residual = 1000.0 * jnp.linalg.norm(fitted - targets, axis=-1)
    return IKResult(skeleton=skeleton, pose=poses, joints=fitted, residual_mm=residual)

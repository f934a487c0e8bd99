"""Arm-rich upper-body motion for paper 003's setting: signalling gestures (after the aircraft
marshalling signals 003 trains on) made with the library's skeleton.

A gesture take is a chain of key postures of both arms, held briefly and joined by smooth
(half-cosine) transitions of 0.4-1.2 s (``transition``). Each key posture is either one of the named signals
``SIGNALS`` or, with probability ``random_share``, a random arm posture within the joints'
ranges; the person stands still (legs straight, a slight sway of the spine and head).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..body import humaneva_body
from ._gait import SyntheticMotion

# (lshoulder_flex, lshoulder_abd, lelbow_flex, rshoulder_flex, rshoulder_abd, relbow_flex), radians
SIGNALS = {
    "rest": (0.0, 0.1, 0.1, 0.0, 0.1, 0.1),
    "both up": (0.2, 2.5, 0.1, 0.2, 2.5, 0.1),
    "arms out": (0.0, 1.5, 0.0, 0.0, 1.5, 0.0),
    "left wave": (0.3, 2.0, 1.2, 0.0, 0.1, 0.2),
    "right wave": (0.0, 0.1, 0.2, 0.3, 2.0, 1.2),
    "stop": (1.5, 0.2, 0.1, 0.0, 0.1, 0.1),
    "come here": (1.0, 0.3, 1.8, 1.0, 0.3, 1.8),
    "left point": (0.1, 1.5, 0.0, 0.0, 0.1, 1.4),
    "right point": (0.0, 0.1, 1.4, 0.1, 1.5, 0.0),
    "slow down": (0.6, 1.2, 0.3, 0.6, 1.2, 0.3),
    "hands on head": (0.4, 1.8, 2.2, 0.4, 1.8, 2.2),
}
_ARM_DOFS = ("lshoulder_flex", "lshoulder_abd", "lelbow_flex", "rshoulder_flex", "rshoulder_abd", "relbow_flex")
_RANDOM_LOW = np.array([-0.3, 0.0, 0.0, -0.3, 0.0, 0.0])
_RANDOM_HIGH = np.array([2.4, 2.5, 2.2, 2.4, 2.5, 2.2])


def signalling_motion(key, *, num_frames: int = 300, fps: float = 30.0, random_share: float = 0.3,
                      limb_lengths=None, facing: float = 0.0, transition=(0.4, 1.2)) -> SyntheticMotion:
    """A take of signalling gestures (module docstring).

    Args:
        key: PRNG key choosing the postures and their timing.
        num_frames: T.
        fps: frame rate, Hz.
        random_share: the probability that a key posture is random rather than a named signal.
        limb_lengths: the subject's limb lengths (``humaneva_body``'s keys), default body if None.
        facing: the direction the person faces, radians about the vertical.
        transition: the shortest and longest time from one key posture to the next, seconds.

    Returns:
        A ``SyntheticMotion`` (gait ``"signals"``) with poses and joints (metres, Z up).
    """
    low, high = (float(v) for v in transition)
    if not 0 < low <= high:
        raise ValueError(f"transition must be (shortest, longest) seconds with 0 < shortest <= longest, got {transition}")
    if num_frames < 2:
        raise ValueError(f"num_frames must be at least 2, got {num_frames}")
    body = humaneva_body(limb_lengths)
    skeleton = body.skeleton
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel().astype(np.uint32))
    names = list(SIGNALS)
    times, postures = [0.0], [np.asarray(SIGNALS["rest"])]
    while times[-1] < num_frames / fps:
        if rng.random() < random_share:
            posture = rng.uniform(_RANDOM_LOW, _RANDOM_HIGH)
        else:
            posture = np.asarray(SIGNALS[names[rng.integers(1, len(names))]])
        hold = rng.uniform(0.1, 0.4)
        times += [times[-1] + rng.uniform(low, high), None]
        times[-1] = times[-2] + hold
        postures += [posture, posture]
    times, postures = np.asarray(times), np.stack(postures)
    t = np.arange(num_frames) / fps
    segment = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    fraction = (t - times[segment]) / np.maximum(times[segment + 1] - times[segment], 1e-9)
    smooth = 0.5 - 0.5 * np.cos(np.pi * np.clip(fraction, 0, 1))
    arms = postures[segment] + smooth[:, None] * (postures[segment + 1] - postures[segment])

    layout = list(skeleton.pose_layout)
    pose = np.zeros((num_frames, len(layout)))
    leg = float(np.linalg.norm(np.asarray(skeleton.offsets)[9]) + np.linalg.norm(np.asarray(skeleton.offsets)[10]))
    pose[:, 2] = leg + 0.08  # standing, the ankles at the library's ankle height
    pose[:, layout.index("root_yaw")] = facing
    for i, name in enumerate(_ARM_DOFS):
        pose[:, layout.index(name)] = arms[:, i]
    sway = 2 * np.pi * t / rng.uniform(3.0, 5.0)
    pose[:, layout.index("spine_twist")] = 0.08 * np.sin(sway)
    pose[:, layout.index("spine_bend")] = 0.04 * np.sin(0.7 * sway)
    pose[:, layout.index("neck_flex")] = 0.1 * np.sin(0.5 * sway)
    lower, upper = np.asarray(skeleton.lower, np.float64), np.asarray(skeleton.upper, np.float64)
    pose = np.clip(pose, lower, upper)
    from ..body import forward_kinematics

    joints = np.asarray(forward_kinematics(skeleton, jnp.asarray(pose, jnp.float32)), np.float64)
    return SyntheticMotion(body=body, pose=pose, joints3d=joints, fps=float(fps), gait="signals", subject="gestures", speed=0.0)

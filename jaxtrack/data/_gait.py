"""Procedural walking, jogging and running for synthetic subjects (the embedded default).

Joint-angle curves follow the shape of clinical sagittal gait data (e.g. Winter, *Biomechanics
and Motor Control of Human Movement*): the hip flexes and extends once per stride (maximum
flexion late in swing), the knee has a small loading-response peak early in stance and a
large peak in swing, the arms swing against the legs, the pelvis rotates and the thorax
counter-rotates, the body sways over the stance leg. Curves are written with the stride
phase ``phi`` (0 at left heel strike; the right leg runs half a stride behind) as

    hip(phi)  = mean + amp c(phi),   c = +1 at the phase of peak flexion, -1 at peak extension
    knee(phi) = k0 + k_load vm(phi; 0.13) + k_swing b(phi)

with ``c`` a warped cosine (two half-cosines joining the two extremes, so stance lasts longer
than swing), ``vm`` a periodic von Mises bump and ``b`` a raised-cosine swing bump that rises
from just before toe-off to its peak in mid-swing and falls back by heel strike. The root follows a circle inside the capture area at
the speed that keeps the stance foot from sliding (estimated from the legs' own motion), and
its height keeps the lower ankle at ankle height (plus a flight bump for jogging and running).
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from ..body import DEFAULT_LIMB_LENGTHS, BodyModel, forward_kinematics, humaneva_body

ANKLE_HEIGHT = 0.08  # metres above the ground at foot contact


@dataclasses.dataclass(frozen=True)
class GaitParameters:
    """Shape of one gait's joint-angle curves (degrees, Hz, metres)."""

    stride_hz: float
    hip_mean: float
    hip_amp: float
    knee_base: float
    knee_load: float
    knee_swing: float
    knee_swing_phase: float  # fraction of the stride at peak swing flexion
    knee_swing_start: float  # fraction of the stride where swing flexion starts rising
    arm_amp: float
    elbow_mean: float
    elbow_amp: float
    lean: float
    pelvis_yaw: float
    spine_twist: float
    pelvis_list: float
    sway: float  # metres
    flight: float  # metres of vertical lift during flight phases
    slide_factor: float  # stride length multiplier over the stance-foot estimate (flight phases)
    hip_extension_phase: float = 0.55  # fraction of the stride at peak hip extension
    hip_flexion_phase: float = 0.88  # fraction of the stride at peak hip flexion


def _gait(*values) -> GaitParameters:
    return GaitParameters(*(float(v) for v in values))


GAITS: dict[str, GaitParameters] = {
    "walk": _gait(0.95, 9, 21, 4, 14, 58, 0.73, 0.42, 18, 22, 10, 3, 5, 9, 3, 0.025, 0.0, 1.0, 0.55, 0.88),
    "jog": _gait(1.35, 16, 28, 10, 24, 85, 0.68, 0.30, 26, 78, 10, 8, 6, 10, 3, 0.015, 0.04, 1.2, 0.45, 0.86),
    "run": _gait(1.5, 20, 34, 12, 28, 105, 0.65, 0.26, 34, 90, 12, 12, 7, 12, 3, 0.012, 0.07, 1.3, 0.40, 0.85),
}


@dataclasses.dataclass(frozen=True)
class SubjectStyle:
    """A synthetic subject: body proportions and personal style.

    Attributes:
        height_scale: multiplies every default limb length.
        limb_lengths: further per-limb multipliers (keys of ``DEFAULT_LIMB_LENGTHS``).
        radius_scale: multiplies every capsule radius (build).
        cadence: multiplies the stride frequency.
        stride: multiplies the hip swing amplitude.
        arm_swing: multiplies the arm swing amplitude.
        knee: multiplies the knee swing peak.
        lean: extra forward trunk lean, degrees.
    """

    name: str
    height_scale: float = 1.0
    limb_lengths: tuple[tuple[str, float], ...] = ()
    radius_scale: float = 1.0
    cadence: float = 1.0
    stride: float = 1.0
    arm_swing: float = 1.0
    knee: float = 1.0
    lean: float = 0.0

    def limb_lengths_m(self) -> dict[str, float]:
        factors = dict(self.limb_lengths)
        return {k: v * self.height_scale * factors.get(k, 1.0) for k, v in DEFAULT_LIMB_LENGTHS.items()}

    def body(self, dtype=jnp.float32) -> BodyModel:
        return humaneva_body(self.limb_lengths_m(), radius_scale=self.radius_scale, dtype=dtype)


SUBJECTS: dict[str, SubjectStyle] = {
    "S1": SubjectStyle("S1"),
    "S2": SubjectStyle(
        "S2", height_scale=0.94, limb_lengths=(("shoulder", 1.08), ("thigh", 0.97)), radius_scale=1.12,
        cadence=1.07, stride=0.93, arm_swing=1.3, knee=0.92, lean=3.0,
    ),
    "S3": SubjectStyle(
        "S3", height_scale=1.06, limb_lengths=(("spine", 1.04), ("forearm", 0.96)), radius_scale=0.92,
        cadence=0.93, stride=1.08, arm_swing=0.7, knee=1.08, lean=-1.5,
    ),
}


def random_subject(key, name: str = "random") -> SubjectStyle:
    """A random subject (proportions and style) drawn from ``key``."""
    k = np.asarray(jax.random.uniform(key, (9,), minval=-1.0, maxval=1.0))
    return SubjectStyle(
        name,
        height_scale=1.0 + 0.07 * k[0],
        limb_lengths=(("shoulder", 1 + 0.08 * k[1]), ("thigh", 1 + 0.04 * k[2]), ("upper_arm", 1 + 0.04 * k[3])),
        radius_scale=1.0 + 0.12 * k[4],
        cadence=1.0 + 0.08 * k[5],
        stride=1.0 + 0.08 * k[6],
        arm_swing=1.0 + 0.3 * k[7],
        knee=1.0 + 0.08 * k[8],
        lean=2.0 * k[0],
    )


@dataclasses.dataclass(frozen=True)
class SyntheticMotion:
    """A generated motion.

    Attributes:
        body: the subject's capsule body (skeleton with its limb lengths).
        pose: (T, D) pose vectors.
        joints3d: (T, J, 3) joint positions, metres.
        fps: frames per second.
        gait, subject: what generated it.
        speed: mean root speed, m/s.
    """

    body: BodyModel
    pose: np.ndarray
    joints3d: np.ndarray
    fps: float
    gait: str
    subject: str
    speed: float


def _warped_cosine(phi, peak_fraction, trough_fraction):
    """Periodic curve in [-1, 1]: +1 at ``peak_fraction``, -1 at ``trough_fraction`` of the
    stride, half-cosines in between (C^1, zero slope at both extremes)."""
    f = np.mod(phi / (2 * np.pi) - peak_fraction, 1.0)  # 0 at the peak
    fall = np.mod(trough_fraction - peak_fraction, 1.0)  # duration peak -> trough
    falling = f < fall
    x = np.where(falling, f / fall, (f - fall) / (1.0 - fall))
    return np.where(falling, np.cos(np.pi * x), -np.cos(np.pi * x))


def _swing_bump(phi, start, peak, end=1.0):
    """Raised cosine in [0, 1]: 0 before ``start``, 1 at ``peak``, back to 0 at ``end``."""
    f = np.mod(phi / (2 * np.pi), 1.0)
    rising = 0.5 * (1 - np.cos(np.pi * np.clip((f - start) / (peak - start), 0, 1)))
    falling = 0.5 * (1 + np.cos(np.pi * np.clip((f - peak) / (end - peak), 0, 1)))
    return np.where(f < peak, rising, falling)


def _von_mises(phi, centre_fraction, concentration):
    return np.exp(concentration * (np.cos(phi - 2 * np.pi * centre_fraction) - 1.0))


def _joint_angles(skeleton, phi, gait: GaitParameters, style: SubjectStyle, amp):
    """(T, D) pose with zero root translation and heading; angles from the phase."""
    T = phi.shape[0]
    pose = np.zeros((T, skeleton.num_dofs))
    rad = np.deg2rad

    def put(name, value):
        pose[:, skeleton.dof_index(name)] = value

    for side, offset in (("l", 0.0), ("r", np.pi)):
        p = phi + offset
        swing = _warped_cosine(p, gait.hip_flexion_phase, gait.hip_extension_phase)
        put(f"{side}hip_flex", rad(gait.hip_mean + gait.hip_amp * style.stride * amp["hip"] * swing))
        put(f"{side}hip_abd", rad(2.0))
        knee = gait.knee_base + gait.knee_load * _von_mises(p, 0.13, 30.0)
        knee = knee + gait.knee_swing * style.knee * amp["knee"] * _swing_bump(p, gait.knee_swing_start, gait.knee_swing_phase)
        put(f"{side}knee_flex", rad(knee))
        put(f"{side}shoulder_flex", rad(4.0 - gait.arm_amp * style.arm_swing * amp["arm"] * swing))
        put(f"{side}shoulder_abd", rad(9.0))
        put(f"{side}elbow_flex", rad(gait.elbow_mean + gait.elbow_amp * np.maximum(-swing, -0.5)))
    left_swing = _warped_cosine(phi, gait.hip_flexion_phase, gait.hip_extension_phase)
    lean = gait.lean + style.lean
    put("spine_flex", rad(lean))
    put("spine_twist", rad(gait.spine_twist * left_swing))
    put("root_roll", rad(gait.pelvis_list * np.cos(2 * phi)))
    put("neck_flex", rad(-0.6 * lean))
    pose[:, skeleton.dof_index("root_yaw")] = rad(-gait.pelvis_yaw * left_swing)
    return pose


def _smooth_multipliers(key, cycles, T, sigma):
    """Per-stride random amplitude multipliers, linearly interpolated in stride phase."""
    n = math.ceil(cycles.max()) + 2
    if key is None:
        return {name: np.ones(T) for name in ("hip", "knee", "arm")}
    draws = np.asarray(jax.random.normal(key, (3, n)))
    grid = np.arange(n)
    return {name: 1.0 + sigma * np.interp(cycles, grid, draws[i]) for i, name in enumerate(("hip", "knee", "arm"))}


def generate_motion(
    gait: str = "walk",
    subject: str | SubjectStyle = "S1",
    *,
    num_frames: int = 120,
    fps: float = 60.0,
    path_radius: float = 1.0,
    start_angle: float = 0.0,
    start_phase: float = 0.0,
    key=None,
    variability: float = 0.04,
    dtype=jnp.float32,
) -> SyntheticMotion:
    """Generate a walking, jogging or running sequence for a synthetic subject.

    Args:
        gait: ``"walk"``, ``"jog"`` or ``"run"``.
        subject: a name in ``SUBJECTS`` (S1, S2, S3) or a ``SubjectStyle``.
        num_frames: number of frames T.
        fps: frame rate, Hz.
        path_radius: radius of the circular path around the capture area's centre, metres.
        start_angle: where on the circle the subject starts, radians.
        start_phase: stride phase at the first frame, fraction of a stride.
        key: PRNG key for stride-to-stride variability of the amplitudes; ``None`` for
            perfectly periodic motion.
        variability: relative standard deviation of those amplitudes.

    Returns:
        A ``SyntheticMotion`` with pose vectors and joint positions (metres, Z up).
    """
    if not isinstance(gait, str):
        raise TypeError(f"generate_motion's first argument is the gait's name ({', '.join(sorted(GAITS))}), got "
                        f"{type(gait).__name__}; pass a PRNG key as key=...")
    if gait not in GAITS:
        raise ValueError(f"unknown gait {gait!r}; choose one of {sorted(GAITS)}")
    if isinstance(subject, str):
        if subject not in SUBJECTS:
            raise ValueError(f"unknown subject {subject!r}; choose one of {sorted(SUBJECTS)} or pass a SubjectStyle")
        subject = SUBJECTS[subject]
    if int(num_frames) < 2:
        raise ValueError(f"num_frames must be at least 2, got {num_frames}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if not path_radius > 0:
        raise ValueError(f"path_radius must be positive, got {path_radius}")
    params = GAITS[gait]
    body = subject.body(dtype=dtype)
    skeleton = body.skeleton
    T = int(num_frames)
    t = np.arange(T) / fps
    frequency = params.stride_hz * subject.cadence
    cycles = frequency * t + start_phase
    phi = 2 * np.pi * cycles
    amp = _smooth_multipliers(key, cycles, T, variability)
    pose = _joint_angles(skeleton, phi, params, subject, amp)

    # Speed: how fast each ankle moves backwards relative to the pelvis during its single
    # support (early-to-mid stance, chosen by phase). The mean is the speed that minimises the
    # stance foot's squared slide; flight phases lengthen the stride by ``slide_factor``.
    local = np.asarray(forward_kinematics(skeleton, jnp.asarray(pose, body.radii.dtype)), np.float64)
    yaw_osc = pose[:, skeleton.dof_index("root_yaw")]  # pelvis rotation about the heading
    velocities = []
    for joint, offset in (("lankle", 0.0), ("rankle", 0.5)):
        x = local[:, skeleton.joint_index(joint), 0]
        fraction = np.mod(cycles + offset, 1.0)
        stance = (fraction > 0.08) & (fraction < params.hip_extension_phase - 0.1)
        velocities.append(np.gradient(x, 1.0 / fps)[stance])
    velocities = np.concatenate(velocities)
    speed = float(-np.mean(velocities)) * params.slide_factor if velocities.size else 1.0
    ankles = local[:, [skeleton.joint_index("lankle"), skeleton.joint_index("rankle")], :]

    arc = speed * t
    angle = start_angle + arc / path_radius
    heading = angle + np.pi / 2
    left = np.stack([-np.sin(heading), np.cos(heading)], axis=1)  # the body's left on the ground
    sway = params.sway * np.sin(phi)
    pose[:, 0] = path_radius * np.cos(angle) + sway * left[:, 0]
    pose[:, 1] = path_radius * np.sin(angle) + sway * left[:, 1]
    pose[:, skeleton.dof_index("root_yaw")] = heading + yaw_osc
    lift = params.flight * 0.5 * (1 - np.cos(2 * phi))
    pose[:, 2] = ANKLE_HEIGHT - ankles[:, :, 2].min(axis=1) + lift
    pose = np.array(skeleton.clip_to_limits(jnp.asarray(pose)), dtype=np.float64)
    pose[:, skeleton.dof_index("root_yaw")] = np.unwrap(pose[:, skeleton.dof_index("root_yaw")])
    joints = np.asarray(forward_kinematics(skeleton, jnp.asarray(pose, body.radii.dtype)), np.float64)
    return SyntheticMotion(body=body, pose=pose, joints3d=joints, fps=float(fps), gait=gait, subject=subject.name, speed=speed)

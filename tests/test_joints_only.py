"""Joints-only motion files (15 HumanEva joints per frame, no pose, no skeleton) convert back to
their skeleton and joints on every frame, whatever the take's length or where in the stride it
starts; the residual is read per frame."""

import glob
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import (
    HUMANEVA_JOINTS,
    forward_kinematics,
    geometric_pose,
    humaneva_skeleton,
    inverse_kinematics,
    residual_report,
    retarget_positions,
    with_offsets,
)
from jaxtrack.cli import main
from jaxtrack.data import generate_motion
from jaxtrack.io import load_sequence, resample

LENGTHS = {"spine": 0.47, "neck": 0.2, "shoulder": 0.17, "upper_arm": 0.3, "forearm": 0.25, "hip": 0.09, "thigh": 0.46,
           "shin": 0.44}  # a person who is not the default body


def _hard_jog(skeleton, start: int, frames: int = 49, seed: int = 14):
    """A jog on a curve with a runner's flexion: elbows bent 1-2.5 rad, knees up to 2.5 rad in
    the swing, the trunk leaning forward; ``frames`` frames from ``start`` (mid-stride). The
    rest-pose start of an undamped Gauss-Newton diverged on such first frames."""
    motion = generate_motion("jog", "S3", num_frames=start + frames, fps=60.0, start_angle=seed * 0.9, path_radius=1.5,
                             key=jax.random.key(seed), dtype=jnp.float64)
    pose = np.asarray(motion.pose).copy()
    layout = list(skeleton.pose_layout)
    for side in "lr":
        elbow, knee, hip = (layout.index(side + name) for name in ("elbow_flex", "knee_flex", "hip_flex"))
        pose[:, elbow] = np.clip(pose[:, elbow] + 1.0, 0.0, 2.5)
        pose[:, knee] = np.clip(1.6 * pose[:, knee], 0.0, 2.5)
        pose[:, hip] *= 1.4
    pose[:, layout.index("spine_flex")] += 0.25
    pose = pose[start:]
    return pose, np.asarray(forward_kinematics(skeleton, jnp.asarray(pose)))


def test_geometric_pose_reads_poses_back_in_numpy_and_under_jit():
    skeleton = humaneva_skeleton(LENGTHS, dtype=jnp.float64)
    low = np.where(np.isfinite(skeleton.lower), skeleton.lower, -3.0)
    high = np.where(np.isfinite(skeleton.upper), skeleton.upper, 3.0)
    poses = low + (high - low) * np.asarray(jax.random.uniform(jax.random.key(0), (500, skeleton.num_dofs)))
    layout = list(skeleton.pose_layout)
    for name in ("lelbow_flex", "relbow_flex", "lknee_flex", "rknee_flex"):  # no straight limb: every twist is seen
        poses[:, layout.index(name)] = np.maximum(poses[:, layout.index(name)], 0.05)
    joints = np.asarray(forward_kinematics(skeleton, jnp.asarray(poses)))
    in_numpy = geometric_pose(skeleton, joints)
    assert isinstance(in_numpy, np.ndarray) and in_numpy.shape == (500, skeleton.num_dofs)
    under_jit = jax.jit(jax.vmap(lambda j: geometric_pose(skeleton, j)))(jnp.asarray(joints))
    np.testing.assert_allclose(np.asarray(under_jit), in_numpy, atol=1e-6)
    # Bone directions are read exactly: the joints come back, whatever the angles were (the pelvis
    # pitch reads as zero and the spine makes it up; angles outside the limits are not pulled in).
    back = np.asarray(forward_kinematics(skeleton, jnp.asarray(in_numpy)))
    np.testing.assert_allclose(back, joints, atol=1e-9)
    assert np.allclose(in_numpy[:, layout.index("root_pitch")], 0.0)


def test_a_joints_only_jog_cut_mid_stride_converts_back_to_its_skeleton(tmp_path, capsys):
    skeleton = humaneva_skeleton(LENGTHS, dtype=jnp.float64)
    _, joints = _hard_jog(skeleton, start=38)
    source = tmp_path / "jog_joints_only.npz"
    np.savez(source, fps=60.0, joints3d=joints, joint_names=np.array(HUMANEVA_JOINTS))
    out = tmp_path / "jog.npz"
    assert main(["convert", str(source), str(out)]) == 0
    printed = capsys.readouterr().out
    assert "at the floor" in printed and "warning" not in printed
    converted = load_sequence(out)
    bones = np.linalg.norm(converted.skeleton_offsets, axis=1)
    np.testing.assert_allclose(bones, np.linalg.norm(np.asarray(skeleton.offsets), axis=1), atol=2e-3)  # 2 mm a bone
    refitted = np.asarray(forward_kinematics(with_offsets(skeleton, converted.skeleton_offsets), jnp.asarray(converted.pose)))
    per_frame = 1000.0 * np.linalg.norm(refitted - joints, axis=-1).mean(axis=1)
    assert per_frame.shape == (49,) and per_frame.max() < 2.0, per_frame.round(2)


def test_the_residual_says_whether_the_skeleton_or_some_frames_are_wrong():
    skeleton = humaneva_skeleton(LENGTHS, dtype=jnp.float64)
    _, joints = _hard_jog(skeleton, start=20, frames=30)
    sound = inverse_kinematics(joints, key=jax.random.key(0))
    assert residual_report(sound.residual_mm).pattern == "floor"
    # The skeleton fails every frame: another person's limbs (the default body, 3-7 cm off here).
    wrong = inverse_kinematics(joints, skeleton=humaneva_skeleton({**LENGTHS, "thigh": 0.38, "shin": 0.37, "spine": 0.55},
                                                                  dtype=jnp.float64), key=jax.random.key(0))
    report = residual_report(wrong.residual_mm)
    assert report.pattern == "every frame" and report.frames == ()
    assert "points at the skeleton" in report.describe()
    # Some frames are wrong: the wrists swapped in frames 10-12.
    swapped = joints.copy()
    left, right = HUMANEVA_JOINTS.index("lwrist"), HUMANEVA_JOINTS.index("rwrist")
    swapped[10:13, [left, right]] = swapped[10:13, [right, left]]
    report = residual_report(inverse_kinematics(swapped, key=jax.random.key(0)).residual_mm)
    assert report.pattern == "some frames" and set(report.frames) >= {10, 11, 12} and len(report.frames) <= 5
    assert "frames 10-12" in report.describe()
    with pytest.raises(ValueError, match="frames, joints"):
        residual_report(np.zeros(5))


def test_degenerate_joints_give_finite_poses():
    # Every joint on one point (a tracker's NaN mask filled with zeros): no NaN leaks out.
    result = inverse_kinematics(np.zeros((3, 15, 3)) + 0.5, skeleton=humaneva_skeleton(dtype=jnp.float64),
                                key=jax.random.key(0))
    assert np.all(np.isfinite(np.asarray(result.pose))) and np.all(np.isfinite(np.asarray(result.residual_mm)))


# --- the shared jogs (../shared/data; skipped when absent) ----------------------------------


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_hdm05_jog_cut_mid_stride_converts_at_its_floor(shared_data):
    """The 49-frame cut of HDM05 bk's jog from frame 98 (60 Hz): the rest-pose start diverged
    on its first frame (554 mm) and left every later frame at 21-24 mm."""
    from jaxtrack.io import load_asf_amc

    folder = os.path.join(shared_data, "multi_subject", "hdm05_bk")
    amc = sorted(glob.glob(os.path.join(folder, "*jogLeftCircle*_003_*.amc")))[0]
    motion = load_asf_amc(os.path.join(folder, "HDM_bk.asf"), amc, fps=120.0)
    joints = resample(retarget_positions(motion.positions, motion.joint_names), 120.0, 60.0)[98:98 + 49]
    report = residual_report(inverse_kinematics(joints, key=jax.random.key(98)).residual_mm)
    assert report.pattern == "floor" and report.per_frame_mm.max() < 6.0, report.describe()

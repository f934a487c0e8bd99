import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import (
    HUMANEVA_JOINTS,
    forward_kinematics,
    humaneva_body,
    humaneva_skeleton,
    part_group_indices,
    with_offsets,
)

from helpers import finite_difference_check


@pytest.fixture
def skeleton():
    return humaneva_skeleton(dtype=jnp.float64)


def random_poses(key, skeleton, n, scale=0.4):
    lower = np.where(np.isfinite(skeleton.lower), skeleton.lower, -1.0)
    upper = np.where(np.isfinite(skeleton.upper), skeleton.upper, 1.0)
    mid, half = (lower + upper) / 2, (upper - lower) / 2
    return jnp.asarray(mid + scale * half * np.asarray(jax.random.uniform(key, (n, skeleton.num_dofs), minval=-1, maxval=1)))


def test_layout_and_tree(skeleton):
    assert skeleton.joint_names == HUMANEVA_JOINTS
    assert skeleton.parents == (-1, 0, 1, 2, 3, 1, 5, 6, 0, 8, 9, 0, 11, 12, 1)
    assert skeleton.num_dofs == 32
    assert len(skeleton.pose_layout) == 32 and skeleton.pose_layout[:3] == ("root_x", "root_y", "root_z")
    groups = part_group_indices(skeleton)
    assert sorted(i for g in groups.values() for i in g) == list(range(15))


def test_rest_pose_positions(skeleton):
    pose = skeleton.zero_pose().at[:3].set(jnp.array([1.0, 2.0, 0.95]))
    joints = np.asarray(forward_kinematics(skeleton, pose))
    np.testing.assert_allclose(joints[0], [1, 2, 0.95])
    np.testing.assert_allclose(joints[1], [1, 2, 1.45])  # thorax 0.50 above the pelvis
    np.testing.assert_allclose(joints[10], [1, 2.1, 0.95 - 0.44 - 0.43])  # left ankle
    np.testing.assert_allclose(joints[14], [1, 2, 1.45 + 0.22])  # head


def test_known_rotations(skeleton):
    base = skeleton.zero_pose().at[2].set(1.0)
    # 90 degrees of hip flexion puts the left knee straight ahead of the hip (+x).
    joints = forward_kinematics(skeleton, base.at[skeleton.dof_index("lhip_flex")].set(jnp.pi / 2))
    np.testing.assert_allclose(joints[9], [0.44, 0.1, 1.0], atol=1e-12)
    # 90 degrees of knee flexion folds the shin backwards (-x) from the knee.
    joints = forward_kinematics(skeleton, base.at[skeleton.dof_index("rknee_flex")].set(jnp.pi / 2))
    np.testing.assert_allclose(joints[13], [-0.43, -0.1, 1.0 - 0.44], atol=1e-12)
    # Abduction raises each arm sideways, outwards.
    joints = forward_kinematics(skeleton, base.at[skeleton.dof_index("lshoulder_abd")].set(jnp.pi / 2))
    np.testing.assert_allclose(joints[3], [0, 0.18 + 0.29, 1.5], atol=1e-12)
    joints = forward_kinematics(skeleton, base.at[skeleton.dof_index("rshoulder_abd")].set(jnp.pi / 2))
    np.testing.assert_allclose(joints[6], [0, -0.18 - 0.29, 1.5], atol=1e-12)
    # A yaw of 90 degrees turns the body to face +y: its left hip moves to -x.
    joints = forward_kinematics(skeleton, base.at[skeleton.dof_index("root_yaw")].set(jnp.pi / 2))
    np.testing.assert_allclose(joints[8], [-0.1, 0, 1.0], atol=1e-12)


def test_bone_lengths_constant_under_any_pose(skeleton, getkey):
    poses = random_poses(getkey(), skeleton, 64, scale=1.0)
    joints = forward_kinematics(skeleton, poses)
    parents = np.array(skeleton.parents)
    lengths = np.linalg.norm(joints[:, 1:] - joints[:, parents[1:]], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(skeleton.bone_lengths()[1:], lengths.shape), rtol=1e-12)


def test_per_subject_limb_lengths():
    tall = humaneva_skeleton({"thigh": 0.5, "shin": 0.5}, dtype=jnp.float64)
    joints = forward_kinematics(tall, tall.zero_pose())
    assert float(joints[10, 2]) == pytest.approx(-1.0)
    moved = with_offsets(tall, np.asarray(tall.offsets) * 2)
    assert float(forward_kinematics(moved, moved.zero_pose())[10, 2]) == pytest.approx(-2.0)
    with pytest.raises(ValueError, match="unknown limb-length"):
        humaneva_skeleton({"tail": 1.0})
    with pytest.raises(ValueError, match="positive"):
        humaneva_skeleton({"thigh": -0.4})


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_fk_gradient_matches_finite_differences(skeleton, getkey):
    pose = random_poses(getkey(), skeleton, 1)[0]
    direction = jax.random.normal(getkey(), pose.shape)
    finite_difference_check(lambda p: forward_kinematics(skeleton, p), pose, direction)
    # ... and with respect to the limb lengths (offsets).
    finite_difference_check(
        lambda o: forward_kinematics(with_offsets(skeleton, o), pose), skeleton.offsets, jax.random.normal(getkey(), (15, 3))
    )


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_fk_jit_vmap_consistency(skeleton, getkey):
    poses = random_poses(getkey(), skeleton, 5)
    batched = forward_kinematics(skeleton, poses)
    jitted = jax.jit(forward_kinematics)(skeleton, poses)
    looped = jnp.stack([forward_kinematics(skeleton, p) for p in poses])
    vmapped = jax.vmap(forward_kinematics, in_axes=(None, 0))(skeleton, poses)
    with jax.disable_jit():
        unjitted = forward_kinematics(skeleton, poses)
    for other in (jitted, looped, vmapped, unjitted):
        np.testing.assert_allclose(batched, other, rtol=1e-12, atol=1e-12)


def test_joint_limits(skeleton):
    pose = skeleton.zero_pose().at[skeleton.dof_index("lknee_flex")].set(-0.3)
    assert float(skeleton.limit_violation(pose)) == pytest.approx(0.3)
    clipped = skeleton.clip_to_limits(pose)
    assert float(clipped[skeleton.dof_index("lknee_flex")]) == 0.0
    assert float(skeleton.limit_violation(clipped)) == 0.0


def test_bad_pose_shape(skeleton):
    with pytest.raises(ValueError, match="needs 32"):
        forward_kinematics(skeleton, jnp.zeros(31))


def test_body_capsules():
    body = humaneva_body(radius_scale={"legs": 2.0}, dtype=jnp.float64)
    assert body.num_capsules == 15
    assert float(body.radii[body.capsule_names.index("lthigh")]) == pytest.approx(0.15)
    start, end = body.capsules(body.skeleton.zero_pose())
    assert start.shape == (15, 3) and end.shape == (15, 3)
    head = body.capsule_names.index("head")
    np.testing.assert_allclose(end[head], [0, 0, 0.50 + 1.05 * 0.22])
    with pytest.raises(ValueError, match="positive"):
        humaneva_body(radius_scale=0.0)


def test_check_poses_names_the_bad_entry(skeleton):
    from jaxtrack.body import check_poses

    poses = np.zeros((3, 32))
    assert check_poses(skeleton, poses).shape == (3, 32)
    poses[1, skeleton.dof_index("lknee_flex")] = np.nan
    with pytest.raises(ValueError, match=r"index \(1, 24\) \(pose entry 'lknee_flex'\)"):
        check_poses(skeleton, poses)
    with pytest.raises(ValueError, match="32 numbers per pose"):
        check_poses(skeleton, np.zeros((3, 30)))

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.camera import default_rig, look_at, make_rig
from jaxtrack.data import NO_NOISE, SUBJECTS, SilhouetteNoise, build_scene, generate_motion, random_subject
from jaxtrack.render import hard_silhouettes


def speed(motion):
    return np.linalg.norm(np.diff(motion.joints3d[:, 0, :2], axis=0), axis=1).mean() * motion.fps


@pytest.mark.parametrize("gait,low,high", [("walk", 1.0, 1.5), ("jog", 2.5, 3.8), ("run", 3.5, 5.5)])
def test_gait_speed_and_geometry(gait, low, high):
    for subject in SUBJECTS:
        motion = generate_motion(gait, subject, num_frames=120, fps=60.0, dtype=jnp.float64)
        assert low < speed(motion) < high, (gait, subject, speed(motion))
        sk = motion.body.skeleton
        # inside the joint limits, feet on the ground, head at a human height
        assert float(jnp.max(sk.limit_violation(jnp.asarray(motion.pose)))) == 0.0
        ankles = motion.joints3d[:, [sk.joint_index("lankle"), sk.joint_index("rankle")], 2]
        assert ankles.min() == pytest.approx(0.08, abs=1e-6)
        assert 1.45 < motion.joints3d[:, sk.joint_index("head"), 2].mean() < 1.85
        # bone lengths constant, the root stays inside the 4 m capture area
        lengths = np.linalg.norm(motion.joints3d[:, 1:] - motion.joints3d[:, list(sk.parents[1:])], axis=-1)
        np.testing.assert_allclose(lengths.std(axis=0), 0, atol=1e-9)
        assert np.abs(motion.joints3d[:, 0, :2]).max() < 2.0


def test_gait_has_alternating_legs_and_knee_swing():
    motion = generate_motion("walk", "S1", num_frames=64, fps=60.0, dtype=jnp.float64)
    sk = motion.body.skeleton
    left, right = motion.pose[:, sk.dof_index("lhip_flex")], motion.pose[:, sk.dof_index("rhip_flex")]
    assert np.corrcoef(left, right)[0, 1] < -0.8  # legs in antiphase
    arm = motion.pose[:, sk.dof_index("lshoulder_flex")]
    assert np.corrcoef(left, arm)[0, 1] < -0.8  # arm swings against its leg
    knee = np.rad2deg(motion.pose[:, sk.dof_index("lknee_flex")])
    assert 50 < knee.max() < 75 and knee.min() < 10


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_subjects_and_keys_change_the_motion():
    a = generate_motion("walk", "S1", num_frames=30, key=jax.random.key(0))
    b = generate_motion("walk", "S1", num_frames=30, key=jax.random.key(0))
    c = generate_motion("walk", "S1", num_frames=30, key=jax.random.key(1))
    d = generate_motion("walk", "S2", num_frames=30, key=jax.random.key(0))
    np.testing.assert_array_equal(a.pose, b.pose)
    assert not np.allclose(a.pose, c.pose)
    assert not np.allclose(a.body.skeleton.offsets, d.body.skeleton.offsets)
    r = random_subject(jax.random.key(3))
    assert generate_motion("jog", r, num_frames=10).subject == "random"
    with pytest.raises(ValueError, match="unknown gait"):
        generate_motion("skip")
    with pytest.raises(ValueError, match="unknown subject"):
        generate_motion("walk", "S9")


@pytest.mark.slow
def test_scene_is_deterministic_and_noisy():
    motion = generate_motion("walk", "S1", num_frames=6, fps=30.0)
    rig = default_rig(40, 30)
    a = build_scene(jax.random.key(0), motion, rig, chunk=4)
    b = build_scene(jax.random.key(0), motion, rig, chunk=6)  # chunking does not matter
    c = build_scene(jax.random.key(1), motion, rig)
    np.testing.assert_array_equal(a.silhouettes, b.silhouettes)
    assert (a.silhouettes != c.silhouettes).any()
    clean = build_scene(jax.random.key(0), motion, rig, NO_NOISE)
    hard = np.asarray(hard_silhouettes(motion.body, rig, jnp.asarray(motion.pose, jnp.float32)))
    np.testing.assert_array_equal(clean.silhouettes, hard.transpose(1, 0, 2, 3))
    changed = (a.silhouettes != clean.silhouettes).mean()
    assert 0.005 < changed < 0.1  # noisy, but still a silhouette


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_noise_effects_individually():
    motion = generate_motion("walk", "S1", num_frames=4, fps=30.0)
    rig = default_rig(80, 60)
    clean = build_scene(jax.random.key(0), motion, rig, NO_NOISE).silhouettes.astype(int)
    only = lambda **kw: build_scene(jax.random.key(0), motion, rig, SilhouetteNoise(**{**NO_NOISE.__dict__, **kw})).silhouettes.astype(int)  # noqa: E731
    shadows = only(shadow_length=0.5, shadow_width=0.08)
    assert (shadows >= clean).all() and (shadows > clean).any()  # shadows only add
    holes = only(holes=6.0, hole_radius=(1.0, 2.0))
    assert (holes <= clean).all() and (holes < clean).any()  # holes only remove
    blobs = only(blobs=6.0, blob_radius=(1.0, 2.0))
    assert (blobs >= clean).all() and (blobs > clean).any()
    with pytest.raises(ValueError, match="boundary_flip"):
        SilhouetteNoise(boundary_flip=1.5)


def test_camera_behind_the_body_is_refused():
    motion = generate_motion("walk", "S1", num_frames=4)
    R, t = look_at([0.2, 0.0, 1.0], [3.0, 0.0, 1.0])  # inside the capture area, looking away
    rig = make_rig([[[50.0, 0, 20], [0, 50, 15], [0, 0, 1]]], R[None], t[None], [(40, 30)])
    with pytest.raises(ValueError, match="camera 'cam0' is behind the body"):
        build_scene(jax.random.key(0), motion, rig)


def test_scene_refuses_nan_poses():
    import dataclasses

    motion = generate_motion("walk", "S1", num_frames=4)
    pose = motion.pose.copy()
    pose[2, 10] = np.inf
    with pytest.raises(ValueError, match=r"motion poses contain a non-finite value at index \(2, 10\)"):
        build_scene(jax.random.key(0), dataclasses.replace(motion, pose=pose), default_rig(40, 30))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_scene_from_a_recorded_sequence(tmp_path):
    """A sequence file's motion renders like the motion itself; centring moves the root path's
    midpoint (and the ground truth with it) to the capture area's centre; the CLI writes a test
    sequence; bad ranges and missing poses are refused."""
    from jaxtrack.cli import main
    from jaxtrack.data import motion_sequence, scene_from_sequence
    from jaxtrack.io import load_sequence, save_sequence

    motion = generate_motion("walk", "S1", num_frames=8, fps=30.0)
    sequence = motion_sequence(motion)
    rig = default_rig(40, 30)
    direct = build_scene(jax.random.key(3), motion, rig, NO_NOISE)
    via = scene_from_sequence(jax.random.key(3), sequence, rig, NO_NOISE, centre=False)
    np.testing.assert_array_equal(via.silhouettes, direct.silhouettes)
    np.testing.assert_allclose(via.joints3d, motion.joints3d)
    centred = scene_from_sequence(jax.random.key(3), sequence, rig, NO_NOISE)  # same frame count: no recompilation
    path = centred.pose[:, :2]
    np.testing.assert_allclose(0.5 * (path.min(0) + path.max(0)), 0.0, atol=1e-12)
    shift = motion.pose[:, :2] - centred.pose[:, :2]
    np.testing.assert_allclose(motion.joints3d[:, :, :2] - centred.joints3d[:, :, :2], np.broadcast_to(shift[:, None], (8, 15, 2)))
    np.testing.assert_allclose(centred.pose[:, 2:], motion.pose[:, 2:])
    with pytest.raises(ValueError, match="outside the sequence's 8 frames"):
        scene_from_sequence(jax.random.key(3), sequence, rig, start=6, frames=5)
    with pytest.raises(ValueError, match="no 'pose' to render"):
        scene_from_sequence(jax.random.key(3), sequence.replace(pose=None, pose_layout=None), rig)
    save_sequence(tmp_path / "motion.npz", sequence)
    assert main(["scene", str(tmp_path / "motion.npz"), str(tmp_path / "scene.npz"), "--start", "0", "--frames", "8",
                 "--width", "40", "--height", "30", "--clean", "--no-centre", "--seed", "3"]) == 0
    written = load_sequence(tmp_path / "scene.npz")
    np.testing.assert_array_equal(written.silhouettes, direct.silhouettes)

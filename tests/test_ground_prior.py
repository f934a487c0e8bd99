"""The ground plane as a pose prior (``jaxtrack.likelihood.GroundPlanePrior``): its values
against a NumPy reference, its gradient against finite differences, jit and vmap, the clearance
fitted from motion, bad input, and what it does to the silhouettes' preferred root height."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import forward_kinematics, humaneva_skeleton
from jaxtrack.camera import default_rig
from jaxtrack.data import ANKLE_HEIGHT, SilhouetteNoise, build_scene, generate_motion, motion_sequence
from jaxtrack.likelihood import GroundPlanePrior, SumLikelihood, ground_clearance, make_ground_prior
from jaxtrack.tracking import add_ground_prior, motion_clearance, prepare_test, sequence_poses


@pytest.fixture(scope="module")
def walk():
    return generate_motion("walk", "S1", num_frames=40, fps=30.0, key=jax.random.key(3))


def reference(prior_args, joints):
    """The prior by hand from (N, J, 3) joints."""
    clearance, tolerance, floor = prior_args
    skeleton = humaneva_skeleton()
    z = joints[:, [skeleton.joint_index("lankle"), skeleton.joint_index("rankle")], 2] - floor
    return -0.5 * np.sum(np.maximum(clearance - z, 0.0) ** 2, axis=1) / tolerance**2


def test_values_match_a_reference_and_are_flat_above_the_clearance(walk):
    skeleton = humaneva_skeleton()
    poses = jnp.asarray(walk.pose[:10])
    prior = make_ground_prior(skeleton, 0.09, tolerance=0.02, floor_height=0.005)
    for shift in (0.0, -0.03, -0.1):  # the whole body lowered by `shift` metres
        lowered = poses.at[:, 2].add(shift)
        joints = np.asarray(forward_kinematics(skeleton, lowered), np.float64)
        np.testing.assert_allclose(prior(lowered, None), reference((0.09, 0.02, 0.005), joints), rtol=1e-4, atol=1e-6)
    raised = poses.at[:, 2].add(0.2)  # every ankle well above the clearance: no penalty
    np.testing.assert_array_equal(prior(raised, None), np.zeros(10))
    assert float(prior(poses.at[:, 2].add(-0.1), None).max()) < -1.0  # 10 cm into the floor costs nats


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_gradient_matches_finite_differences(walk):
    prior = make_ground_prior(humaneva_skeleton(dtype=jnp.float64), 0.1, tolerance=0.01)
    pose = jnp.asarray(walk.pose[5], jnp.float64).at[2].add(-0.04)  # one or both ankles below the clearance

    @jax.jit
    def value(p):
        return prior(p[None], None)[0]

    grad = np.asarray(jax.grad(value)(pose))
    assert np.abs(grad).max() > 1.0
    eps = 1e-6
    for i in (0, 1, 2, 6, 10, 20):
        step = jnp.zeros_like(pose).at[i].set(eps)
        fd = (float(value(pose + step)) - float(value(pose - step))) / (2 * eps)
        assert grad[i] == pytest.approx(fd, rel=1e-4, abs=1e-4)


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_jit_and_vmap_agree_with_plain_calls(walk):
    prior = make_ground_prior(humaneva_skeleton(), 0.1)
    poses = jnp.asarray(walk.pose[:8]).at[:, 2].add(-0.03)
    plain = prior(poses, None)
    np.testing.assert_allclose(jax.jit(lambda p: prior(p, None))(poses), plain, rtol=1e-6)
    one_by_one = np.array([float(prior(p[None], None)[0]) for p in poses])
    np.testing.assert_allclose(plain, one_by_one, rtol=1e-6)
    summed = prior + prior
    assert isinstance(summed, SumLikelihood)
    np.testing.assert_allclose(summed(poses, None), 2 * plain, rtol=1e-6)


def test_clearance_is_fitted_from_motion_and_lowered_for_a_known_pose(walk):
    skeleton = humaneva_skeleton()
    joints = np.asarray(walk.joints3d)
    # The synthetic gait puts the stance ankle ANKLE_HEIGHT above the floor.
    assert ground_clearance([joints], skeleton.joint_names) == pytest.approx(ANKLE_HEIGHT, abs=0.003)
    assert ground_clearance([joints + [0, 0, 0.5]], skeleton.joint_names, floor_height=0.5) == pytest.approx(ANKLE_HEIGHT, abs=0.003)
    assert ground_clearance([joints], skeleton.joint_names, percentile=0.0) == pytest.approx(joints[:, [10, 13], 2].min(), abs=1e-6)
    prior = make_ground_prior(skeleton, 0.2)
    pose = jnp.asarray(walk.pose[0])
    lowest = prior.lowest_ankle(pose)
    assert lowest == pytest.approx(joints[0, [10, 13], 2].min(), abs=1e-5)
    allowed = prior.allowing(pose)
    assert float(allowed.clearance) == pytest.approx(lowest, abs=1e-6)
    assert float(allowed(pose[None], None)[0]) == pytest.approx(0.0, abs=1e-9)
    assert float(prior.allowing(pose.at[2].add(1.0)).clearance) == pytest.approx(0.2)  # never raised


def test_bad_input_is_refused_with_a_clear_error(walk):
    skeleton = humaneva_skeleton()
    joints = np.asarray(walk.joints3d)
    with pytest.raises(ValueError, match="at least one frame"):
        ground_clearance([], skeleton.joint_names)
    with pytest.raises(ValueError, match=r"must be \(T, 15, 3\)"):
        ground_clearance([joints[:, :14]], skeleton.joint_names)
    bad = joints.copy()
    bad[7, 3, 1] = np.nan
    with pytest.raises(ValueError, match="frame 7"):
        ground_clearance([bad], skeleton.joint_names)
    with pytest.raises(ValueError, match="lacks"):
        ground_clearance([joints], [n.replace("ankle", "foot") for n in skeleton.joint_names])
    with pytest.raises(ValueError, match="percentile"):
        ground_clearance([joints], skeleton.joint_names, percentile=101.0)
    with pytest.raises(ValueError, match="tolerance"):
        make_ground_prior(skeleton, 0.08, tolerance=0.0)
    with pytest.raises(ValueError, match="finite"):
        make_ground_prior(skeleton, float("nan"))
    with pytest.raises(ValueError, match="make_ground_prior"):
        GroundPlanePrior(skeleton=skeleton, clearance=jnp.asarray(0.1), tolerance=jnp.asarray(0.01), floor_height=jnp.asarray(0.0))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_the_prior_removes_the_noisy_silhouettes_pull_on_the_root():
    """In noisy views the silhouettes prefer the body lower than it is (shadows and a ragged
    lower edge); times the ground prior, fitted on another take, the preferred root height is
    the true one."""
    key = jax.random.key(0)
    test = build_scene(jax.random.fold_in(key, 1), generate_motion("walk", "S1", num_frames=12, fps=30.0, key=key),
                       default_rig(80, 60), SilhouetteNoise())
    validation = motion_sequence(generate_motion("walk", "S1", num_frames=20, fps=30.0, key=jax.random.key(7)))
    scene = prepare_test(test, "walk", key=key)
    clearance = motion_clearance([validation], [sequence_poses(validation, "validation", key=key)])
    assert clearance == pytest.approx(ANKLE_HEIGHT, abs=0.005)
    grounded = add_ground_prior(scene, clearance)
    assert grounded.ground_prior is not None and float(grounded.ground_prior.clearance) <= clearance + 1e-6
    truth = jnp.asarray(scene.truth_poses, jnp.float32)
    shifts = np.arange(-20, 6, 2.5)  # mm

    def sequence_total(likelihood):
        @jax.jit
        def total(shift):  # the sequence's log-likelihood with the root lowered by `shift` metres
            return jnp.sum(jax.vmap(lambda p, o: likelihood(p[None], o)[0])(truth.at[:, 2].add(shift), scene.observations))

        return np.array([float(total(jnp.float32(d / 1000))) for d in shifts])

    # The grounded likelihood is the sum of the two, so each is scored once.
    assert isinstance(grounded.likelihood, SumLikelihood) and grounded.likelihood.terms[1] is grounded.ground_prior
    silhouettes, ground = sequence_total(scene.likelihood), sequence_total(grounded.ground_prior)
    alone, with_ground = shifts[np.argmax(silhouettes)], shifts[np.argmax(silhouettes + ground)]
    assert alone <= -7.5 and abs(with_ground) <= 2.5, (alone, with_ground)

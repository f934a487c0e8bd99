"""``filters.RecoveringSIR`` (004 sec. 6.1): SIR exactly when there is no evidence to fit and
no restart; a lost tracker restarted from its dynamics' restart distribution; the evidence of a
likelihood fitted from several starts."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import AbstractRestartableDynamics, PoseRandomWalk, make_pose_random_walk
from jaxtrack.filters import SIR, RecoveringSIR, run_filter
from jaxtrack.likelihood import as_likelihood, evidence_scorer, has_evidence, lost_threshold

D = 8
SIGMA = 0.1


def _gaussian(poses, target):
    """A Gaussian likelihood around the frame's target pose (sd 0.1 in every entry)."""
    return -0.5 * jnp.sum((poses - target) ** 2, axis=1) / SIGMA ** 2


class _JumpWalk(AbstractRestartableDynamics):
    """A pose random walk whose restart puts every joint angle (entries 6:) near ``home``."""

    walk: PoseRandomWalk
    home: float = 1.0

    def init(self, key, pose, num_particles):
        return self.walk.init(key, pose, num_particles)

    def to_pose(self, states):
        return states

    def propose(self, key, previous):
        return self.walk.propose(key, previous)

    def perturb(self, key, states, factor):
        return self.walk.perturb(key, states, factor)

    def restart(self, key, states):
        fresh = self.home + 0.05 * jax.random.normal(key, states[:, 6:].shape, states.dtype)
        return jnp.concatenate([states[:, :6], fresh], axis=1)


def _targets(frames=6, home=1.0):
    return jnp.broadcast_to(jnp.concatenate([jnp.zeros(6), jnp.full(D - 6, home)]), (frames, D)).astype(jnp.float32)


def test_without_evidence_or_restarts_it_is_sir_exactly():
    walk = make_pose_random_walk(jnp.full(D, 0.05))
    likelihood = as_likelihood(_gaussian)
    sir = SIR(walk, likelihood, 64)
    recovering = RecoveringSIR(walk, likelihood, 64)
    targets = (0.1 * jnp.arange(6)[:, None] * jnp.ones((6, D))).astype(jnp.float32)
    start = jnp.zeros(D, jnp.float32)
    s_state, s_info = run_filter(sir, jax.random.key(3), start, targets)
    r_state, r_info = run_filter(recovering, jax.random.key(3), start, targets)
    np.testing.assert_array_equal(np.asarray(r_info.estimate), np.asarray(s_info.estimate))
    np.testing.assert_array_equal(np.asarray(r_state.log_weights), np.asarray(s_state.log_weights))
    assert r_info.restarted is None and not has_evidence(likelihood) and lost_threshold(likelihood) is None


def test_a_lost_tracker_restarts_and_a_tracking_one_does_not():
    dynamics = _JumpWalk(make_pose_random_walk(jnp.full(D, 0.02)))
    likelihood = as_likelihood(_gaussian)
    targets = _targets()
    start = jnp.zeros(D, jnp.float32)  # every joint angle 1 rad (10 sd) from the targets': the best particle scores about -100
    lost = RecoveringSIR(dynamics, likelihood, 128, lost_below=-20.0)
    _, info = run_filter(lost, jax.random.key(0), start, targets)
    restarted = np.asarray(info.restarted)
    assert restarted[0] and not restarted[1:].any()  # once, then tracking
    np.testing.assert_allclose(np.asarray(info.estimate)[1:, 6:], 1.0, atol=0.05)
    # the same filter without restarts stays where it started (0.02 rad a frame)
    _, stuck = run_filter(dataclasses.replace(lost, lost_below=None), jax.random.key(0), start, targets)
    assert np.all(np.abs(np.asarray(stuck.estimate)[:, 6:] - 1.0) > 0.5)
    # started at the targets it never restarts, and restarting keeps the roots
    _, fine = run_filter(lost, jax.random.key(0), targets[0], targets)
    assert not np.asarray(fine.restarted).any()
    states = jnp.tile(jnp.arange(D, dtype=jnp.float32), (5, 1))
    np.testing.assert_array_equal(np.asarray(dynamics.restart(jax.random.key(1), states)[:, :6]), np.asarray(states[:, :6]))


def test_restarts_need_restartable_dynamics():
    with pytest.raises(ValueError, match="PoseRandomWalk has none"):
        RecoveringSIR(make_pose_random_walk(jnp.full(D, 0.05)), as_likelihood(_gaussian), 16, lost_below=-10.0)
    with pytest.raises(ValueError, match="starts must be"):
        RecoveringSIR(make_pose_random_walk(jnp.full(D, 0.05)), as_likelihood(_gaussian), 16, starts="last")


@pytest.mark.slow  # compiles the visual hull (6-7 s cold)
def test_blob_evidence_from_two_starts_keeps_the_better_fit():
    from jaxtrack.body import humaneva_body
    from jaxtrack.camera import default_rig
    from jaxtrack.likelihood import make_blob_likelihood
    from jaxtrack.render import hard_silhouettes

    body = humaneva_body()
    rig = default_rig(80, 60)
    pose = jnp.zeros(body.skeleton.num_dofs).at[2].set(0.95).at[3].set(0.4)
    pose = pose.at[body.skeleton.dof_index("lhip_flex")].set(0.4).at[body.skeleton.dof_index("rshoulder_flex")].set(0.5)
    silhouettes = eqx.filter_jit(hard_silhouettes)(body, rig, pose).astype(jnp.float32)
    far = pose.at[3].add(np.pi).at[body.skeleton.dof_index("lhip_flex")].set(-0.6)  # turned round, the other leg forward
    likelihood = make_blob_likelihood(body, rig, power=10.0) + as_likelihood(lambda p, o: jnp.zeros(p.shape[0]))
    blobs = likelihood.terms[0]
    assert has_evidence(likelihood) and lost_threshold(likelihood) == pytest.approx(-10.0 * np.log(blobs.lost_divergence))
    poses = pose + 0.05 * jax.random.normal(jax.random.key(0), (40, pose.shape[0]))

    @eqx.filter_jit
    def scores(starts, lik):
        evidence = lik.terms[0].fit_evidence(silhouettes, starts)
        return evidence_scorer(lik, silhouettes, starts)(poses), evidence.fit

    both, fits = scores(jnp.stack([far, pose]), likelihood)
    alone, _ = scores(pose[None], likelihood)
    assert float(fits[1]) > float(fits[0])  # the true pose's start explains the voxels better
    np.testing.assert_allclose(np.asarray(both), np.asarray(alone), rtol=1e-6)
    # one start: the evidence likelihood is its own log_likelihood from the poses' mean
    mean_start, _ = scores(jnp.mean(poses, axis=0)[None], likelihood)
    np.testing.assert_allclose(np.asarray(mean_start), np.asarray(eqx.filter_jit(likelihood)(poses, silhouettes)), rtol=1e-6)

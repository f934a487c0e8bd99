"""The off-manifold pose residual (``jaxtrack.dynamics.PoseResidual``): where it starts, what it
draws, its density, its fit, and a tracker that reaches a pose its manifold does not hold."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import PoseResidual, StateVelocity, fit_gpdm_latent_dynamics, fit_pose_residual, fit_root_velocity
from jaxtrack.errors import ConfigurationError
from jaxtrack.experiment import ExperimentConfig
from jaxtrack.filters import SIR, LangevinRefinement, StateMean, run_filter
from jaxtrack.likelihood import as_likelihood

from helpers import check_refinement_keeps_transition


@pytest.fixture(scope="module")
def gpdm(walk, gpdm_prior):
    return fit_gpdm_latent_dynamics(gpdm_prior, walk[45:])


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_starts_at_the_given_pose_not_at_its_projection(gpdm, walk, getkey):
    residual = fit_pose_residual(gpdm, walk[45:], 1.0)
    pose = jnp.asarray(walk[10]).at[10].add(0.3)  # off the manifold
    on_manifold = gpdm.to_pose(gpdm.init(getkey(), pose, 1))[0]
    assert float(jnp.abs(on_manifold - pose).max()) > 0.1
    for dynamics in (residual, fit_root_velocity(walk[45:]).wrap(residual)):
        states = dynamics.init(getkey(), pose, 5)
        np.testing.assert_allclose(dynamics.to_pose(states), np.broadcast_to(pose, (5, 32)), atol=1e-12)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_draws_the_inner_transition_and_a_gaussian_walk_of_the_angles(gpdm, walk, getkey):
    """The inner part is the inner dynamics' draw bit for bit (from the first half of the key),
    the residual moves by N(0, scales^2), and ``log_transition`` is the sum of both densities."""
    scales = jnp.linspace(0.01, 0.05, 26)
    dynamics = PoseResidual(gpdm, scales)
    start = dynamics.init(getkey(), jnp.asarray(walk[10]), 40000)
    key = getkey()
    drawn, correction = dynamics.propose(key, start)
    inner_drawn, inner_correction = gpdm.propose(jax.random.split(key)[0], start[:, :-26])
    np.testing.assert_array_equal(drawn[:, :-26], inner_drawn)
    np.testing.assert_array_equal(correction, inner_correction)
    steps = np.asarray(drawn[:, -26:] - start[:, -26:])
    np.testing.assert_allclose(steps.std(0), scales, rtol=0.03)
    assert np.abs(steps.mean(0) / scales).max() < 0.03

    previous, states = drawn[:4], dynamics.propose(getkey(), drawn[:4])[0]
    walk_part = -0.5 * np.sum((np.asarray(states[:, -26:] - previous[:, -26:]) / np.asarray(scales)) ** 2, axis=1)
    expected = np.asarray(gpdm.log_transition(previous[:, :-26], states[:, :-26])) + walk_part
    got = np.asarray(dynamics.log_transition(previous, states))
    np.testing.assert_allclose(got - got[0], expected - expected[0], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(dynamics.noise_scales(), np.concatenate([gpdm.noise_scales(), scales]))
    np.testing.assert_array_equal(dynamics.perturb(getkey(), states, 0.0)[:, -26:], states[:, -26:])
    np.testing.assert_array_equal(dynamics.velocity_states(jnp.asarray(walk)), gpdm.velocity_states(jnp.asarray(walk)))


@pytest.mark.slow
def test_refinement_keeps_the_residual_transition_invariant(gpdm, walk, getkey):
    check_refinement_keeps_transition(PoseResidual(gpdm, jnp.full(26, 0.03)), jnp.asarray(walk[40]), getkey)


def test_fit_and_bad_input(gpdm, walk):
    fitted = fit_pose_residual(gpdm, [walk[45:], walk[:20]], 0.5)
    steps = np.concatenate([np.diff(walk[45:], axis=0), np.diff(walk[:20], axis=0)])[:, 6:]
    np.testing.assert_allclose(fitted.scales, np.maximum(0.5 * np.sqrt(np.mean(steps**2, axis=0)), 0.5e-3), rtol=1e-9)
    for scale in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="residual's scale must be a positive number"):
            fit_pose_residual(gpdm, walk[45:], scale)
    with pytest.raises(ValueError, match="already carries a pose residual"):
        PoseResidual(fitted, fitted.scales)
    with pytest.raises(ValueError, match="covers 26 joint angles"):
        fitted.init(jax.random.key(0), jnp.zeros(20), 3)
    with pytest.raises(ConfigurationError, match="residual must be a scale >= 0"):
        ExperimentConfig(methods=("glegbpf",), residual=-0.5)
    for decay in (0.0, 1.01, float("nan")):
        with pytest.raises(ConfigurationError, match="residual_decay must be a number in"):
            ExperimentConfig(methods=("glegbpf",), residual=0.1, residual_decay=decay)
    assert fit_pose_residual(gpdm, walk[45:], 0.5, decay=0.9).decay == 0.9
    config = ExperimentConfig(methods=("sir", "latentpf", "glegbpf"), residual=1.5)
    assert [config.residual_of(m) for m in config.methods] == [0.0, 1.5, 1.5]  # SIR's state is the pose
    assert [config.residual_decay_of(m) for m in config.methods] == [1.0, 1.0, 1.0]  # a named residual walks
    default = ExperimentConfig(methods=("latentpf", "glegbpf", "vlmmpf"))  # a fading start by default
    assert [(default.residual_of(m), default.residual_decay_of(m)) for m in default.methods] == [(0.05, 0.9), (0.05, 0.9), (0.0, 1.0)]
    from jaxtrack.tracking import FADING_START

    assert FADING_START == (0.05, 0.9)
    assert ExperimentConfig(methods=("glegbpf",), residual_decay=0.5).residual_decay_of("glegbpf") == 0.5


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_a_latent_tracker_with_a_residual_reaches_a_pose_off_its_manifold(gpdm, walk, getkey):
    """The truth is the manifold's pose with one knee bent 0.25 rad further: LatentPF on the
    manifold alone stays about 0.25 rad off in that angle; with the residual most of the offset
    is found within 18 frames (the residual walks in all 26 angles with 300 particles)."""
    target = jnp.asarray(walk[12:30])
    target = target.at[:, 20].add(0.25)
    lik = as_likelihood(lambda poses, truth: -0.5 * jnp.sum(((poses - truth) / 0.05) ** 2, axis=1))
    errors = {}
    for scale in (0.0, 1.0):
        dynamics = gpdm if scale == 0.0 else fit_pose_residual(gpdm, walk[45:], scale)
        tracker = SIR(dynamics, lik, 300, estimator=StateMean())
        key = getkey()
        info = run_filter(tracker, key, jnp.asarray(walk[11]), target)[1]
        errors[scale] = float(jnp.mean(jnp.abs(info.estimate[-6:, 20] - target[-6:, 20])))
    assert errors[0.0] > 0.15, errors
    assert errors[1.0] < 0.4 * errors[0.0], errors


@pytest.mark.slow
def test_same_key_same_result_jitted_or_not(gpdm, walk, getkey):
    """A tracker with the residual inside a velocity, plain and refined: the same run jitted or
    not, and finite."""
    lik = as_likelihood(lambda poses, truth: -0.5 * jnp.sum(((poses - truth) / 0.05) ** 2, axis=1))
    dynamics = StateVelocity(fit_pose_residual(gpdm, walk[45:], 1.0), jnp.full(6, 0.01), jnp.full(6, 0.02))
    key, observations = getkey(), jnp.asarray(walk[12:15])
    for tracker in (SIR(dynamics, lik, 100, estimator=StateMean()), SIR(dynamics, lik, 100, refine=LangevinRefinement(1))):
        jitted = run_filter(tracker, key, jnp.asarray(walk[11]), observations)[1]
        with jax.disable_jit():
            eager = run_filter(tracker, key, jnp.asarray(walk[11]), observations)[1]
        np.testing.assert_allclose(jitted.estimate, eager.estimate, rtol=1e-7, atol=1e-9)
        assert np.all(np.isfinite(np.asarray(jitted.estimate)))


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_build_tracker_wraps_the_residual_inside_the_velocity(gpdm, walk):
    from jaxtrack.tracking import Budget, build_tracker, get_tracker

    lik = as_likelihood(lambda poses, truth: -jnp.sum((poses - truth) ** 2, axis=1))
    recipe = get_tracker("latentpf")
    plain = build_tracker(recipe, gpdm, lik, Budget(50), velocity_from=[walk[45:]])
    assert not isinstance(plain.dynamics.inner, PoseResidual)
    wrapped = build_tracker(recipe, gpdm, lik, Budget(50), velocity_from=[walk[45:]], residual_from=[walk[45:]], residual_scale=1.0)
    assert isinstance(wrapped.dynamics, StateVelocity) and isinstance(wrapped.dynamics.inner, PoseResidual)
    assert eqx.tree_equal(wrapped.dynamics.inner.inner, plain.dynamics.inner)
    assert wrapped.dynamics.inner.scales.dtype == jnp.float32


def test_a_decaying_residual_is_an_ar1_process_that_fades_to_the_manifold(getkey):
    """With ``decay`` d the residual draws ``d r + N(0, scales^2)`` and its density is that
    Gaussian's; the start is still the given pose (the residual is its offset)."""
    from jaxtrack.dynamics import PoseRandomWalk

    inner = PoseRandomWalk(jnp.full(32, 0.01))
    scales = jnp.linspace(0.005, 0.03, 26)
    dynamics = PoseResidual(inner, scales, 0.8)
    offset = jnp.linspace(-0.3, 0.3, 26)
    start = jnp.concatenate([jnp.zeros((20000, 32)), jnp.broadcast_to(offset, (20000, 26))], axis=1)
    drawn, _ = dynamics.propose(getkey(), start)
    residual = np.asarray(drawn[:, 32:])
    np.testing.assert_allclose(residual.mean(0), 0.8 * np.asarray(offset), atol=4 * 0.03 / np.sqrt(20000))
    np.testing.assert_allclose(residual.std(0), scales, rtol=0.03)
    walk = -0.5 * np.sum(((residual[:3] - 0.8 * np.asarray(offset)) / np.asarray(scales)) ** 2, axis=1)
    expected = np.asarray(inner.log_transition(start[:3, :32], drawn[:3, :32])) + walk
    np.testing.assert_allclose(dynamics.log_transition(start[:3], drawn[:3]), expected, rtol=1e-5)
    pose = jnp.zeros(32).at[6:].set(offset)
    np.testing.assert_array_equal(dynamics.to_pose(dynamics.init(getkey(), pose, 2)), np.broadcast_to(pose, (2, 32)))
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ValueError, match="decay must be a number in"):
            PoseResidual(inner, scales, bad)


def test_a_residual_with_a_target_fades_to_that_offset(getkey):
    """With a target ``m`` the residual draws ``m + d (r - m) + N(0, scales^2)``, its density is
    that Gaussian's, the start is still the given pose, and the inner dynamics start from the pose
    less ``m``; no target is a target of zeros; a target of the wrong shape is refused."""
    from jaxtrack.dynamics import PoseRandomWalk

    inner = PoseRandomWalk(jnp.full(32, 0.01))
    scales = jnp.linspace(0.005, 0.03, 26)
    target = jnp.linspace(0.2, -0.1, 26)
    dynamics = PoseResidual(inner, scales, 0.8, target)
    offset = jnp.linspace(-0.3, 0.3, 26)
    start = jnp.concatenate([jnp.zeros((20000, 32)), jnp.broadcast_to(offset, (20000, 26))], axis=1)
    drawn, _ = dynamics.propose(getkey(), start)
    residual = np.asarray(drawn[:, 32:])
    centre = np.asarray(target) + 0.8 * (np.asarray(offset) - np.asarray(target))
    np.testing.assert_allclose(residual.mean(0), centre, atol=4 * 0.03 / np.sqrt(20000))
    np.testing.assert_allclose(residual.std(0), scales, rtol=0.03)
    walk = -0.5 * np.sum(((residual[:3] - centre) / np.asarray(scales)) ** 2, axis=1)
    expected = np.asarray(inner.log_transition(start[:3, :32], drawn[:3, :32])) + walk
    np.testing.assert_allclose(dynamics.log_transition(start[:3], drawn[:3]), expected, rtol=1e-5)

    pose = jnp.zeros(32).at[6:].set(offset)
    states = dynamics.init(getkey(), pose, 2)
    np.testing.assert_allclose(dynamics.to_pose(states), np.broadcast_to(pose, (2, 32)), atol=1e-6)
    np.testing.assert_allclose(states[:, 6:32], np.broadcast_to(offset - target, (2, 26)), atol=1e-6)  # the inner pose: pose - m

    key = getkey()
    zeros = PoseResidual(inner, scales, 0.8, jnp.zeros(26))
    np.testing.assert_array_equal(zeros.propose(key, start[:5])[0], PoseResidual(inner, scales, 0.8).propose(key, start[:5])[0])
    with pytest.raises((ValueError, TypeError)):  # jaxtyping's check of "angles", or the module's own
        PoseResidual(inner, scales, 0.8, jnp.zeros(25))
    fitted = fit_pose_residual(inner, np.cumsum(np.full((20, 32), 0.01), axis=0), 1.0, decay=0.9, target=np.asarray(target))
    np.testing.assert_allclose(fitted.target, target)
    with pytest.raises(ValueError, match="one offset per joint angle"):
        fit_pose_residual(inner, np.cumsum(np.full((20, 32), 0.01), axis=0), 1.0, target=np.zeros(25))
    with pytest.raises(ConfigurationError, match="residual_target"):
        ExperimentConfig(residual_target=[float("nan")] * 26)
    config = ExperimentConfig(residual_target=np.asarray(target))  # kept as a tuple, given to the trackers with a residual
    np.testing.assert_allclose(config.residual_target_of("latentpf"), target)
    assert config.residual_target_of("sir") is None

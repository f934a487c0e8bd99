"""The per-particle gait rate (``jaxtrack.dynamics.GaitRate``): how many steps of the wrapped
dynamics a rate makes, that rate 1 is the wrapped dynamics' own draw, its state, jit, and bad
settings."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import AbstractDynamics, GaitRate
from jaxtrack.errors import ConfigurationError


class Counter(AbstractDynamics):
    """A state ``[pose entries..., steps taken]``: ``propose`` adds 1 to the count and moves the
    pose by a known noise, ``perturb`` leaves the count."""

    def init(self, key, pose, num_particles):
        return jnp.broadcast_to(jnp.concatenate([pose, jnp.zeros(1, pose.dtype)]), (num_particles, pose.shape[0] + 1))

    def to_pose(self, states):
        return states[:, :-1]

    def propose(self, key, previous):
        noise = 0.01 * jax.random.normal(key, previous[:, :-1].shape, previous.dtype)
        return jnp.concatenate([previous[:, :-1] + noise, previous[:, -1:] + 1.0], axis=1), jnp.full(previous.shape[0], 0.5)

    def perturb(self, key, states, factor):
        return states.at[:, :-1].add(factor * 0.001 * jax.random.normal(key, states[:, :-1].shape, states.dtype))


def _run(dynamics, key, frames, particles=64):
    states = dynamics.init(jax.random.fold_in(key, 0), jnp.zeros(8), particles)
    first = states
    corrections = []
    for t in range(frames):
        states, correction = dynamics.propose(jax.random.fold_in(key, t + 1), states)
        corrections.append(correction)
    return first, states, jnp.stack(corrections)


@pytest.mark.parametrize("spread", [0.0, 0.2])
def test_a_particle_steps_floor_of_its_phase_plus_rate_times_frames(spread):
    """With no rate steps, particle i makes floor(a_0 + T rho_i) steps of the wrapped dynamics
    in T frames, its accumulator ends at the fractional part, and each of its steps carries the
    wrapped dynamics' correction."""
    dynamics = GaitRate(Counter(), spread=spread, step=0.0, low=0.6, high=1.6)
    first, states, corrections = _run(dynamics, jax.random.key(3), 40)
    rate, phase = np.exp(np.asarray(first[:, -2])), np.asarray(first[:, -1])
    expected = np.floor(phase + 40 * rate)
    np.testing.assert_array_equal(np.asarray(states[:, -3]), expected)
    np.testing.assert_allclose(np.asarray(states[:, -1]), phase + 40 * rate - expected, atol=1e-9)
    np.testing.assert_allclose(np.asarray(corrections.sum(0)), 0.5 * expected, atol=1e-12)
    np.testing.assert_allclose(np.asarray(dynamics.rates(states)), rate, rtol=1e-12)
    if spread:
        assert 0.1 < np.log(rate).std() < 0.3 and rate.min() >= 0.6 and rate.max() <= 1.6
        assert len(np.unique(expected)) > 5  # several cadences, as the filter needs
    else:
        np.testing.assert_array_equal(rate, 1.0)
        np.testing.assert_array_equal(expected, 40)


def test_rate_one_is_the_wrapped_draw_and_the_rest_is_the_wrapper_s():
    inner = Counter()
    dynamics = GaitRate(inner, spread=0.0, step=0.0)
    states = dynamics.init(jax.random.key(0), jnp.arange(8.0), 5)
    np.testing.assert_array_equal(dynamics.to_pose(states), np.broadcast_to(np.arange(8.0), (5, 8)))
    key = jax.random.key(1)
    moved, correction = dynamics.propose(key, states)
    inner_moved, inner_correction = inner.propose(jax.random.split(key, 4)[2], states[:, :-2])
    np.testing.assert_array_equal(moved[:, :-2], inner_moved)
    np.testing.assert_array_equal(correction, inner_correction)
    perturbed = dynamics.perturb(jax.random.key(2), moved, 1.0)
    np.testing.assert_array_equal(perturbed[:, -3:], moved[:, -3:])  # the count, rate and phase held
    walk = jnp.ones((4, 8))
    np.testing.assert_array_equal(dynamics.velocity_states(walk), inner.velocity_states(walk))


def test_the_rate_walks_within_its_bounds_and_jit_draws_the_same():
    dynamics = GaitRate(Counter(), spread=0.3, step=0.2, low=0.7, high=1.3)
    states = dynamics.init(jax.random.key(4), jnp.zeros(8), 500)
    jitted = jax.jit(dynamics.propose)
    for t in range(30):
        key = jax.random.key(100 + t)
        eager, eager_correction = dynamics.propose(key, states)
        states, correction = jitted(key, states)
        np.testing.assert_allclose(states, eager, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(correction, eager_correction)
    rates = np.asarray(dynamics.rates(states))
    assert rates.min() >= 0.7 - 1e-6 and rates.max() <= 1.3 + 1e-6 and rates.std() > 0.1
    assert np.all((states[:, -1] >= 0) & (states[:, -1] < 1))


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="bounds must satisfy"):
        GaitRate(Counter(), low=1.2)
    with pytest.raises(ValueError, match="bounds must satisfy"):
        GaitRate(Counter(), high=2.0)
    with pytest.raises(ValueError, match="spread must be a finite number"):
        GaitRate(Counter(), spread=float("nan"))
    with pytest.raises(ValueError, match="step must be a finite number"):
        GaitRate(Counter(), step=-0.1)
    with pytest.raises(ValueError, match="already carries a gait rate"):
        GaitRate(GaitRate(Counter()))
    with pytest.raises(TypeError, match="AbstractDynamics"):
        GaitRate(object())


def test_the_pipeline_puts_the_rate_innermost_and_a_filter_runs_on_it_jitted_or_not():
    from jaxtrack.dynamics import PoseResidual
    from jaxtrack.filters import run_filter
    from jaxtrack.likelihood import as_likelihood
    from jaxtrack.tracking import Budget, TrackingSpec, build_tracker, get_tracker

    lik = as_likelihood(lambda poses, target: -0.5 * jnp.sum((poses - target) ** 2, axis=1) / 0.05**2)
    recipe = get_tracker("latentpf")
    validation = [np.cumsum(np.full((20, 8), 0.01), axis=0)]
    tracker = build_tracker(recipe, Counter(), lik, Budget(64), residual_from=validation, residual_scale=1.0, gait_rate=0.2)
    assert isinstance(tracker.dynamics, PoseResidual) and isinstance(tracker.dynamics.inner, GaitRate)
    assert tracker.dynamics.inner.spread == 0.2 and isinstance(tracker.dynamics.inner.inner, Counter)
    assert not isinstance(build_tracker(recipe, Counter(), lik, Budget(64)).dynamics, GaitRate)

    targets = jnp.cumsum(jnp.full((5, 8), 0.01), axis=0)
    key = jax.random.key(5)
    jitted = run_filter(tracker, key, jnp.zeros(8), targets)[1]
    with jax.disable_jit():
        eager = run_filter(tracker, key, jnp.zeros(8), targets)[1]
    np.testing.assert_allclose(jitted.estimate, eager.estimate, rtol=1e-5, atol=1e-6)
    assert np.all(np.isfinite(np.asarray(jitted.estimate)))

    spec = TrackingSpec(gait_rate=0.2)
    assert spec.gait_rate_of("glegbpf") == 0.2 and spec.gait_rate_of("sir") == 0.0
    assert TrackingSpec().gait_rate_of("latentpf") == 0.0
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ConfigurationError, match="gait_rate must be a spread in"):
            TrackingSpec(gait_rate=bad)

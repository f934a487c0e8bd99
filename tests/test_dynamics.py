"""Dynamics against references with known answers: fitted parameters recover the generating
ones, proposals move states as their equations say, and SIR with second-order dynamics matches
the Kalman filter of the same linear-Gaussian model."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.dynamics import AutoregressivePoseDynamics, fit_autoregressive_dynamics
from jaxtrack.filters import SIR, run_filter
from jaxtrack.likelihood import as_likelihood

A = np.array([0.9, 0.5])  # damping of the generating AR(2)
S = np.array([0.02, 0.05])  # its noise
R = np.array([0.05, 0.08])  # observation noise


def ar2_motion(key, frames):
    """x_t = x_{t-1} + A (x_{t-1} - x_{t-2}) + N(0, S^2), from rest at the origin."""
    noise = np.asarray(jax.random.normal(key, (frames, 2), jnp.float64)) * S
    x = np.zeros((frames + 2, 2))
    for t in range(2, frames + 2):
        x[t] = x[t - 1] + A * (x[t - 1] - x[t - 2]) + noise[t - 2]
    return x[2:]


def test_fit_recovers_the_generating_model(getkey):
    sequences = [ar2_motion(getkey(), 3000) for _ in range(2)]
    fitted = fit_autoregressive_dynamics(sequences, floor=1e-6)
    np.testing.assert_allclose(fitted.damping, A, atol=0.03)
    np.testing.assert_allclose(fitted.scales, S, rtol=0.04)
    steps = np.concatenate([np.diff(s, axis=0) for s in sequences])
    np.testing.assert_allclose(fitted.initial_speed, np.sqrt((steps**2).mean(0)))
    with pytest.raises(ValueError, match="at least 3 frames"):
        fit_autoregressive_dynamics([sequences[0][:2]])


def test_proposal_and_perturbation(getkey):
    dynamics = AutoregressivePoseDynamics(damping=jnp.asarray(A), scales=jnp.zeros(2), initial_speed=jnp.zeros(2))
    state = jnp.concatenate([jnp.array([1.0, 2.0]), jnp.array([0.5, 2.5])])[None]
    moved, correction = dynamics.propose(getkey(), state)
    np.testing.assert_allclose(moved[0], [1.0 + 0.9 * 0.5, 2.0 - 0.5 * 0.5, 1.0, 2.0])
    np.testing.assert_array_equal(correction, [0.0])
    noisy = AutoregressivePoseDynamics(damping=jnp.asarray(A), scales=jnp.asarray(S), initial_speed=jnp.asarray(S))
    perturbed = noisy.perturb(getkey(), jnp.tile(state, (5, 1)), 0.5)
    np.testing.assert_array_equal(perturbed[:, 2:], np.tile([0.5, 2.5], (5, 1)))  # x_{t-1} is kept
    assert np.all(perturbed[:, :2] != state[:, :2])
    np.testing.assert_array_equal(dynamics.init(getkey(), jnp.array([3.0, 4.0]), 2), [[3.0, 4.0, 3.0, 4.0]] * 2)
    # an unknown initial velocity: x_{-1} = x_0 - v0 with v0 ~ N(0, initial_speed^2)
    speed = jnp.array([0.1, 0.01])
    spread = AutoregressivePoseDynamics(damping=jnp.asarray(A), scales=jnp.asarray(S), initial_speed=speed)
    start = np.asarray(spread.init(getkey(), jnp.array([3.0, 4.0]), 20000))
    np.testing.assert_array_equal(start[:, :2], np.tile([3.0, 4.0], (20000, 1)))
    np.testing.assert_allclose((start[:, :2] - start[:, 2:]).std(0), speed, rtol=0.03)
    with pytest.raises((ValueError, TypeError)):  # jaxtyping catches the shape clash first when enabled
        AutoregressivePoseDynamics(damping=jnp.ones(3), scales=jnp.ones(2), initial_speed=jnp.ones(2))


def kalman_ar2(ys):
    """Exact filtering means and log-evidence of the AR(2) model observed as y = x_t + N(0, R^2),
    per entry, state [x_t, x_{t-1}] starting at rest at 0 (known)."""
    means, log_evidence = [], 0.0
    m = np.zeros((2, 2))  # entry, [x_t, x_{t-1}]
    P = np.zeros((2, 2, 2))
    for y in ys:
        F = np.stack([np.array([[1 + a, -a], [1.0, 0.0]]) for a in A])
        m = np.einsum("eij,ej->ei", F, m)
        P = F @ P @ np.transpose(F, (0, 2, 1))
        P[:, 0, 0] += S**2
        innovation_var = P[:, 0, 0] + R**2
        residual = y - m[:, 0]
        log_evidence += float(np.sum(-0.5 * (residual**2 / innovation_var + np.log(2 * np.pi * innovation_var))))
        gain = P[:, :, 0] / innovation_var[:, None]
        m = m + gain * residual[:, None]
        P = P - gain[:, :, None] * P[:, 0, :][:, None, :]
        means.append(m[:, 0].copy())
    return np.array(means), log_evidence


def test_sir_with_second_order_dynamics_matches_the_kalman_filter(getkey):
    truth = ar2_motion(getkey(), 30)
    ys = jnp.asarray(truth + R * np.asarray(jax.random.normal(getkey(), truth.shape, jnp.float64)))
    likelihood = as_likelihood(lambda x, y: -0.5 * jnp.sum(((x - y) / R) ** 2 + jnp.log(2 * jnp.pi * R**2), axis=1))
    sir = SIR(AutoregressivePoseDynamics(damping=jnp.asarray(A), scales=jnp.asarray(S), initial_speed=jnp.zeros(2)), likelihood, 4000)
    expected_means, expected_evidence = kalman_ar2(np.asarray(ys))
    runs = [run_filter(sir, k, jnp.zeros(2), ys)[1] for k in jax.random.split(getkey(), 4)]
    means = np.mean([np.asarray(r.estimate) for r in runs], axis=0)
    evidence = np.array([float(r.log_evidence.sum()) for r in runs])
    assert np.abs(means - expected_means).max() < 0.01, np.abs(means - expected_means).max()
    assert abs(evidence.mean() - expected_evidence) < max(4 * evidence.std(), 0.1), (evidence, expected_evidence)

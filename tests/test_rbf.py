"""Paper 002's RBF networks with full-covariance Gaussian activations (eqs. 8-9) and the
mixture's noise covariance (eq. 10)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import ConfigurationError
from jaxtrack.manifold import fit_gaussian_mixture, fit_rbf_network


@pytest.fixture(autouse=True)
def _float64():
    jax.config.update("jax_enable_x64", True)


def test_an_rbf_network_reproduces_a_smooth_function():
    """400 points of a smooth 2-D -> 2-D function, 30 Gaussians: held-out rms error under 6 % of
    the function's spread (measured 2.8 %)."""
    rng = np.random.default_rng(0)

    def f(x):
        return np.stack([np.sin(x[:, 0]) * np.cos(x[:, 1]), 0.3 * x[:, 0] * x[:, 1]], 1)

    X, held_out = rng.uniform(-2, 2, size=(400, 2)), rng.uniform(-1.8, 1.8, size=(200, 2))
    network = fit_rbf_network(X, f(X), 30)
    error = np.sqrt(np.mean((np.asarray(network(jnp.asarray(held_out))) - f(held_out)) ** 2))
    assert error < 0.06 * f(X).std(), error
    jitted = np.asarray(jax.jit(network.__call__)(jnp.asarray(X)))
    np.testing.assert_allclose(jitted, np.asarray(network(jnp.asarray(X))), rtol=1e-9, atol=1e-12)


def test_the_inverse_map_inverts_the_forward_map_on_the_training_set():
    """A loop embedded in 20 dimensions (a stand-in for a pose manifold): forward latent -> pose
    and inverse pose -> latent networks, each fitted by least squares; inverse(forward(z))
    returns z (rms under 1 % of the loop's radius; measured 0.1 %)."""
    rng = np.random.default_rng(1)
    angle = np.linspace(0, 2 * np.pi, 300, endpoint=False)
    Z = np.stack([np.cos(angle), np.sin(angle)], 1)
    Y = Z @ rng.normal(size=(2, 20)) + 0.3 * np.sin(2 * Z) @ rng.normal(size=(2, 20))
    forward, inverse = fit_rbf_network(Z, Y, 25), fit_rbf_network(Y, Z, 25)
    reconstruction = np.asarray(forward(jnp.asarray(Z)))
    assert np.sqrt(np.mean((reconstruction - Y) ** 2)) < 0.01 * Y.std()
    back = np.asarray(inverse(jnp.asarray(reconstruction)))
    assert np.sqrt(np.mean((back - Z) ** 2)) < 0.01


def test_noise_covariance_is_the_mixture_of_the_gaussians_nearby():
    """002 eq. 10: at a Gaussian's centre with a tight threshold, that Gaussian's covariance; far
    from every Gaussian, the nearest one's; with a loose threshold, the mixture-weighted mean of
    those within it."""
    rng = np.random.default_rng(2)
    X = np.concatenate([rng.normal(size=(100, 2)) * [0.3, 0.1], rng.normal(size=(100, 2)) * [0.1, 0.4] + [3.0, 0.0]])
    network = fit_rbf_network(X, X[:, :1], 2)
    covariances, mixing, centres = (np.asarray(a) for a in (network.covariances, network.mixing, network.centres))
    at_centres = np.asarray(network.noise_covariance(network.centres, threshold=0.5))
    np.testing.assert_allclose(at_centres, covariances, rtol=1e-10)
    delta = np.array([30.0, 0.0]) - centres
    nearest = int(np.argmin(np.einsum("gi,gij,gj->g", delta, np.linalg.inv(covariances), delta)))  # in Mahalanobis distance
    far = np.asarray(network.noise_covariance(jnp.asarray([[30.0, 0.0]]), threshold=1.0))[0]
    np.testing.assert_allclose(far, covariances[nearest], rtol=1e-10)
    both = np.asarray(network.noise_covariance(jnp.asarray([[1.5, 0.0]]), threshold=1e3))[0]
    np.testing.assert_allclose(both, np.einsum("g,gij->ij", mixing, covariances) / mixing.sum(), rtol=1e-10)


def test_gaussian_mixture_recovers_two_clusters_and_bad_inputs_are_refused():
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.normal(size=(300, 2)) * 0.2, rng.normal(size=(100, 2)) * 0.2 + [4.0, 1.0]])
    means, _, weights = fit_gaussian_mixture(X, 2, ridge=0.0)
    order = np.argsort(weights)
    np.testing.assert_allclose(weights[order], [0.25, 0.75], atol=1e-6)
    np.testing.assert_allclose(means[order], [[4.0, 1.0], [0.0, 0.0]], atol=0.05)
    with pytest.raises(ConfigurationError, match="at least 40 training points"):
        fit_gaussian_mixture(X[:30], 20)
    with pytest.raises(ConfigurationError, match="must share M"):
        fit_rbf_network(X, X[:10], 3)
    with pytest.raises(ConfigurationError, match="finite"):
        fit_rbf_network(np.where(X > 3, np.nan, X), X, 3)

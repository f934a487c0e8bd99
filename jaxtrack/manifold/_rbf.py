"""Radial basis function networks with full-covariance Gaussian activations (002 eqs. 8-9) and
their Gaussians as a mixture model giving the process noise at any latent point (002 eq. 10).

Spectral embeddings (LE, temporal LE, GLE) give latent coordinates for the training frames
only; the networks map both ways, latent -> pose (forward) and pose -> latent (inverse):

    f(x) = sum_j w_j phi_j(x) + b,   phi_j(x) = exp(-1/2 (x - mu_j)^T Sigma_j^{-1} (x - mu_j))

The Gaussians (mu_j, Sigma_j, mixing weights pi_j) are a Gaussian mixture fitted to the
network's inputs by EM (full covariances, a ridge of ``ridge`` times the mean input variance
on every covariance, so that a Gaussian over few points in many dimensions, as for the inverse
map's pose inputs, stays positive definite and the activations overlap); the output weights and bias are then the
least-squares fit (with a small Tikhonov term) of the outputs on the activations.

Eq. 10: the noise covariance at a latent point x is the covariance of the subset of Gaussians
within a Mahalanobis distance ``threshold`` of x, ``sum_{j in S(x)} pi_j Sigma_j / sum pi_j``;
where none is that close, the nearest Gaussian's.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..errors import ConfigurationError
from ._predictor import AbstractPredictor


class RBFNetwork(eqx.Module):
    """A fitted RBF network (002 eqs. 8-9) and its Gaussian mixture.

    Attributes:
        centres: (G, d_in) Gaussian means ``mu_j``.
        covariances: (G, d_in, d_in) ``Sigma_j``, the mixture's covariances (for eq. 10).
        precisions: (G, d_in, d_in) the activations' inverse covariances,
            ``(width^2 Sigma_j)^{-1}``.
        mixing: (G,) mixture weights ``pi_j`` (sum 1).
        weights: (G, d_out) output weights ``w_j``.
        bias: (d_out,) output bias ``b``.
    """

    centres: Float[Array, "g d_in"]
    covariances: Float[Array, "g d_in d_in"]
    precisions: Float[Array, "g d_in d_in"]
    mixing: Float[Array, " g"]
    weights: Float[Array, "g d_out"]
    bias: Float[Array, " d_out"]

    def mahalanobis(self, x: Float[Array, "n d_in"], precisions=None) -> Float[Array, "n g"]:
        """Squared Mahalanobis distance of each input to each Gaussian (the activations'
        metric, or ``precisions`` (G, d_in, d_in))."""
        delta = x[:, None, :] - self.centres[None]
        return jnp.einsum("ngi,gij,ngj->ng", delta, self.precisions if precisions is None else precisions, delta)

    def activations(self, x: Float[Array, "n d_in"]) -> Float[Array, "n g"]:
        """``phi_j(x)`` (002 eq. 9)."""
        return jnp.exp(-0.5 * self.mahalanobis(x))

    def __call__(self, x: Float[Array, "n d_in"]) -> Float[Array, "n d_out"]:
        """The network's output ``f(x)`` (002 eq. 8)."""
        return self.activations(x) @ self.weights + self.bias

    def noise_covariance(self, x: Float[Array, "n d_in"], threshold: float = 2.0) -> Float[Array, "n d_in d_in"]:
        """002 eq. 10: the mixture covariance of the Gaussians within Mahalanobis distance
        ``threshold`` of each point (the nearest Gaussian's where none is)."""
        distance = self.mahalanobis(x, jnp.linalg.inv(self.covariances))
        near = distance <= threshold**2
        nearest = jnp.arange(self.mixing.shape[0])[None, :] == jnp.argmin(distance, axis=1)[:, None]
        chosen = jnp.where(jnp.any(near, axis=1, keepdims=True), near, nearest)
        weight = chosen * self.mixing[None, :]
        weight = weight / jnp.sum(weight, axis=1, keepdims=True)
        return jnp.einsum("ng,gij->nij", weight, self.covariances)


class RBFPredictor(AbstractPredictor):
    """An RBF network as a manifold's predictive map (the Laplacian Eigenmaps family's
    ``predictor``): the mean is the network's output (002 eq. 8); the network has no predictive
    variance of its own, so the variance (standardised units, without ``noise``) is
    ``1 - max_j phi_j(z)``: 0 on a Gaussian's centre, growing to 1 (the standardised data's own
    variance, as a unit-variance GP's far from its data) where no activation covers the point.
    ``noise`` is the network's training residual.

    Attributes:
        network: the forward network, latent -> standardised joint angles.
        mean, scale: (D,) joint angles = mean + scale * standardised.
        residual: the network's mean squared residual on its training set.
    """

    network: RBFNetwork
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    residual: Float[Array, ""]

    def __call__(self, Z):
        activations = self.network.activations(Z)
        mean = self.mean + self.scale * (activations @ self.network.weights + self.network.bias)
        return mean, 1.0 - jnp.max(activations, axis=1)

    @property
    def noise(self):
        return self.residual

    @property
    def latent_dim(self) -> int:
        return self.network.centres.shape[1]

    @property
    def pose_dim(self) -> int:
        return self.network.weights.shape[1]


def squared_mahalanobis(covariances, delta):
    """(n, G) squared Mahalanobis distances of ``delta`` (n, G, d) under ``covariances`` (G, d, d),
    through each covariance's Cholesky factor inverted once: G small inverses instead of one
    solve per point and Gaussian (docs/gle.md, "The networks' mixtures")."""
    whitened = np.einsum("gij,ngj->ngi", np.linalg.inv(np.linalg.cholesky(covariances)), delta)
    return np.sum(whitened**2, axis=-1)


def fit_gaussian_mixture(X, components: int, *, seed: int = 0, iterations: int = 200, ridge: float = 1e-3,
                         tolerance: float = 1e-8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """EM for a full-covariance Gaussian mixture, initialised by k-means++ seeding (NumPy: it
    runs once, on the training set). Returns ``(means (G, d), covariances (G, d, d), weights (G,))``.
    """
    X = np.asarray(X, np.float64)
    n, d = X.shape
    if isinstance(components, bool) or not isinstance(components, (int, np.integer)) or components < 1:
        raise ConfigurationError(f"the number of Gaussians must be a positive integer, got {components!r}")
    if n < 2 * components:
        raise ConfigurationError(f"{components} Gaussians need at least {2 * components} training points, got {n}")
    rng = np.random.default_rng(seed)
    floor = ridge * float(np.mean(X.var(axis=0))) + 1e-12
    # k-means++ seeding: each next centre drawn with probability proportional to the squared
    # distance to the nearest centre chosen so far.
    centres = [X[rng.integers(n)]]
    for _ in range(components - 1):
        gap = np.min(np.sum((X[:, None] - np.asarray(centres)[None]) ** 2, axis=-1), axis=1)
        centres.append(X[rng.choice(n, p=gap / gap.sum())] if gap.sum() > 0 else X[rng.integers(n)])
    means = np.asarray(centres)
    nearest = np.argmin(np.sum((X[:, None] - means[None]) ** 2, axis=-1), axis=1)
    responsibility = np.eye(components)[nearest]
    previous = -np.inf
    for _ in range(iterations):
        counts = responsibility.sum(axis=0) + 1e-12
        weights = counts / n
        means = responsibility.T @ X / counts[:, None]
        delta = X[:, None, :] - means[None]
        covariances = np.einsum("ng,ngi,ngj->gij", responsibility, delta, delta) / counts[:, None, None] + floor * np.eye(d)
        _, logdet = np.linalg.slogdet(covariances)
        log_density = -0.5 * (squared_mahalanobis(covariances, delta) + logdet[None] + d * np.log(2 * np.pi)) + np.log(weights)[None]
        top = log_density.max(axis=1, keepdims=True)
        log_total = top[:, 0] + np.log(np.exp(log_density - top).sum(axis=1))
        responsibility = np.exp(log_density - log_total[:, None])
        likelihood = float(log_total.mean())
        if likelihood - previous < tolerance * max(1.0, abs(likelihood)):
            break
        previous = likelihood
    return means, covariances, weights


def fit_rbf_network(inputs, outputs, components: int, *, width: float = 3.0, seed: int = 0, ridge: float = 0.05,
                    tikhonov: float = 1e-8, dtype=jnp.float64) -> RBFNetwork:
    """Fit an RBF network ``inputs (M, d_in) -> outputs (M, d_out)``: the Gaussians by EM on the
    inputs, then the output weights and bias by regularised least squares.

    Args:
        components: Gaussians G.
        width: the activations use ``width^2 Sigma_j``: a mixture component is as wide as its
            own points, and neighbouring activations must overlap for the network to
            interpolate between them (``width = 1`` leaves gaps).
        ridge: added to every covariance, times the inputs' mean variance. EM on points that
            fill a region gives thin components, and thin activations interpolate badly.

    The defaults (``width`` 3, ``ridge`` 0.05) were chosen on two synthetic problems (a smooth
    function of 2-D inputs, and the two maps between a loop and a 20-D curve), where they fit
    several times better than ``width`` 1.5-2 or ``ridge`` 1e-3 (tests/test_rbf.py).
    """
    X, Y = np.asarray(inputs, np.float64), np.asarray(outputs, np.float64)
    if X.ndim != 2 or Y.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise ConfigurationError(f"inputs (M, d_in) and outputs (M, d_out) must share M, got {X.shape} and {Y.shape}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y))):
        raise ConfigurationError("the RBF network's training inputs and outputs must be finite")
    means, covariances, mixing = fit_gaussian_mixture(X, components, seed=seed, ridge=ridge)
    if not (np.isfinite(width) and width > 0):
        raise ConfigurationError(f"width must be positive, got {width!r}")
    precisions = np.linalg.inv(width**2 * covariances)
    delta = X[:, None, :] - means[None]
    phi = np.exp(-0.5 * np.einsum("ngi,gij,ngj->ng", delta, precisions, delta))
    design = np.concatenate([phi, np.ones((X.shape[0], 1))], axis=1)
    gram = design.T @ design
    solution = np.linalg.solve(gram + tikhonov * np.trace(gram) / gram.shape[0] * np.eye(gram.shape[0]), design.T @ Y)
    cast = lambda a: jnp.asarray(a, dtype)  # noqa: E731
    return RBFNetwork(centres=cast(means), covariances=cast(covariances), precisions=cast(precisions), mixing=cast(mixing),
                      weights=cast(solution[:-1]), bias=cast(solution[-1]))

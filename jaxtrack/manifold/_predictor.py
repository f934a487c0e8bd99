"""The GP predictive distribution precomputed once, so that a filter can evaluate it for
hundreds of particles per frame without refactorising the training covariance.

For a full GP (000 eqs. 23-26): ``mu(z) = k(z, Z) K^-1 Y`` and
``var(z) = k(z, z) - k(z, Z) K^-1 k(Z, z)``. For the sparse (inducing point) GPLVM the same
form holds with the inducing points ``U`` in place of ``Z``: ``mu(z) = k(z, U) Sigma^-1 ... Y``
(see ``_sparse.py``). Both are stored as ``mean = k(z, X) @ mean_weights`` and
``var = k(z, z) - sum_j (k(z, X) @ variance_matrix)_j k(z, X)_j``.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._kernels import LinearRBFKernel, RBFBiasKernel


class AbstractPredictor(eqx.Module):
    """A manifold's predictive map from latent points to poses, as the trackers use it: a GP's
    (``GPPredictor``) or an RBF network's (``RBFPredictor``, for the Laplacian Eigenmaps family).

    Attributes:
        mean, scale: (D,) the training data standardisation (pose units).
    """

    mean: eqx.AbstractVar[Float[Array, " d"]]
    scale: eqx.AbstractVar[Float[Array, " d"]]

    @abc.abstractmethod
    def __call__(self, Z: Float[Array, "p q"]) -> tuple[Float[Array, "p d"], Float[Array, " p"]]:
        """Predictive mean (P, D) in pose units and variance (P,) in standardised units (without
        ``noise``)."""

    @property
    @abc.abstractmethod
    def noise(self) -> Float[Array, ""]:
        """The observation noise variance (standardised units) a new pose adds to the variance."""

    @property
    @abc.abstractmethod
    def latent_dim(self) -> int:
        """q."""

    @property
    @abc.abstractmethod
    def pose_dim(self) -> int:
        """D."""


class GPPredictor(AbstractPredictor):
    """Precomputed predictive map from latent points to poses.

    Attributes:
        support: (M, q) training latent points (or inducing points).
        kernel: the covariance function (the pose kernel; a GPDM's dynamics kernel for its
            latent dynamics).
        mean_weights: (M, D) weights so that the standardised mean is ``k(z, support) @ w``.
        variance_matrix: (M, M) ``K^-1`` (full GP) or ``Kuu^-1 - Sigma`` (sparse GP).
        mean, scale: (D,) the training data standardisation (pose units).
    """

    support: Float[Array, "m q"]
    kernel: RBFBiasKernel | LinearRBFKernel
    mean_weights: Float[Array, "m d"]
    variance_matrix: Float[Array, "m m"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]

    def __call__(self, Z: Float[Array, "p q"]) -> tuple[Float[Array, "p d"], Float[Array, " p"]]:
        """Predictive mean (P, D) in pose units and variance (P,) in standardised units
        (without the noise ``kernel.noise``)."""
        k = self.kernel(Z, self.support)
        mean = self.mean + self.scale * (k @ self.mean_weights)
        variance = self.kernel.diag(Z) - jnp.sum((k @ self.variance_matrix) * k, axis=1)
        return mean, jnp.maximum(variance, 0.0)

    @property
    def noise(self) -> Float[Array, ""]:
        return self.kernel.noise

    @property
    def latent_dim(self) -> int:
        return self.support.shape[1]

    @property
    def pose_dim(self) -> int:
        return self.mean_weights.shape[1]


def full_gp_predictor(kernel, latent, data, mean, scale) -> GPPredictor:
    """``GPPredictor`` of an exact GP with training inputs ``latent`` and outputs ``data``."""
    from ._kernels import safe_cholesky

    L = safe_cholesky(kernel.gram(latent))
    eye = jnp.eye(latent.shape[0], dtype=latent.dtype)
    inverse = jax.scipy.linalg.cho_solve((L, True), eye)
    weights = jax.scipy.linalg.cho_solve((L, True), data)
    return GPPredictor(
        support=latent, kernel=kernel, mean_weights=weights, variance_matrix=0.5 * (inverse + inverse.T), mean=mean, scale=scale
    )

"""Covariance functions and the Gaussian-process pieces shared by every manifold model.

RBF + bias kernel (paper 000 eq. 14): ``k(z, z') = beta exp(-gamma/2 ||z - z'||^2) + beta0``,
plus ``sigma^2`` on the diagonal of training covariances. The GPDM dynamics kernel (001 eq. 9)
adds a linear term: ``k(x, x') = a1 exp(-a2/2 ||x - x'||^2) + a3 x.x'``.
Hyperparameters are stored as logs (always positive) and exposed as properties.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float

JITTER_LADDER = (0.0, 1e-8, 1e-6, 1e-4, 1e-2)  # relative to the mean diagonal


def squared_distances(a: Float[Array, "n q"], b: Float[Array, "m q"]) -> Float[Array, "n m"]:
    """Pairwise squared Euclidean distances, clipped at 0 against rounding."""
    d2 = jnp.sum(a * a, -1)[:, None] + jnp.sum(b * b, -1)[None, :] - 2.0 * a @ b.T
    return jnp.maximum(d2, 0.0)


class RBFBiasKernel(eqx.Module):
    """``beta exp(-gamma/2 ||z - z'||^2) + beta0`` with white noise ``sigma^2`` (000 eq. 14)."""

    log_beta: Float[Array, ""]
    log_gamma: Float[Array, ""]
    log_beta0: Float[Array, ""]
    log_noise: Float[Array, ""]

    @property
    def beta(self):
        return jnp.exp(self.log_beta)

    @property
    def gamma(self):
        return jnp.exp(self.log_gamma)

    @property
    def beta0(self):
        return jnp.exp(self.log_beta0)

    @property
    def noise(self):
        """Noise variance ``sigma^2``."""
        return jnp.exp(self.log_noise)

    def __call__(self, a, b):
        """Cross-covariance (n, m) without noise."""
        return self.beta * jnp.exp(-0.5 * self.gamma * squared_distances(a, b)) + self.beta0

    def diag(self, a):
        """``k(z, z)`` for each row (no noise)."""
        return jnp.full(a.shape[:1], self.beta + self.beta0)

    def gram(self, z):
        """Training covariance ``K + sigma^2 I``."""
        return self(z, z) + self.noise * jnp.eye(z.shape[0], dtype=z.dtype)


def rbf_bias_kernel(beta=1.0, gamma=1.0, beta0=1e-2, noise=1e-2, dtype=jnp.float64) -> RBFBiasKernel:
    """An ``RBFBiasKernel`` from positive hyperparameters."""
    values = [jnp.log(jnp.asarray(v, dtype)) for v in (beta, gamma, beta0, noise)]
    return RBFBiasKernel(*values)


class LinearRBFKernel(eqx.Module):
    """GPDM dynamics kernel ``a1 exp(-a2/2 ||x - x'||^2) + a3 x.x'`` plus ``1/a4`` noise (001 eq. 9)."""

    log_a1: Float[Array, ""]
    log_a2: Float[Array, ""]
    log_a3: Float[Array, ""]
    log_noise: Float[Array, ""]

    def __call__(self, a, b):
        return jnp.exp(self.log_a1) * jnp.exp(-0.5 * jnp.exp(self.log_a2) * squared_distances(a, b)) + jnp.exp(
            self.log_a3
        ) * (a @ b.T)

    def diag(self, a):
        return jnp.exp(self.log_a1) + jnp.exp(self.log_a3) * jnp.sum(a * a, -1)

    @property
    def noise(self):
        return jnp.exp(self.log_noise)

    def gram(self, z):
        return self(z, z) + self.noise * jnp.eye(z.shape[0], dtype=z.dtype)


def linear_rbf_kernel(a1=1.0, a2=1.0, a3=1e-2, noise=1e-2, dtype=jnp.float64) -> LinearRBFKernel:
    values = [jnp.log(jnp.asarray(v, dtype)) for v in (a1, a2, a3, noise)]
    return LinearRBFKernel(*values)


def safe_cholesky(K: Float[Array, "n n"]) -> Float[Array, "n n"]:
    """Cholesky factor with adaptive jitter: the first rung of ``JITTER_LADDER`` (times the mean
    diagonal) that gives a finite factor. Duplicated training frames therefore do not break it.
    Works under jit and grad: each further rung is tried inside a ``lax.cond`` only when the
    previous factor failed, so the usual cost is one factorisation."""
    n = K.shape[0]
    scale = jnp.mean(jnp.diag(K))
    eye = jnp.eye(n, dtype=K.dtype)

    def attempt(rung: int):
        factor = jnp.linalg.cholesky(K + JITTER_LADDER[rung] * scale * eye)
        if rung == len(JITTER_LADDER) - 1:
            return factor
        return jax.lax.cond(jnp.all(jnp.isfinite(factor)), lambda: factor, lambda: attempt(rung + 1))

    return attempt(0)


def gaussian_log_marginal(K: Float[Array, "n n"], Y: Float[Array, "n d"], columns: Float[Array, " d"] | None = None) -> Float[Array, ""]:
    """``sum_i ln N(Y[:, i] | 0, K) = -DN/2 ln 2pi - D/2 ln|K| - 1/2 tr(K^-1 Y Y^T)`` (000 eq. 15);
    with ``columns`` (D,) of 0/1, only the columns marked 1 count."""
    n, d = Y.shape
    L = safe_cholesky(K)
    alpha = jax.scipy.linalg.cho_solve((L, True), Y)
    logdet = 2.0 * jnp.sum(jnp.log(jnp.diag(L)))
    count = d if columns is None else jnp.sum(columns)
    fit = Y * alpha if columns is None else Y * alpha * columns
    return -0.5 * count * n * jnp.log(2 * jnp.pi) - 0.5 * count * logdet - 0.5 * jnp.sum(fit)

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


def _jittered_factor(K: Float[Array, "n n"]) -> Float[Array, "n n"]:
    """The first finite Cholesky factor of ``K + JITTER_LADDER[r] * mean(diag K) * I``, r = 0,
    1, ...: one factorisation unless it fails (a ``lax.while_loop`` tries the next rung)."""
    scale = jnp.mean(jnp.diag(K))
    eye = jnp.eye(K.shape[0], dtype=K.dtype)
    ladder = jnp.asarray(JITTER_LADDER, K.dtype)

    def cond(carry):
        rung, factor = carry
        return ~jnp.all(jnp.isfinite(factor)) & (rung < len(JITTER_LADDER) - 1)

    def body(carry):
        rung = carry[0] + 1
        return rung, jnp.linalg.cholesky(K + ladder[rung] * scale * eye)

    return jax.lax.while_loop(cond, body, (jnp.asarray(0), jnp.linalg.cholesky(K)))[1]


@jax.custom_jvp
def safe_cholesky(K: Float[Array, "n n"]) -> Float[Array, "n n"]:
    """Cholesky factor with adaptive jitter: the first rung of ``JITTER_LADDER`` (times the mean
    diagonal) that gives a finite factor, so duplicated training frames do not break it. Works
    under jit, vmap and both modes of autodiff; the derivative is that of the factorisation of
    ``K + jitter I`` with the jitter held constant (the rule JAX's ``cholesky`` uses,
    ``dL = L Phi(L^-1 dK L^-T)``, Phi the lower triangle with half the diagonal)."""
    return _jittered_factor(K)


@safe_cholesky.defjvp
def _safe_cholesky_jvp(primals, tangents):
    (K,), (dK,) = primals, tangents
    L = _jittered_factor(K)
    dK = 0.5 * (dK + dK.T)  # the factorisation reads a symmetric matrix
    inner = jax.scipy.linalg.solve_triangular(L, jax.scipy.linalg.solve_triangular(L, dK, lower=True).T, lower=True).T
    phi = jnp.tril(inner) - 0.5 * jnp.diag(jnp.diag(inner))
    return L, L @ phi


def gaussian_log_marginal(K: Float[Array, "n n"], Y: Float[Array, "n d"], columns: Float[Array, " d"] | None = None) -> Float[Array, ""]:
    """``sum_i ln N(Y[:, i] | 0, K) = -DN/2 ln 2pi - D/2 ln|K| - 1/2 tr(K^-1 Y Y^T)`` (000 eq. 15);
    with ``columns`` (D,) of 0/1, only the columns marked 1 count.

    Differentiable in ``K`` and ``Y`` in both modes, by the matrix-calculus rule of a Gaussian
    log-density (``d/dK = 1/2 (K^-1 Y Y^T K^-1 - D K^-1)``, ``d/dY = -K^-1 Y``; Rasmussen and
    Williams 2006 eq. 5.9) instead of differentiating through the Cholesky factorisation: one
    block-recursive ``K^-1`` (``cholesky_inverse``) instead of three N x N triangular solves.
    The models' objectives are still differentiated by autodiff through everything else
    (kernels, back-constraints, dynamics, priors), as JAX differentiates through its own
    ``cholesky`` by a rule.
    """
    if columns is None:
        columns = jnp.ones(Y.shape[1], Y.dtype)
    return _log_marginal(K, Y, jnp.asarray(columns, Y.dtype))


def _log_marginal_parts(K, Y, columns):
    n = Y.shape[0]
    L = safe_cholesky(K)  # differentiated only for second derivatives: the rule below is the first
    alpha = jax.scipy.linalg.cho_solve((L, True), Y) * columns
    logdet = 2.0 * jnp.sum(jnp.log(jnp.diag(L)))
    count = jnp.sum(columns)
    value = -0.5 * count * n * jnp.log(2 * jnp.pi) - 0.5 * count * logdet - 0.5 * jnp.sum(Y * alpha)
    return value, L, alpha, count


CHOLESKY_INVERSE_BLOCK = 128  # rows below which a block is inverted by one triangular solve


def cholesky_inverse(L: Float[Array, "n n"], *, block: int = CHOLESKY_INVERSE_BLOCK) -> Float[Array, "n n"]:
    """``K^-1 = L^-T L^-1`` from the lower Cholesky factor ``L`` of ``K``, by 2 x 2 block recursion.

    With ``L = [[A, 0], [C, B]]``, ``L^-1 = [[A^-1, 0], [E, B^-1]]`` where ``E = -B^-1 C A^-1``, and
    ``L^-T L^-1 = [[A^-T A^-1 + E^T E, E^T B^-1], [B^-T E, B^-T B^-1]]``: the two diagonal blocks
    are the same problem at half the size. The work is matrix products (which XLA runs at
    several times the rate of a triangular solve with N right-hand sides), about half the flops
    of forming ``L^-1`` and then the full product ``L^-T L^-1``, and a triangular solve only
    for blocks of at most ``block`` rows. Measured on 2 cores: 1.6 -> 1.1 ms at N = 350 and
    23 -> 11 ms at N = 1000 against that two-step form.
    """
    return _cholesky_inverse(L, block)[1]


def _cholesky_inverse(L, block):
    """``(L^-1, L^-T L^-1)``."""
    n = L.shape[0]
    if n <= block:
        inverse = jax.scipy.linalg.solve_triangular(L, jnp.eye(n, dtype=L.dtype), lower=True)
        return inverse, inverse.T @ inverse
    h = n // 2
    A_inv, A_gram = _cholesky_inverse(L[:h, :h], block)
    B_inv, B_gram = _cholesky_inverse(L[h:, h:], block)
    E = -B_inv @ (L[h:, :h] @ A_inv)
    corner = B_inv.T @ E
    gram = jnp.block([[A_gram + E.T @ E, corner.T], [corner, B_gram]])
    return jnp.block([[A_inv, jnp.zeros((h, n - h), L.dtype)], [E, B_inv]]), gram


@jax.custom_jvp
def _log_marginal(K, Y, columns):
    return _log_marginal_parts(K, Y, columns)[0]


@_log_marginal.defjvp
def _log_marginal_jvp(primals, tangents):
    K, Y, columns = primals
    dK, dY, _ = tangents  # the column mask is data, not a parameter
    value, L, alpha, count = _log_marginal_parts(K, Y, columns)
    K_inverse = cholesky_inverse(L)
    weights = jax.lax.optimization_barrier(0.5 * (alpha @ alpha.T - count * K_inverse))  # one N x N pass, not one per use
    tangent = jnp.sum(weights * dK) - jnp.sum(alpha * dY)
    return value, tangent

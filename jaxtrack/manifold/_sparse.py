"""Sparse GPLVM with inducing points (paper 004 uses 100-200 pseudo points).

The exact GPLVM costs O(N^3) per objective; with M inducing points ``U`` the collapsed
variational bound of Titsias (2009) costs O(N M^2 D) and lower-bounds ``ln p(Y|Z)``:

    ln p(Y|Z) >= sum_d ln N(Y[:, d] | 0, Q_nn + sigma^2 I) - D/(2 sigma^2) tr(K_nn - Q_nn),
    Q_nn = K_nu K_uu^-1 K_un.

``approximation="dtc"`` drops the trace term (the deterministic training conditional of
Lawrence's sparse GPLVM). The model maximises the bound minus ``1/2 ||Z||_F^2`` (the prior of
000 eq. 16) over Z, U and the kernel hyperparameters. With ``U = Z`` the bound is exact.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._kernels import RBFBiasKernel, rbf_bias_kernel, safe_cholesky
from ._predictor import GPPredictor
from ._serialise import AbstractSaveableManifold, register_manifold

APPROXIMATIONS = ("vfe", "dtc")
INDUCING_JITTER = 1e-8  # relative jitter on K_uu, always added (inducing points may coincide)


def _factors(kernel: RBFBiasKernel, inducing, latent):
    """``L = chol(Kuu)``, ``A = L^-1 Kuf / sigma`` and ``LB = chol(I + A A^T)``."""
    sigma = jnp.sqrt(kernel.noise)
    Kuu = kernel(inducing, inducing)
    eye = jnp.eye(inducing.shape[0], dtype=Kuu.dtype)
    L = safe_cholesky(Kuu + INDUCING_JITTER * jnp.mean(jnp.diag(Kuu)) * eye)
    # L^-1 (M x M) then one matrix product: a triangular solve with N right-hand sides, and its
    # derivative, cost 1.2x more at N = 3000 (same rounding: 1e-5 from a long-double value of the
    # bound). Forming Kuf Kuf^T first would be cheaper still but loses precision through L^-1's
    # norm when Kuu is near singular (1.4 off in 3.7e6 on random data at N = 3000).
    A = (jax.scipy.linalg.solve_triangular(L, eye, lower=True) @ kernel(inducing, latent)) / sigma
    B = eye + A @ A.T
    return L, A, jnp.linalg.cholesky(B)


def sparse_log_marginal(kernel: RBFBiasKernel, inducing, latent, Y, approximation: str = "vfe"):
    """The collapsed bound on ``ln p(Y|Z)`` (module docstring); (N, D) data, (M, q) inducing."""
    n, d = Y.shape
    _L, A, LB = _factors(kernel, inducing, latent)
    sigma2 = kernel.noise
    c = jax.scipy.linalg.solve_triangular(LB, A @ Y, lower=True) / jnp.sqrt(sigma2)
    value = (
        -0.5 * n * d * jnp.log(2 * jnp.pi)
        - d * jnp.sum(jnp.log(jnp.diag(LB)))
        - 0.5 * n * d * jnp.log(sigma2)
        - 0.5 * jnp.sum(Y * Y) / sigma2
        + 0.5 * jnp.sum(c * c)
    )
    if approximation == "vfe":
        value = value - 0.5 * d * jnp.sum(kernel.diag(latent)) / sigma2 + 0.5 * d * jnp.sum(A * A)
    return value


@register_manifold
class SparseGPLVM(AbstractSaveableManifold):
    """GPLVM with M inducing points and the collapsed bound of the module docstring.

    Attributes:
        latent: (N, q) latent points Z.
        inducing: (M, q) inducing inputs U (learned).
        kernel, data, mean, scale: as for ``GPLVM``.
        approximation: "vfe" (Titsias bound, default) or "dtc" (static).
    """

    latent: Float[Array, "n q"]
    inducing: Float[Array, "m q"]
    kernel: RBFBiasKernel
    data: Float[Array, "n d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    approximation: str = eqx.field(static=True, default="vfe")

    def training_latent(self):
        return self.latent

    def objective(self):
        """Bound on ``ln p(Y|Z)`` minus ``1/2 ||Z||_F^2``, to be maximised."""
        bound = sparse_log_marginal(self.kernel, self.inducing, self.latent, self.data, self.approximation)
        return bound - 0.5 * jnp.sum(self.latent**2)

    def trainable(self):
        spec = jax.tree.map(lambda _: False, self)
        return eqx.tree_at(lambda m: (m.latent, m.inducing, m.kernel), spec, (True, True, jax.tree.map(lambda _: True, self.kernel)))

    def back_constraint(self):
        return None

    def header(self) -> dict:
        return {"inducing": int(self.inducing.shape[0]), "approximation": self.approximation}

    @classmethod
    def template(cls, header, dtype):
        n, d, q = header["frames"], header["dims"], header["latent_dim"]
        z = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        return cls(
            latent=z(n, q), inducing=z(header["inducing"], q), kernel=rbf_bias_kernel(dtype=dtype), data=z(n, d), mean=z(d),
            scale=z(d), approximation=header["approximation"],
        )

    def predictor(self) -> GPPredictor:
        """Predictive mean ``k(z, U) L^-T LB^-T c / sigma`` and variance
        ``k(z,z) - k(z,U) (Kuu^-1 - Sigma) k(U,z)`` with ``Sigma = (Kuu + Kuf Kfu / sigma^2)^-1``."""
        L, A, LB = _factors(self.kernel, self.inducing, self.latent)
        sigma = jnp.sqrt(self.kernel.noise)
        c = jax.scipy.linalg.solve_triangular(LB, A @ self.data, lower=True) / sigma
        weights = jax.scipy.linalg.solve_triangular(L.T, jax.scipy.linalg.solve_triangular(LB.T, c, lower=False), lower=False)
        m = self.inducing.shape[0]
        eye = jnp.eye(m, dtype=self.data.dtype)
        L_inv = jax.scipy.linalg.solve_triangular(L, eye, lower=True)
        B_inv = jax.scipy.linalg.cho_solve((LB, True), eye)
        variance_matrix = L_inv.T @ (eye - B_inv) @ L_inv
        return GPPredictor(
            support=self.inducing, kernel=self.kernel, mean_weights=weights,
            variance_matrix=0.5 * (variance_matrix + variance_matrix.T), mean=self.mean, scale=self.scale,
        )


def make_sparse_gplvm(
    Y, latent_dim: int = 2, *, num_inducing: int = 150, approximation: str = "vfe", scale: bool = False, dtype=jnp.float64
) -> SparseGPLVM:
    """A sparse GPLVM initialised from PCA, with inducing points at evenly spaced training frames.

    Args:
        num_inducing: M, at most N (004 uses 100-200).
        approximation: "vfe" or "dtc".
    """
    from ._models import _initial_latent, check_training_data, standardise

    if approximation not in APPROXIMATIONS:
        raise ValueError(f"approximation must be one of {APPROXIMATIONS}, got {approximation!r}")
    Y = check_training_data(Y, latent_dim)
    if not 1 <= num_inducing <= Y.shape[0]:
        raise ValueError(f"num_inducing must be between 1 and the {Y.shape[0]} training frames, got {num_inducing}")
    Yn, mean, std = standardise(Y, scale)
    Z0 = jnp.asarray(_initial_latent(Yn, latent_dim), dtype)
    chosen = np.linspace(0, Y.shape[0] - 1, num_inducing).round().astype(int)
    return SparseGPLVM(
        latent=Z0,
        inducing=Z0[chosen],
        kernel=rbf_bias_kernel(beta=float(np.mean(Yn.var(axis=0))) + 1e-3, gamma=1.0, beta0=1e-2, noise=1e-2, dtype=dtype),
        data=jnp.asarray(Yn, dtype),
        mean=jnp.asarray(mean, dtype),
        scale=jnp.asarray(std, dtype),
        approximation=approximation,
    )

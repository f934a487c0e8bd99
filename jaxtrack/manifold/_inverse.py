"""Pose -> latent point without a back-constraint: the optimisation of paper 003 eq. 5,

    argmin_z ||y - mu(z)||^2 / (2 sigma^2(z)) + D/2 ln sigma^2(z) + 1/2 ||z||^2

(standardised units, ``sigma^2`` the predictive variance plus the noise), solved with BFGS
(optimistix), batched over poses and started at the training latent point whose pose is nearest.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optimistix as optx

from .._custom_types import Array, Float
from ._kernels import squared_distances

ENCODE_TOLERANCE = 1e-7  # BFGS rtol = atol on the objective's scale


def optimise_latent(
    predictor, training_latent: Float[Array, "n q"], training_data: Float[Array, "n a"],
    standardised: Float[Array, "m a"], *, max_steps: int,
) -> Float[Array, "m q"]:
    """Latent points (m, q) of standardised poses (m, a) by 003 eq. 5 (module docstring)."""
    start = training_latent[jnp.argmin(squared_distances(standardised, training_data), axis=1)]
    noise = predictor.noise
    dims = standardised.shape[1]

    def objective(z, y):
        mean, var = predictor(z[None])
        var = var[0] + noise
        residual = (y * predictor.scale + predictor.mean - mean[0]) / predictor.scale
        return jnp.sum(residual**2) / (2 * var) + 0.5 * dims * jnp.log(var) + 0.5 * jnp.sum(z * z)

    solver = optx.BFGS(rtol=ENCODE_TOLERANCE, atol=ENCODE_TOLERANCE)

    def solve(z0, y):
        return optx.minimise(objective, solver, z0, args=y, max_steps=max_steps, throw=False).value

    return jax.vmap(solve)(start, standardised)

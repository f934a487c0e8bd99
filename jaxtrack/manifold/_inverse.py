"""Pose -> latent point: the back-constraint where there is one, otherwise the optimisation of
paper 003 eq. 5, ``argmin_x ||y - mu(x)||^2 / (2 sigma^2(x)) + D/2 ln sigma^2(x) + 1/2 ||x||^2``,
solved with BFGS (optimistix), batched over poses and started at the training latent point
whose pose is nearest."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optimistix as optx

from ._kernels import squared_distances
from ._models import BCGPLVM, predict


def encode(model, poses, *, max_steps: int = 200):
    """Latent points (m, q) for poses (m, D) in pose units."""
    poses = jnp.asarray(poses, model.data.dtype)
    if poses.ndim != 2 or poses.shape[1] != model.data.shape[1]:
        raise ValueError(f"poses must be (m, {model.data.shape[1]}), got {poses.shape}")
    if isinstance(model, BCGPLVM):
        return model.encode(poses)
    train = model.training_latent()
    standardised = (poses - model.mean) / model.scale
    nearest = jnp.argmin(squared_distances(standardised, model.data), axis=1)
    d = poses.shape[1]

    def objective(x, y):
        mean, var = predict(model, x[None])
        var = var[0] + model.kernel.noise
        return jnp.sum(((y - mean[0]) / model.scale) ** 2) / (2 * var) + 0.5 * d * jnp.log(var) + 0.5 * jnp.sum(x * x)

    solver = optx.BFGS(rtol=1e-8, atol=1e-8)

    def solve(x0, y):
        return optx.minimise(objective, solver, x0, args=y, max_steps=max_steps, throw=False).value

    return jax.vmap(solve)(train[nearest], poses)

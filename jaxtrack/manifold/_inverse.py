"""Pose -> latent point without a back-constraint, by one of two optimisations (BFGS,
optimistix, batched over poses):

- ``"projection"`` (the default): the nearest point of the manifold's mean surface in joint
  angles (pose units, radians), ``argmin_z ||y - mu(z)||^2 / (2 s^2) + 1/2 ||z||^2`` with
  ``s^2`` the GP's noise variance in pose units, started at the training latent point whose
  pose is nearest in pose units. It is what a tracker needs to start from a pose or to project
  an average onto the manifold: the decoded pose is as close to ``y`` as the manifold allows.
- ``"likelihood"``: paper 003 eq. 5, the latent point under which ``y`` is most probable,

      argmin_z ||y - mu(z)||^2 / (2 sigma^2(z)) + D/2 ln sigma^2(z) + 1/2 ||z||^2

  (standardised units, ``sigma^2`` the predictive variance plus the noise), started at the
  training latent point nearest in standardised units. For a pose of a subject the manifold
  was not trained on, whose residual is far above the noise, the first term is cheapest where
  ``sigma^2`` is large: the optimum leaves the training points for the mean pose. Measured on
  the four real test takes of ``benchmarks/real_motion.py`` (GPDMs of latent dimension 2),
  encode -> decode is 47-82 mm from the truth this way, 13-21 mm by projection.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optimistix as optx

from .._custom_types import Array, Float
from ._kernels import squared_distances

ENCODE_MAX_STEPS = 100  # BFGS iterations per pose (ample from the nearest training point)
ENCODE_TOLERANCE = 1e-7  # BFGS rtol = atol on the objective's scale
INVERSE_METHODS = ("projection", "likelihood")


def check_inverse_method(method: str) -> None:
    if method not in INVERSE_METHODS:
        raise ValueError(f"encode method must be one of {INVERSE_METHODS}, got {method!r}")


def optimise_latent(
    predictor, training_latent: Float[Array, "n q"], training_data: Float[Array, "n a"],
    standardised: Float[Array, "m a"], *, max_steps: int, method: str = "projection",
) -> Float[Array, "m q"]:
    """Latent points (m, q) of standardised poses (m, a) by ``method`` (module docstring)."""
    check_inverse_method(method)
    scale, offset = predictor.scale, predictor.mean
    dims = standardised.shape[1]
    if method == "projection":
        poses = offset + scale * standardised
        start = training_latent[jnp.argmin(squared_distances(poses, offset + scale * training_data), axis=1)]
        noise = predictor.noise * jnp.mean(scale**2)

        def objective(z, y):
            residual = y - predictor(z[None])[0][0]
            return jnp.sum(residual**2) / (2 * noise) + 0.5 * jnp.sum(z * z)

        targets = poses
    else:
        start = training_latent[jnp.argmin(squared_distances(standardised, training_data), axis=1)]

        def objective(z, y):
            mean, var = predictor(z[None])
            var = var[0] + predictor.noise
            residual = (y * scale + offset - mean[0]) / scale
            return jnp.sum(residual**2) / (2 * var) + 0.5 * dims * jnp.log(var) + 0.5 * jnp.sum(z * z)

        targets = standardised

    solver = optx.BFGS(rtol=ENCODE_TOLERANCE, atol=ENCODE_TOLERANCE)

    def solve(z0, y):
        return optx.minimise(objective, solver, z0, args=y, max_steps=max_steps, throw=False).value

    return jax.vmap(solve)(start, targets)


def encode_poses(
    predictor, back_constraint, training_latent: Float[Array, "n q"], training_data: Float[Array, "n a"],
    angles: Float[Array, "m a"], *, max_steps: int | None = None, method: str = "projection",
) -> Float[Array, "m q"]:
    """Joint angles (pose units) -> latent points: the back-constraint where there is one (000
    eq. 22), else ``optimise_latent`` by ``method`` (``max_steps`` BFGS iterations, default
    ``ENCODE_MAX_STEPS``) from the nearest training latent point."""
    standardised = (angles - predictor.mean) / predictor.scale
    if back_constraint is not None:
        return back_constraint(standardised)
    steps = ENCODE_MAX_STEPS if max_steps is None else max_steps
    return optimise_latent(predictor, training_latent, training_data, standardised, max_steps=steps, method=method)

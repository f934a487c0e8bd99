"""A fitted pose manifold as the trackers use it: the predictive mean ``mu(z)`` precomputed
(000 eq. 25), the pose -> latent map (the back-constraint g of 000 eq. 22, or the optimisation of
003 eq. 5), and which entries of the pose vector the manifold covers (the joint angles; the
global position and orientation stay outside it, 001 sec. 5).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import optimistix as optx

from .._custom_types import Array, Float
from ..manifold._predictor import GPPredictor


class ManifoldPrior(eqx.Module):
    """Attributes:
        predictor: the GP predictive map (latent -> joint angles, pose units).
        encoder: the back-constraint (poses -> latent) or None.
        training_latent: (N, q) the training latent points.
        training_poses: (N, Da) the training poses (pose units) they came from.
        global_dims: G; the manifold covers pose entries G..D-1, entries 0..G-1 are global.
    """

    predictor: GPPredictor
    encoder: object
    training_latent: Float[Array, "n q"]
    training_poses: Float[Array, "n a"]
    global_dims: int = eqx.field(static=True)

    @property
    def latent_dim(self) -> int:
        return self.training_latent.shape[1]

    @property
    def pose_dim(self) -> int:
        return self.global_dims + self.training_poses.shape[1]

    def decode(self, Z: Float[Array, "p q"]) -> Float[Array, "p a"]:
        """Predictive mean joint angles (000 eq. 25) at latent points."""
        return self.predictor(Z)[0]

    def compose(self, global_part: Float[Array, "p g"], Z: Float[Array, "p q"]) -> Float[Array, "p d"]:
        """Full poses ``[global, mu(z)]`` (001 Alg. 2's ``Omega = P(omega)``)."""
        return jnp.concatenate([global_part, self.decode(Z)], axis=-1)

    def encode(self, angles: Float[Array, "p a"], *, max_steps: int = 50) -> Float[Array, "p q"]:
        """Joint angles -> latent points: the back-constraint, or 003 eq. 5 solved by BFGS
        from the training latent point whose pose is nearest."""
        if self.encoder is not None:
            return self.encoder(angles)
        predictor = self.predictor
        standardised = lambda y: (y - predictor.mean) / predictor.scale  # noqa: E731
        d2 = jnp.sum((standardised(angles)[:, None] - standardised(self.training_poses)[None]) ** 2, axis=-1)
        start = self.training_latent[jnp.argmin(d2, axis=1)]
        noise = predictor.kernel.noise
        dims = angles.shape[1]

        def objective(z, y):
            mean, var = predictor(z[None])
            var = var[0] + noise
            return jnp.sum(standardised(y - mean[0] + predictor.mean) ** 2) / (2 * var) + 0.5 * dims * jnp.log(var) + 0.5 * jnp.sum(z * z)

        solver = optx.BFGS(rtol=1e-6, atol=1e-6)
        solve = lambda z0, y: optx.minimise(objective, solver, z0, args=y, max_steps=max_steps, throw=False).value  # noqa: E731
        return jax.vmap(solve)(start, angles)

    def astype(self, dtype) -> "ManifoldPrior":
        """The same prior with every floating array in ``dtype`` (filters run in float32)."""
        return jax.tree.map(lambda a: a.astype(dtype) if eqx.is_inexact_array(a) else a, self)


def make_manifold_prior(model, pose_dim: int, *, dtype=None) -> ManifoldPrior:
    """A ``ManifoldPrior`` from a fitted manifold model whose data are the last entries of a
    ``pose_dim``-long pose vector (``jaxtrack fit`` drops the six root entries).

    Raises:
        ValueError: if the model's data dimension does not fit inside the pose vector.
    """
    angles = model.data.shape[1]
    if angles > pose_dim:
        raise ValueError(f"the manifold models {angles} pose entries but the pose vector has only {pose_dim}")
    encoder = model.encode if hasattr(model, "encode") and hasattr(model, "back") else None
    prior = ManifoldPrior(
        predictor=model.predictor(),
        encoder=encoder,
        training_latent=model.training_latent(),
        training_poses=model.mean + model.scale * model.data,
        global_dims=pose_dim - angles,
    )
    return prior.astype(dtype) if dtype is not None else prior

"""A fitted manifold as the trackers use it: the predictive map factorised once (000 eq. 25),
the pose -> latent map (the back-constraint g of 000 eq. 22, or a projection onto the mean
surface, or the optimisation of 003 eq. 5),
and which entries of the pose vector it covers (the joint angles; the global position and
orientation stay outside it, 001 sec. 5). Made by ``to_prior`` or
``make_manifold_prior``: the model (``_base``) knows nothing of tracking, and this module reads
the model's interface.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from .._tree import cast_floating
from ._base import AbstractManifold
from ._inverse import encode_poses
from ._predictor import AbstractPredictor, GPPredictor


class ManifoldPrior(eqx.Module):
    """Attributes:
        predictor: the predictive map (latent -> joint angles, pose units): a GP's, or an RBF
            network's for the Laplacian Eigenmaps family.
        back_constraint: the map from standardised joint angles to latent points, or None.
        training_latent: (N, q) the training latent points.
        training_data: (N, Da) the standardised training poses they came from.
        global_dims: G; the manifold covers pose entries G..D-1, entries 0..G-1 are global.
        latent_dynamics: the latent dynamics' predictive map ``x_{t-1} -> (mean of x_t,
            variance)`` (a GPDM's, 001 eqs. 7-9), or None for manifolds without dynamics.
    """

    predictor: AbstractPredictor
    back_constraint: eqx.Module | None
    training_latent: Float[Array, "n q"]
    training_data: Float[Array, "n a"]
    global_dims: int = eqx.field(static=True)
    latent_dynamics: GPPredictor | None = None

    def __check_init__(self):
        if self.global_dims < 0:
            raise ValueError(f"global_dims must be non-negative, got {self.global_dims}")
        if self.training_latent.shape[0] != self.training_data.shape[0]:
            raise ValueError(f"{self.training_latent.shape[0]} training latent points for {self.training_data.shape[0]} poses")

    @property
    def latent_dim(self) -> int:
        return self.training_latent.shape[1]

    @property
    def pose_dim(self) -> int:
        return self.global_dims + self.training_data.shape[1]

    @property
    def has_back_constraint(self) -> bool:
        return self.back_constraint is not None

    def training_poses(self) -> Float[Array, "n a"]:
        """The training joint angles in pose units."""
        return self.predictor.mean + self.predictor.scale * self.training_data

    def decode(self, latent: Float[Array, "p q"]) -> tuple[Float[Array, "p a"], Float[Array, " p"]]:
        """Predictive mean joint angles and variance (000 eqs. 25-26) at latent points."""
        return self.predictor(latent)

    def decode_mean(self, latent: Float[Array, "p q"]) -> Float[Array, "p a"]:
        """Predictive mean joint angles (000 eq. 25) at latent points."""
        return self.predictor(latent)[0]

    def compose(self, global_part: Float[Array, "p g"], latent: Float[Array, "p q"]) -> Float[Array, "p d"]:
        """Full poses ``[global, mu(z)]`` (001 Alg. 2's ``Omega = P(omega)``)."""
        return jnp.concatenate([global_part, self.decode_mean(latent)], axis=-1)

    def predict_latent(self, latent: Float[Array, "p q"]) -> tuple[Float[Array, "p q"], Float[Array, " p"]]:
        """Mean and variance (with the dynamics' noise) of the next latent point (001 eqs. 7-9).

        Raises:
            ValueError: if the manifold has no latent dynamics (only a GPDM has).
        """
        if self.latent_dynamics is None:
            raise ValueError("this manifold has no latent dynamics: fit a GPDM (make_gpdm) for them")
        mean, variance = self.latent_dynamics(latent)
        return mean, variance + self.latent_dynamics.kernel.noise

    def encode(self, angles: Float[Array, "p a"], *, max_steps: int | None = None, method: str = "projection") -> Float[Array, "p q"]:
        """Joint angles (pose units) -> latent points: the back-constraint where there is one,
        else by BFGS from the nearest training latent point (``max_steps`` iterations, default
        ``ENCODE_MAX_STEPS``) either the projection onto the mean surface (``method=
        "projection"``: the decoded pose is as near as the manifold allows) or 003 eq. 5
        (``"likelihood"``); ``jaxtrack.manifold._inverse`` says why projection is the default."""
        return encode_poses(self.predictor, self.back_constraint, self.training_latent, self.training_data, angles,
                            max_steps=max_steps, method=method)

    def astype(self, dtype) -> ManifoldPrior:
        """The same prior with every floating array in ``dtype`` (trackers run in float32)."""
        return cast_floating(self, dtype)


def to_prior(model: AbstractManifold, global_dims: int) -> ManifoldPrior:
    """A fitted manifold precomputed for tracking: its predictive map factorised once, its
    back-constraint, training latent points and data, and its latent dynamics (a GPDM's),
    covering the entries ``global_dims..`` of a pose vector.

    Raises:
        TypeError: if ``model`` is not an ``AbstractManifold``.
    """
    if not isinstance(model, AbstractManifold):
        raise TypeError(f"to_prior needs a fitted AbstractManifold, got {type(model).__name__}")
    return ManifoldPrior(
        predictor=model.predictor(), back_constraint=model.back_constraint(), training_latent=model.training_latent(),
        training_data=model.data, global_dims=global_dims, latent_dynamics=model.latent_dynamics(),
    )


def make_manifold_prior(model, pose_dim: int, *, dtype=None) -> ManifoldPrior:
    """The ``ManifoldPrior`` of a fitted manifold whose data are the last entries of a
    ``pose_dim``-long pose vector (``jaxtrack fit`` drops the global entries).

    Raises:
        TypeError: if ``model`` is not an ``AbstractManifold``.
        ValueError: if the model's data dimension does not fit inside the pose vector.
    """
    if not isinstance(model, AbstractManifold):
        raise TypeError(f"make_manifold_prior needs a fitted AbstractManifold, got {type(model).__name__}")
    angles = model.data_dim
    if angles > pose_dim:
        raise ValueError(f"the manifold models {angles} pose entries but the pose vector has only {pose_dim}")
    prior = to_prior(model, pose_dim - angles)
    return prior.astype(dtype) if dtype is not None else prior

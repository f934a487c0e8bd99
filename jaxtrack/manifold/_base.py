"""The manifold interface every pose model implements: the model alone.

A manifold maps joint angles (pose units) to a low-dimensional latent space and back: ``encode``
(pose -> latent), ``decode`` (latent -> predictive mean and variance), and a pure ``objective``
that ``fit`` (``fit_model``) maximises over the leaves ``trainable`` marks. What tracking needs
of it is ``to_prior`` (``_prior.py``: the predictive map factorised once), and what a file
needs ``AbstractSaveableManifold`` (``_serialise.py``: a header and a template); both read this
interface, and this module imports neither.
"""

from __future__ import annotations

import abc
from typing import Any

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._inverse import check_inverse_method, encode_poses


class AbstractManifold(eqx.Module):
    """A learned pose manifold (GPLVM family). Attributes every model has:

    Attributes:
        data: (N, Da) standardised training data.
        mean, scale: (Da,) the standardisation: pose = mean + scale * data.
    """

    data: eqx.AbstractVar[Float[Array, "n a"]]
    mean: eqx.AbstractVar[Float[Array, " a"]]
    scale: eqx.AbstractVar[Float[Array, " a"]]

    def __check_init__(self):
        shape = jnp.shape(self.data)
        if len(shape) != 2:
            raise ValueError(f"{type(self).__name__}: data must be (frames, dims), got shape {shape}")
        for name in ("mean", "scale"):
            if jnp.shape(getattr(self, name)) != (shape[1],):
                raise ValueError(f"{type(self).__name__}: {name} must have shape ({shape[1]},), got {jnp.shape(getattr(self, name))}")

    @abc.abstractmethod
    def training_latent(self) -> Float[Array, "n q"]:
        """The latent points of the N training poses."""

    @abc.abstractmethod
    def objective(self) -> Float[Array, ""]:
        """The pure objective fitting maximises (a log posterior or a bound on it)."""

    @abc.abstractmethod
    def trainable(self) -> Any:
        """Filter spec (same structure as the model): True for the leaves fitting changes."""

    @abc.abstractmethod
    def predictor(self):
        """The predictive map latent -> pose (a ``GPPredictor``), factorised once."""

    @abc.abstractmethod
    def back_constraint(self):
        """The learned map from standardised poses to latent points, or None when the model
        has none (then ``encode`` optimises 003 eq. 5)."""

    @property
    def latent_dim(self) -> int:
        return self.training_latent().shape[1]

    @property
    def data_dim(self) -> int:
        return self.data.shape[1]

    def training_poses(self) -> Float[Array, "n a"]:
        """The training data in pose units."""
        return self.mean + self.scale * self.data

    def encode(self, poses: Float[Array, "m a"], *, max_steps: int | None = None, method: str = "projection") -> Float[Array, "m q"]:
        """Joint angles (pose units) -> latent points: the back-constraint where there is one,
        otherwise by BFGS, projection onto the mean surface or 003 eq. 5's ``"likelihood"``
        (see ``ManifoldPrior.encode``).

        Raises:
            ValueError: if ``poses`` is not (m, Da).
        """
        poses = jnp.asarray(poses, self.data.dtype)
        if poses.ndim != 2 or poses.shape[1] != self.data_dim:
            raise ValueError(f"poses must be (m, {self.data_dim}), got {poses.shape}")
        check_inverse_method(method)
        return encode_poses(self.predictor(), self.back_constraint(), self.training_latent(), self.data, poses,
                            max_steps=max_steps, method=method)

    def decode(self, latent: Float[Array, "m q"]) -> tuple[Float[Array, "m a"], Float[Array, " m"]]:
        """Predictive mean (pose units) and variance (standardised units, without the noise)
        at latent points (000 eqs. 23-26). Factorises the covariance on every call: trackers
        use ``to_prior`` once instead."""
        return self.predictor()(latent)

    def fit(self, **options):
        """Maximise ``objective()`` over the ``trainable()`` leaves: ``fit_model(self, **options)``
        (L-BFGS in one compiled loop; options ``max_steps``, ``tolerance``, ``target``,
        ``progress``, ``report_every``). Returns
        ``(fitted_model, FitInfo)``."""
        from ._fit import fit_model

        return fit_model(self, **options)

    def latent_dynamics(self):
        """The latent dynamics' predictive map (a ``GPPredictor`` from ``x_{t-1}`` to ``x_t``),
        or None: only models with latent dynamics (``GPDM``) override this."""
        return None

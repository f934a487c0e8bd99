"""Pose estimates from a weighted particle set (000 Alg. 1's weighted mean; 001 sec. 5.4)."""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..dynamics import AbstractDynamics
from ..manifold import ManifoldPrior
from ._weights import best_particle, weighted_mean


class AbstractEstimator(eqx.Module):
    """Maps normalised log-weights (N,) and states (N, S) to one pose (D,)."""

    @abc.abstractmethod
    def __call__(self, log_weights: Float[Array, " n"], states: Float[Array, "n s"], dynamics: AbstractDynamics) -> Float[Array, " d"]:
        """The pose estimate of one frame."""


class WeightedMean(AbstractEstimator):
    """``sum_i w_i pose(s_i)``: the posterior mean pose (000 Alg. 1)."""

    def __call__(self, log_weights, states, dynamics):
        return weighted_mean(log_weights, dynamics.to_pose(states))


class BestParticle(AbstractEstimator):
    """The pose of the particle of largest weight."""

    def __call__(self, log_weights, states, dynamics):
        return best_particle(log_weights, dynamics.to_pose(states))


class StateMean(AbstractEstimator):
    """``pose(sum_i w_i s_i)``: for latent states ``mu(E[omega])`` (003 Alg. 2)."""

    def __call__(self, log_weights, states, dynamics):
        return dynamics.to_pose(weighted_mean(log_weights, states)[None])[0]


class ProjectedMean(AbstractEstimator):
    """The weighted mean pose with its joint angles projected onto the manifold,
    ``mu(g(E[x^a]))`` (001 sec. 5.4: the average in data space, projected back)."""

    manifold: ManifoldPrior

    def __call__(self, log_weights, states, dynamics):
        average = weighted_mean(log_weights, dynamics.to_pose(states))
        g = self.manifold.global_dims
        projected = self.manifold.decode_mean(self.manifold.encode(average[None, g:]))[0]
        return jnp.concatenate([average[:g], projected])


def make_estimator(name: str | AbstractEstimator, manifold: ManifoldPrior | None = None) -> AbstractEstimator:
    """An estimator by name: "mean", "best", "latent_mean" (``StateMean``) or "data_mean"
    (``ProjectedMean``, needs the manifold); an ``AbstractEstimator`` is returned as it is."""
    if isinstance(name, AbstractEstimator):
        return name
    simple = {"mean": WeightedMean, "best": BestParticle, "latent_mean": StateMean}
    if name in simple:
        return simple[name]()
    if name == "data_mean":
        if manifold is None:
            raise ValueError("the 'data_mean' estimator projects onto a manifold; none was given")
        return ProjectedMean(manifold)
    raise ValueError(f"estimator must be one of ('mean', 'best', 'latent_mean', 'data_mean'), got {name!r}")

"""SIR / Condensation (001 eqs. 1-4): a Gaussian random walk in pose space, one layer. The one
definition of the tracker: ``sir_filter`` composes it, ``make_sir`` builds it from scales given
directly, ``RECIPE`` fits the scales on validation motion and builds it for a budget."""

import jax.numpy as jnp

from ..dynamics import fit_pose_random_walk, make_pose_random_walk
from ..filters import SIR, make_estimator
from ..likelihood import as_likelihood
from ._registry import TrackerRecipe


def sir_filter(dynamics, likelihood, num_particles: int, *, resampler="systematic", estimator="mean") -> SIR:
    """SIR over ``dynamics`` (any pose-space dynamics), estimate by ``estimator`` (a name of
    ``filters.make_estimator`` or an ``AbstractEstimator``)."""
    return SIR(dynamics, as_likelihood(likelihood), num_particles, resampler, make_estimator(estimator))


def make_sir(likelihood, scales, num_particles: int, *, resampler="systematic", estimator="mean", dtype=jnp.float32) -> SIR:
    """SIR with the random walk ``scales`` (D,) (standard deviation per pose entry)."""
    return sir_filter(make_pose_random_walk(scales, dtype=dtype), likelihood, num_particles, resampler=resampler, estimator=estimator)


def fit(key, motion):
    del key  # a deterministic fit
    return fit_pose_random_walk(list(motion.validation))


def build(dynamics, likelihood, budget):
    return sir_filter(dynamics, likelihood, budget.particles)


RECIPE = TrackerRecipe("sir", "SIR", "sampling importance resampling with a pose random walk (001 eqs. 1-4)", fit, build)

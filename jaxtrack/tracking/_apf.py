"""The annealed particle filter (001 Alg. 1): the pose random walk, ``layers`` layers. The one
definition of the tracker: ``apf_filter`` composes it, ``make_apf`` builds it from scales given
directly, ``RECIPE`` fits the scales on validation motion and builds it for a budget."""

import jax.numpy as jnp

from ..dynamics import fit_pose_random_walk, make_pose_random_walk
from ..filters import APF, make_estimator
from ..likelihood import as_likelihood
from ._registry import TrackerRecipe


def apf_filter(dynamics, likelihood, num_particles: int, num_layers: int = 5, *, estimator="mean", **options) -> APF:
    """An APF over ``dynamics`` with ``num_layers`` x ``num_particles`` likelihood evaluations
    per frame; ``options`` are ``APF``'s (survival_target, variance_decay, fixed_betas,
    partitions, coarse_likelihood, coarse_layers, resampler)."""
    return APF(dynamics, as_likelihood(likelihood), num_particles, num_layers, estimator=make_estimator(estimator), **options)


def make_apf(likelihood, scales, num_particles: int, num_layers: int = 5, *, estimator="mean", dtype=jnp.float32, **options) -> APF:
    """An APF on the random walk ``scales`` (D,); ``options`` as ``apf_filter``'s."""
    return apf_filter(make_pose_random_walk(scales, dtype=dtype), likelihood, num_particles, num_layers, estimator=estimator,
                      **options)


def fit(key, motion):
    del key
    return fit_pose_random_walk(list(motion.validation))


def build(dynamics, likelihood, budget):
    return apf_filter(dynamics, likelihood, budget.per_layer, budget.layers)


RECIPE = TrackerRecipe("apf", "APF", "annealed particle filter in pose space (Deutscher and Reid; 001 Alg. 1)", fit, build,
                       annealed=True)

"""GPAPF (001 Alg. 2-3): annealing over (global entries, latent point) with ``layers - 1``
layers, then the final full-pose layer (001 Alg. 3) with half the pose random walk's scales.
On a GPDM (its paper's manifold, the default) the latent points follow the GPDM's predictive
dynamics; on a manifold without dynamics, a latent random walk."""

import jax.numpy as jnp

from ..dynamics import PoseRandomWalk, fit_latent_dynamics, fit_pose_random_walk
from ..filters import APF, ProjectedMean
from ._registry import TrackerRecipe

FINAL_LAYER_SCALE = 0.5  # the final layer's steps, relative to the pose random walk's


def fit(key, motion):
    del key
    latent = fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts)
    pose = fit_pose_random_walk(list(motion.validation))
    return latent, PoseRandomWalk(FINAL_LAYER_SCALE * jnp.asarray(pose.scales))


def build(fitted, likelihood, budget):
    latent, final = fitted
    return APF(latent, likelihood, budget.per_layer, budget.layers - 1, final_layer=final,
               estimator=ProjectedMean(latent.manifold))


RECIPE = TrackerRecipe("gpapf", "GPAPF", "annealed filter over (global pose, latent point) with a final full-pose layer (001)",
                       fit, build, needs_manifold=True, manifold="gpdm", annealed=True, min_layers=2)

"""GPAPF (001 Alg. 2-3): annealing over (global entries, latent point) with ``layers - 1``
layers, then the final full-pose layer (001 Alg. 3) with half the pose random walk's scales.
On a GPDM (its paper's manifold, the default) the latent points follow the GPDM's predictive
dynamics mean, with its predictive sd scaled by the two-component mixture fitted on the
validation motion (``LATENT_NOISE``); on a manifold without dynamics, a latent random walk."""

import jax.numpy as jnp

from ..dynamics import PoseRandomWalk, fit_latent_dynamics, fit_pose_random_walk
from ..filters import APF, ProjectedMean
from ._registry import TrackerRecipe

FINAL_LAYER_SCALE = 0.5  # the final layer's steps, relative to the pose random walk's


# The GPDM's latent noise refitted on the validation motion, as every other noise scale is
# (dynamics._latent_noise): 001 uses the GPDM's own predictive variance ("gpdm"). Over 20 runs
# on both Bandai runs (the tuned 005 and the held-out 006; 4 and 3 views) the fitted mixture
# took GPAPF's drift ratio from 1.36-1.49 to 0.91-1.11 and its lost runs from 1-9 of 20 to 0-3;
# even elsewhere (docs/floor.md, "The floor", GPAPF on the held-out Bandai run).
LATENT_NOISE = "validation"


def fit(key, motion):
    del key
    latent = fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts, latent_noise=LATENT_NOISE)
    pose = fit_pose_random_walk(list(motion.validation))
    return latent, PoseRandomWalk(FINAL_LAYER_SCALE * jnp.asarray(pose.scales))


def build(fitted, likelihood, budget):
    latent, final = fitted
    return APF(latent, likelihood, budget.per_layer, budget.layers - 1, final_layer=final,
               estimator=ProjectedMean(latent.manifold))


# 001 sec. 5.4 tried latent spaces of 2 and 3 dimensions. 3 it is here: on real motion rendered
# with another body it was better than 2 on all eight walk, jog and run rows, by 0.6-11 mm
# (docs/trackers.md, "Where the manifold trackers start").
LATENT_DIM = 3

RECIPE = TrackerRecipe("gpapf", "GPAPF", "annealed filter over (global pose, latent point) with a final full-pose layer (001)",
                       fit, build, needs_manifold=True, manifold="gpdm", annealed=True, min_layers=2, latent_dim=LATENT_DIM)

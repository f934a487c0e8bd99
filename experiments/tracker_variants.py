"""Variants of the one-layer manifold trackers tried against their drift on real motion (issue
#13, item 5), registered as trackers over the public API and run through ``real_motion.py``'s
protocol (every option of that script applies):

- ``mrpf-final``: MRPF (eq. 28 sampled exactly, GPDM latent proposal) at half the budget, then
  001 Alg. 3's final full-pose layer (half the pose random walk's scales) at the other half,
  which gives the estimate; the MRPF particles carry on to the next frame;
- ``mrpf-anneal``: MRPF's transition as layer 0 of a 3-layer annealed filter (later layers
  perturb with eq. 29's random walk, shrinking), budget split in three;
- ``latentpf-final``, ``latentpf-anneal``: the same two changes to LatentPF on the GPDM;
- ``mrpf-final100``, ``latentpf-final100``: the tracker keeps 400 particles and carries them on;
  a final full-pose layer of 100 particles, drawn from them by weight, gives the estimate (the
  split of GPAPF's budget, 4 x 100 + 100);
- ``mrpf-mixture``, ``latentpf-mixture``: the tracker with its GPDM latent noise refitted on
  the validation motion (``latent_noise="validation"``: a scale mixture of the GPDM's
  predictive sd, ``jaxtrack.dynamics._latent_noise``), everything else its own. GPAPF has it by
  default (since 2026-11-25); ``gpapf-gpdm-noise`` is GPAPF with the GPDM's own noise (001's,
  its earlier default).
- ``apf-partitioned``, ``gpapf-partitioned``: hierarchical partitioned annealing (Deutscher and
  Reid; ``APF(partitions=...)``), the schedule set before any measurement. APF's layers after
  the transition perturb the root and the spine, then the legs, then the arms and the neck,
  then everything; GPAPF's, the global entries, then the latent point, then both.
- ``mrpf-gle-start``: MRPF on its 2-D GPDM fitted from 002's GLE embedding
  (``make_gpdm(..., init="gle")``) instead of the principal components, which fold each gait
  cycle of the demo's motion into a thin loop whose two sides lie side by side (``GLE_START_STEPS`` fit
  steps and the optimiser, the experiment's defaults, whatever ``--fit-steps`` says).
- ``mrpf-weight1``, ``mrpf-weight2``, ``mrpf-weight8``: MRPF with eq. 30's factor raised to
  the power 1 (the maximum-likelihood fit as it is, MRPF's default before 2026-11-25), 2 or 8
  instead of its default 4 (``fit_mrpf_transition(..., manifold_weight=...)``). Run on the
  validation takes (``real_motion.py --sequences validation``) they chose the default.
- ``apf-coarse``, ``gpapf-coarse``: coarse-to-fine annealing (``APF(coarse_likelihood=...,
  coarse_layers=...)`` with ``likelihood.coarsen_likelihood``), the schedule set before any
  measurement: the first half of the annealing layers (rounded down: 2 of APF's 5, 2 of
  GPAPF's 4) score the silhouettes at half the resolution (40x30 for 80x60), the rest, and
  GPAPF's final layer, at the full one. A coarse evaluation is counted as a full one.

    taskset -c 0,1 python experiments/tracker_variants.py --cmu /tmp/cmu --bandai /tmp/bandai \\
        --sequences cmu-jog --views 4 --runs 5 --fit-steps 200 \\
        --methods mrpf mrpf-final mrpf-anneal latentpf latentpf-final latentpf-anneal --json variants.json
"""

from __future__ import annotations

import dataclasses
import os
import sys

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxtrack.body import GLOBAL_DOFS, humaneva_skeleton, joint_angles, mirrored_groups
from jaxtrack.dynamics import AbstractDynamics, PoseRandomWalk, fit_latent_dynamics, fit_mrpf_transition, fit_pose_random_walk
from jaxtrack.filters import APF, SIR, AbstractFilter, FilterState, ProjectedMean, WeightedMean, choose_beta, get_resampler, smc_layer
from jaxtrack.likelihood import AbstractLikelihood, coarsen_likelihood
from jaxtrack.manifold import make_gpdm, to_prior
from jaxtrack.tracking import TrackerRecipe, get_tracker, register_tracker

FINAL_LAYER_SCALE = 0.5  # as GPAPF's final layer: half the pose random walk's steps


def _final_layer(motion):
    return PoseRandomWalk(FINAL_LAYER_SCALE * jnp.asarray(fit_pose_random_walk(list(motion.validation)).scales))


def _mrpf(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="product", latent_proposal="gpdm")


def _latent(key, motion):
    del key
    return fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts)


def _with_final(fit_one):
    return lambda key, motion: (fit_one(key, motion), _final_layer(motion))


def _build_final(fitted, likelihood, budget):
    dynamics, final = fitted  # layer 0 at beta = 1 is SIR's step exactly; the final layer refines the estimate
    return APF(dynamics, likelihood, budget.evaluations // 2, 1, fixed_betas=(1.0,), final_layer=final)


def _build_annealed(estimator=None):
    def build(dynamics, likelihood, budget):
        options = {} if estimator is None else {"estimator": estimator(dynamics.manifold)}
        return APF(dynamics, likelihood, budget.evaluations // 3, 3, **options)

    return build


FINAL_PARTICLES = 100


class SIRWithFinalLayer(AbstractFilter):
    """SIR over ``num_particles``, then 001 Alg. 3's final full-pose layer on ``final_particles``
    drawn from them by weight, for the estimate only (the SIR particles carry on)."""

    dynamics: AbstractDynamics
    likelihood: AbstractLikelihood
    final: AbstractDynamics
    num_particles: int = eqx.field(static=True)
    final_particles: int = eqx.field(static=True)

    def init(self, key, initial_pose) -> FilterState:
        return SIR(self.dynamics, self.likelihood, self.num_particles).init(key, initial_pose)

    def step(self, key, state, observation):
        sir_key, draw_key, final_key = jax.random.split(key, 3)
        state, info = SIR(self.dynamics, self.likelihood, self.num_particles).step(sir_key, state, observation)
        drawn = jax.random.categorical(draw_key, state.log_weights, shape=(self.final_particles,))
        poses = self.dynamics.to_pose(state.particles)[drawn]
        refined, weights, _ = smc_layer(
            tuple(jax.random.split(final_key)), poses, jnp.zeros(self.final_particles, poses.dtype), move=self.final.propose,
            log_likelihood=lambda x: self.likelihood(self.final.to_pose(x), observation), resample=get_resampler("systematic"),
            temper=lambda log_lik: choose_beta(log_lik, 0.5),
        )
        return state, eqx.tree_at(lambda i: i.estimate, info, WeightedMean()(weights, refined, self.final))


POSE_PARTS = {  # the pose's entries by part: 3 root positions, then the skeleton's angles
    "root": ("x", "y", "z", "root_yaw", "root_pitch", "root_roll", "spine_flex", "spine_bend", "spine_twist"),
    "legs": ("lhip_flex", "lhip_abd", "lhip_twist", "lknee_flex", "rhip_flex", "rhip_abd", "rhip_twist", "rknee_flex"),
    "arms": ("lclavicle_elev", "lclavicle_prot", "lshoulder_flex", "lshoulder_abd", "lshoulder_twist", "lelbow_flex",
             "rclavicle_elev", "rclavicle_prot", "rshoulder_flex", "rshoulder_abd", "rshoulder_twist", "relbow_flex",
             "neck_flex", "neck_bend", "neck_twist"),
}


def _pose_partitions(layers):
    """APF's partitions for ``layers`` layers: root and spine, legs, arms and neck, then all."""
    names = ("x", "y", "z", *humaneva_skeleton().dof_names)
    parts = [tuple(names.index(n) for n in POSE_PARTS[p]) for p in ("root", "legs", "arms")]
    schedule = [*parts, tuple(range(len(names)))]
    return tuple(schedule[min(m, len(schedule) - 1)] for m in range(layers - 1))


def _build_apf_partitioned(dynamics, likelihood, budget):
    return APF(dynamics, likelihood, budget.per_layer, budget.layers, partitions=_pose_partitions(budget.layers))


def _build_gpapf_partitioned(fitted, likelihood, budget):
    latent, final = fitted
    width = GLOBAL_DOFS + latent.manifold.latent_dim
    schedule = [tuple(range(GLOBAL_DOFS)), tuple(range(GLOBAL_DOFS, width)), tuple(range(width))]
    layers = budget.layers - 1
    return APF(latent, likelihood, budget.per_layer, layers, final_layer=final, estimator=ProjectedMean(latent.manifold),
               partitions=tuple(schedule[min(m, 2)] for m in range(layers - 1)))


COARSE_FACTOR = 2  # the coarse layers' images: half the width and height


def _build_apf_coarse(dynamics, likelihood, budget):
    return APF(dynamics, likelihood, budget.per_layer, budget.layers, coarse_likelihood=coarsen_likelihood(likelihood, COARSE_FACTOR),
               coarse_layers=budget.layers // 2)


def _build_gpapf_coarse(fitted, likelihood, budget):
    latent, final = fitted
    layers = budget.layers - 1
    return APF(latent, likelihood, budget.per_layer, layers, final_layer=final, estimator=ProjectedMean(latent.manifold),
               coarse_likelihood=coarsen_likelihood(likelihood, COARSE_FACTOR), coarse_layers=layers // 2)


def _build_final100(fitted, likelihood, budget):
    dynamics, final = fitted
    return SIRWithFinalLayer(dynamics, likelihood, final, budget.evaluations - FINAL_PARTICLES, FINAL_PARTICLES)


def _mixture(name, fit):
    base = get_tracker(name)
    return dataclasses.replace(base, name=f"{name}-mixture", label=f"{base.label}+mixture", manifolds=("gpdm",), fit=fit,
                               description=f"{base.label} with its GPDM latent noise fitted on the validation motion")


def _latent_mixture(key, motion):
    del key
    return fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts, latent_noise="validation")


def _mrpf_mixture(key, motion):
    return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="product", latent_proposal="gpdm",
                               latent_noise="validation")


MIRRORED = mirrored_groups(humaneva_skeleton().dof_names[3:])  # MRPF's tied scales (the real takes are HumanEva's)


def _manifold_weight(weight):
    """MRPF with eq. 30's factor raised to ``weight`` instead of its default."""
    base = get_tracker("mrpf")

    def fit(key, motion):
        return fit_mrpf_transition(motion.manifold, list(motion.validation), key=key, proposal="product",
                                   latent_proposal="gpdm", tied=MIRRORED, manifold_weight=weight)

    return dataclasses.replace(base, name=f"mrpf-weight{weight:g}", label=f"MRPF, manifold^{weight:g}", fit=fit,
                               manifolds=("gpdm",), description=f"MRPF with eq. 30's factor to the power {weight:g}")


def _gpapf_gpdm_noise(key, motion):
    latent = fit_latent_dynamics(motion.manifold, list(motion.validation), motion.training_starts, latent_noise="gpdm")
    return latent, get_tracker("gpapf").fit(key, motion)[1]


GLE_START_STEPS = 300  # the experiment's default fit steps


def _gle_start(name):
    """Tracker ``name`` on a GPDM of its own latent dimension refitted from the GLE start."""
    base = get_tracker(name)

    def fit(key, motion):
        angles = [joint_angles(p) for p in motion.training]
        model, _ = make_gpdm(angles, motion.manifold.latent_dim, init="gle").fit(max_steps=GLE_START_STEPS, optimiser="optax")
        return base.fit(key, dataclasses.replace(motion, manifold=to_prior(model, motion.manifold.global_dims), model=model))

    return dataclasses.replace(base, name=f"{name}-gle-start", label=f"{base.label}+GLE start", manifolds=("gpdm",), fit=fit,
                               description=f"{base.label} on a GPDM fitted from the GLE embedding instead of PCA")


MRPF_DIM = get_tracker("mrpf").latent_dim  # each variant on its base tracker's latent dimension
LATENT_DIM = get_tracker("latentpf").latent_dim

VARIANTS = [
    dataclasses.replace(get_tracker("apf"), name="apf-partitioned", label="APF+partitioned", build=_build_apf_partitioned,
                        description="APF with hierarchical partitioned annealing"),
    dataclasses.replace(get_tracker("gpapf"), name="gpapf-partitioned", label="GPAPF+partitioned", build=_build_gpapf_partitioned,
                        description="GPAPF with partitioned annealing: the global entries, then the latent point"),
    dataclasses.replace(get_tracker("apf"), name="apf-coarse", label="APF+coarse", build=_build_apf_coarse,
                        description="APF, its first half of the layers on silhouettes at half the resolution"),
    dataclasses.replace(get_tracker("gpapf"), name="gpapf-coarse", label="GPAPF+coarse", build=_build_gpapf_coarse,
                        description="GPAPF, its first half of the annealing layers at half the resolution"),
    _mixture("mrpf", _mrpf_mixture),
    dataclasses.replace(get_tracker("gpapf"), name="gpapf-gpdm-noise", label="GPAPF+GPDM noise", manifolds=("gpdm",),
                        fit=_gpapf_gpdm_noise, description="GPAPF with the GPDM's own predictive variance (001; its default "
                        "before 2026-11-25)"),
    _mixture("latentpf", _latent_mixture),
    *(_manifold_weight(weight) for weight in (1.0, 2.0, 8.0)),
    _gle_start("mrpf"),
    TrackerRecipe("mrpf-final", "MRPF+final", "MRPF, then a final full-pose layer for the estimate", _with_final(_mrpf), _build_final,
                  needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True, latent_dim=MRPF_DIM),
    TrackerRecipe("mrpf-anneal", "MRPF+anneal3", "MRPF's transition as layer 0 of three annealing layers", _mrpf, _build_annealed(),
                  needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True, latent_dim=MRPF_DIM),
    TrackerRecipe("latentpf-final", "LatentPF+final", "LatentPF, then a final full-pose layer for the estimate", _with_final(_latent),
                  _build_final, needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True, latent_dim=LATENT_DIM),
    TrackerRecipe("latentpf-anneal", "LatentPF+anneal3", "LatentPF's GPDM step as layer 0 of three annealing layers", _latent,
                  _build_annealed(ProjectedMean), needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True,
                  latent_dim=LATENT_DIM),
    TrackerRecipe("mrpf-final100", "MRPF+final100", "MRPF on 400 particles, a 100-particle final full-pose layer for the estimate",
                  _with_final(_mrpf), _build_final100, needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True,
                  latent_dim=MRPF_DIM),
    TrackerRecipe("latentpf-final100", "LatentPF+final100", "LatentPF on 400 particles, a 100-particle final layer for the estimate",
                  _with_final(_latent), _build_final100, needs_manifold=True, manifold="gpdm", manifolds=("gpdm",), velocity=True,
                  latent_dim=LATENT_DIM),
]

if __name__ == "__main__":
    for recipe in VARIANTS:
        register_tracker(recipe, replace=True)
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))
    import real_motion

    real_motion.main()

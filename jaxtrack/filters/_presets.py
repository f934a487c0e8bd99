"""The papers' trackers as compositions of a filter, a dynamics and an estimator, built from
noise scales given directly (``jaxtrack.tracking`` builds them from fitted dynamics instead):

- SIR / Condensation (001 eqs. 1-4): ``SIR`` + ``PoseRandomWalk``;
- APF (001 Alg. 1): ``APF`` + ``PoseRandomWalk``;
- MRPF (000 Alg. 1): ``SIR`` + ``ManifoldRegularisedTransition``;
- GPAPF (001 Alg. 2-3): ``APF`` + ``LatentRandomWalk`` (+ a final ``PoseRandomWalk`` layer);
- LatentPF (003 Alg. 2): ``SIR`` + ``LatentRandomWalk``, estimate ``mu(E[omega])``.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..dynamics import LatentRandomWalk, ManifoldRegularisedTransition, as_scale_vector, make_pose_random_walk
from ..likelihood import as_likelihood
from ..manifold import ManifoldPrior
from ._apf import APF
from ._estimators import make_estimator
from ._sir import SIR


def make_sir(likelihood, scales, num_particles: int, *, resampler="systematic", estimator="mean", dtype=jnp.float32) -> SIR:
    """SIR with the random walk ``scales`` (D,) (standard deviation per pose entry)."""
    return SIR(make_pose_random_walk(scales, dtype=dtype), as_likelihood(likelihood), num_particles, resampler,
               make_estimator(estimator))


def make_apf(likelihood, scales, num_particles: int, num_layers: int = 5, *, estimator="mean", dtype=jnp.float32, **options) -> APF:
    """An APF with ``num_layers`` x ``num_particles`` likelihood evaluations per frame; ``options``
    are ``APF``'s (survival_target, variance_decay, fixed_betas, resampler)."""
    return APF(make_pose_random_walk(scales, dtype=dtype), as_likelihood(likelihood), num_particles, num_layers,
               estimator=make_estimator(estimator), **options)


def make_mrpf(likelihood, prior: ManifoldPrior, s_xx, s_xz, s_zx, num_particles: int, *, proposal="product",
              resampler="systematic", estimator="mean", dtype=jnp.float32) -> SIR:
    """MRPF with noise scales of 000 eqs. 27, 29, 30 (usually from ``fit_mrpf_transition``);
    ``proposal="prior"`` is 000 Alg. 1 as printed, ``"product"`` (default) samples eq. 28 exactly."""
    dynamics = ManifoldRegularisedTransition(
        manifold=prior.astype(dtype),
        s_xx=jnp.asarray(as_scale_vector("s_xx", s_xx, prior.pose_dim, dtype), dtype),
        s_xz=jnp.asarray(as_scale_vector("s_xz", s_xz, prior.latent_dim, dtype), dtype),
        s_zx=jnp.asarray(as_scale_vector("s_zx", s_zx, prior.pose_dim - prior.global_dims, dtype), dtype),
        proposal=proposal,
    )
    return SIR(dynamics, as_likelihood(likelihood), num_particles, resampler, make_estimator(estimator))


def latent_random_walk(prior: ManifoldPrior, s_global, s_latent, dtype) -> LatentRandomWalk:
    """A ``LatentRandomWalk`` from scalars or vectors, in ``dtype``."""
    return LatentRandomWalk(
        manifold=prior.astype(dtype), s_global=jnp.asarray(as_scale_vector("s_global", s_global, prior.global_dims), dtype),
        s_latent=jnp.asarray(as_scale_vector("s_latent", s_latent, prior.latent_dim), dtype),
    )


def make_gpapf(likelihood, prior: ManifoldPrior, s_global, s_latent, num_particles: int, num_layers: int = 5, *, s_final=None,
               estimator="data_mean", dtype=jnp.float32, **options) -> APF:
    """GPAPF (001 Alg. 2); ``s_final`` (D,) adds the final full-pose layer (001 Alg. 3).
    Estimators (001 sec. 5.4): "data_mean" (the mean pose projected onto the manifold),
    "latent_mean" (``mu(E[omega])``), "best"."""
    dynamics = latent_random_walk(prior, s_global, s_latent, dtype)
    final = None if s_final is None else make_pose_random_walk(s_final, prior.pose_dim, dtype=dtype)
    return APF(dynamics, as_likelihood(likelihood), num_particles, num_layers, final_layer=final,
               estimator=make_estimator(estimator, dynamics.manifold), **options)


def make_latent_pf(likelihood, prior: ManifoldPrior, s_global, nu, num_particles: int, *, resampler="systematic",
                   estimator="latent_mean", dtype=jnp.float32) -> SIR:
    """LatentPF (003 Alg. 2): Condensation whose particles are (global entries, latent point)
    with random walks ``x_{t+1} = x_t + N(0, nu^2)``, weights from the likelihood of ``mu(x)``,
    estimate ``mu(E[x])``."""
    dynamics = latent_random_walk(prior, s_global, nu, dtype)
    return SIR(dynamics, as_likelihood(likelihood), num_particles, resampler, make_estimator(estimator, dynamics.manifold))

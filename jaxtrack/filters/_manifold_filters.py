"""Trackers guided by a learned manifold: MRPF (000 Alg. 1), GPAPF (001 Alg. 2 and 3) and the
latent-space Condensation of 003 Alg. 2 (LatentPF)."""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._annealing import check_annealing, choose_beta
from ._core import FilterState, StepInfo, check_particles, check_scales, duplicate
from ._manifold_prior import ManifoldPrior
from ._pose_filters import _check_estimator, annealed_layers, diffuse, estimate_pose
from ._resampling import get_resampler
from ._weights import best_particle, effective_sample_size, log_mean_exp, normalise_log_weights, weighted_mean

LATENT_STREAM = 7919  # fold_in tag of the latent noise, so the pose noise matches SIR's
MRPF_PROPOSALS = ("product", "prior")


class MRPF(eqx.Module):
    """Manifold regularised particle filter (000 Alg. 1, eqs. 4-11 and 27-30).

    The dynamics (000 eqs. 27-30): ``z_t ~ N(g(x_{t-1}), diag(s_xz^2))`` (g the back-constraint)
    and ``p(x_t | x_{t-1}, z_t) ∝ N(x_t | x_{t-1}, diag(s_xx^2)) N(x_t^a | mu(z_t), diag(s_zx^2))``
    (eq. 28; ``x^a`` the joint angles the manifold covers, the global entries follow eq. 29 only).
    Per frame, after resampling by the previous weights, ``proposal`` picks how x_t is drawn:

    - ``"product"`` (default): x_t drawn exactly from eq. 28 normalised over x_t, a Gaussian
      with mean ``(s_zx^2 x_{t-1} + s_xx^2 mu(z_t)) / (s_xx^2 + s_zx^2)`` and variance
      ``s_xx^2 s_zx^2 / (s_xx^2 + s_zx^2)``; the weight of eq. 7 is then 1 and eq. 11 leaves
      the image likelihood ``p(I_t | x_t)``. The paper calls this draw intractable in general
      (000 sec. 3); with the Gaussian models of sec. 5.2 it is not.
    - ``"prior"`` (000 Alg. 1 as printed): ``x_t ~ N(x_{t-1}, diag(s_xx^2))`` (eq. 29) and the
      weight ``p(I_t | x_t) N(x_t^a | mu(z_t), diag(s_zx^2))`` (eqs. 11 and 30). Eq. 30 drops
      eq. 28's normaliser ``N(x_{t-1}^a | mu(z_t), diag(s_xx^2 + s_zx^2))``, which depends on the
      particle: it rewards latent draws whose mean stays near the previous pose, a pull towards
      standing still, and with ``s_zx`` below ``s_xx`` the weights collapse onto a few particles.

    The estimate is the weighted mean (or the best particle). With ``s_zx`` very large both
    proposals reduce to SIR with ``s_xx``. ``fit_noise_scales`` fits ``s_zx`` and the angle
    entries of ``s_xx`` (``mrpf_s_xx``) by maximum likelihood of the eq. 27-28 transition.
    """

    likelihood: Callable
    prior: ManifoldPrior
    s_xx: Float[Array, " d"]
    s_xz: Float[Array, " q"]
    s_zx: Float[Array, " a"]
    num_particles: int = eqx.field(static=True)
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: str = eqx.field(static=True, default="mean")
    proposal: str = eqx.field(static=True, default="product")

    def __check_init__(self):
        check_particles(self.num_particles)
        get_resampler(self.resampler)
        _check_estimator(self.estimator)
        if self.proposal not in MRPF_PROPOSALS:
            raise ValueError(f"proposal must be one of {MRPF_PROPOSALS}, got {self.proposal!r}")
        if self.prior.encoder is None:
            raise ValueError("MRPF needs a back-constrained manifold (BC-GPLVM): p(z|x) uses the back-constraint g (000 eq. 27)")

    def init(self, key, initial_pose) -> FilterState:
        del key
        return duplicate(initial_pose.astype(self.s_xx.dtype), self.num_particles)

    def _product(self, previous, manifold_mean):
        """Mean (N, D) and standard deviation (D,) of eq. 28 normalised over x_t."""
        g = self.prior.global_dims
        s_xx = self.s_xx[g:]
        pull = 1.0 / (1.0 + (self.s_zx / s_xx) ** 2)  # s_xx^2 / (s_xx^2 + s_zx^2), finite for any s_zx (inf: 0)
        angles = previous[:, g:] + pull * (manifold_mean - previous[:, g:])
        return jnp.concatenate([previous[:, :g], angles], axis=1), jnp.concatenate([self.s_xx[:g], s_xx * jnp.sqrt(1.0 - pull)])

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        resample_key, move_key = jax.random.split(key)
        ancestors = get_resampler(self.resampler)(jax.random.fold_in(resample_key, 0), state.log_weights)
        previous = state.particles[ancestors]
        g = self.prior.global_dims
        latent = diffuse(jax.random.fold_in(move_key, LATENT_STREAM), self.prior.encode(previous[:, g:]), self.s_xz)
        manifold_mean = self.prior.decode(latent)
        if self.proposal == "prior":
            particles = diffuse(jax.random.fold_in(move_key, 0), previous, self.s_xx)
            log_manifold = -0.5 * jnp.sum(((particles[:, g:] - manifold_mean) / self.s_zx) ** 2, axis=1)
        else:
            particles = diffuse(jax.random.fold_in(move_key, 0), *self._product(previous, manifold_mean))
            log_manifold = 0.0
        log_lik = self.likelihood(particles, observation)
        log_weights, degenerate = normalise_log_weights(log_lik + log_manifold)
        ess = effective_sample_size(log_weights)
        info = StepInfo(
            estimate=estimate_pose(self.estimator, log_weights, particles), ess=ess, log_evidence=log_mean_exp(log_lik), betas=jnp.ones(1, particles.dtype),
            survival=(ess / self.num_particles)[None], degenerate=degenerate,
        )
        return FilterState(particles, log_weights), info


LATENT_ESTIMATORS = ("data_mean", "latent_mean", "best")


class GPAPF(eqx.Module):
    """Annealed particle filter over (global 6 DoF, latent point) (001 Alg. 2 and 3).

    Particles are ``[Lambda, omega]``; the pose is ``[Lambda, mu(omega)]``. Each of the
    ``num_layers`` annealing layers diffuses Lambda and omega (scales ``s_global``, ``s_latent``,
    shrinking as in APF). Estimators (001 sec. 5.4): ``"data_mean"`` averages the poses in data
    space and projects the average back to the manifold, ``"latent_mean"`` is ``mu(E[omega])``
    (003 Alg. 2), ``"best"`` the best particle. With ``final_layer=True`` (the improved variant)
    one more layer diffuses the full pose with ``s_final`` and gives the estimate only.

    With ``num_layers=1`` and ``fixed_betas=(1.0,)`` this is the latent-space Condensation of
    003 Alg. 2 (see ``make_latent_pf``).
    """

    likelihood: Callable
    prior: ManifoldPrior
    s_global: Float[Array, " g"]
    s_latent: Float[Array, " q"]
    s_final: Float[Array, " d"]
    num_particles: int = eqx.field(static=True)
    num_layers: int = eqx.field(static=True, default=5)
    final_layer: bool = eqx.field(static=True, default=False)
    survival_target: float = eqx.field(static=True, default=0.5)
    variance_decay: float = eqx.field(static=True, default=0.5)
    fixed_betas: tuple | None = eqx.field(static=True, default=None)
    resampler: str = eqx.field(static=True, default="systematic")
    estimator: str = eqx.field(static=True, default="data_mean")

    def __check_init__(self):
        check_particles(self.num_particles)
        check_annealing(self.num_layers, self.survival_target, self.fixed_betas)
        if self.estimator not in LATENT_ESTIMATORS:
            raise ValueError(f"estimator must be one of {LATENT_ESTIMATORS}, got {self.estimator!r}")
        get_resampler(self.resampler)

    def _to_pose(self, particles):
        g = self.prior.global_dims
        return self.prior.compose(particles[:, :g], particles[:, g:])

    def init(self, key, initial_pose) -> FilterState:
        del key
        pose = initial_pose.astype(self.s_latent.dtype)
        g = self.prior.global_dims
        state = jnp.concatenate([pose[:g], self.prior.encode(pose[None, g:])[0]])
        return duplicate(state, self.num_particles)

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        anneal_key, final_key = jax.random.split(key)
        dtype = self.s_latent.dtype
        betas = None if self.fixed_betas is None else jnp.asarray(self.fixed_betas, dtype)
        particles, log_weights, betas, survival, degenerate, evidence = annealed_layers(
            anneal_key, state.particles, state.log_weights, observation, likelihood=self.likelihood, to_pose=self._to_pose,
            scales=jnp.concatenate([self.s_global, self.s_latent]), num_layers=self.num_layers,
            variance_decay=self.variance_decay, survival_target=self.survival_target, fixed_betas=betas,
            resampler=self.resampler,
        )
        poses = self._to_pose(particles)
        g = self.prior.global_dims
        if self.final_layer:
            resample_key, move_key = jax.random.split(final_key)
            ancestors = get_resampler(self.resampler)(resample_key, log_weights)
            refined = diffuse(move_key, poses[ancestors], self.s_final)
            log_lik = self.likelihood(refined, observation)
            final_weights, final_degenerate = normalise_log_weights(choose_beta(log_lik, self.survival_target) * log_lik)
            estimate = weighted_mean(final_weights, refined)
            degenerate = jnp.concatenate([degenerate, final_degenerate[None]])
        elif self.estimator == "data_mean":
            average = weighted_mean(log_weights, poses)
            estimate = jnp.concatenate([average[:g], self.prior.decode(self.prior.encode(average[None, g:]))[0]])
        elif self.estimator == "latent_mean":
            average = weighted_mean(log_weights, particles)
            estimate = self._to_pose(average[None])[0]
        else:
            estimate = best_particle(log_weights, poses)
        info = StepInfo(
            estimate=estimate, ess=effective_sample_size(log_weights), log_evidence=evidence, betas=betas,
            survival=survival, degenerate=jnp.any(degenerate),
        )
        return FilterState(particles, log_weights), info


def make_gpapf(likelihood, prior: ManifoldPrior, s_global, s_latent, num_particles: int, num_layers: int = 5, *, s_final=None,
               dtype=jnp.float32, **options) -> GPAPF:
    """A ``GPAPF``; ``s_final`` (D,) enables the final full-pose layer (the improved variant)."""
    g, q = prior.global_dims, prior.latent_dim
    final = s_final is not None
    s_final = check_scales("s_final", s_final if final else 0.0, prior.pose_dim)
    return GPAPF(
        likelihood=likelihood, prior=prior.astype(dtype), s_global=jnp.asarray(check_scales("s_global", s_global, g), dtype),
        s_latent=jnp.asarray(check_scales("s_latent", s_latent, q), dtype), s_final=jnp.asarray(s_final, dtype),
        num_particles=num_particles, num_layers=num_layers, final_layer=final, **options,
    )


def make_latent_pf(likelihood, prior: ManifoldPrior, s_global, nu, num_particles: int, *, dtype=jnp.float32, **options) -> GPAPF:
    """LatentPF (003 Alg. 2): Condensation whose particles are (global 6 DoF, latent point) with
    random walks ``x_{t+1} = x_t + N(0, nu^2)``; weights from the likelihood of ``mu(x)``;
    estimate ``mu(E[x])``."""
    options.setdefault("estimator", "latent_mean")
    return make_gpapf(likelihood, prior, s_global, nu, num_particles, 1, fixed_betas=(1.0,), dtype=dtype, **options)


def make_mrpf(likelihood, prior: ManifoldPrior, s_xx, s_xz, s_zx, num_particles: int, *, dtype=jnp.float32, **options) -> MRPF:
    """An ``MRPF`` with noise scales (000 eqs. 27, 29, 30), usually from ``fit_noise_scales``;
    ``proposal="prior"`` is 000 Alg. 1 as printed, ``"product"`` (default) samples eq. 28 exactly.
    Pass ``scales.mrpf_s_xx`` as ``s_xx`` when the scales come from ``fit_noise_scales``."""
    return MRPF(
        likelihood=likelihood, prior=prior.astype(dtype),
        s_xx=jnp.asarray(check_scales("s_xx", s_xx, prior.pose_dim, dtype), dtype),
        s_xz=jnp.asarray(check_scales("s_xz", s_xz, prior.latent_dim, dtype), dtype),
        s_zx=jnp.asarray(check_scales("s_zx", s_zx, prior.pose_dim - prior.global_dims, dtype), dtype),
        num_particles=num_particles, **options,
    )

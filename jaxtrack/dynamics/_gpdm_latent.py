"""GPDM latent dynamics over (global entries, latent point): the dynamics of GPAPF as 001
specifies it (sec. 4, Alg. 2) and of the latent Condensation when its manifold is a GPDM.

The latent point moves by the GPDM's predictive dynamics (001 eqs. 7-9),
``omega_t ~ N(mu_X(omega_{t-1}), sigma_X^2(omega_{t-1}) I)``, the GP's mean of the next latent
point and its predictive variance (with the dynamics noise); the global entries take a random
walk, ``Lambda_t = Lambda_{t-1} + N(0, s_global^2)``. A periodic motion therefore advances along
its learned cycle every frame instead of diffusing around it. The pose is ``[Lambda, mu(omega)]``.
Optionally (``latent_noise="validation"``) the latent noise is the GPDM's predictive sd times a
scale mixture refitted on validation motion (``_latent_noise``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..manifold import ManifoldPrior
from ._base import AbstractRefinableDynamics, check_scale_vector, gaussian_log_density, motion_sequences, rms_step
from ._latent_noise import JUMP_STREAM, LatentNoiseMixture, check_latent_noise_fit, fit_latent_noise, gpdm_noise
from ._latent_random_walk import fit_latent_random_walk, latent_states


class GPDMLatentDynamics(AbstractRefinableDynamics):
    """GPDM predictive dynamics of the latent point, random walk of the global entries.

    Attributes:
        manifold: a fitted manifold with latent dynamics (``ManifoldPrior.latent_dynamics``,
            a GPDM's).
        s_global: (G,) step standard deviation of the global entries (metres, radians).
        noise: the latent noise relative to the GPDM's predictive sd (``LatentNoiseMixture``;
            default the GPDM's own, ``gpdm_noise()``).
    """

    manifold: ManifoldPrior
    s_global: Float[Array, " g"]
    noise: LatentNoiseMixture = eqx.field(default_factory=gpdm_noise)

    def __check_init__(self):
        if self.manifold.latent_dynamics is None:
            raise ValueError("GPDMLatentDynamics needs a GPDM's prior: this manifold has no latent dynamics")
        check_scale_vector("s_global", self.s_global, self.manifold.global_dims)

    def init(self, key, pose, num_particles):
        del key  # the pose and its latent point are the whole state
        return latent_states(self.manifold, pose.astype(self.s_global.dtype), num_particles)

    def to_pose(self, states):
        g = self.manifold.global_dims
        return self.manifold.compose(states[:, :g], states[:, g:])

    def _predict(self, states):
        """Per particle: the next state's mean (N, S) and the latent standard deviation (N,)."""
        g = self.manifold.global_dims
        mean, variance = self.manifold.predict_latent(states[:, g:])
        return jnp.concatenate([states[:, :g], mean], axis=1), jnp.sqrt(variance)

    def propose(self, key, previous):
        mean, latent_sd = self._predict(previous)
        n, g, q = previous.shape[0], self.s_global.shape[0], self.manifold.latent_dim
        latent_scale = self.noise.factors(jax.random.fold_in(key, JUMP_STREAM), n, previous.dtype) * latent_sd
        scales = jnp.concatenate([jnp.broadcast_to(self.s_global, (n, g)), jnp.broadcast_to(latent_scale[:, None], (n, q))], axis=1)
        moved = mean + scales * jax.random.normal(key, previous.shape, previous.dtype)
        return moved, jnp.zeros(n, previous.dtype)

    def perturb(self, key, states, factor):
        # annealing layers: the common component's scale, no jumps
        _, latent_sd = self._predict(states)
        q = self.manifold.latent_dim
        n, g = latent_sd.shape[0], self.s_global.shape[0]
        core_sd = self.noise.core.astype(states.dtype) * latent_sd
        scales = jnp.concatenate([jnp.broadcast_to(self.s_global, (n, g)), jnp.broadcast_to(core_sd[:, None], (n, q))], axis=1)
        return states + factor * scales * jax.random.normal(key, states.shape, states.dtype)

    def log_transition(self, previous, states):
        mean, latent_sd = self._predict(previous)
        g = self.manifold.global_dims
        latent = self.noise.log_density(states[:, g:] - mean[:, g:], latent_sd)
        return gaussian_log_density(states[:, :g], mean[:, :g], self.s_global) + latent

    def noise_scales(self):
        # One preconditioner for every particle: the RMS latent sd over the training points.
        _, variance = self.manifold.predict_latent(self.manifold.training_latent.astype(self.s_global.dtype))
        latent = self.noise.core.astype(self.s_global.dtype) * jnp.sqrt(jnp.mean(variance))
        return jnp.concatenate([self.s_global, jnp.full((self.manifold.latent_dim,), latent)])


def fit_gpdm_latent_dynamics(manifold: ManifoldPrior, validation, *, floor: float = 1e-3,
                             latent_noise: str = "gpdm") -> GPDMLatentDynamics:
    """The latent dynamics are the GPDM's; fitted on the validation poses (one (T, D) array or a
    list): ``s_global``, the RMS frame-to-frame step of their global entries (floored at
    ``floor``), and with ``latent_noise="validation"`` the latent noise mixture
    (``fit_latent_noise``; default ``"gpdm"``: the GPDM's own predictive noise)."""
    check_latent_noise_fit(latent_noise)
    if manifold.latent_dynamics is None:
        raise ValueError("GPDM latent dynamics need a GPDM: this manifold has no latent dynamics (use --manifold gpdm)")
    sequences = motion_sequences(validation, manifold.pose_dim)
    g = manifold.global_dims
    s_global = rms_step([s[:, :g] for s in sequences], floor)
    noise = fit_latent_noise(manifold, sequences) if latent_noise == "validation" else gpdm_noise()
    return GPDMLatentDynamics(manifold=manifold, s_global=jnp.asarray(s_global, manifold.training_latent.dtype), noise=noise)


def fit_latent_dynamics(manifold: ManifoldPrior, validation, training_starts=None, *, floor: float = 1e-3,
                        latent_noise: str = "gpdm"):
    """The latent dynamics a manifold supports: its GPDM dynamics (``fit_gpdm_latent_dynamics``,
    with ``latent_noise``) when it has them, else the latent random walk
    (``fit_latent_random_walk``)."""
    check_latent_noise_fit(latent_noise)
    if manifold.latent_dynamics is not None:
        return fit_gpdm_latent_dynamics(manifold, validation, floor=floor, latent_noise=latent_noise)
    return fit_latent_random_walk(manifold, validation, training_starts, floor=floor)

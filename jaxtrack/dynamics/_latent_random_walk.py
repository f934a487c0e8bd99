"""Random walk over (global pose entries, latent point): the dynamics of GPAPF (001 Alg. 2-3)
and of the latent-space Condensation of 003 Alg. 2, ``omega_t = omega_{t-1} + N(0, nu^2)``,
``Lambda_t = Lambda_{t-1} + N(0, s_global^2)``; the pose is ``[Lambda, mu(omega)]``."""

from __future__ import annotations

import itertools

import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..manifold import ManifoldPrior
from ._base import (
    AbstractRefinableDynamics,
    check_scale_vector,
    copies,
    gaussian_log_density,
    gaussian_step,
    motion_sequences,
    rms_step,
)


class LatentRandomWalk(AbstractRefinableDynamics):
    """Gaussian random walk of ``[global entries (G), latent point (q)]`` states.

    Attributes:
        manifold: the fitted manifold the latent points live on.
        s_global: (G,) step standard deviation of the global entries (metres, radians).
        s_latent: (q,) step standard deviation in the latent space (003 Alg. 2's ``nu``).
    """

    manifold: ManifoldPrior
    s_global: Float[Array, " g"]
    s_latent: Float[Array, " q"]

    def __check_init__(self):
        check_scale_vector("s_global", self.s_global, self.manifold.global_dims)
        check_scale_vector("s_latent", self.s_latent, self.manifold.latent_dim)

    def init(self, key, pose, num_particles):
        del key  # the pose and its latent point are the whole state
        return latent_states(self.manifold, pose.astype(self.s_latent.dtype), num_particles)

    def to_pose(self, states):
        g = self.manifold.global_dims
        return self.manifold.compose(states[:, :g], states[:, g:])

    def propose(self, key, previous):
        return gaussian_step(key, previous, self.noise_scales()), jnp.zeros(previous.shape[0], previous.dtype)

    def perturb(self, key, states, factor):
        return gaussian_step(key, states, self.noise_scales() * factor)

    def velocity_states(self, poses):
        # The global entries and the latent point: a walk round the manifold's loop of a
        # periodic motion is a nearly constant latent velocity.
        g = self.manifold.global_dims
        return jnp.concatenate([poses[:, :g], self.manifold.encode(poses[:, g:])], axis=1)

    def log_transition(self, previous, states):
        return gaussian_log_density(states, previous, self.noise_scales())

    def noise_scales(self):
        return jnp.concatenate([self.s_global, self.s_latent])


def latent_states(manifold: ManifoldPrior, pose: Float[Array, " d"], num_particles: int) -> Float[Array, "n s"]:
    """N copies of a pose's (global entries, latent point) state."""
    g = manifold.global_dims
    return copies(jnp.concatenate([pose[:g], manifold.encode(pose[None, g:])[0]]), num_particles)


def fit_latent_random_walk(
    manifold: ManifoldPrior, validation, training_starts=None, *, floor: float = 1e-3
) -> LatentRandomWalk:
    """Fit the walk's scales.

    Args:
        manifold: the manifold prior (fitted on the training sequences).
        validation: one (T, D) pose array or a list of them; ``s_global`` is the RMS
            frame-to-frame step of their global entries.
        training_starts: first frame of each training sequence in the manifold's training
            data, ending with N (default: one sequence); ``s_latent`` (003's ``nu``) is the
            RMS step of the training latent trajectory within each sequence.
        floor: smallest scale, so that no entry is deterministic.
    """
    sequences = motion_sequences(validation, manifold.pose_dim)
    g = manifold.global_dims
    s_global = rms_step([s[:, :g] for s in sequences], floor)
    train = np.asarray(manifold.training_latent, np.float64)
    starts = list(training_starts) if training_starts is not None else [0, len(train)]
    pieces = [train[a:b] for a, b in itertools.pairwise(starts) if b - a >= 2]
    if not pieces:
        raise ValueError(f"training_starts {starts} leave no training sequence of two or more frames")
    dtype = manifold.training_latent.dtype
    return LatentRandomWalk(manifold=manifold, s_global=jnp.asarray(s_global, dtype), s_latent=jnp.asarray(rms_step(pieces, floor), dtype))

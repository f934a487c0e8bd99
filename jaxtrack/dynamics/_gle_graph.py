"""GLE-GbPF's propagation (002 Alg. 1 steps 1d-1l and 2): the graph walk over a fitted GLE.

Given a particle's latent point z (after the filter's own resampling by weight, Alg. 1 1a-1c):

1. attach it to training frame j with probability proportional to
   ``exp(-||z - z_j||^2 / (2 h^2))`` (002 eq. 11, h the model's bandwidth);
2. step to j's next temporal neighbour ``k = next(j)``;
3. move to one of k's stylistic neighbours (one per other repetition) with weight ``alpha``
   each, or stay at k with weight 1;
4. add Gaussian noise whose covariance is 002 eq. 10's at the chosen point, times
   ``noise_scale^2``.

The global entries (root position and orientation) take a Gaussian random walk beside it, as
002 tracks them outside the manifold. The pose is ``[global, decode(z)]``. The move is the
transition itself, so its importance correction is zero.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..body import GLOBAL_DOFS as GLOBAL_DIMS
from ..manifold import SpectralEmbedding
from ._base import AbstractDynamics, check_scale_vector, copies, gaussian_step


class GLEGraphWalk(AbstractDynamics):
    """The graph-based propagation of GLE-GbPF over ``[global entries (6), latent point (n)]``.

    Attributes:
        model: the fitted embedding (GLE; LE or temporal LE walk their temporal graph only).
        s_global: (6,) step standard deviation of the global entries (metres, radians).
        noise_threshold: Mahalanobis radius of 002 eq. 10's Gaussian subset.
        noise_scale: multiplies eq. 10's standard deviations. A mixture component spans many
            frames of the cycle, so eq. 10 as it stands diffuses a particle by about twice a
            frame's latent step; 0.3 (the default) tracked best of 0.15-1 on the demo's scenes.
    """

    model: SpectralEmbedding
    s_global: Float[Array, " g"]
    noise_threshold: float = 2.0
    noise_scale: float = 0.3

    def __check_init__(self):
        check_scale_vector("s_global", self.s_global, GLOBAL_DIMS)

    def init(self, key, pose, num_particles):
        """Every particle at the initial pose's global entries and at the latent point of the
        training frame nearest to its joint angles (radians, not standardised: an angle that
        barely moves in the training set would dominate a standardised distance). Not the
        inverse network: on a subject outside the training set it extrapolates, and its
        encode -> decode lands 110-240 mm from the pose where the nearest training frame is
        60-100 mm away (``benchmarks/gle_cross_subject.py --floors``)."""
        del key
        pose = pose.astype(self.s_global.dtype)
        nearest = jnp.argmin(jnp.sum((self.model.training_poses() - pose[GLOBAL_DIMS:]) ** 2, axis=1))
        return copies(jnp.concatenate([pose[:GLOBAL_DIMS], self.model.latent[nearest]]), num_particles)

    def to_pose(self, states):
        return jnp.concatenate([states[:, :GLOBAL_DIMS], self.model.decode(states[:, GLOBAL_DIMS:])[0]], axis=1)

    def graph_step(self, key, latent: Float[Array, "n q"]):
        """Steps 1-3: the training frame each particle moves to, (N,) indices."""
        attach_key, style_key = jax.random.split(key)
        model = self.model
        gaps = jnp.sum((latent[:, None, :] - model.latent[None]) ** 2, axis=-1)
        attached = jax.random.categorical(attach_key, -0.5 * gaps / model.bandwidth**2, axis=1)
        temporal = model.next_frame[attached]
        candidates = jnp.concatenate([temporal[:, None], model.style[temporal]], axis=1)  # (N, 1 + R)
        weights = jnp.concatenate([jnp.ones((latent.shape[0], 1)), jnp.where(model.style[temporal] >= 0, model.alpha, 0.0)], axis=1)
        choice = jax.random.categorical(style_key, jnp.log(weights), axis=1)
        return jnp.take_along_axis(candidates, choice[:, None], axis=1)[:, 0]

    def propose(self, key, previous):
        graph_key, noise_key, global_key = jax.random.split(key, 3)
        frame = self.graph_step(graph_key, previous[:, GLOBAL_DIMS:])
        centre = self.model.latent[frame]
        covariance = self.model.forward.noise_covariance(centre, self.noise_threshold)
        factor = self.noise_scale * jnp.linalg.cholesky(covariance + 1e-9 * jnp.eye(centre.shape[1], dtype=centre.dtype))
        latent = centre + jnp.einsum("nij,nj->ni", factor, jax.random.normal(noise_key, centre.shape, centre.dtype))
        global_entries = gaussian_step(global_key, previous[:, :GLOBAL_DIMS], self.s_global)
        return jnp.concatenate([global_entries, latent], axis=1), jnp.zeros(previous.shape[0], previous.dtype)

    def perturb(self, key, states, factor):
        noise_key, global_key = jax.random.split(key)
        latent = states[:, GLOBAL_DIMS:]
        covariance = self.model.forward.noise_covariance(latent, self.noise_threshold)
        root = self.noise_scale * jnp.linalg.cholesky(covariance + 1e-9 * jnp.eye(latent.shape[1], dtype=latent.dtype))
        moved = latent + factor * jnp.einsum("nij,nj->ni", root, jax.random.normal(noise_key, latent.shape, latent.dtype))
        return jnp.concatenate([gaussian_step(global_key, states[:, :GLOBAL_DIMS], self.s_global * factor), moved], axis=1)


def fit_gle_graph_walk(model: SpectralEmbedding, validation, *, floor: float = 1e-3) -> GLEGraphWalk:
    """The graph walk on ``model`` with the global entries' step scales fitted as the RMS
    frame-to-frame steps of the validation poses (a list of (T, D) arrays)."""
    import numpy as np

    from ._base import motion_sequences, rms_step

    sequences = motion_sequences(list(validation), np.shape(validation[0])[-1])
    scales = rms_step(sequences, floor)[:GLOBAL_DIMS]
    return GLEGraphWalk(model=model, s_global=jnp.asarray(scales, model.latent.dtype))

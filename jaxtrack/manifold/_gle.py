"""A fitted Generalised Laplacian Eigenmap (002 sec. 2): the training frames' latent points, the
temporal and stylistic graphs the graph-based particle filter walks on, and the RBF networks
that map latent points to poses (and back). Built in closed form by ``fit_gle`` (no objective to
optimise), so it is not an ``AbstractManifold`` (whose interface is the GP family's: objective,
GP predictor); the graph walk of ``jaxtrack.dynamics.GLEGraphWalk`` reads it directly.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, Int
from ..errors import ConfigurationError
from ._eigenmaps import gait_cycles, laplacian_embedding, stylistic_graph, stylistic_neighbours, temporal_graph
from ._rbf import RBFNetwork, fit_rbf_network


class GLEModel(eqx.Module):
    """Attributes:
        latent: (M, n) the training frames' latent points.
        next_frame: (M,) each training frame's next temporal neighbour (itself at a
            sequence's last frame).
        style: (M, R) each frame's stylistic neighbours, one per other repetition (-1: none).
        forward: RBF network latent -> standardised joint angles (002 eq. 8).
        inverse: RBF network standardised joint angles -> latent.
        mean, scale: (D,) joint angles = mean + scale * standardised.
        bandwidth: latent distance scale of the attachment probabilities (002 eq. 11).
        alpha: the stylistic graph's weight (002 eq. 6), also the weight of a stylistic move
            against staying (weight 1) in the third resampling.
    """

    latent: Float[Array, "m n"]
    next_frame: Int[Array, " m"]
    style: Int[Array, "m r"]
    forward: RBFNetwork
    inverse: RBFNetwork
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    bandwidth: Float[Array, ""]
    alpha: Float[Array, ""]

    def decode(self, latent: Float[Array, "k n"]) -> Float[Array, "k d"]:
        """Latent points -> joint angles (the forward RBF network)."""
        return self.mean + self.scale * self.forward(latent)

    def encode(self, angles: Float[Array, "k d"]) -> Float[Array, "k n"]:
        """Joint angles -> latent points (the inverse RBF network)."""
        return self.inverse((angles - self.mean) / self.scale)


def fit_gle(sequences, *, latent_dim: int = 3, t: int = 2, alpha: float = 0.2, components: int = 30, min_period: int = 8,
            dtype=jnp.float64) -> GLEModel:
    """Fit GLE (002 sec. 2.1) on training joint-angle sequences (a list of (T_i, D) arrays, e.g.
    several subjects' walks): each sequence is split into gait cycles (``gait_cycles``), the
    repetitions among which stylistic neighbours are found by sliding DTW; the embedding is the
    generalised eigenproblem of ``W_T + alpha W_S``; then the forward and inverse RBF networks
    with ``components`` Gaussians each.

    The defaults (3 latent dimensions, ``alpha`` 0.2) tracked best on the demo's scenes among
    ``alpha`` 0.05-1 and 2-3 dimensions: with ``alpha`` 1 in 2-D, walks and jogs of two
    subjects fold onto each other (a frame's nearest latent neighbour is a pose 0.19 rad rms
    away, against 0.016 in pose space).
    """
    arrays = [np.asarray(s, np.float64) for s in sequences]
    if not arrays or any(a.ndim != 2 for a in arrays) or len({a.shape[1] for a in arrays}) != 1:
        raise ConfigurationError("fit_gle needs one or more (frames, joint angles) sequences of the same width")
    lengths = []
    for a in arrays:
        try:
            cycles = gait_cycles(a, min_period=min_period)
        except ConfigurationError:  # no clear period (e.g. under two cycles): one repetition
            cycles = [a.shape[0]]
        lengths.extend(cycles)
    Y = np.concatenate(arrays)
    mean, scale = Y.mean(axis=0), Y.std(axis=0)
    scale = np.where(scale > 1e-8, scale, 1.0)
    Yn = (Y - mean) / scale
    neighbours = stylistic_neighbours(Yn, lengths, t)
    W = temporal_graph(lengths, t) + alpha * stylistic_graph(neighbours)
    Z, _ = laplacian_embedding(W, latent_dim)
    Z = Z / Z.std(axis=0)  # unit spread: the networks' and the walk's scales do not depend on M
    # The next temporal neighbour continues across the cycles of one sequence, and stops at its end.
    ends = np.cumsum([a.shape[0] for a in arrays]) - 1
    next_frame = np.minimum(np.arange(Y.shape[0]) + 1, Y.shape[0] - 1)
    next_frame[ends] = ends
    gaps = np.sqrt(np.sum((Z[:, None] - Z[None]) ** 2, axis=-1))
    np.fill_diagonal(gaps, np.inf)
    bandwidth = float(np.median(gaps.min(axis=1)))
    components = min(components, Y.shape[0] // 4)
    return GLEModel(
        latent=jnp.asarray(Z, dtype), next_frame=jnp.asarray(next_frame, jnp.int32), style=jnp.asarray(neighbours, jnp.int32),
        forward=fit_rbf_network(Z, Yn, components, dtype=dtype), inverse=fit_rbf_network(Yn, Z, components, dtype=dtype),
        mean=jnp.asarray(mean, dtype), scale=jnp.asarray(scale, dtype), bandwidth=jnp.asarray(bandwidth, dtype),
        alpha=jnp.asarray(alpha, dtype),
    )


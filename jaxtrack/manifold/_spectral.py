"""The Laplacian Eigenmaps family as a pose manifold (002 sec. 2.1; docs/papers.md): plain LE (k
nearest neighbours in pose space), temporal LE (the t previous and next frames) and GLE
(temporal plus ``alpha`` times stylistic neighbours found by sliding DTW across repetitions),
each with the RBF networks that map latent points to poses and back (002 eqs. 8-9).

An embedding is fitted in closed form (a generalised eigenproblem, ``fit_spectral``), not by
optimising an objective, so ``fit`` returns the model unchanged; ``objective`` is still the
quantity the eigenvectors optimise, minus the sum of the embedding's generalised Rayleigh
quotients ``z_k^T L z_k / z_k^T D z_k`` (002 eq. 1 under eq. 7's constraint; at the fit it is
minus the sum of the n smallest non-zero eigenvalues). The model keeps its graph (as an edge
list), the training frames' next temporal neighbours and stylistic neighbours, which is what
GLE-GbPF's graph walk (``jaxtrack.dynamics.GLEGraphWalk``) moves on.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, Int
from ..errors import ConfigurationError
from ._eigenmaps import gait_cycles, knn_graph, laplacian_embedding, stylistic_graph, stylistic_neighbours, temporal_graph
from ._rbf import RBFNetwork, RBFPredictor, fit_rbf_network
from ._serialise import AbstractSaveableManifold, register_manifold

SPECTRAL_GRAPHS = ("le", "tle", "gle")  # plain LE, temporal LE, generalised LE (002)


@register_manifold
class SpectralEmbedding(AbstractSaveableManifold):
    """A fitted LE / temporal LE / GLE embedding with its RBF networks.

    Attributes:
        data: (M, D) standardised training joint angles; ``mean``, ``scale``: (D,).
        latent: (M, n) the training frames' latent points (unit spread per dimension).
        next_frame: (M,) each frame's next temporal neighbour (itself at a sequence's end).
        style: (M, R) each frame's stylistic neighbour in each repetition (-1: its own
            repetition, or none); R = 0 for LE and temporal LE.
        edges: (E, 2) the graph's edges i < j; ``edge_weights``: (E,) their ``W_ij``.
        forward: RBF network latent -> standardised joint angles (002 eq. 8).
        inverse: RBF network standardised joint angles -> latent (the back-constraint).
        residual: the forward network's mean squared training residual (standardised units):
            the predictive variance on the data.
        bandwidth: latent distance scale of GLE-GbPF's attachment probabilities (002 eq. 11):
            the median distance from a training point to its nearest neighbour.
        alpha: the stylistic graph's weight (002 eq. 6; 0 for LE and temporal LE).
        graph: "le", "tle" or "gle".
        repetitions: frames of each repetition (gait cycle or sequence) in order, for plots
            by phase.
    """

    data: Float[Array, "m d"]
    mean: Float[Array, " d"]
    scale: Float[Array, " d"]
    latent: Float[Array, "m n"]
    next_frame: Int[Array, " m"]
    style: Int[Array, "m r"]
    edges: Int[Array, "e 2"]
    edge_weights: Float[Array, " e"]
    forward: RBFNetwork
    inverse: RBFNetwork
    residual: Float[Array, ""]
    bandwidth: Float[Array, ""]
    alpha: Float[Array, ""]
    graph: str = eqx.field(static=True, default="gle")
    repetitions: tuple[int, ...] = eqx.field(static=True, default=())

    def training_latent(self):
        return self.latent

    def objective(self):
        i, j = self.edges[:, 0], self.edges[:, 1]
        degree = jnp.zeros(self.latent.shape[0], self.latent.dtype).at[i].add(self.edge_weights).at[j].add(self.edge_weights)
        spread = jnp.sum(self.edge_weights[:, None] * (self.latent[i] - self.latent[j]) ** 2, axis=0)  # z^T L z per dimension
        return -jnp.sum(spread / jnp.sum(degree[:, None] * self.latent**2, axis=0))

    def trainable(self):
        return jax.tree.map(lambda _: False, self)

    def fit(self, **options):
        """The embedding is fitted in closed form by ``fit_spectral``: returns ``(self, FitInfo)``
        with no steps (``options`` are accepted for the interface and ignored)."""
        from ._fit import FitInfo

        del options
        return self, FitInfo(objective=float(self.objective()), steps=0, trace=np.zeros(0))

    def predictor(self):
        return RBFPredictor(network=self.forward, mean=self.mean, scale=self.scale, residual=self.residual)

    def back_constraint(self):
        return self.inverse

    def header(self):
        return {"graph": self.graph, "edges": int(self.edges.shape[0]), "style_width": int(self.style.shape[1]),
                "forward_components": int(self.forward.mixing.shape[0]), "inverse_components": int(self.inverse.mixing.shape[0]),
                "repetitions": [int(n) for n in self.repetitions]}

    @classmethod
    def template(cls, header, dtype):
        m, d, n = header["frames"], header["dims"], header["latent_dim"]
        if header.get("graph") not in SPECTRAL_GRAPHS:
            raise ValueError(f"unknown graph {header.get('graph')!r}")
        zeros = lambda *shape: jnp.zeros(shape, dtype)  # noqa: E731
        ints = lambda *shape: jnp.zeros(shape, jnp.int32)  # noqa: E731

        def network(g, d_in, d_out):
            return RBFNetwork(centres=zeros(g, d_in), covariances=zeros(g, d_in, d_in), precisions=zeros(g, d_in, d_in),
                              mixing=zeros(g), weights=zeros(g, d_out), bias=zeros(d_out))

        return cls(data=zeros(m, d), mean=zeros(d), scale=zeros(d), latent=zeros(m, n), next_frame=ints(m),
                   style=ints(m, header["style_width"]), edges=ints(header["edges"], 2), edge_weights=zeros(header["edges"]),
                   forward=network(header["forward_components"], n, d), inverse=network(header["inverse_components"], d, n),
                   residual=zeros(), bandwidth=zeros(), alpha=zeros(), graph=header["graph"],
                   repetitions=tuple(int(r) for r in header["repetitions"]))


def _cycles(poses, min_period: int) -> list[int]:
    """One sequence split into gait cycles; a sequence without a clear period (e.g. under two
    cycles) is one repetition."""
    try:
        return gait_cycles(poses, min_period=min_period)
    except ConfigurationError:
        return [poses.shape[0]]


def fit_spectral(sequences, graph: str = "gle", *, latent_dim: int = 3, t: int = 2, k: int = 10, alpha: float = 0.2,
                 components: int = 30, min_period: int = 8, dtype=jnp.float64) -> SpectralEmbedding:
    """Fit an LE-family embedding on training joint-angle sequences (a list of (T_i, D) arrays,
    e.g. several subjects' walks) and its forward and inverse RBF networks (``components``
    Gaussians each).

    Args:
        graph: "le" (k nearest neighbours in standardised pose space), "tle" (the ``t``
            previous and next frames of each sequence) or "gle" (each sequence split into gait
            cycles, ``gait_cycles``; temporal neighbours within a cycle plus ``alpha`` times the
            stylistic neighbours found by sliding DTW of each frame's window of 2t + 1 frames
            over every other cycle, 002 eqs. 2-6).

    The GLE defaults (3 latent dimensions, ``alpha`` 0.2) tracked best on the demo's scenes
    among ``alpha`` 0.05-1 and 2-3 dimensions: with ``alpha`` 1 in 2-D, walks and jogs of two
    subjects fold onto each other (a frame's nearest latent neighbour is a pose 0.19 rad rms
    away, against 0.016 in pose space).

    Raises:
        ConfigurationError: for an unknown graph, sequences of different widths, too few frames
            for the neighbourhood (k + 1 for LE, t + 1 per sequence, a DTW window of 2t + 1 per
            repetition), or a graph in several pieces (the components are named).
    """
    if graph not in SPECTRAL_GRAPHS:
        raise ConfigurationError(f"graph must be one of {SPECTRAL_GRAPHS}, got {graph!r}")
    arrays = [np.asarray(s, np.float64) for s in sequences]
    if not arrays or any(a.ndim != 2 for a in arrays) or len({a.shape[1] for a in arrays}) != 1:
        raise ConfigurationError("fit_spectral needs one or more (frames, joint angles) sequences of the same width")
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise ConfigurationError("the training joint angles must be finite")
    if not (np.isfinite(alpha) and alpha >= 0):
        raise ConfigurationError(f"alpha must be a finite number >= 0, got {alpha!r}")
    Y = np.concatenate(arrays)
    mean, scale = Y.mean(axis=0), Y.std(axis=0)
    scale = np.where(scale > 1e-8, scale, 1.0)
    Yn = (Y - mean) / scale
    sequence_lengths = [a.shape[0] for a in arrays]
    if graph == "le":
        repetitions, neighbours = sequence_lengths, np.zeros((Y.shape[0], 0), np.int64)
        W = knn_graph(Yn, k)
    elif graph == "tle":
        repetitions, neighbours = sequence_lengths, np.zeros((Y.shape[0], 0), np.int64)
        W = temporal_graph(sequence_lengths, t)
    else:
        repetitions = [n for a in arrays for n in _cycles(a, min_period)]
        if len(repetitions) < 2:
            # 002's stylistic neighbours align repetitions with each other; with one there is
            # nothing to align, and the GLE is its temporal graph (the TLE of that one sequence).
            warnings.warn(f"GLE: the training motion is one repetition ({repetitions[0]} frames, under two gait cycles): no "
                          "stylistic neighbours to align, so the graph is the temporal one alone", stacklevel=2)
            neighbours = np.zeros((Y.shape[0], 0), np.int64)
            W = temporal_graph(repetitions, t)
        else:
            neighbours = stylistic_neighbours(Yn, repetitions, t)
            W = temporal_graph(repetitions, t) + alpha * stylistic_graph(neighbours)
    Z, _ = laplacian_embedding(W, latent_dim)
    Z = Z / Z.std(axis=0)  # unit spread: the networks' and the walk's scales do not depend on M
    # The next temporal neighbour continues across the cycles of one sequence, and stops at its end.
    ends = np.cumsum(sequence_lengths) - 1
    next_frame = np.minimum(np.arange(Y.shape[0]) + 1, Y.shape[0] - 1)
    next_frame[ends] = ends
    gaps = np.sqrt(np.sum((Z[:, None] - Z[None]) ** 2, axis=-1))
    np.fill_diagonal(gaps, np.inf)
    bandwidth = float(np.median(gaps.min(axis=1)))
    components = min(components, Y.shape[0] // 4)
    forward = fit_rbf_network(Z, Yn, components, dtype=dtype)
    residual = float(np.mean((np.asarray(forward(jnp.asarray(Z, dtype))) - Yn) ** 2))
    rows, cols = np.nonzero(np.triu(W, 1))
    cast = lambda a: jnp.asarray(a, dtype)  # noqa: E731
    return SpectralEmbedding(
        data=cast(Yn), mean=cast(mean), scale=cast(scale), latent=cast(Z), next_frame=jnp.asarray(next_frame, jnp.int32),
        style=jnp.asarray(neighbours, jnp.int32), edges=jnp.asarray(np.stack([rows, cols], 1), jnp.int32),
        edge_weights=cast(W[rows, cols]), forward=forward, inverse=fit_rbf_network(Yn, Z, components, dtype=dtype),
        residual=cast(residual), bandwidth=cast(bandwidth), alpha=cast(alpha if graph == "gle" else 0.0), graph=graph,
        repetitions=tuple(int(n) for n in repetitions),
    )


def fit_gle(sequences, **options) -> SpectralEmbedding:
    """``fit_spectral(sequences, "gle", **options)``: the Generalised Laplacian Eigenmap of 002."""
    return fit_spectral(sequences, "gle", **options)

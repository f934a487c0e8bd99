"""The VLMM-PF's dynamics (004 secs. 5.1-5.4): particles in the augmented latent space
``(x, x_dot)`` of a back-constrained manifold, moved by motion prototypes (a Gaussian mixture,
``fit_uncertain_mixture``) whose order a variable-length Markov model (``VLMM``) predicts.

State of a particle: ``[global entries (G), x (q), x_dot (q), VLMM state, prototype]``; the last
two are small integers held as floats (exact in float32), so that every dynamics' state stays
one float array. Each frame (004 secs. 5.3-5.4):

1. the next prototype ``k_t ~ gamma(q_{t-1}, .)``, and ``q_t = tau(q_{t-1}, k_t)``;
2. if ``k_t != k_{t-1}``: ``(x_t, x_dot_t) ~ N(mu_k, Sigma_k)`` (a new draw from the new
   prototype); else the local second-order step ``x_dot_t = x_dot_{t-1} + lambda d_xdot``,
   ``x_t = x_{t-1} + x_dot_t + lambda d_x``, ``[d_x, d_xdot] ~ N(0, Sigma_k)``;
3. the global entries by a Gaussian random walk (004: "propagated with Gaussian noise").

The pose is ``[global, mu(x_t)]``, the manifold's predictive mean (004 uses the mean "for
efficiency reasons" too).
"""

from __future__ import annotations

import dataclasses
import itertools

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, PRNGKeyArray
from ..manifold import ManifoldPrior
from ._base import AbstractRestartableDynamics, check_scale_vector, copies, motion_sequences, rms_step
from ._prototypes import GaussianMixture, MixtureFit, fit_uncertain_mixture
from ._vlmm import VLMM, SuffixTree, fit_vlmm


class VLMMDynamics(AbstractRestartableDynamics):
    """Attributes:
        manifold: the back-constrained manifold the latent points live on.
        prototypes: the motion prototypes, a mixture over ``(x, x_dot)`` (2q dimensions).
        vlmm: the automaton over the prototypes' labels.
        s_global: (G,) step standard deviation of the global entries (metres, radians).
        step_scale: lambda, the local dynamics' noise scale (004 sec. 5.4).
    """

    manifold: ManifoldPrior
    prototypes: GaussianMixture
    vlmm: VLMM
    s_global: Float[Array, " g"]
    step_scale: Float[Array, ""]

    def __check_init__(self):
        check_scale_vector("s_global", self.s_global, self.manifold.global_dims)
        q = self.manifold.latent_dim
        if self.prototypes.dim != 2 * q:
            raise ValueError(f"the prototypes live in {self.prototypes.dim} dimensions, not the augmented latent space's {2 * q}")
        if self.vlmm.num_symbols != self.prototypes.num_components:
            raise ValueError(f"the VLMM has {self.vlmm.num_symbols} symbols for {self.prototypes.num_components} prototypes")

    @property
    def _split(self):
        g, q = self.manifold.global_dims, self.manifold.latent_dim
        return g, q

    def _factors(self):
        return jnp.linalg.cholesky(self.prototypes.covariances)

    def nearest_prototype(self, latent: Float[Array, "n q"]) -> Array:
        """The most probable prototype of latent points by the mixture's marginal over ``x``."""
        q = self.manifold.latent_dim
        marginal = GaussianMixture(self.prototypes.weights, self.prototypes.means[:, :q], self.prototypes.covariances[:, :q, :q])
        return marginal.labels(latent)

    def init(self, key, pose, num_particles):
        del key  # N copies of the pose's state (000 Alg. 1 line 1)
        g, q = self._split
        dtype = self.s_global.dtype
        pose = pose.astype(dtype)
        x = self.manifold.encode(pose[None, g:])[0]
        k = self.nearest_prototype(x[None])[0]
        mean, cov = self.prototypes.means[k], self.prototypes.covariances[k]
        # The velocity's conditional mean under the prototype, given x.
        x_dot = mean[q:] + cov[q:, :q] @ jnp.linalg.solve(cov[:q, :q], x - mean[:q])
        state = self.vlmm.step(jnp.zeros((), self.vlmm.transition.dtype), k)
        row = jnp.concatenate([pose[:g], x, x_dot, jnp.stack([state, k]).astype(dtype)])
        return copies(row, num_particles)

    def to_pose(self, states):
        g, q = self._split
        return self.manifold.compose(states[:, :g], states[:, g:g + q])

    def split_states(self, states):
        """``(global, x, x_dot, VLMM state, prototype)`` of (N, S) states."""
        g, q = self._split
        discrete = jnp.round(states[:, g + 2 * q:]).astype(jnp.int32)
        return states[:, :g], states[:, g:g + q], states[:, g + q:g + 2 * q], discrete[:, 0], discrete[:, 1]

    def propose(self, key, previous):
        q = self.manifold.latent_dim
        glob, x, x_dot, state, label = self.split_states(previous)
        k_label, k_switch, k_local, k_global = jax.random.split(key, 4)
        n = previous.shape[0]
        new_label = self.vlmm.sample(k_label, state)
        new_state = self.vlmm.step(state, new_label)
        factors = self._factors()[new_label]  # (N, 2q, 2q)
        noise = jnp.einsum("nij,nj->ni", factors, jax.random.normal(k_local, (n, 2 * q), previous.dtype))
        x_dot_local = x_dot + self.step_scale * noise[:, q:]
        x_local = x + x_dot_local + self.step_scale * noise[:, :q]
        fresh = self.prototypes.means[new_label] + jnp.einsum(
            "nij,nj->ni", factors, jax.random.normal(k_switch, (n, 2 * q), previous.dtype))
        switched = (new_label != label)[:, None]
        augmented = jnp.where(switched, fresh, jnp.concatenate([x_local, x_dot_local], axis=1))
        glob = glob + self.s_global * jax.random.normal(k_global, glob.shape, previous.dtype)
        discrete = jnp.stack([new_state, new_label], axis=1).astype(previous.dtype)
        return jnp.concatenate([glob, augmented, discrete], axis=1), jnp.zeros(n, previous.dtype)

    def restart(self, key, states):
        """004 sec. 6.1: each particle's automaton state drawn from ``s`` (``vlmm.initial``), its
        prototype from ``gamma`` of that state, ``(x, x_dot)`` from the prototype; the global
        entries kept."""
        g, q = self._split
        n = states.shape[0]
        k_state, k_label, k_point = jax.random.split(key, 3)
        start = jax.random.categorical(k_state, jnp.log(jnp.maximum(self.vlmm.initial, 1e-30)), shape=(n,))
        label = self.vlmm.sample(k_label, start)
        state = self.vlmm.step(start, label)
        augmented = self.prototypes.means[label] + jnp.einsum(
            "nij,nj->ni", self._factors()[label], jax.random.normal(k_point, (n, 2 * q), states.dtype))
        discrete = jnp.stack([state, label], axis=1).astype(states.dtype)
        return jnp.concatenate([states[:, :g], augmented, discrete], axis=1)

    def perturb(self, key, states, factor):
        g, q = self._split
        glob, x, x_dot, _, label = self.split_states(states)
        k_global, k_latent = jax.random.split(key)
        noise = jnp.einsum("nij,nj->ni", self._factors()[label], jax.random.normal(k_latent, (states.shape[0], 2 * q), states.dtype))
        glob = glob + factor * self.s_global * jax.random.normal(k_global, glob.shape, states.dtype)
        x = x + factor * self.step_scale * noise[:, :q]
        x_dot = x_dot + factor * self.step_scale * noise[:, q:]
        return jnp.concatenate([glob, x, x_dot, states[:, g + 2 * q:]], axis=1)


@dataclasses.dataclass(frozen=True)
class VLMMFit:
    """What ``fit_vlmm_dynamics`` learnt, besides the dynamics.

    Attributes:
        augmented: (N, 2q) the training points ``[x, x_dot]``.
        uncertainties: (N, 2q, 2q) their covariances ``C_n``.
        labels: the prototype of each training frame, one array per training sequence.
        mixture_fit: the ``MixtureFit`` (message length per component count).
        tree: the pruned ``SuffixTree``.
    """

    augmented: np.ndarray
    uncertainties: np.ndarray
    labels: tuple
    mixture_fit: MixtureFit
    tree: SuffixTree


def _pieces(n: int, training_starts) -> list[tuple[int, int]]:
    starts = list(training_starts) if training_starts is not None else [0, n]
    if starts[0] != 0 or starts[-1] != n or any(b <= a for a, b in itertools.pairwise(starts)):
        raise ValueError(f"training_starts must rise from 0 to the {n} training points, got {starts}")
    return list(itertools.pairwise(starts))


def augmented_latent(latent: np.ndarray, training_starts=None) -> np.ndarray:
    """``[x_n, x_dot_n]`` with ``x_dot_n = x_n - x_{n-1}`` within each sequence (004 sec. 5.4's
    ``x_t = x_{t-1} + x_dot_t``), the first frame of a sequence taking its successor's step."""
    latent = np.asarray(latent, np.float64)
    velocity = np.zeros_like(latent)
    for a, b in _pieces(len(latent), training_starts):
        if b - a < 2:
            raise ValueError("every training sequence needs two or more frames for a latent velocity")
        velocity[a + 1:b] = np.diff(latent[a:b], axis=0)
        velocity[a] = velocity[a + 1]
    return np.concatenate([latent, velocity], axis=1)


def latent_uncertainties(manifold: ManifoldPrior, key: PRNGKeyArray, training_starts=None, *, samples: int = 100) -> np.ndarray:
    """Each training point's covariance ``C_n`` in the augmented space (004 sec. 5.1): ``samples``
    poses drawn from the manifold's prediction at ``x_n`` (mean and variance, noise included),
    mapped back through the back-constraint; ``C_n`` is their covariance, and ``x_dot``'s
    follows from the difference of independent draws at ``n`` and ``n - 1``."""
    if not manifold.has_back_constraint:
        raise ValueError("the prototypes' uncertainties map samples back through a back-constraint: fit a bc-gplvm")
    latent = manifold.training_latent
    n, q = latent.shape
    mean, variance = manifold.decode(latent)
    sd = jnp.sqrt(variance + manifold.predictor.noise)[:, None, None] * manifold.predictor.scale
    draws = mean[:, None, :] + sd * jax.random.normal(key, (n, samples, mean.shape[1]), mean.dtype)
    mapped = manifold.encode(draws.reshape(n * samples, -1)).reshape(n, samples, q)
    centred = mapped - jnp.mean(mapped, axis=1, keepdims=True)
    position = np.asarray(jnp.einsum("nsi,nsj->nij", centred, centred) / (samples - 1), np.float64)
    out = np.zeros((n, 2 * q, 2 * q))
    for a, b in _pieces(n, training_starts):
        for i in range(a, b):
            j = i - 1 if i > a else i + 1  # the neighbour the velocity differences with
            sign = 1.0 if i > a else -1.0
            out[i, :q, :q] = position[i]
            out[i, :q, q:] = out[i, q:, :q] = sign * position[i]
            out[i, q:, q:] = position[i] + position[j]
    return out


def fit_step_scale(prototypes: GaussianMixture, augmented: np.ndarray, labels: np.ndarray, training_starts=None,
                   floor: float = 1e-3) -> float:
    """lambda by maximum likelihood on the training frames that stay in their prototype.

    With ``x_dot_t = x_t - x_{t-1}`` (``augmented_latent``) the position's residual
    ``x_t - x_{t-1} - x_dot_t`` is zero, so lambda is the scale of the velocity's residual
    ``x_dot_t - x_dot_{t-1}`` whitened by the prototype's velocity covariance:
    ``lambda^2 = mean_t r_t^T Sigma_k[x_dot]^-1 r_t / q``."""
    q = augmented.shape[1] // 2
    velocity_cov = np.asarray(prototypes.covariances, np.float64)[:, q:, q:]
    total, count = 0.0, 0
    for a, b in _pieces(len(augmented), training_starts):
        for t in range(a + 1, b):
            if labels[t] != labels[t - 1]:
                continue
            residual = augmented[t, q:] - augmented[t - 1, q:]
            total += float(residual @ np.linalg.solve(velocity_cov[labels[t]], residual))
            count += q
    return max(float(np.sqrt(total / count)) if count else 1.0, floor)


def fit_vlmm_dynamics(manifold: ManifoldPrior, validation, training_starts=None, *, key: PRNGKeyArray,
                      max_components: int = 20, max_memory: int = 5, kl_threshold: float = 1e-3, samples: int = 100,
                      floor: float = 1e-3) -> tuple[VLMMDynamics, VLMMFit]:
    """Fit the VLMM-PF's dynamics on a back-constrained manifold.

    Args:
        manifold: the fitted manifold prior (its training latent points are the motion).
        validation: (T, D) pose sequences: the global entries' random-walk scales.
        training_starts: first frame of each training sequence in the manifold's data, ending
            with N (default: one sequence).
        key: draws the uncertainty samples and the mixture's start.
        max_components: the largest prototype count the MML search starts from.
        max_memory, kl_threshold: the VLMM's (``fit_suffix_tree``).
        samples: draws per training point for its uncertainty.
        floor: smallest scale.
    """
    sequences = motion_sequences(validation, manifold.pose_dim)
    g = manifold.global_dims
    latent = np.asarray(manifold.training_latent, np.float64)
    augmented = augmented_latent(latent, training_starts)
    k_noise, k_mix = jax.random.split(key)
    uncertainties = latent_uncertainties(manifold.astype(jnp.float64), k_noise, training_starts, samples=samples)
    count = min(max_components, max(1, len(augmented) // (2 * augmented.shape[1])))
    mixture_fit = fit_uncertain_mixture(augmented, uncertainties, key=k_mix, max_components=count)
    prototypes = mixture_fit.mixture
    labels = np.asarray(prototypes.labels(jnp.asarray(augmented), jnp.asarray(uncertainties)))
    pieces = tuple(labels[a:b] for a, b in _pieces(len(augmented), training_starts))
    vlmm, tree = fit_vlmm(pieces, prototypes.num_components, max_memory=max_memory, threshold=kl_threshold)
    step_scale = fit_step_scale(prototypes, augmented, labels, training_starts)
    dtype = manifold.training_latent.dtype
    dynamics = VLMMDynamics(
        manifold=manifold, prototypes=jax.tree.map(lambda a: jnp.asarray(a, dtype), prototypes), vlmm=vlmm,
        s_global=jnp.asarray(rms_step([s[:, :g] for s in sequences], floor), dtype), step_scale=jnp.asarray(step_scale, dtype),
    )
    return dynamics, VLMMFit(augmented, uncertainties, pieces, mixture_fit, tree)


VLMM_RECORD_VERSION = 1


def vlmm_to_record(dynamics: VLMMDynamics) -> dict:
    """The prototypes, automaton and scales of fitted VLMM-PF dynamics as JSON-ready lists (the
    ``"vlmm"`` entry ``jaxtrack fit --model vlmm`` stores beside its BC-GPLVM)."""
    as_list = lambda a: np.asarray(a, np.float64).tolist()  # noqa: E731
    return {
        "version": VLMM_RECORD_VERSION,
        "weights": as_list(dynamics.prototypes.weights),
        "means": as_list(dynamics.prototypes.means),
        "covariances": as_list(dynamics.prototypes.covariances),
        "transition": np.asarray(dynamics.vlmm.transition).astype(int).tolist(),
        "output": as_list(dynamics.vlmm.output),
        "initial": as_list(dynamics.vlmm.initial),
        "contexts": [list(c) for c in dynamics.vlmm.contexts],
        "s_global": as_list(dynamics.s_global),
        "step_scale": float(dynamics.step_scale),
    }


def vlmm_from_record(record: dict, manifold: ManifoldPrior, validation=None, floor: float = 1e-3) -> VLMMDynamics:
    """``VLMMDynamics`` on ``manifold`` from a ``vlmm_to_record`` dict; with ``validation`` ((T, D)
    pose sequences), the global entries' random-walk scales are fitted on them instead of read
    (as ``fit_vlmm_dynamics`` fits them: the experiment's and ``track``'s validation files).

    Raises:
        ValueError: an unknown version, a missing entry, or tables whose shapes disagree (named).
    """
    if not isinstance(record, dict) or record.get("version") != VLMM_RECORD_VERSION:
        raise ValueError(f"not a VLMM record of version {VLMM_RECORD_VERSION} (got version "
                         f"{record.get('version') if isinstance(record, dict) else type(record).__name__})")
    missing = [k for k in ("weights", "means", "covariances", "transition", "output", "initial", "contexts", "s_global",
                           "step_scale") if k not in record]
    if missing:
        raise ValueError(f"the VLMM record lacks {', '.join(missing)}")
    dtype = manifold.training_latent.dtype
    arrays = {k: np.asarray(record[k], np.float64) for k in ("weights", "means", "covariances", "output", "initial", "s_global")}
    transition = np.asarray(record["transition"], np.int64)
    M, Q = arrays["weights"].shape[0], transition.shape[0]
    shapes = {"means": (M, 2 * manifold.latent_dim), "covariances": (M, 2 * manifold.latent_dim, 2 * manifold.latent_dim),
              "output": (Q, M), "initial": (Q,), "s_global": (manifold.global_dims,)}
    for name, shape in shapes.items():
        if arrays[name].shape != shape:
            raise ValueError(f"the VLMM record's {name} has shape {arrays[name].shape}, expected {shape}")
    if transition.shape != (Q, M) or transition.min() < 0 or transition.max() >= Q or len(record["contexts"]) != Q:
        raise ValueError(f"the VLMM record's transition table must be ({Q}, {M}) states, with one context per state")
    vlmm = VLMM(transition=jnp.asarray(transition, jnp.int32), output=jnp.asarray(arrays["output"], dtype),
                initial=jnp.asarray(arrays["initial"], dtype), contexts=tuple(tuple(int(v) for v in c) for c in record["contexts"]))
    prototypes = GaussianMixture(*(jnp.asarray(arrays[k], dtype) for k in ("weights", "means", "covariances")))
    s_global = arrays["s_global"]
    if validation is not None:
        s_global = rms_step([s[:, :manifold.global_dims] for s in motion_sequences(validation, manifold.pose_dim)], floor)
    return VLMMDynamics(manifold=manifold, prototypes=prototypes, vlmm=vlmm, s_global=jnp.asarray(s_global, dtype),
                        step_scale=jnp.asarray(float(record["step_scale"]), dtype))

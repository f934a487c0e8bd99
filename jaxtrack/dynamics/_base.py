"""The dynamics interface: how a particle's state moves from one frame to the next, and the
checks and statistics the fitting functions share.

A dynamics module owns the particle state space. ``init`` makes the state of a pose (the pose
itself, or the global entries plus a latent point), ``to_pose`` maps states back to poses for
the likelihood, ``propose`` draws the next states with the log importance weight that keeps
the filter exact, and ``perturb`` is the local move an annealing layer makes. Each concrete
dynamics comes with a ``fit_*`` function that estimates its parameters from motion data and
returns the fitted module.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, PRNGKeyArray


class AbstractDynamics(eqx.Module):
    """A transition model ``p(s_t | s_{t-1})`` over particle states (S numbers each)."""

    @abc.abstractmethod
    def init(self, key: PRNGKeyArray, pose: Float[Array, " dofs"], num_particles: int) -> Float[Array, "particles state"]:
        """N initial states for a known initial pose (000 Alg. 1 line 1: N copies of it); the
        key draws what the pose leaves unknown (e.g. the velocity of second-order dynamics)."""

    @abc.abstractmethod
    def to_pose(self, states: Float[Array, "particles state"]) -> Float[Array, "particles dofs"]:
        """The poses of N states (what the likelihood scores)."""

    @abc.abstractmethod
    def propose(
        self, key: PRNGKeyArray, previous: Float[Array, "particles state"]
    ) -> tuple[Float[Array, "particles state"], Float[Array, " particles"]]:
        """Draw ``s_t ~ q(s_t | s_{t-1})`` for each of N particles, and the log weight
        ``ln p(s_t | s_{t-1}) / q(s_t | s_{t-1})`` (up to a constant shared by the particles)
        that corrects for drawing from ``q`` instead of the transition: zeros when the draw is
        from the transition itself."""

    @abc.abstractmethod
    def perturb(
        self, key: PRNGKeyArray, states: Float[Array, "particles state"], factor: Float[Array, ""]
    ) -> Float[Array, "particles state"]:
        """A zero-mean local move: the transition's noise, standard deviation times ``factor``,
        without its drift (the diffusion of annealing layer m, factor ``decay^(m/2)``)."""

    def velocity_states(self, poses: Float[Array, "frames dofs"]) -> Float[Array, "frames k"]:
        """The K leading state entries of a pose sequence that carry a velocity
        (``StateVelocity``): by default the six global entries (the root), for dynamics whose
        other entries move in ways a constant velocity does not describe (e.g. a learned
        latent dynamics) or whose state holds more than a pose's worth of a frame."""
        return poses[:, :6]


class AbstractRefinableDynamics(AbstractDynamics):
    """Dynamics with a tractable transition density: what a gradient-refined move
    (``jaxtrack.filters.LangevinRefinement``) needs. Filters check for it with ``is_refinable``."""

    @abc.abstractmethod
    def log_transition(
        self, previous: Float[Array, "particles state"], states: Float[Array, "particles state"]
    ) -> Float[Array, " particles"]:
        """``ln p(s_t | s_{t-1})`` of each particle's pair, up to a constant that does not
        depend on ``s_t``: the prior term of a gradient-refined move's target."""

    @abc.abstractmethod
    def noise_scales(self) -> Float[Array, " state"]:
        """(S,) standard deviation of the transition's noise per state entry (0 for entries the
        transition sets exactly): the preconditioner of a gradient-refined move, whose steps
        leave zero-scale entries where they are."""


class AbstractRestartableDynamics(AbstractDynamics):
    """Dynamics with a distribution to restart a lost tracker from (004 sec. 6.1: the VLMM's
    initial states ``s``). Filters check for it with ``is_restartable``."""

    @abc.abstractmethod
    def restart(self, key: PRNGKeyArray, states: Float[Array, "particles state"]) -> Float[Array, "particles state"]:
        """N states drawn afresh from the restart distribution, the global entries (the root)
        kept from ``states``."""


class AbstractDynamicsWrapper(AbstractDynamics):
    """Dynamics that carry state entries of their own after those of an ``inner`` dynamics (a
    Kalman-tracked velocity, an off-manifold residual). A wrapper that is an
    ``AbstractRefinableDynamics`` is refinable when its inner dynamics are (``is_refinable``);
    any wrapper is restartable when its inner dynamics are (``is_restartable``), its own entries
    kept (``restart_states``)."""

    inner: eqx.AbstractVar[AbstractDynamics]

    @abc.abstractmethod
    def own_size(self) -> int:
        """How many state entries the wrapper appends after the inner dynamics' state."""


def is_refinable(dynamics: AbstractDynamics) -> bool:
    """Whether ``dynamics`` define the transition density and noise scales a gradient-refined
    move needs: an ``AbstractRefinableDynamics``, and for a wrapper its inner dynamics too."""
    if not isinstance(dynamics, AbstractRefinableDynamics):
        return False
    return is_refinable(dynamics.inner) if isinstance(dynamics, AbstractDynamicsWrapper) else True


def is_restartable(dynamics: AbstractDynamics) -> bool:
    """Whether ``dynamics`` (through any wrappers) can restart a lost tracker
    (``AbstractRestartableDynamics``)."""
    if isinstance(dynamics, AbstractDynamicsWrapper):
        return is_restartable(dynamics.inner)
    return isinstance(dynamics, AbstractRestartableDynamics)


def restart_states(dynamics: AbstractDynamics, key: PRNGKeyArray,
                   states: Float[Array, "particles state"]) -> Float[Array, "particles state"]:
    """``dynamics.restart`` of the innermost restartable dynamics, each wrapper's own entries
    kept (a velocity's belief, a residual)."""
    if isinstance(dynamics, AbstractDynamicsWrapper):
        own = dynamics.own_size()
        inner = restart_states(dynamics.inner, key, states[:, :-own])
        return jnp.concatenate([inner, states[:, -own:]], axis=1)
    if not isinstance(dynamics, AbstractRestartableDynamics):
        raise TypeError(f"{type(dynamics).__name__} has no restart distribution (it is not an AbstractRestartableDynamics)")
    return dynamics.restart(key, states)


def copies(state: Float[Array, " state"], num_particles: int) -> Float[Array, "particles state"]:
    """``num_particles`` copies of one state."""
    return jnp.broadcast_to(state, (num_particles,) + state.shape)


def gaussian_step(key: PRNGKeyArray, states: Float[Array, "n s"], scales: Float[Array, ...]) -> Float[Array, "n s"]:
    """``s + N(0, diag(scales^2))`` for every particle; ``scales`` (S,), or (N, S) / (N, 1) per particle."""
    return states + scales * jax.random.normal(key, states.shape, states.dtype)


def gaussian_log_density(values: Float[Array, "n s"], means: Float[Array, "n s"], scales: Float[Array, ...]) -> Float[Array, " n"]:
    """``sum_j ln N(values_j | means_j, scales_j^2)`` per row (``scales`` (S,) or per particle,
    (N, S) / (N, 1)), without the constant
    ``-sum_j ln(sqrt(2 pi) scales_j)`` (entries of zero scale are left out)."""
    safe = jnp.where(scales > 0, scales, 1.0)
    return -0.5 * jnp.sum(jnp.where(scales > 0, ((values - means) / safe) ** 2, 0.0), axis=-1)


def check_scale_vector(name: str, scales, size: int | None):
    """Raise ``ValueError`` unless ``scales`` is a (size,) vector (any length for None) of
    finite non-negative numbers; values are checked only when concrete (not under jit)."""
    shape = np.shape(scales)
    if len(shape) != 1 or (size is not None and shape != (size,)):
        raise ValueError(f"{name} must have shape ({'D' if size is None else size},), got {shape}")
    if isinstance(scales, jax.core.Tracer):
        return
    values = np.asarray(scales)
    if not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"{name} must be finite and non-negative, got {values}")


def as_scale_vector(name: str, scales, size: int, dtype=None) -> np.ndarray:
    """A (size,) float64 NumPy vector from a scalar or a vector, checked as in
    ``check_scale_vector``; with ``dtype``, values beyond its range are clipped to its largest
    finite number (a scale that large is flat; casting would overflow to inf)."""
    values = np.asarray(scales, np.float64)
    values = np.broadcast_to(values, (size,)).copy() if values.ndim == 0 else values
    check_scale_vector(name, values, size)
    if dtype is not None:
        values = np.minimum(values, float(np.finfo(np.dtype(dtype)).max))
    return values


def motion_sequences(sequences, dims: int, name: str = "validation poses") -> list[np.ndarray]:
    """One (T, D) pose array or a list (or tuple) of them as float64 arrays with T >= 2, finite;
    raises ``ValueError`` naming the sequence otherwise."""
    if not isinstance(sequences, (list, tuple)):
        sequences = [sequences]  # one (T, D) array (NumPy or JAX)
    arrays = [np.asarray(s, np.float64) for s in sequences]
    if not arrays:
        raise ValueError(f"{name}: need at least one sequence")
    for i, s in enumerate(arrays):
        if s.ndim != 2 or s.shape[1] != dims or s.shape[0] < 2:
            raise ValueError(f"{name} must be (T >= 2, {dims}) arrays, got {s.shape} for sequence {i}")
        if not np.all(np.isfinite(s)):
            raise ValueError(f"{name} contain NaN or infinite values (sequence {i})")
    return arrays


def rms_step(sequences: list[np.ndarray], floor: float) -> np.ndarray:
    """Per entry, the RMS of the frame-to-frame steps within each sequence, at least ``floor``."""
    steps = np.concatenate([np.diff(s, axis=0) for s in sequences])
    return np.maximum(np.sqrt(np.mean(np.square(steps), axis=0)), floor)

"""A velocity for any dynamics: constant speed of the leading state entries (the root, and
where the dynamics says so the pose or the latent point; ``AbstractDynamics.velocity_states``),
the root's in the body's heading frame (a coordinated-turn model), tracked per particle by a
Kalman filter (003 sec. 5.2's second-order dynamics, Rao-Blackwellised).

Each particle carries a Gaussian belief ``N(mean, var)`` over the velocity ``v`` of its K
leading entries: ``v_t = v_{t-1} + N(0, diag(acceleration^2))``, and each frame's step of the
entries is ``R(yaw) v_t`` plus the wrapped dynamics' noise (the horizontal speeds rotated by
the state's yaw, so a person running round a circle has a constant velocity). ``propose``
updates the belief with the particle's last step (its final position after annealing and
refinement, which the likelihood chose) by the Kalman equations, predicts it one frame on,
draws ``v_t`` from it, shifts the previous state by ``v_t`` and lets the wrapped dynamics add
its own noise. Drawing ``v_t`` from the belief and then the step is an exact draw from the
step's marginal with ``v`` integrated out, so the velocity never collapses onto a few
resampled values: every particle keeps the Kalman spread. The wrapped noise is the random
walk's spread, now centred where the body is going, so the model is never narrower than the
walk it replaces (a narrow second-order model loses the person as soon as one velocity is
wrong; see ``AutoregressivePoseDynamics``). Annealing layers move only the wrapped state.

A velocity belief is learnt from the particle's own steps, so when the likelihood has led a
particle astray its belief carries it further off. With ``rest_probability`` p (the fitted
velocities' default, ``REST_PROBABILITY``) each particle instead draws, with probability p, a
velocity about zero (``N(0, acceleration^2)``: a body starting from rest), a defensive mixture
in the prior itself (Hesterberg's defensive importance sampling), so some particles always try
the zero-mean walk the velocity replaced. The transition density is the two-component mixture,
and the weights stay the likelihood's. The belief is updated as before by every particle's
step, so a particle that restarts from rest and lands well passes a slower belief on to its
copies.

Pose layout (``jaxtrack.body``): entries 0-2 are the root position (z up), 3-5 its yaw (about
z), pitch and roll; every built-in dynamics' state starts with them.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._base import AbstractDynamics, AbstractDynamicsWrapper, AbstractRefinableDynamics, check_scale_vector, is_refinable, motion_sequences

VELOCITY_DIM = 6  # forward, left, up (m/frame); yaw, pitch, roll rates (rad/frame)
# A quarter of the draws restart from rest, set before any measurement (not tuned on the test
# takes); what it does: docs/trackers.md, "A velocity that may restart from rest".
REST_PROBABILITY = 0.25
YAW = 3  # the root yaw's entry in a pose (and in every built-in state)


def heading_to_world(velocity: Float[Array, "n k"], yaw: Float[Array, " n"]) -> Float[Array, "n k"]:
    """Steps of the K >= 2 tracked entries from heading-frame velocities: the horizontal root
    (x, y) rotated by the yaw, the rest (z, yaw, pitch, roll and any pose entries MRPF tracks
    on a BC-GPLVM) as they are."""
    cos, sin = jnp.cos(yaw), jnp.sin(yaw)
    forward, left = velocity[:, 0], velocity[:, 1]
    horizontal = jnp.stack([cos * forward - sin * left, sin * forward + cos * left], axis=1)
    return jnp.concatenate([horizontal, velocity[:, 2:]], axis=1)


def world_to_heading(steps: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """The inverse of ``heading_to_world`` (NumPy, for fitting): (T, 6) steps -> velocities."""
    cos, sin = np.cos(yaw), np.sin(yaw)
    forward = cos * steps[:, 0] + sin * steps[:, 1]
    left = -sin * steps[:, 0] + cos * steps[:, 1]
    return np.concatenate([forward[:, None], left[:, None], steps[:, 2:]], axis=1)


class StateVelocity(AbstractDynamicsWrapper, AbstractRefinableDynamics):
    """``inner`` with a velocity of its K leading state entries, tracked by a Kalman filter per
    particle (module docstring).

    State ``[inner state (S), v (6), mean (6), var (6), anchor (6), seen (1)]``: ``v`` the
    velocity this frame's step was drawn with, ``N(mean, var)`` the predictive distribution it
    was drawn from, ``anchor`` the global entries the step started at, ``seen`` 0 until one
    step has been observed. Everything but ``inner`` and ``v`` is a function of the previous
    state, so the transition density is ``p(inner | anchor + R v) N(v | mean, var)``.

    Attributes:
        inner: the wrapped dynamics (its state's first six entries are the pose's global ones,
            as for every built-in dynamics).
        acceleration: (6,) standard deviation of the velocity's change per frame.
        initial_speed: (6,) standard deviation of the unknown first velocity.
        displacement_noise: (6,) standard deviation of the global entries' step about the
            velocity (the observation noise of the Kalman update); by default the inner
            dynamics' noise scales of those entries, the horizontal pair averaged in variance
            (the update assumes a step noise that does not depend on the heading).
        rest_probability: the probability that a particle draws its velocity from
            ``N(0, acceleration^2)`` instead of its belief (module docstring); 0 (the
            default here; the fitted velocities use ``REST_PROBABILITY``): the belief alone.
    """

    inner: AbstractDynamics
    acceleration: Float[Array, " 6"]
    initial_speed: Float[Array, " 6"]
    displacement_noise: Float[Array, " 6"]
    rest_probability: float = eqx.field(static=True, default=0.0)

    def __init__(self, inner, acceleration, initial_speed, displacement_noise=None, rest_probability=0.0):
        if not isinstance(inner, AbstractDynamics):
            raise TypeError(f"StateVelocity wraps an AbstractDynamics, got {type(inner).__name__}")
        if isinstance(inner, StateVelocity):
            raise ValueError("the dynamics already carries a root velocity")
        self.inner = inner
        self.acceleration = acceleration
        self.initial_speed = initial_speed
        if displacement_noise is None:
            if not is_refinable(inner):
                raise ValueError(f"{type(inner).__name__} defines no noise scales: pass StateVelocity's displacement_noise")
            displacement_noise = inner.noise_scales()[: len(acceleration)]
        check_scale_vector("displacement_noise", displacement_noise, len(acceleration))
        horizontal = jnp.sqrt(0.5 * (displacement_noise[0] ** 2 + displacement_noise[1] ** 2))
        self.displacement_noise = jnp.asarray(displacement_noise).at[:2].set(horizontal)
        self.rest_probability = float(rest_probability)

    def __check_init__(self):
        check_scale_vector("acceleration", self.acceleration, None)
        if self.size < VELOCITY_DIM:
            raise ValueError(f"a root velocity covers at least the {VELOCITY_DIM} global entries, got {self.size}")
        check_scale_vector("initial_speed", self.initial_speed, self.size)
        if not 0.0 <= self.rest_probability < 1.0:
            raise ValueError(f"rest_probability must be in [0, 1), got {self.rest_probability}")
        if self.rest_probability > 0 and not np.all(np.asarray(self.acceleration) > 0):
            raise ValueError("a velocity that may restart from rest needs every acceleration > 0 (its spread about zero)")

    @property
    def size(self) -> int:
        """K, the leading inner-state entries that carry a velocity."""
        return self.acceleration.shape[0]

    def own_size(self) -> int:
        return 4 * self.size + 1

    def _split(self, states):
        d = self.size
        inner = states[:, : -(4 * d + 1)]
        v, mean, var, anchor = (states[:, -(4 * d + 1) + i * d : -(3 * d + 1) + i * d] for i in range(4))
        return inner, v, mean, var, anchor, states[:, -1:]

    def _shifted(self, inner_states, velocity):
        step = heading_to_world(velocity, inner_states[:, YAW])
        return inner_states.at[:, : self.size].add(step)

    def _predict(self, previous):
        """The predictive ``N(mean, var)`` of this frame's velocity and its anchor, from the
        previous state: the Kalman update by the previous step (unless none was seen), then the
        random-walk prediction."""
        inner, _, mean, var, anchor, seen = self._split(previous)
        here = inner[:, : self.size]
        step = here - anchor
        observed = jnp.concatenate([_to_heading(step, anchor[:, YAW]), step[:, 2:]], axis=1)
        total = var + self.displacement_noise**2
        gain = seen * jnp.where(total > 0, var / jnp.where(total > 0, total, 1.0), 0.0)
        mean = mean + gain * (observed - mean)
        var = (1.0 - gain) * var + self.acceleration**2
        return mean, var, here

    def init(self, key, pose, num_particles):
        inner = self.inner.init(key, pose, num_particles)
        n, dtype = inner.shape[0], inner.dtype
        zeros = jnp.zeros((n, self.size), dtype)
        # The step into the first frame is unknown: mean 0, the fitted spread, not yet seen, so
        # the first prediction adds the acceleration and no update.
        var = jnp.broadcast_to((self.initial_speed**2 - self.acceleration**2).clip(0.0).astype(dtype), zeros.shape)
        return jnp.concatenate([inner, zeros, zeros, var, inner[:, : self.size], jnp.zeros((n, 1), dtype)], axis=1)

    def to_pose(self, states):
        return self.inner.to_pose(self._split(states)[0])

    def propose(self, key, previous):
        velocity_key, inner_key = jax.random.split(key)
        inner = self._split(previous)[0]
        mean, var, anchor = self._predict(previous)
        if self.rest_probability > 0:
            velocity_key, rest_key = jax.random.split(velocity_key)
            noise = jax.random.normal(velocity_key, mean.shape, mean.dtype)
            rests = jax.random.uniform(rest_key, (mean.shape[0], 1), mean.dtype) < self.rest_probability
            velocity = jnp.where(rests, self.acceleration * noise, mean + jnp.sqrt(var) * noise)
        else:
            velocity = mean + jnp.sqrt(var) * jax.random.normal(velocity_key, mean.shape, mean.dtype)
        moved, correction = self.inner.propose(inner_key, self._shifted(inner, velocity))
        seen = jnp.ones((moved.shape[0], 1), moved.dtype)
        return jnp.concatenate([moved, velocity, mean, var, anchor, seen], axis=1), correction

    def perturb(self, key, states, factor):
        inner = self._split(states)[0]
        return jnp.concatenate([self.inner.perturb(key, inner, factor), states[:, inner.shape[1] :]], axis=1)

    def log_transition(self, previous, states):
        mean, var, _ = self._predict(previous)
        inner, velocity = self._split(states)[:2]
        shifted = self._shifted(self._split(previous)[0], velocity)
        # Entries of zero spread are set exactly (a refined move leaves them alone).
        safe = jnp.where(var > 0, var, 1.0)
        log_velocity = -0.5 * jnp.sum(jnp.where(var > 0, (velocity - mean) ** 2 / safe + jnp.log(safe), 0.0), axis=1)
        if self.rest_probability > 0:  # the mixture with N(0, acceleration^2) (every acceleration > 0)
            rest = self.acceleration**2
            log_rest = -0.5 * jnp.sum(velocity**2 / rest + jnp.log(rest), axis=1)
            p = self.rest_probability
            log_velocity = jnp.logaddexp(jnp.log1p(-p) + log_velocity, jnp.log(p) + log_rest)
        return self.inner.log_transition(shifted, inner) + log_velocity

    def noise_scales(self):
        # The velocity's steady-state predictive spread (scalar Riccati equation); the Kalman
        # entries are set exactly by the transition.
        a2, q2 = self.acceleration**2, self.displacement_noise**2
        spread = jnp.sqrt(0.5 * (a2 + jnp.sqrt(a2**2 + 4.0 * a2 * q2)))
        fixed = jnp.zeros(3 * self.size + 1, spread.dtype)
        return jnp.concatenate([self.inner.noise_scales(), spread, fixed])


def _to_heading(step, yaw):
    """Horizontal world steps (N, >= 2) -> (N, 2) forward and leftward, for a body at ``yaw``."""
    cos, sin = jnp.cos(yaw), jnp.sin(yaw)
    return jnp.stack([cos * step[:, 0] + sin * step[:, 1], -sin * step[:, 0] + cos * step[:, 1]], axis=1)


class VelocityFit(eqx.Module):
    """Fitted velocity parameters, ready to wrap a dynamics (``wrap``).

    Attributes:
        acceleration, initial_speed: (K,) as for ``StateVelocity``.
        step_noise: (K,) RMS frame-to-frame step of the entries: the displacement noise for a
            wrapped dynamics that defines no noise scales of its own.
        rest_probability: as for ``StateVelocity``.
    """

    acceleration: Float[Array, " k"]
    initial_speed: Float[Array, " k"]
    step_noise: Float[Array, " k"]
    rest_probability: float = eqx.field(static=True, default=REST_PROBABILITY)

    def wrap(self, dynamics: AbstractDynamics) -> StateVelocity:
        """``dynamics`` with this velocity (its K leading state entries); the displacement noise
        is the dynamics' own noise scales where it defines them."""
        noise = dynamics.noise_scales()[: self.acceleration.shape[0]] if is_refinable(dynamics) else self.step_noise
        return StateVelocity(dynamics, self.acceleration, self.initial_speed, noise, self.rest_probability)


def fit_root_velocity(validation, *, entries: int | None = VELOCITY_DIM, floor: float = 1e-4, dtype=jnp.float64,
                      rest_probability: float = REST_PROBABILITY) -> VelocityFit:
    """The velocity's parameters from validation motion (one (T >= 3, S) array of poses, or of
    any states whose first six entries are the global ones, or a list): per heading-frame
    entry, ``initial_speed`` and ``step_noise`` are the RMS velocity (the RMS step) and
    ``acceleration`` the RMS change of the velocity between frames, all floored at ``floor``. ``entries`` is how many leading entries
    get a velocity: the six global ones (the root) by default, None for all. ``rest_probability``
    is kept for ``wrap`` (``StateVelocity``; 0: the belief alone)."""
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    if sequences[0].shape[1] < VELOCITY_DIM:
        raise ValueError(f"a root velocity needs poses with the {VELOCITY_DIM} global entries, got {sequences[0].shape[1]} entries")
    if any(len(s) < 3 for s in sequences):
        raise ValueError("fitting a root velocity needs validation sequences of at least 3 frames")
    entries = sequences[0].shape[1] if entries is None else entries
    if not VELOCITY_DIM <= entries <= sequences[0].shape[1]:
        raise ValueError(f"entries must be between {VELOCITY_DIM} and {sequences[0].shape[1]}, got {entries}")
    velocities = [world_to_heading(np.diff(s[:, :entries], axis=0), s[:-1, YAW]) for s in sequences]
    speed = np.sqrt(np.mean(np.concatenate(velocities) ** 2, axis=0))
    change = np.sqrt(np.mean(np.concatenate([np.diff(v, axis=0) for v in velocities]) ** 2, axis=0))
    return VelocityFit(
        acceleration=jnp.asarray(np.maximum(change, floor), dtype), initial_speed=jnp.asarray(np.maximum(speed, floor), dtype),
        step_noise=jnp.asarray(np.maximum(speed, floor), dtype), rest_probability=rest_probability,
    )


def fit_state_velocity(dynamics: AbstractDynamics, validation, *, floor: float = 1e-4, dtype=jnp.float64,
                       rest_probability: float = REST_PROBABILITY) -> VelocityFit:
    """The velocity ``dynamics`` supports (``dynamics.velocity_states``: the root's, the pose's or
    the latent point's), fitted as ``fit_root_velocity`` on the validation poses (one (T >= 3,
    D) array or a list) mapped to those state entries."""
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    states = [np.asarray(dynamics.velocity_states(jnp.asarray(s, dtype)), np.float64) for s in sequences]
    return fit_root_velocity(states, entries=None, floor=floor, dtype=dtype, rest_probability=rest_probability)

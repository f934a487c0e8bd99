"""Root velocity for any dynamics: constant speed and turn rate of the global entries in the
body's heading frame (a coordinated-turn model; 003 sec. 5.2's second-order dynamics, applied
where a person's motion is nearly constant).

The state of the wrapped dynamics gains the root velocity ``v`` (6 numbers per frame: forward,
leftward and upward speed in metres, then yaw, pitch and roll rates in radians),
``v_t = v_{t-1} + N(0, diag(acceleration^2))``. Before the wrapped dynamics propagates a state,
its global entries are shifted by ``v_t``, the horizontal speeds rotated by the state's yaw, so
a person running round a circle has a constant velocity. The wrapped dynamics keeps its own
noise: the random walk's spread, now centred where the body is going, so the model is never
narrower than the walk it replaces (a narrow second-order model loses the person as soon as one
velocity is wrong; see ``AutoregressivePoseDynamics``). The first frame's velocity is unknown:
each particle draws its own from ``N(0, initial_speed^2)`` and the likelihood selects among
them over the next frames. Annealing layers leave the velocity where it is: the current frame's
likelihood does not see it.

Pose layout (``jaxtrack.body``): entries 0-2 are the root position (z up), 3-5 its yaw (about
z), pitch and roll; every built-in dynamics' state starts with them.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._base import AbstractDynamics, check_scale_vector, gaussian_log_density, gaussian_step, motion_sequences

VELOCITY_DIM = 6  # forward, left, up (m/frame); yaw, pitch, roll rates (rad/frame)
YAW = 3  # the root yaw's entry in a pose (and in every built-in state)


def heading_to_world(velocity: Float[Array, "n 6"], yaw: Float[Array, " n"]) -> Float[Array, "n 6"]:
    """Steps of the global entries (x, y, z, yaw, pitch, roll) from heading-frame velocities."""
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


class RootVelocity(AbstractDynamics):
    """``inner`` with a heading-frame root velocity; state ``[inner state, v (6)]``.

    Attributes:
        inner: the wrapped dynamics (its state's first six entries are the pose's global ones,
            as for every built-in dynamics).
        acceleration: (6,) standard deviation of the velocity's change per frame.
        initial_speed: (6,) standard deviation of the unknown first velocity.
    """

    inner: AbstractDynamics
    acceleration: Float[Array, " 6"]
    initial_speed: Float[Array, " 6"]

    def __check_init__(self):
        if not isinstance(self.inner, AbstractDynamics):
            raise TypeError(f"RootVelocity wraps an AbstractDynamics, got {type(self.inner).__name__}")
        if isinstance(self.inner, RootVelocity):
            raise ValueError("the dynamics already carries a root velocity")
        check_scale_vector("acceleration", self.acceleration, VELOCITY_DIM)
        check_scale_vector("initial_speed", self.initial_speed, VELOCITY_DIM)

    @staticmethod
    def _split(states):
        return states[:, :-VELOCITY_DIM], states[:, -VELOCITY_DIM:]

    @staticmethod
    def _shifted(inner_states, velocity):
        step = heading_to_world(velocity, inner_states[:, YAW])
        return inner_states.at[:, :VELOCITY_DIM].add(step)

    def init(self, key, pose, num_particles):
        inner_key, velocity_key = jax.random.split(key)
        inner = self.inner.init(inner_key, pose, num_particles)
        velocity = self.initial_speed * jax.random.normal(velocity_key, (num_particles, VELOCITY_DIM), inner.dtype)
        return jnp.concatenate([inner, velocity], axis=1)

    def to_pose(self, states):
        return self.inner.to_pose(self._split(states)[0])

    def propose(self, key, previous):
        velocity_key, inner_key = jax.random.split(key)
        inner, velocity = self._split(previous)
        velocity = gaussian_step(velocity_key, velocity, self.acceleration)
        moved, correction = self.inner.propose(inner_key, self._shifted(inner, velocity))
        return jnp.concatenate([moved, velocity], axis=1), correction

    def perturb(self, key, states, factor):
        inner, velocity = self._split(states)
        return jnp.concatenate([self.inner.perturb(key, inner, factor), velocity], axis=1)

    def log_transition(self, previous, states):
        inner_before, velocity_before = self._split(previous)
        inner, velocity = self._split(states)
        return self.inner.log_transition(self._shifted(inner_before, velocity), inner) + gaussian_log_density(
            velocity, velocity_before, self.acceleration
        )

    def noise_scales(self):
        return jnp.concatenate([self.inner.noise_scales(), self.acceleration])


class VelocityFit(eqx.Module):
    """Fitted root-velocity parameters, ready to wrap any tracker's dynamics (``wrap``).

    Attributes:
        acceleration, initial_speed: (6,) as for ``RootVelocity``.
    """

    acceleration: Float[Array, " 6"]
    initial_speed: Float[Array, " 6"]

    def wrap(self, dynamics: AbstractDynamics) -> RootVelocity:
        """``dynamics`` with this root velocity."""
        return RootVelocity(dynamics, self.acceleration, self.initial_speed)


def fit_root_velocity(validation, *, floor: float = 1e-4, dtype=jnp.float64) -> VelocityFit:
    """The velocity's parameters from validation motion (one (T >= 3, D) pose array or a list):
    per heading-frame entry, ``initial_speed`` is the RMS velocity and ``acceleration`` the RMS
    change of the velocity between frames, both floored at ``floor``."""
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    if sequences[0].shape[1] < VELOCITY_DIM:
        raise ValueError(f"a root velocity needs poses with the {VELOCITY_DIM} global entries, got {sequences[0].shape[1]} entries")
    if any(len(s) < 3 for s in sequences):
        raise ValueError("fitting a root velocity needs validation sequences of at least 3 frames")
    velocities = [world_to_heading(np.diff(s[:, :VELOCITY_DIM], axis=0), s[:-1, YAW]) for s in sequences]
    speed = np.sqrt(np.mean(np.concatenate(velocities) ** 2, axis=0))
    change = np.sqrt(np.mean(np.concatenate([np.diff(v, axis=0) for v in velocities]) ** 2, axis=0))
    return VelocityFit(
        acceleration=jnp.asarray(np.maximum(change, floor), dtype), initial_speed=jnp.asarray(np.maximum(speed, floor), dtype)
    )

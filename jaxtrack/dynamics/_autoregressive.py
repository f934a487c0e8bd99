"""Second-order autoregressive (constant-velocity) pose dynamics (003 sec. 5.2's AR(2) baseline;
docs/papers.md).

Per pose entry, ``x_t = x_{t-1} + a (x_{t-1} - x_{t-2}) + N(0, s^2)``: the previous step,
damped by ``a`` in [0, 1], plus noise. The particle state is ``[x_t, x_{t-1}]`` (2D numbers), so
the velocity is carried by every particle and selected by the likelihood with its pose; a root
moving at 3 m/s is predicted where it goes instead of being left behind by a zero-mean walk.
``a`` and ``s`` are fitted per entry by least squares on validation motion. The first frame's
velocity is unknown: each particle starts with its own, drawn from ``N(0, initial_speed^2)``
(``initial_speed`` fitted as the RMS frame-to-frame step), so the likelihood can select the
right one within a few frames.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._base import AbstractRefinableDynamics, check_scale_vector, gaussian_log_density, gaussian_step, motion_sequences


class AutoregressivePoseDynamics(AbstractRefinableDynamics):
    """``x_t = x_{t-1} + a (x_{t-1} - x_{t-2}) + N(0, diag(scales^2))``; state ``[x_t, x_{t-1}]``.

    Attributes:
        damping: (D,) ``a`` per pose entry, in [0, 1] (0: a random walk, 1: constant velocity).
        scales: (D,) standard deviation of the noise (metres, radians, per frame).
        initial_speed: (D,) standard deviation of the unknown velocity at the first frame.
    """

    damping: Float[Array, " dofs"]
    scales: Float[Array, " dofs"]
    initial_speed: Float[Array, " dofs"]

    def __check_init__(self):
        check_scale_vector("scales", self.scales, None)
        check_scale_vector("damping", self.damping, np.shape(self.scales)[0])
        check_scale_vector("initial_speed", self.initial_speed, np.shape(self.scales)[0])

    @property
    def pose_dim(self) -> int:
        return self.scales.shape[0]

    def init(self, key, pose, num_particles):
        pose = pose.astype(self.scales.dtype)
        velocity = self.initial_speed * jax.random.normal(key, (num_particles, pose.shape[0]), pose.dtype)
        return jnp.concatenate([jnp.broadcast_to(pose, velocity.shape), pose - velocity], axis=1)

    def to_pose(self, states):
        return states[:, : self.pose_dim]

    def propose(self, key, previous):
        d = self.pose_dim
        current, before = previous[:, :d], previous[:, d:]
        predicted = current + self.damping * (current - before)
        moved = gaussian_step(key, predicted, self.scales)
        return jnp.concatenate([moved, current], axis=1), jnp.zeros(previous.shape[0], previous.dtype)

    def perturb(self, key, states, factor):
        d = self.pose_dim
        return jnp.concatenate([gaussian_step(key, states[:, :d], self.scales * factor), states[:, d:]], axis=1)

    def log_transition(self, previous, states):
        # s_t's second half is s_{t-1}'s first, set exactly (a refined move leaves it alone).
        d = self.pose_dim
        current, before = previous[:, :d], previous[:, d:]
        return gaussian_log_density(states[:, :d], current + self.damping * (current - before), self.scales)

    def noise_scales(self):
        return jnp.concatenate([self.scales, jnp.zeros_like(self.scales)])


def fit_autoregressive_dynamics(
    validation, *, entries=None, floor: float = 1e-3, dtype=jnp.float64
) -> AutoregressivePoseDynamics:
    """Least-squares ``a`` (clipped to [0, 1]) and the RMS residual ``s`` per pose entry, from the
    steps ``v_t = x_t - x_{t-1}`` of one (T >= 3, D) pose array or a list of them,
    ``v_t = a v_{t-1} + e_t``; ``initial_speed`` is the RMS step. Scales are floored at ``floor``.

    ``entries`` (indices, default all) are the entries that carry a velocity; the others get
    ``a = 0``, for which the fit is exactly the random walk (``s`` = their RMS step)."""
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    if any(len(s) < 3 for s in sequences):
        raise ValueError("fitting second-order dynamics needs validation sequences of at least 3 frames")
    steps = [np.diff(s, axis=0) for s in sequences]
    now = np.concatenate([v[1:] for v in steps])
    before = np.concatenate([v[:-1] for v in steps])
    power = np.sum(before**2, axis=0)
    damping = np.clip(np.sum(now * before, axis=0) / np.where(power > 0, power, 1.0), 0.0, 1.0)
    if entries is not None:
        keep = np.zeros(damping.shape, bool)
        keep[np.asarray(entries, int)] = True
        damping = np.where(keep, damping, 0.0)
    residual = now - damping * before
    scales = np.maximum(np.sqrt(np.mean(residual**2, axis=0)), floor)
    speed = np.where(damping > 0, np.maximum(np.sqrt(np.mean(np.concatenate(steps) ** 2, axis=0)), floor), 0.0)
    return AutoregressivePoseDynamics(
        damping=jnp.asarray(damping, dtype), scales=jnp.asarray(scales, dtype), initial_speed=jnp.asarray(speed, dtype)
    )

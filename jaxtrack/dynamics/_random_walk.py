"""Gaussian random walk in pose space: the dynamics of SIR / Condensation and APF
(001 eqs. 1-4), ``x_t = x_{t-1} + N(0, diag(s^2))``, with ``s`` fitted as the RMS
frame-to-frame step of validation motion (000 eq. 29's ``s_xx``, 000 sec. 5.2)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._base import (
    AbstractRefinableDynamics,
    as_scale_vector,
    check_scale_vector,
    copies,
    gaussian_log_density,
    gaussian_step,
    motion_sequences,
    rms_step,
)


class PoseRandomWalk(AbstractRefinableDynamics):
    """``x_t = x_{t-1} + N(0, diag(scales^2))``; the state is the pose.

    Attributes:
        scales: (D,) standard deviation of the step per pose entry (metres, radians).
    """

    scales: Float[Array, " dofs"]

    def __check_init__(self):
        check_scale_vector("scales", self.scales, None)

    def init(self, key, pose, num_particles):
        del key  # the pose is the whole state
        return copies(pose.astype(self.scales.dtype), num_particles)

    def to_pose(self, states):
        return states

    def propose(self, key, previous):
        return gaussian_step(key, previous, self.scales), jnp.zeros(previous.shape[0], previous.dtype)

    def perturb(self, key, states, factor):
        return gaussian_step(key, states, self.scales * factor)

    def log_transition(self, previous, states):
        return gaussian_log_density(states, previous, self.scales)

    def noise_scales(self):
        return self.scales


def make_pose_random_walk(scales, pose_dim: int | None = None, *, dtype=jnp.float32) -> PoseRandomWalk:
    """A ``PoseRandomWalk`` from a (D,) vector of scales, or a scalar and ``pose_dim``."""
    if pose_dim is None and np.ndim(scales) != 1:
        raise ValueError(f"scales must have shape (D,) (or pass pose_dim with a scalar), got shape {np.shape(scales)}")
    size = np.shape(scales)[0] if pose_dim is None else pose_dim
    return PoseRandomWalk(jnp.asarray(as_scale_vector("scales", scales, size), dtype))


def fit_pose_random_walk(validation, *, floor: float = 1e-3, dtype=jnp.float64) -> PoseRandomWalk:
    """The random walk whose scales are the RMS frame-to-frame steps of ``validation`` (one
    (T, D) pose array or a list of them), floored at ``floor`` so no entry is deterministic."""
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    return PoseRandomWalk(jnp.asarray(rms_step(sequences, floor), dtype))

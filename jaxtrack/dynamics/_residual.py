"""An off-manifold pose residual for any dynamics whose pose is decoded from a manifold.

A manifold tracker's pose is ``decode(z)``: it cannot leave the training motion. For a person
the manifold was not trained on, the nearest training pose is 61-99 mm away on the shared real
motion (``benchmarks/gle_cross_subject.py --floors``), and a tracker confined to the manifold
starts at that floor and stays there. ``PoseResidual`` adds a residual ``r`` of the joint
angles to the state, so the pose is ``[global, decode(z)^a + r]``, and lets it take a Gaussian
random walk beside the wrapped dynamics:

    r_t = r_{t-1} + N(0, diag(s_r^2)),     s_r = scale * s_xx^a,

``s_xx^a`` the joint-angle entries of the pose random walk's scales (the RMS frame-to-frame
step of the validation poses, 000 eq. 29, what SIR diffuses by). The manifold's dynamics keep
carrying the motion (the phase of the gait, the next pose of the cycle); the residual carries
what is constant or slow in the subject and absent from the training motion (another actor's
posture, another capture's conventions), found by the likelihood as a pose-space filter finds
a pose. ``r_0`` is the initial pose's residual from its manifold point, so the filter starts at
the given pose, not at its projection.

With ``decay`` below 1 the residual is an AR(1) process, ``r_t = decay r_{t-1} + N(0,
diag(s_r^2))``: it starts at the given pose's offset and fades back onto the manifold (the
latent trackers' default "fading start", ``tracking.FADING_START``). With a ``target`` offset
``m`` it fades to ``m`` instead, ``r_t - m = decay (r_{t-1} - m) + N(0, diag(s_r^2))``: the
posture of a person whose mean joint angles differ from the training subjects' by ``m``
(``fit_pose_residual(..., target=...)``; docs/subjects.md, "A person's own posture").

The wrapped dynamics are untouched, so the transition density is the product of theirs and
the residual walk's (gradient-refined moves work), and ``scale = 0`` leaves them as they were.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..body import GLOBAL_DOFS
from ._base import (
    AbstractDynamics,
    AbstractDynamicsWrapper,
    AbstractRefinableDynamics,
    check_scale_vector,
    gaussian_log_density,
    gaussian_step,
    motion_sequences,
    rms_step,
)


class PoseResidual(AbstractDynamicsWrapper, AbstractRefinableDynamics):
    """``inner`` with a random-walk residual of the joint angles (module docstring).

    State ``[inner state (S), r (A)]``, ``A = D - 6`` the joint-angle entries of a pose.

    Attributes:
        inner: the wrapped dynamics (any ``AbstractDynamics``; meant for those whose pose is
            decoded from a latent point).
        scales: (A,) standard deviation of the residual's step per joint angle (radians).
        decay: the residual's factor per frame, ``r_t = decay r_{t-1} + N(0, diag(scales^2))``
            (1: a random walk; below 1 it fades back to the manifold, an AR(1) process).
        target: (A,) the offset an AR(1) residual fades to (radians; None: 0, the manifold).
    """

    inner: AbstractDynamics
    scales: Float[Array, " angles"]
    decay: float = eqx.field(static=True, default=1.0)
    target: Float[Array, " angles"] | None = None

    def __check_init__(self):
        if not isinstance(self.inner, AbstractDynamics):
            raise TypeError(f"PoseResidual wraps an AbstractDynamics, got {type(self.inner).__name__}")
        if isinstance(self.inner, PoseResidual):
            raise ValueError("the dynamics already carries a pose residual")
        check_scale_vector("scales", self.scales, None)
        if isinstance(self.decay, bool) or not isinstance(self.decay, (int, float)) or not 0 < self.decay <= 1:
            raise ValueError(f"the residual's decay must be a number in (0, 1], got {self.decay!r}")
        if self.target is not None and jnp.shape(self.target) != jnp.shape(self.scales):
            raise ValueError(f"the residual's target must be one offset per joint angle, shape {jnp.shape(self.scales)}, "
                             f"got {jnp.shape(self.target)}")

    def _mean(self, residual):
        """Where the residual's next step is centred: ``decay r + (1 - decay) target``."""
        if self.target is None:
            return self.decay * residual
        return self.decay * residual + (1.0 - self.decay) * self.target.astype(residual.dtype)

    @property
    def size(self) -> int:
        """A, the residual's entries (the pose's joint angles)."""
        return self.scales.shape[0]

    def own_size(self) -> int:
        return self.size

    def _split(self, states):
        return states[:, : -self.size], states[:, -self.size :]

    def init(self, key, pose, num_particles):
        if pose.shape[-1] != GLOBAL_DOFS + self.size:
            raise ValueError(f"the residual covers {self.size} joint angles; a pose of {pose.shape[-1]} entries has "
                             f"{pose.shape[-1] - GLOBAL_DOFS}")
        # With a target, the start pose less the person's offset is what lies near the manifold.
        shifted = pose if self.target is None else pose.at[GLOBAL_DOFS:].add(-self.target.astype(pose.dtype))
        inner = self.inner.init(key, shifted, num_particles)
        residual = pose[GLOBAL_DOFS:].astype(inner.dtype) - self.inner.to_pose(inner)[:, GLOBAL_DOFS:]
        return jnp.concatenate([inner, residual], axis=1)

    def to_pose(self, states):
        inner, residual = self._split(states)
        return self.inner.to_pose(inner).at[:, GLOBAL_DOFS:].add(residual)

    def propose(self, key, previous):
        inner_key, residual_key = jax.random.split(key)
        inner, residual = self._split(previous)
        moved, correction = self.inner.propose(inner_key, inner)
        return jnp.concatenate([moved, gaussian_step(residual_key, self._mean(residual), self.scales)], axis=1), correction

    def perturb(self, key, states, factor):
        inner_key, residual_key = jax.random.split(key)
        inner, residual = self._split(states)
        return jnp.concatenate([self.inner.perturb(inner_key, inner, factor),
                                gaussian_step(residual_key, residual, self.scales * factor)], axis=1)

    def velocity_states(self, poses):
        return self.inner.velocity_states(poses)

    def log_transition(self, previous, states):
        inner_previous, residual_previous = self._split(previous)
        inner, residual = self._split(states)
        walk = gaussian_log_density(residual, self._mean(residual_previous), self.scales)
        return self.inner.log_transition(inner_previous, inner) + walk

    def noise_scales(self):
        inner = self.inner.noise_scales()
        return jnp.concatenate([inner, self.scales.astype(inner.dtype)])


def fit_pose_residual(dynamics: AbstractDynamics, validation, scale: float, *, floor: float = 1e-3,
                      decay: float = 1.0, target=None) -> PoseResidual:
    """``dynamics`` with a residual whose step scales are ``scale`` times the RMS frame-to-frame
    step of the validation poses' joint angles (one (T, D) array or a list of them): the pose
    random walk's steps, what SIR diffuses by; ``target`` (A,) the offset it fades to (None: 0).

    (The RMS step of the validation poses' own residual from their manifold points, the other
    candidate, is 0.6-1.0 times these on the shared walks: a pose's nearest manifold point moves
    in jumps, so it is no smaller a scale.)"""
    if not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"the residual's scale must be a positive number, got {scale!r}")
    first = validation[0] if isinstance(validation, (list, tuple)) and validation else validation
    sequences = motion_sequences(validation, np.shape(first)[-1])
    if sequences[0].shape[1] <= GLOBAL_DOFS:
        raise ValueError(f"poses need joint angles after the {GLOBAL_DOFS} global entries, got {sequences[0].shape[1]} entries")
    steps = scale * rms_step(sequences, floor)[GLOBAL_DOFS:]
    if target is not None and np.shape(target) != steps.shape:
        raise ValueError(f"the residual's target must hold one offset per joint angle ({steps.shape[0]}), got shape {np.shape(target)}")
    target = None if target is None else jnp.asarray(target, jnp.float64)
    return PoseResidual(dynamics, jnp.asarray(steps, jnp.float64), decay, target)

"""A gait rate per particle for dynamics that step along a learned cycle: cadence found online.

A manifold tracker's dynamics advance the gait by one training frame a frame (GLE-GbPF's graph
walk, 002 Alg. 1) or by the GPDM's mean step (001 eqs. 7-9): the training subjects' cadence.
A person who walks 20 % faster or slower than them drifts out of phase and the likelihood has
to pull every particle back each frame. On the shared walks the gait period is 55-56 frames at
60 Hz for CMU 16, 64-73 for CMU 07 and 67-68 for CMU 35 (``manifold.gait_period``).

``GaitRate`` gives each particle a rate ``rho`` and a phase accumulator ``a`` in [0, 1):

    log rho_t = clip(log rho_{t-1} + N(0, step^2), log low, log high)
    n_t = floor(a_{t-1} + rho_t),   a_t = a_{t-1} + rho_t - n_t,

and moves the wrapped dynamics ``n_t`` times (0, 1 or 2: the rate is bounded below 2): once is
the wrapped dynamics unchanged; twice is two of its steps; zero is its annealing move at factor
1 (``perturb``: its noise about the same point, the phase held). Particles start with
``log rho_0 ~ N(0, spread^2)`` and ``a_0 ~ U(0, 1)``, so the filter carries several cadences
and the likelihood keeps those that stay in phase with the person: 003 sec. 5's
second-order idea applied to the phase rather than to the pose.

The move is drawn from the transition itself, so its importance correction is the wrapped
dynamics' (zero for the built-in ones). No transition density is defined (a mixture over
``n_t``), so gradient-refined moves are refused on it.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._base import AbstractDynamics, AbstractDynamicsWrapper

RATE_ENTRIES = 2  # log rate, phase accumulator


class GaitRate(AbstractDynamicsWrapper):
    """``inner`` stepped ``n_t`` times a frame at a per-particle rate (module docstring).

    State ``[inner state (S), log rho, a]``.

    Attributes:
        inner: the wrapped dynamics (meant for those that advance along a cycle each frame).
        spread: standard deviation of the particles' initial log rate.
        step: standard deviation of the log rate's step per frame.
        low, high: bounds of the rate (``0 < low <= 1 <= high < 2``).
    """

    inner: AbstractDynamics
    spread: float = eqx.field(static=True, default=0.15)
    step: float = eqx.field(static=True, default=0.01)
    low: float = eqx.field(static=True, default=0.6)
    high: float = eqx.field(static=True, default=1.6)

    def __check_init__(self):
        if not isinstance(self.inner, AbstractDynamics):
            raise TypeError(f"GaitRate wraps an AbstractDynamics, got {type(self.inner).__name__}")
        if isinstance(self.inner, GaitRate):
            raise ValueError("the dynamics already carries a gait rate")
        for name in ("spread", "step"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ValueError(f"the gait rate's {name} must be a finite number >= 0, got {value!r}")
        if not 0 < self.low <= 1 <= self.high < 2:
            raise ValueError(f"the gait rate's bounds must satisfy 0 < low <= 1 <= high < 2, got low {self.low!r}, high {self.high!r}")

    def own_size(self) -> int:
        return RATE_ENTRIES

    def _split(self, states):
        return states[:, :-RATE_ENTRIES], states[:, -2], states[:, -1]

    def _clip(self, log_rate):
        return jnp.clip(log_rate, np.log(self.low), np.log(self.high))

    def init(self, key, pose, num_particles):
        inner_key, rate_key, phase_key = jax.random.split(key, 3)
        inner = self.inner.init(inner_key, pose, num_particles)
        log_rate = self._clip(self.spread * jax.random.normal(rate_key, (num_particles,), inner.dtype))
        phase = jax.random.uniform(phase_key, (num_particles,), inner.dtype)
        return jnp.concatenate([inner, log_rate[:, None], phase[:, None]], axis=1)

    def to_pose(self, states):
        return self.inner.to_pose(states[:, :-RATE_ENTRIES])

    def rates(self, states) -> jax.Array:
        """(N,) each particle's gait rate (training frames a frame)."""
        return jnp.exp(states[:, -2])

    def propose(self, key, previous):
        rate_key, stay_key, first_key, second_key = jax.random.split(key, 4)
        inner, log_rate, phase = self._split(previous)
        log_rate = self._clip(log_rate + self.step * jax.random.normal(rate_key, log_rate.shape, log_rate.dtype))
        total = phase + jnp.exp(log_rate)
        steps = jnp.floor(total)
        stay = self.inner.perturb(stay_key, inner, 1.0)
        once, first_correction = self.inner.propose(first_key, inner)
        twice, second_correction = self.inner.propose(second_key, once)
        moved = jnp.where((steps < 1)[:, None], stay, jnp.where((steps < 2)[:, None], once, twice))
        correction = jnp.where(steps < 1, 0.0, jnp.where(steps < 2, first_correction, first_correction + second_correction))
        return jnp.concatenate([moved, log_rate[:, None], (total - steps)[:, None]], axis=1), correction

    def perturb(self, key, states, factor):
        inner, log_rate, phase = self._split(states)
        return jnp.concatenate([self.inner.perturb(key, inner, factor), log_rate[:, None], phase[:, None]], axis=1)

    def velocity_states(self, poses):
        return self.inner.velocity_states(poses)

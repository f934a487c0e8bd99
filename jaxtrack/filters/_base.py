"""The filter interface, the state every filter carries and the info every step reports.

A filter is an equinox Module with two pure methods,

    init(key, initial_pose (D,)) -> FilterState
    step(key, state, observation) -> (FilterState, StepInfo)

built from a dynamics (``jaxtrack.dynamics``), a likelihood (``jaxtrack.likelihood``) and the
one SMC layer of ``smc_layer``; ``run_filter`` scans ``step`` over the frames of a sequence.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Any

import equinox as eqx

from .._custom_types import Array, Bool, Float, PRNGKeyArray
from ..dynamics import AbstractDynamics
from ..likelihood import AbstractLikelihood
from ._refine import LangevinRefinement


class FilterState(eqx.Module):
    """Particles (a leading axis of N) and their log-weights (not necessarily normalised).

    ``particles`` is (N, S) in the state space of the filter's dynamics: poses for the
    pose-space dynamics, (global entries, latent point) for the latent ones.
    """

    particles: Float[Array, "n s"]
    log_weights: Float[Array, " n"]


class StepInfo(eqx.Module):
    """What a step reports for its frame.

    Attributes:
        estimate: (D,) the pose estimate.
        ess: effective sample size of the final weights.
        log_evidence: ``ln mean_i p(I_t | x_i)`` over the first layer's proposed particles, the
            estimate of the likelihood increment ``ln p(I_t | I_1:t-1)`` for exact proposals.
        betas: (M,) annealing exponents per layer (ones for unannealed filters).
        survival: (M,) survival rate ``ESS / N`` per layer.
        degenerate: whether any layer's weights were all ``-inf``/NaN (then made uniform).
        refine: the ``RefineInfo`` of gradient-refined moves (None without them).
        restarted: whether the filter restarted its particles this frame (``RecoveringSIR``;
            None for filters that never do).
    """

    estimate: Float[Array, " d"]
    ess: Float[Array, ""]
    log_evidence: Float[Array, ""]
    betas: Float[Array, " m"]
    survival: Float[Array, " m"]
    degenerate: Bool[Array, ""]
    refine: Any = None
    restarted: Any = None


class AbstractFilter(eqx.Module):
    """A particle filter: pure ``init`` and ``step`` (module docstring).

    Concrete filters validate their settings in ``__check_init__``, so no way of constructing
    one skips the checks. Randomness comes only from the keys passed in.
    """

    @abc.abstractmethod
    def init(self, key: PRNGKeyArray, initial_pose: Float[Array, " dofs"]) -> FilterState:
        """The state at frame 0 (000 Alg. 1 line 1: N copies of the initial pose's state)."""

    @abc.abstractmethod
    def step(self, key: PRNGKeyArray, state: FilterState, observation: Any) -> tuple[FilterState, StepInfo]:
        """One frame: resample, propagate, weight, normalise, estimate (see ``smc_layer``)."""


class AbstractComposedFilter(AbstractFilter):
    """A filter composed of a dynamics and a likelihood (``SIR``, ``APF``), optionally with
    gradient-refined moves, that says how to take new ones: ``with_dynamics``,
    ``with_likelihood`` and ``with_refinement`` return a new filter built (and validated) by its
    own constructor, so the pipeline wraps a tracker's dynamics (a velocity, a residual) or adds
    refinement without reaching into its fields."""

    dynamics: eqx.AbstractVar[AbstractDynamics]
    likelihood: eqx.AbstractVar[AbstractLikelihood]
    # and a field ``refine: LangevinRefinement | None`` (with a default, so not an AbstractVar)

    def with_dynamics(self, dynamics: AbstractDynamics):
        """This filter with ``dynamics`` in place of its own (checked as at construction)."""
        return dataclasses.replace(self, dynamics=dynamics)

    def with_likelihood(self, likelihood: AbstractLikelihood):
        """This filter with ``likelihood`` in place of its own."""
        return dataclasses.replace(self, likelihood=likelihood)

    def with_refinement(self, refine: LangevinRefinement | None):
        """This filter with gradient-refined moves ``refine`` (None: none); raises
        ``ValueError`` if its dynamics define no transition density (``is_refinable``)."""
        return dataclasses.replace(self, refine=refine)


def check_particles(num_particles) -> None:
    if isinstance(num_particles, bool) or not isinstance(num_particles, int) or num_particles < 1:
        raise ValueError(f"num_particles must be a positive integer, got {num_particles!r}")

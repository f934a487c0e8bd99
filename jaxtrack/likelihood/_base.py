"""The likelihood interface: a batch of poses and one frame's observation in, one
log-likelihood per pose out. Sums of likelihoods are likelihoods (multiple cues)."""

from __future__ import annotations

import abc
from collections.abc import Callable
from typing import Any, ClassVar

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..errors import TrackingError


class AbstractLikelihood(eqx.Module):
    """``ln p(observation | pose)`` for a batch of poses, up to a constant shared by the batch.

    Subclasses implement ``log_likelihood``; calling the module is the same thing. Every
    filter scores its particles through this interface (after mapping its states to poses).
    ``a + b`` is the ``SumLikelihood`` of two likelihoods (independent cues).

    ``reads_observation`` is False for a prior on the pose that ignores the frame (e.g. the
    ground plane's): such a term is kept as it is where the observation is transformed (the
    coarse-to-fine likelihood).
    """

    reads_observation: ClassVar[bool] = True

    @abc.abstractmethod
    def log_likelihood(self, poses: Float[Array, "particles dofs"], observation: Any) -> Float[Array, " particles"]:
        """Log-likelihood of each of N poses given one frame's observation (any pytree, e.g.
        silhouettes (views, H, W)). Pure: jit- and vmap-safe, and differentiable in ``poses``
        where the likelihood is smooth. May return ``-inf`` for an impossible pose."""

    def __call__(self, poses: Float[Array, "particles dofs"], observation: Any) -> Float[Array, " particles"]:
        values = self.log_likelihood(poses, observation)
        # Checked when traced, before anything runs: a wrong shape would otherwise broadcast silently.
        n = poses.shape[0]
        if getattr(values, "shape", None) != (n,) or not jnp.issubdtype(values.dtype, jnp.floating):
            found = f"shape {getattr(values, 'shape', None)}" if getattr(values, "shape", None) != (n,) else f"{values.dtype} values"
            raise TrackingError(f"the likelihood {type(self).__name__} returned {found} for {n} particles; it must return one "
                                f"floating log-likelihood per particle, shape ({n},)")
        return values

    def __add__(self, other: AbstractLikelihood) -> SumLikelihood:
        if not isinstance(other, AbstractLikelihood):
            return NotImplemented
        return SumLikelihood((self, other))


class SumLikelihood(AbstractLikelihood):
    """``sum_k ln p_k(observation | pose)``: independent cues multiply their likelihoods.

    Every term receives the same observation; a likelihood that needs its own part of a
    multi-cue observation reads it from a pytree (e.g. a dict of arrays).
    """

    terms: tuple[AbstractLikelihood, ...]

    def __check_init__(self):
        if not self.terms or not all(isinstance(t, AbstractLikelihood) for t in self.terms):
            raise TypeError("SumLikelihood needs one or more AbstractLikelihood terms")

    def log_likelihood(self, poses, observation):
        total = self.terms[0].log_likelihood(poses, observation)
        for term in self.terms[1:]:
            total = total + term.log_likelihood(poses, observation)
        return total


class ObservationPart(AbstractLikelihood):
    """``term`` scoring one entry of a frame's observation dict: ``observation[key]``. What lets
    independent cues with observations of their own (silhouettes, keypoints) be summed:
    ``ObservationPart(silhouettes, "silhouettes") + ObservationPart(keypoints, "keypoints")``
    on ``{"silhouettes": (C, H, W), "keypoints": (C, 15, 3)}`` frames."""

    term: AbstractLikelihood
    key: str = eqx.field(static=True)

    def __check_init__(self):
        if not isinstance(self.term, AbstractLikelihood):
            raise TypeError(f"ObservationPart wraps an AbstractLikelihood, got {type(self.term).__name__}")

    @property
    def reads_observation(self) -> bool:  # a prior stays a prior
        return self.term.reads_observation

    def log_likelihood(self, poses, observation):
        if not isinstance(observation, dict) or self.key not in observation:
            raise TrackingError(f"ObservationPart({type(self.term).__name__}, {self.key!r}) needs a dict observation with the "
                                f"entry {self.key!r}, got {type(observation).__name__}")
        return self.term.log_likelihood(poses, observation[self.key])


class FunctionLikelihood(AbstractLikelihood):
    """A plain function ``(poses (N, D), observation) -> (N,)`` as a likelihood (e.g. a
    Gaussian stand-in in tests). The function is static: closing over arrays you want to
    change without recompiling is better done in a Module of your own."""

    function: Callable = eqx.field(static=True)

    def log_likelihood(self, poses, observation):
        return jnp.asarray(self.function(poses, observation))


class AbstractEvidenceLikelihood(AbstractLikelihood):
    """A likelihood that first summarises a frame's observation into evidence fitted from
    starting poses, then scores poses against that evidence (004 sec. 6: blobs fitted to the
    visual hull). ``log_likelihood`` fits from the poses' mean alone; a filter that knows better
    starts (004 sec. 6.1: the last estimate and the prediction) calls ``fit_evidence`` and
    ``score`` itself, through ``evidence_scorer``."""

    @abc.abstractmethod
    def fit_evidence(self, observation: Any, starts: Float[Array, "starts dofs"]) -> Any:
        """The frame's evidence fitted from each of S starting poses, the best fit kept (a pytree)."""

    @abc.abstractmethod
    def score(self, poses: Float[Array, "particles dofs"], evidence: Any) -> Float[Array, " particles"]:
        """Log-likelihood of each of N poses against fitted evidence."""

    def log_likelihood(self, poses, observation):
        return self.score(poses, self.fit_evidence(observation, jnp.mean(poses, axis=0)[None]))


def evidence_scorer(likelihood: AbstractLikelihood, observation: Any, starts: Float[Array, "starts dofs"]) -> Callable:
    """``poses (N, D) -> (N,)``: the likelihood with the evidence of every
    ``AbstractEvidenceLikelihood`` among its terms (through ``SumLikelihood`` and
    ``ObservationPart``) fitted once from ``starts`` (S, D); any other term as it is."""
    if isinstance(likelihood, AbstractEvidenceLikelihood):
        evidence = likelihood.fit_evidence(observation, starts)
        return lambda poses: likelihood.score(poses, evidence)
    if isinstance(likelihood, SumLikelihood):
        scorers = [evidence_scorer(term, observation, starts) for term in likelihood.terms]

        def total(poses):  # in SumLikelihood's order, so one start gives its values exactly
            value = scorers[0](poses)
            for scorer in scorers[1:]:
                value = value + scorer(poses)
            return value

        return total
    if isinstance(likelihood, ObservationPart) and isinstance(observation, dict) and likelihood.key in observation:
        return evidence_scorer(likelihood.term, observation[likelihood.key], starts)
    return lambda poses: likelihood.log_likelihood(poses, observation)


def has_evidence(likelihood: AbstractLikelihood) -> bool:
    """Whether any term of ``likelihood`` is an ``AbstractEvidenceLikelihood``."""
    if isinstance(likelihood, AbstractEvidenceLikelihood):
        return True
    if isinstance(likelihood, SumLikelihood):
        return any(has_evidence(term) for term in likelihood.terms)
    return isinstance(likelihood, ObservationPart) and has_evidence(likelihood.term)


def lost_threshold(likelihood: AbstractLikelihood) -> float | None:
    """The log-likelihood under which a filter that can restart deems itself lost: the sum of the
    ``lost_below`` of the likelihood's evidence terms (through ``SumLikelihood`` and
    ``ObservationPart``; a term without one contributes 0, its best value), None when no term
    has one."""
    if isinstance(likelihood, SumLikelihood):
        found = [lost_threshold(term) for term in likelihood.terms]
        return None if all(f is None for f in found) else float(sum(f for f in found if f is not None))
    if isinstance(likelihood, ObservationPart):
        return lost_threshold(likelihood.term)
    value = getattr(likelihood, "lost_below", None) if isinstance(likelihood, AbstractEvidenceLikelihood) else None
    return None if value is None else float(value)


def as_likelihood(likelihood) -> AbstractLikelihood:
    """An ``AbstractLikelihood`` as it is, a plain callable wrapped in ``FunctionLikelihood``."""
    if isinstance(likelihood, AbstractLikelihood):
        return likelihood
    if callable(likelihood):
        return FunctionLikelihood(likelihood)
    raise TypeError(f"a likelihood must be an AbstractLikelihood or a callable, got {type(likelihood).__name__}")


def set_references(likelihood, pose, observation):
    """``likelihood`` with every term that keeps a reference of the person's appearance (a
    ``with_reference(pose, observation)`` method: 001's colour histograms, 003's templates) given
    its reference at ``pose`` (D,) on one frame's ``observation``."""
    import jax

    def refers(leaf) -> bool:
        return isinstance(leaf, AbstractLikelihood) and callable(getattr(leaf, "with_reference", None))

    return jax.tree.map(lambda leaf: leaf.with_reference(pose, observation) if refers(leaf) else leaf, likelihood, is_leaf=refers)

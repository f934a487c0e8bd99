"""SIR that fits its likelihood's evidence from the last estimate and the prediction, and
restarts a lost tracker (004 sec. 6.1).

Per frame, as ``SIR``: resample by the previous weights, ``s_t ~ dynamics.propose(s_{t-1})``.
Then, where the likelihood summarises the frame into evidence fitted from starting poses
(``likelihood.AbstractEvidenceLikelihood``: 004's blobs fitted to the visual hull), that
evidence is fitted once from two starts, the previous frame's estimate and the mean of the
predicted particles, and the better fit kept: "initialising the blob fitting from the last
tracked pose can be insufficient for fast movements ... therefore we also initialise [it] with
appearance models predicted by the VLMM and retain the best result" (004 sec. 6.1). Every
particle is scored against it.

With ``lost_below`` set, a frame whose best particle scores below it is deemed lost (004: "if
the best fitting mixture provides a poor fit then the tracker is deemed lost"; here the poor fit
is read where it matters, as the best particle's log-likelihood against the evidence): the
particles are redrawn from the dynamics' restart distribution (``dynamics.restart_states``:
the VLMM's initial states ``s``), their roots kept, and scored instead.

With a likelihood that has no evidence and ``lost_below=None`` this is ``SIR`` exactly (the same
keys, the same numbers).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..dynamics import is_restartable, restart_states
from ..likelihood import evidence_scorer
from ._base import FilterState, StepInfo
from ._resampling import get_resampler
from ._sir import AbstractOneLayerFilter, refine_and_report
from ._smc import check_layer_shapes, layer_keys, weigh_layer

RESTART_STREAM = 1299709  # fold_in tag of a frame's restart key


class RecoveringSIR(AbstractOneLayerFilter):
    """``SIR`` with 004 sec. 6.1's two-start evidence and restarts (module docstring).

    Attributes:
        dynamics, likelihood, num_particles, resampler, estimator, refine: as ``SIR``'s.
        lost_below: the best particle's log-likelihood under which a frame is deemed lost and
            the particles restart (static; None: never). Needs restartable dynamics
            (``dynamics.is_restartable``).
        starts: where an evidence likelihood's fit starts (static): "prediction", the predicted
            particles' mean pose, or "both", that and the previous estimate (004 sec. 6.1).
    """

    lost_below: float | None = eqx.field(static=True, default=None)
    starts: str = eqx.field(static=True, default="prediction")

    def __check_init__(self):  # the parts are checked by AbstractOneLayerFilter's
        if self.starts not in ("prediction", "both"):
            raise ValueError(f"starts must be 'prediction' or 'both', got {self.starts!r}")
        if self.lost_below is not None and not is_restartable(self.dynamics):
            raise ValueError(f"lost_below needs dynamics with a restart distribution; {type(self.dynamics).__name__} has none "
                             "(it is not an AbstractRestartableDynamics, all the way in)")

    def step(self, key, state: FilterState, observation) -> tuple[FilterState, StepInfo]:
        resample = get_resampler(self.resampler)
        resample_key, move_key = layer_keys(key, 0)
        ancestors = resample(resample_key, state.log_weights)
        moved, log_correction = self.dynamics.propose(move_key, state.particles[ancestors])
        predicted = jnp.mean(self.dynamics.to_pose(moved), axis=0)
        starts = [predicted]
        if self.starts == "both":
            starts.insert(0, self.estimator(state.log_weights, state.particles, self.dynamics))
        score = evidence_scorer(self.likelihood, observation, jnp.stack(starts).astype(moved.dtype))

        def log_likelihood(s):
            return score(self.dynamics.to_pose(s))

        log_lik = log_likelihood(moved)
        check_layer_shapes(state.particles, moved, log_correction, log_lik)
        restarted = None
        if self.lost_below is not None:
            restarted = ~(jnp.max(jnp.where(jnp.isnan(log_lik), -jnp.inf, log_lik)) >= self.lost_below)

            def restart(_):
                fresh = restart_states(self.dynamics, jax.random.fold_in(key, RESTART_STREAM), moved)
                return fresh, jnp.zeros_like(log_correction), log_likelihood(fresh)

            moved, log_correction, log_lik = jax.lax.cond(restarted, restart, lambda _: (moved, log_correction, log_lik), None)
        log_weights, layer = weigh_layer(log_lik, log_correction, ancestors)
        return refine_and_report(self, key, state, moved, log_weights, layer, log_likelihood, resample, restarted)

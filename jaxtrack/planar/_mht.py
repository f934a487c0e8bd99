"""Paper 003's second baseline (sec. 5.2), registered as ``mht2d``: a multiple-hypothesis tracker
after Cham and Rehg on the 6-state shoulder-anchored arm chain.

It keeps ``modes`` hypotheses (003: 10). Each frame, every mode is predicted by the AR(2) model
and ``samples`` draws are made around each prediction (its noise); each draw descends the
matching cost ``E(x) = sum_m (1 - NCC_m(x))^2`` over the markers by ``iterations`` damped
Gauss-Newton steps, ``dx = -(J^T J + lambda I)^-1 J^T r``, each step's length chosen by the
Armijo rule (halved until ``E`` falls by at least ``1e-4`` times the predicted decrease, at
most ``backtracks`` times; no step if none does). The descended draws are weighted by the
template likelihood (003 eq. 7), as 003 weights Condensation's particles, and the best
``modes`` distinct ones (no two closer than ``separation`` in the state, radians / scale
units) become the next modes. The estimate is the best mode.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ._arm_chain import ArmAnchor, arm_anchor, arm_markers, arm_state_from_markers
from ._arm_condensation import _cast
from ._base import AbstractTracker2D, Tracker2DRecipe, clean_log_weights, marker_log_weights, register_tracker2d, uniform_start
from ._model import ArmAR
from ._silhouette import SILHOUETTE_WEIGHT, SilhouetteChamfer, silhouette_chamfer
from ._templates import MarkerTemplates, marker_templates

ARMIJO = 1e-4


def gauss_newton(residual, x0, *, iterations: int, backtracks: int, damping: float):
    """Damped Gauss-Newton with the Armijo rule on ``E = ||residual(x)||^2`` from ``x0``."""

    def cost(x):
        r = residual(x)
        return jnp.sum(r * r)

    def one(x, _):
        r = residual(x)
        J = jax.jacfwd(residual)(x)
        JtJ = J.T @ J
        lam = damping * (jnp.trace(JtJ) / x.shape[0] + 1e-9)
        gradient = J.T @ r
        dx = -jnp.linalg.solve(JtJ + lam * jnp.eye(x.shape[0], dtype=x.dtype), gradient)
        e0 = jnp.sum(r * r)
        lengths = 0.5 ** jnp.arange(backtracks + 1, dtype=x.dtype)
        costs = jax.vmap(lambda a: cost(x + a * dx))(lengths)
        accept = (costs <= e0 + ARMIJO * lengths * 2.0 * jnp.dot(gradient, dx)) & jnp.isfinite(costs)
        first = jnp.argmax(accept)
        step = jnp.where(jnp.any(accept), lengths[first], 0.0)
        x_new = x + step * dx
        return jnp.where(jnp.all(jnp.isfinite(x_new)), x_new, x), None

    return jax.lax.scan(one, x0, None, length=iterations)[0]


def distinct_best(log_weights, states, count: int, separation: float):
    """Indices of the ``count`` best states, each at least ``separation`` (max-norm) from those
    chosen before it (fewer distinct ones: the best repeated)."""

    def pick(taken, _):
        distance = jnp.min(jnp.where(taken[:, None] >= 0, jnp.max(jnp.abs(states[None] - states[jnp.maximum(taken, 0)][:, None]), -1),
                                     jnp.inf), axis=0)
        score = jnp.where(distance >= separation, log_weights, -jnp.inf)
        best = jnp.where(jnp.any(jnp.isfinite(score)), jnp.argmax(score), jnp.argmax(log_weights))
        slot = jnp.argmin(taken >= 0)
        return taken.at[slot].set(best.astype(jnp.int32)), best

    taken = jnp.full(count, -1, jnp.int32)
    return jax.lax.scan(pick, taken, None, length=count)[1]


class MultipleHypothesisTracker(AbstractTracker2D):
    """Attributes:
        anchor, ar, start: as ``ArmCondensation``.
        modes, samples, iterations, backtracks: sizes (static).
        damping, separation, noise_scale: settings.
    """

    anchor: ArmAnchor
    ar: ArmAR
    start: Float[Array, " 6"]
    templates: MarkerTemplates
    silhouette: SilhouetteChamfer
    damping: float
    separation: float
    modes: int = eqx.field(static=True)
    samples: int = eqx.field(static=True)
    iterations: int = eqx.field(static=True)
    backtracks: int = eqx.field(static=True)
    template_update: float = eqx.field(static=True, default=0.0)

    def init(self, key):
        del key
        return uniform_start(self.start, self.modes, (2,))  # (x_t, x_{t-1}) per mode

    def step(self, state, templates, frame, key):
        modes, _log_weights = state
        now, before = modes[:, 0], modes[:, 1]
        predicted = self.ar.predict(now, before)  # (K, 6)
        noise = self.ar.noise * jax.random.normal(key, (self.modes, self.samples, 6), now.dtype)
        noise = noise.at[:, 0].set(0.0)  # each mode's own prediction is one of its draws
        draws = (predicted[:, None] + noise).reshape(-1, 6)
        parents = jnp.repeat(now, self.samples, axis=0)

        def residual(x):
            markers = arm_markers(x, self.anchor)
            r = 1.0 - templates.correlations(frame.grey, markers)
            if frame.silhouette is None:
                return r
            # ln p = scale * mean NCC - sum s^2 ~ const - (scale / M) (sum (1 - NCC) + (M / scale) sum s^2)
            s = self.silhouette.residuals(frame.silhouette, markers).astype(r.dtype)
            return jnp.concatenate([r, jnp.sqrt(r.shape[0] / templates.scale) * s])

        descended = jax.vmap(lambda x: gauss_newton(residual, x, iterations=self.iterations, backtracks=self.backtracks,
                                                    damping=self.damping))(draws)
        markers = arm_markers(descended, self.anchor)
        log_weights = marker_log_weights(templates, self.silhouette, frame, markers)
        chosen = distinct_best(log_weights, descended, self.modes, self.separation)
        new_modes = jnp.stack([descended[chosen], parents[chosen]], axis=1)
        return (new_modes, clean_log_weights(log_weights[chosen])), arm_markers(descended[chosen[0]], self.anchor)


def make_mht(model, first_image, first_markers, *, modes: int = 10, samples: int = 3, iterations: int = 5, backtracks: int = 6,
             damping: float = 1e-2, separation: float = 0.05, likelihood_scale: float = 20.0,
             template_update: float = 0.0, silhouette_weight: float = SILHOUETTE_WEIGHT) -> MultipleHypothesisTracker:
    """003's MHT baseline on an ``SPMModel``'s AR(2), from the first frame and its markers; on
    frames with masks the matching cost gains the silhouette's residuals (``silhouette_weight``)."""
    for name, value in (("modes", modes), ("samples", samples), ("iterations", iterations)):
        if int(value) < 1:
            raise ValueError(f"{name} must be at least 1, got {value}")
    templates = marker_templates(first_image, first_markers, scale=likelihood_scale)
    dtype = templates.templates.dtype
    anchor = _cast(arm_anchor(jnp.asarray(first_markers, dtype)), dtype)
    return MultipleHypothesisTracker(
        anchor=anchor, ar=_cast(model.arm_ar, dtype), start=arm_state_from_markers(anchor.markers, anchor), templates=templates,
        silhouette=silhouette_chamfer(weight=silhouette_weight), damping=float(damping), separation=float(separation),
        modes=int(modes), samples=int(samples), iterations=int(iterations), backtracks=int(backtracks),
        template_update=float(template_update),
    )


register_tracker2d(Tracker2DRecipe(
    "mht2d", "003's baseline: multiple-hypothesis tracking (damped Gauss-Newton, Armijo rule) on the arm chain",
    make_mht, options={"modes": 10, "samples": 3, "iterations": 5, "backtracks": 6, "damping": 1e-2, "separation": 0.05,
                       "likelihood_scale": 20.0, "template_update": 0.0, "silhouette_weight": SILHOUETTE_WEIGHT},
))

"""Paper 003's first baseline (sec. 5.2), registered as ``condensation2d``: standard Condensation
(Isard and Blake) on the 6-state shoulder-anchored arm chain (``_arm_chain``), predicting each
particle by the second-order autoregressive model (``ArmAR``) plus its noise, weighting by the
template likelihood (003 eq. 7), estimating the weighted mean state. 003 uses 1000 particles.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..filters import weighted_mean
from ._arm_chain import ArmAnchor, arm_anchor, arm_markers, arm_state_from_markers
from ._base import AbstractTracker2D, Tracker2DRecipe, marker_log_weights, register_tracker2d, resample_indices, uniform_start
from ._model import ArmAR
from ._silhouette import SILHOUETTE_WEIGHT, SilhouetteChamfer, silhouette_chamfer
from ._templates import MarkerTemplates, marker_templates


class ArmCondensation(AbstractTracker2D):
    """Attributes:
        anchor: the fixed torso and the arms' reference lengths.
        ar: the AR(2) prediction.
        start: (6,) the first frame's arm-chain state.
        particles: N (static).
    """

    anchor: ArmAnchor
    ar: ArmAR
    start: Float[Array, " 6"]
    templates: MarkerTemplates
    silhouette: SilhouetteChamfer
    particles: int = eqx.field(static=True)
    template_update: float = eqx.field(static=True, default=0.0)

    def init(self, key):
        del key
        return uniform_start(self.start, self.particles, (2,))  # (x_t, x_{t-1}) per particle

    def step(self, state, templates, frame, key):
        states, log_weights = state
        k_resample, k_noise = jax.random.split(key)
        states = states[resample_indices(k_resample, log_weights)]
        now, before = states[:, 0], states[:, 1]
        new = self.ar.predict(now, before) + self.ar.noise * jax.random.normal(k_noise, now.shape, now.dtype)
        markers = arm_markers(new, self.anchor)
        log_weights = marker_log_weights(templates, self.silhouette, frame, markers)
        estimate = weighted_mean(log_weights, new)
        return (jnp.stack([new, now], axis=1), log_weights), arm_markers(estimate, self.anchor)


def _cast(tree, dtype):
    return jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, tree)


def make_arm_condensation(model, first_image, first_markers, *, particles: int = 1000, noise_scale: float = 1.0,
                          likelihood_scale: float = 20.0, template_update: float = 0.0,
                          silhouette_weight: float = SILHOUETTE_WEIGHT) -> ArmCondensation:
    """003's standard Condensation baseline on an ``SPMModel``'s AR(2) (``noise_scale`` times
    its noise), from the first frame (grey (H, W)) and its markers (9, 2); ``silhouette_weight``
    weighs the silhouette term on frames with masks (``SilhouetteChamfer``)."""
    if int(particles) < 1:
        raise ValueError(f"particles must be at least 1, got {particles}")
    templates = marker_templates(first_image, first_markers, scale=likelihood_scale)
    dtype = templates.templates.dtype
    anchor = _cast(arm_anchor(jnp.asarray(first_markers, dtype)), dtype)
    ar = _cast(model.arm_ar, dtype)
    ar = eqx.tree_at(lambda a: a.noise, ar, ar.noise * noise_scale)
    return ArmCondensation(anchor=anchor, ar=ar, start=arm_state_from_markers(anchor.markers, anchor), templates=templates,
                           silhouette=silhouette_chamfer(weight=silhouette_weight), particles=int(particles),
                           template_update=float(template_update))


register_tracker2d(Tracker2DRecipe(
    "condensation2d", "003's baseline: Condensation on the 6-state shoulder-anchored arm chain with an AR(2) model",
    make_arm_condensation, options={"particles": 1000, "noise_scale": 1.0, "likelihood_scale": 20.0, "template_update": 0.0,
                                    "silhouette_weight": SILHOUETTE_WEIGHT},
))

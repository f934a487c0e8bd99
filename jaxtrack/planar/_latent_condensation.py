"""Paper 003's modified Condensation (Algorithm 2), registered as ``latentpf2d``.

Particles live in the manifold's latent space (plus the pelvis's image position and the log
scale, which 003 keeps in its state vector and a view-sphere manifold cannot know): resample
by weight, predict by the random walk of 003 eq. 6 (``x += nu * N(0, I)``, ``nu`` learned from
the training sequences' latent steps; the global part by ``translation_sd`` times the
spine-to-neck height and ``scale_sd``), weight by the template likelihood (003 eq. 7) of the
markers ``mu(x)`` gives, and estimate ``mu(E[x])``. 003 uses 200 particles.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..filters import weighted_mean
from ._base import AbstractTracker2D, Tracker2DRecipe, marker_log_weights, register_tracker2d, resample_indices, uniform_start
from ._silhouette import SILHOUETTE_WEIGHT, SilhouetteChamfer, silhouette_chamfer
from ._spm import SPM_REFERENCE_LENGTHS, spine_to_neck, spm_features, spm_forward, spm_from_markers, spm_state
from ._templates import MarkerTemplates, marker_templates


class LatentCondensation(AbstractTracker2D):
    """Attributes:
        predictor: the manifold's predictive map (latent -> SPM features).
        start: (q + 3,) the first frame's [latent, pelvis u, v, log scale].
        step_sd: (q + 3,) the random walk's standard deviations.
        particles: N (static).
    """

    predictor: eqx.Module
    start: Float[Array, " s"]
    step_sd: Float[Array, " s"]
    templates: MarkerTemplates
    silhouette: SilhouetteChamfer
    particles: int = eqx.field(static=True)
    template_update: float = eqx.field(static=True, default=0.0)
    estimate: str = eqx.field(static=True, default="latent-mean")

    def markers(self, states: Float[Array, "n s"]) -> Float[Array, "n 9 2"]:
        q = states.shape[-1] - 3
        features, _variance = self.predictor(states[:, :q])
        return spm_forward(spm_state(features, states[:, q : q + 2], states[:, q + 2]))

    def init(self, key):
        del key
        return uniform_start(self.start, self.particles)

    def step(self, state, templates, frame, key):
        states, log_weights = state
        k_resample, k_walk = jax.random.split(key)
        states = states[resample_indices(k_resample, log_weights)]
        states = states + self.step_sd * jax.random.normal(k_walk, states.shape, states.dtype)
        markers = self.markers(states)
        log_weights = marker_log_weights(templates, self.silhouette, frame, markers)
        if self.estimate == "marker-mean":
            return (states, log_weights), weighted_mean(log_weights, markers)
        return (states, log_weights), self.markers(weighted_mean(log_weights, states)[None])[0]


START_METHODS = ("projection", "fitted")


def start_state(model, first_markers, *, method: str = "projection",
                candidates=(1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7)) -> np.ndarray:
    """[latent, pelvis u, v, log scale] of the first frame's markers (9, 2) pixels.

    ``method="projection"`` (003's inverse map): the scale tried as the spine seen at each
    ``candidates`` share of its length, each pose encoded by projection onto the manifold (one
    batched ``encode``), the one whose decoded markers fit best kept. ``"fitted"``: the decoded
    markers fitted to the given ones, by Levenberg-Marquardt (optimistix) on the latent point,
    the pelvis and the scale together, from the best of the projection and every training
    point's latent position at each scale candidate (the decoded pose is then 3-6 px from the
    markers where the projection leaves 5-29 px, docs/planar.md).
    """
    if method not in START_METHODS:
        raise ValueError(f"start must be one of {START_METHODS}, got {method!r}")
    projected = _projection_start(model, first_markers, candidates)
    if method == "projection":
        return projected
    return _fitted_start(model, first_markers, projected, candidates)


def _decoded(predictor, x, q):
    features, _ = predictor(x[None, :q])
    return spm_forward(spm_state(features[0], x[q : q + 2], x[q + 2]))


def _fitted_start(model, first_markers, projected, candidates) -> np.ndarray:
    import optimistix as optx

    markers = jnp.asarray(first_markers, jnp.float64)
    predictor = model.manifold.predictor()
    latent = jnp.asarray(model.manifold.latent, jnp.float64)
    q = latent.shape[1]
    spine = spine_to_neck(markers)
    log_scales = jnp.log(spine / (SPM_REFERENCE_LENGTHS[0] * jnp.asarray(candidates, jnp.float64)))
    features, _ = predictor(latent)

    def error(f, log_scale):
        return jnp.mean(jnp.sum((spm_forward(spm_state(f, markers[0], log_scale)) - markers) ** 2, -1))

    errors = jax.vmap(lambda s: jax.vmap(lambda f: error(f, s))(features))(log_scales)  # (K, N)
    k, n = np.unravel_index(int(jnp.argmin(errors)), errors.shape)
    seeds = jnp.stack([jnp.asarray(projected), jnp.concatenate([latent[n], markers[0], log_scales[k : k + 1]])])

    def residual(x, _args):
        return (_decoded(predictor, x, q) - markers).ravel()

    def solve(x0):
        solution = optx.least_squares(residual, optx.LevenbergMarquardt(rtol=1e-6, atol=1e-6), x0, max_steps=200, throw=False)
        x = jnp.where(jnp.all(jnp.isfinite(solution.value)), solution.value, x0)
        return x, jnp.sum(residual(x, None) ** 2)

    fitted, costs = jax.vmap(solve)(seeds)
    return np.asarray(fitted[int(jnp.argmin(costs))])


def _projection_start(model, first_markers, candidates) -> np.ndarray:
    markers = jnp.asarray(first_markers, jnp.float64)
    spine = float(spine_to_neck(markers))
    scales = jnp.asarray([spine / (SPM_REFERENCE_LENGTHS[0] * share) for share in candidates], jnp.float64)
    states = jax.vmap(lambda scale: spm_from_markers(markers, scale))(scales)  # (K, 19)
    latent = model.manifold.encode(spm_features(states).astype(model.manifold.data.dtype))  # (K, q)
    features, _ = model.manifold.predictor()(latent)
    decoded = spm_forward(spm_state(features, states[:, :2], states[:, 2]))
    errors = jnp.mean(jnp.linalg.norm(decoded - markers[None], axis=-1), axis=-1)
    best = int(jnp.argmin(errors))
    return np.asarray(jnp.concatenate([latent[best], states[best, :2], states[best, 2:3]]))


def make_latent_condensation(model, first_image, first_markers, *, particles: int = 200, translation_sd: float = 0.03,
                             scale_sd: float = 0.01, diffusion: float = 1.0, likelihood_scale: float = 20.0,
                             template_update: float = 0.0, estimate: str = "latent-mean", start: str = "projection",
                             silhouette_weight: float = SILHOUETTE_WEIGHT) -> LatentCondensation:
    """003's tracker on an ``SPMModel`` from the first frame (grey (H, W)) and its markers (9, 2).

    Args:
        particles: N (003: 200).
        translation_sd: the pelvis's per-frame step, as a share of the spine-to-neck height.
        scale_sd: the log scale's per-frame step.
        diffusion: a factor on the learned ``nu``.
        likelihood_scale: ``ln p = scale * mean NCC``.
        template_update: the templates' update rate (0: fixed, as 003).
        estimate: "latent-mean" (003: ``mu(E[x])``) or "marker-mean" (the weighted mean of the
            particles' markers, which a latent space folded over several views cannot pull
            between its folds).
        start: "projection" (003's inverse map) or "fitted" (``start_state``).
        silhouette_weight: the silhouette term's weight on frames with masks (``SilhouetteChamfer``).
    """
    if estimate not in ("latent-mean", "marker-mean"):
        raise ValueError(f"estimate must be latent-mean or marker-mean, got {estimate!r}")
    if int(particles) < 1:
        raise ValueError(f"particles must be at least 1, got {particles}")
    templates = marker_templates(first_image, first_markers, scale=likelihood_scale)
    dtype = templates.templates.dtype
    start = start_state(model, first_markers, method=start)
    height = float(spine_to_neck(jnp.asarray(first_markers)))
    step_sd = np.concatenate([diffusion * np.asarray(model.step_sd), [translation_sd * height] * 2, [scale_sd]])
    predictor = jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, model.manifold.predictor())
    return LatentCondensation(predictor=predictor, start=jnp.asarray(start, dtype), step_sd=jnp.asarray(step_sd, dtype),
                              templates=templates, silhouette=silhouette_chamfer(weight=silhouette_weight),
                              particles=int(particles), template_update=float(template_update), estimate=estimate)


register_tracker2d(Tracker2DRecipe(
    "latentpf2d", "003's Condensation in the active-set GPLVM's latent space (Algorithm 2, random walk eq. 6)",
    make_latent_condensation,
    options={"particles": 200, "translation_sd": 0.03, "scale_sd": 0.01, "diffusion": 1.0, "likelihood_scale": 20.0,
             "template_update": 0.0, "estimate": "latent-mean", "start": "projection",
             "silhouette_weight": SILHOUETTE_WEIGHT},
))

"""The monocular 2-D tracker interface, its registry, and the one jitted loop over frames.

A tracker is an ``AbstractTracker2D``: pure ``init`` and ``step`` functions of an equinox
module that holds its model, its marker templates (003 eq. 7), its silhouette likelihood
(``SilhouetteChamfer``, used on frames that come with foreground masks) and its settings.
``track_frames`` scans it over grey frames (``lax.scan``, jitted), each a ``Frame2D`` with the
evidence of its mask when masks are given, carrying the tracker's state and the templates
(blended with the patches at each estimate when ``template_update`` > 0), and keys each frame
by ``fold_in(key, frame index)`` so a video read in chunks gives the same tracks as in one go.
A new tracker is one module with a ``Tracker2DRecipe`` passed to ``register_tracker2d``.
"""

from __future__ import annotations

import abc
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .._custom_types import Array, Float
from .._registries import Registry, check_name
from ._silhouette import SilhouetteChamfer, SilhouetteEvidence, silhouette_evidence
from ._templates import MarkerTemplates

_SILHOUETTE_KEY = 0x51  # frame key -> fold_in(frame key, this) draws the mask's foreground samples


class Frame2D(eqx.Module):
    """One frame as the trackers see it.

    Attributes:
        grey: (H, W) grey values in [0, 1].
        silhouette: the evidence of its foreground mask, or None (templates only, as 003).
    """

    grey: Float[Array, "H W"]
    silhouette: SilhouetteEvidence | None = None


def frame_log_likelihood(templates: MarkerTemplates, silhouette: SilhouetteChamfer, frame: Frame2D,
                         markers: Float[Array, "9 2"]) -> Float[Array, ""]:
    """``ln p`` of markers (9, 2): 003 eq. 7's templates, plus the silhouette term where the frame
    has a mask."""
    log_p = templates.log_likelihood(frame.grey, markers)
    if frame.silhouette is not None:
        log_p = log_p + silhouette.log_likelihood(frame.silhouette, markers).astype(log_p.dtype)
    return log_p


def marker_log_weights(templates: MarkerTemplates, silhouette: SilhouetteChamfer, frame: Frame2D,
                       markers: Float[Array, "n 9 2"]) -> Float[Array, " n"]:
    """Every hypothesis's ``frame_log_likelihood``, normalised (NaN -> -inf; all -inf -> uniform):
    the weights each tracker gives its particles or draws."""
    return clean_log_weights(jax.vmap(lambda m: frame_log_likelihood(templates, silhouette, frame, m))(markers))


class AbstractTracker2D(eqx.Module):
    """A monocular tracker of the SPM markers.

    Attributes every tracker declares (as fields of its own, ``template_update`` static):
        templates: the markers' templates from the first frame (``MarkerTemplates``).
        silhouette: the silhouette likelihood (``SilhouetteChamfer``) for frames with masks.
        template_update: the rate ``alpha`` at which templates follow the estimate (0: 003's
            fixed templates).
    """

    @abc.abstractmethod
    def init(self, key) -> Any:
        """The state at the first frame (where the markers are given)."""

    @abc.abstractmethod
    def step(self, state, templates: MarkerTemplates, frame: Frame2D, key) -> tuple[Any, Float[Array, "9 2"]]:
        """One frame: the next state and the estimated markers (9, 2) pixels."""


class TrackCarry(eqx.Module):
    """What one chunk of frames hands the next: the tracker's state and the templates."""

    state: Any
    templates: MarkerTemplates


@eqx.filter_jit
def _scan(tracker: AbstractTracker2D, carry: TrackCarry, frames, masks, indices, key):
    def body(c: TrackCarry, inputs):
        image, mask, index = inputs
        frame_key = jax.random.fold_in(key, index)
        evidence = None
        if mask is not None:
            evidence = silhouette_evidence(mask, jax.random.fold_in(frame_key, _SILHOUETTE_KEY), dtype=image.dtype)
        state, markers = tracker.step(c.state, c.templates, Frame2D(image, evidence), frame_key)
        templates = c.templates
        if tracker.template_update:
            templates = templates.updated(image, markers, tracker.template_update)
        return TrackCarry(state, templates), markers

    return jax.lax.scan(body, carry, (frames, masks, indices))


def start_tracking(tracker: AbstractTracker2D, key) -> TrackCarry:
    """The carry at the first frame: ``tracker.init(key)`` and its templates."""
    return TrackCarry(tracker.init(key), tracker.templates)


def track_frames(tracker: AbstractTracker2D, frames: Float[Array, "T H W"], key, *, masks=None,
                 carry: TrackCarry | None = None, first_index: int = 1) -> tuple[TrackCarry, Float[Array, "T 9 2"]]:
    """Track grey frames (T, H, W) in [0, 1] that follow the first frame (or ``carry``'s last).

    Args:
        key: the run's PRNG key; frame ``i`` uses ``fold_in(key, i)``.
        masks: (T, H, W) boolean foreground masks of the same frames (background subtraction),
            scored by the tracker's ``silhouette``; None: the templates alone (003).
        carry: where the previous chunk ended (None: ``start_tracking(tracker, key)``).
        first_index: the index of ``frames[0]`` in the video (1 for the frame after the first).

    Returns:
        ``(carry, markers (T, 9, 2) pixels)``.
    """
    frames = jnp.asarray(frames)
    if frames.ndim != 3:
        raise ValueError(f"frames must be grey (T, H, W), got shape {frames.shape}")
    if masks is not None:
        masks = jnp.asarray(masks)
        if masks.shape != frames.shape or masks.dtype != jnp.bool_:
            raise ValueError(f"masks must be boolean {frames.shape} like the frames, got {masks.dtype} {masks.shape}")
    carry = start_tracking(tracker, key) if carry is None else carry
    indices = first_index + jnp.arange(frames.shape[0])
    return _scan(tracker, carry, frames, masks, indices, key)


@dataclasses.dataclass(frozen=True)
class Tracker2DRecipe:
    """How to build one monocular tracker.

    Attributes:
        name: the registry name (``jaxtrack track2d --method NAME``).
        description: one line for ``--help`` and the docs.
        make: ``(model: SPMModel, first_image (H, W), first_markers (9, 2), **options) ->
            AbstractTracker2D``.
        options: the maker's keyword options and their defaults.
    """

    name: str
    description: str
    make: Callable[..., AbstractTracker2D]
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        check_name("2-D tracker", self.name)

    def build(self, model, first_image, first_markers, **options) -> AbstractTracker2D:
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise ValueError(f"2-D tracker {self.name!r} takes no option {', '.join(map(repr, unknown))}"
                             f" (it takes: {', '.join(self.options)})")
        return self.make(model, first_image, first_markers, **{**self.options, **options})


_TRACKERS: Registry[Tracker2DRecipe] = Registry("2-D tracker", Tracker2DRecipe, "register_tracker2d")


def register_tracker2d(recipe: Tracker2DRecipe, *, replace: bool = False) -> Tracker2DRecipe:
    """Add a monocular tracker to the registry; returns it."""
    return _TRACKERS.register(recipe, replace=replace)


def get_tracker2d(name: str) -> Tracker2DRecipe:
    return _TRACKERS.get(name)


def tracker2d_names() -> tuple[str, ...]:
    return _TRACKERS.names()


def uniform_start(start, count: int, shape=()):
    """``count`` copies of ``start`` (each of ``shape + start.shape``) with equal log-weights: every
    tracker's state at the first frame."""
    states = jnp.broadcast_to(start, (count, *shape, *jnp.shape(start)))
    return states, jnp.full(count, -jnp.log(count), jnp.asarray(start).dtype)


def resample_indices(key, log_weights):
    """Systematic resampling (the library's), as indices."""
    from ..filters import systematic

    return systematic(key, log_weights)


def clean_log_weights(log_weights):
    """NaN -> -inf; all -inf -> uniform (numerical trouble never leaks)."""
    from ..filters import normalise_log_weights

    return normalise_log_weights(jnp.where(jnp.isnan(log_weights), -jnp.inf, log_weights))[0]

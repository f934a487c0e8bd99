"""The likelihood registry: every likelihood a test scene can be tracked with, by name, in one
table that ``tracking.prepare_test`` (so ``jaxtrack experiment``, ``jaxtrack track`` and the
demo) reads.

A likelihood recipe builds an ``AbstractLikelihood`` from what a test scene offers
(``SceneInputs``: the body, the cameras, the observed silhouettes and 2-D keypoints, the
temperature) and its own options, and says which of the scene's observations it reads
(``observes``): a frame's observation is that entry's array when it reads one, a dict of them
when it reads several (each term then wrapped in ``ObservationPart``). Register one of your
own with ``register_likelihood(LikelihoodRecipe(...))``; loaded with ``--plugin``, it is then
a ``--likelihood`` of ``jaxtrack experiment`` and ``jaxtrack track``, its options given by
``--likelihood-option KEY=VALUE``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._registries import Registry, check_name
from ..errors import ConfigurationError
from ._base import AbstractLikelihood, ObservationPart
from ._blobs import LOST_DIVERGENCE, make_blob_likelihood
from ._edges import make_edge_foreground_likelihood
from ._histogram import make_histogram_likelihood
from ._keypoints import make_keypoint_likelihood
from ._silhouette import make_silhouette_likelihood
from ._template import make_template_likelihood


@dataclasses.dataclass(frozen=True)
class SceneInputs:
    """What a test scene offers a likelihood builder.

    Attributes:
        body: the subject's ``BodyModel`` (skeleton and capsules) the likelihood renders or
            projects; a likelihood that holds it as a field is fitted by ``calibrate_body``.
        rig: the calibrated ``CameraRig`` (C views).
        silhouettes: (C, T, H, W) float32 observed silhouettes in [0, 1], the tracked frames.
        scale: the temperature, ``ln p = -scale * cost`` (``--likelihood-scale``).
        window: the silhouette window requested (``"auto"``, None for dense, or (rows, cols)).
        keypoints: (C, T, 15, 3) 2-D detections of the 15 HumanEva joints (pixels u, v and a
            confidence in [0, 1]), the tracked frames, or None where the scene has none.
        edges, foreground: (C, T, H, W) edge-proximity and foreground maps in [0, 1] (001's
            observations), made by ``prepare_test`` for a recipe that observes them, else None.
        images: (C, T, H, W, 3) colour frames in [0, 1], for a recipe that observes them.
    """

    body: Any
    rig: Any
    silhouettes: Any
    scale: float
    window: Any = "auto"
    keypoints: Any = None
    edges: Any = None
    foreground: Any = None
    images: Any = None


@dataclasses.dataclass(frozen=True)
class LikelihoodRecipe:
    """How to make one likelihood.

    Attributes:
        name: the registry name (``--likelihood NAME``).
        description: one line for ``--help`` and the docs.
        build: ``(SceneInputs, **options) -> AbstractLikelihood`` whose ``log_likelihood(poses,
            observation)`` reads one frame's (C, H, W) silhouettes.
        options: the builder's keyword options and their defaults (``--likelihood-option K=V``;
            each value is parsed as its default's type).
        observes: the scene observations it reads, of ``OBSERVATION_KINDS``: ``("silhouettes",)``
            (the default), ``("keypoints",)``, or several, whose frames then arrive as a dict
            ``{"silhouettes": (C, H, W), "keypoints": (C, 15, 3)}``.
    """

    name: str
    description: str
    build: Callable[..., AbstractLikelihood]
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    observes: tuple[str, ...] = ("silhouettes",)

    def __post_init__(self):
        check_name("likelihood", self.name)
        if not callable(self.build):
            raise TypeError(f"likelihood {self.name!r}: build must be a callable")
        observes = tuple(self.observes) if isinstance(self.observes, (tuple, list)) else ()
        if not observes or len(set(observes)) != len(observes) or not set(observes) <= set(OBSERVATION_KINDS):
            raise ValueError(f"likelihood {self.name!r}: observes must name one or more of {OBSERVATION_KINDS} once each, "
                             f"got {self.observes!r}")
        object.__setattr__(self, "observes", observes)

    def make(self, inputs: SceneInputs, **options) -> AbstractLikelihood:
        """The likelihood of a scene; ``options`` override ``self.options``. Raises
        ``ValueError`` for an option the recipe does not take, ``TypeError`` if the builder does
        not return an ``AbstractLikelihood``."""
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise ValueError(f"likelihood {self.name!r} takes no option {', '.join(map(repr, unknown))}"
                             f" (it takes: {', '.join(self.options) or 'none'})")
        likelihood = self.build(inputs, **{**self.options, **options})
        if not isinstance(likelihood, AbstractLikelihood):
            raise TypeError(f"likelihood {self.name!r}: its builder returned a {type(likelihood).__name__}, "
                            "not an AbstractLikelihood")
        return likelihood


OBSERVATION_KINDS = ("silhouettes", "keypoints", "edges", "foreground", "images")

_LIKELIHOODS: Registry[LikelihoodRecipe] = Registry("likelihood", LikelihoodRecipe, "register_likelihood")


def register_likelihood(recipe: LikelihoodRecipe, *, replace: bool = False) -> LikelihoodRecipe:
    """Add a likelihood to the registry (``replace=True`` to redefine a name); returns it."""
    return _LIKELIHOODS.register(recipe, replace=replace)


def unregister_likelihood(name: str) -> None:
    """Remove a likelihood from the registry."""
    _LIKELIHOODS.unregister(name)


def get_likelihood(name: str) -> LikelihoodRecipe:
    """The recipe registered as ``name``; raises ``ValueError`` listing the names otherwise."""
    return _LIKELIHOODS.get(name)


def available_likelihoods() -> tuple[str, ...]:
    """The registered likelihood names, in registration order (the built-in ones first)."""
    return _LIKELIHOODS.names()


def _silhouette(inputs: SceneInputs, *, edge_width: float) -> AbstractLikelihood:
    return make_silhouette_likelihood(inputs.body, inputs.rig, edge_width=edge_width, scale=inputs.scale, window=inputs.window,
                                      silhouettes=inputs.silhouettes)


DEFAULT_LIKELIHOOD = "silhouette"
register_likelihood(LikelihoodRecipe(
    DEFAULT_LIKELIHOOD, "the bidirectional silhouette likelihood through the soft rasteriser (000 eq. 12); "
    "on sampled pixels above 160x120 (--pixel-samples)", _silhouette, {"edge_width": 1.0}))


def _keypoints(inputs: SceneInputs, *, sigma_px: float, robust: str, weight: float) -> AbstractLikelihood:
    return make_keypoint_likelihood(inputs.body, inputs.rig, sigma_px=sigma_px, robust=robust, weight=weight,
                                    dtype=inputs.body.radii.dtype)


_KEYPOINT_OPTIONS = {"sigma_px": 4.0, "robust": "cauchy", "weight": 1.0}
register_likelihood(LikelihoodRecipe(
    "keypoints", "the reprojection error of 2-D joint detections, robust and confidence-weighted (the file's keypoints2d)",
    _keypoints, _KEYPOINT_OPTIONS, observes=("keypoints",)))


def _silhouette_and_keypoints(inputs: SceneInputs, *, edge_width: float, sigma_px: float, robust: str,
                              weight: float) -> AbstractLikelihood:
    silhouettes = _silhouette(inputs, edge_width=edge_width)
    keypoints = _keypoints(inputs, sigma_px=sigma_px, robust=robust, weight=weight)
    return ObservationPart(silhouettes, "silhouettes") + ObservationPart(keypoints, "keypoints")


register_likelihood(LikelihoodRecipe(
    "silhouette+keypoints", "the silhouettes' likelihood times the keypoints' (independent cues: their log-likelihoods add)",
    _silhouette_and_keypoints, {"edge_width": 1.0, **_KEYPOINT_OPTIONS}, observes=("silhouettes", "keypoints")))


def _edge_foreground(inputs: SceneInputs, *, points: int, edge_width: float, edges: bool, foreground: bool,
                     visibility: str, foreground_weight: float = 1.0, weight: float = 1.0, **map_options) -> AbstractLikelihood:
    # map_options (EDGE_MAP_OPTIONS) shape the maps tracking.prepare_test makes, not the likelihood
    if not (np.isfinite(weight) and weight > 0):
        raise ConfigurationError(f"weight must be a positive number, got {weight!r}")
    return make_edge_foreground_likelihood(inputs.body, inputs.rig, scale=weight * inputs.scale, points=points,
                                           edge_width=edge_width, use_edges=edges, use_foreground=foreground,
                                           visibility=visibility, foreground_weight=foreground_weight,
                                           dtype=inputs.body.radii.dtype)


EDGE_MAP_OPTIONS = {"edge_colour": False, "edges_near": 0}  # likelihood.maps_from_images's colour and near
_EDGE_OPTIONS = {"points": 6, "edge_width": 1.0, "edges": True, "foreground": True, "visibility": "occlusion",
                 "foreground_weight": 1.0, **EDGE_MAP_OPTIONS}
register_likelihood(LikelihoodRecipe(
    "edge+foreground", "paper 001's edge term with occlusion weights and foreground term (001 eqs. 12-16), on edge maps "
    "and foreground maps made from the file's images or silhouettes", _edge_foreground, _EDGE_OPTIONS,
    observes=("edges", "foreground")))


def _silhouette_edge_foreground(inputs: SceneInputs, *, edge_width: float, weight: float, **edge_options) -> AbstractLikelihood:
    silhouettes = _silhouette(inputs, edge_width=edge_width)
    return ObservationPart(silhouettes, "silhouettes") + _edge_foreground(inputs, edge_width=edge_width, weight=weight,
                                                                           **edge_options)


SILHOUETTE_FOREGROUND_WEIGHT = 0.1
"""``foreground_weight`` of ``silhouette+edge+foreground``: 001's foreground term at a tenth of its
edge term (001 eq. 19 weighs them equally; ``edge+foreground`` keeps that). Next to the
silhouettes, which already cover the foreground, the full term cost accuracy; at 0.1 the three
terms beat the silhouettes alone on both films, clean and corrupted (docs/likelihood.md,
"The foreground at a tenth by default")."""
register_likelihood(LikelihoodRecipe(
    "silhouette+edge+foreground", "the silhouettes' likelihood times 001's edge and foreground terms (weight: their "
    "temperature over the silhouettes'; foreground_weight: the foreground term's against the edges', 0.1 by default)",
    _silhouette_edge_foreground, {**_EDGE_OPTIONS, "weight": 1.0, "foreground_weight": SILHOUETTE_FOREGROUND_WEIGHT},
    observes=("silhouettes", "edges", "foreground")))


def _edge_foreground_histogram(inputs: SceneInputs, *, points: int, edge_width: float, bins: int, visibility: str,
                               **map_options) -> AbstractLikelihood:
    histogram = make_histogram_likelihood(inputs.body, inputs.rig, scale=inputs.scale, bins=bins, points=points,
                                          dtype=inputs.body.radii.dtype)
    return _edge_foreground(inputs, points=points, edge_width=edge_width, edges=True, foreground=True,
                            visibility=visibility) + histogram


register_likelihood(LikelihoodRecipe(
    "edge+foreground+histogram", "paper 001's combined weight (001 eq. 19): its edge, foreground and colour-histogram terms "
    "(001 eqs. 12-18), the histograms' references taken at the start pose on the first frame; needs the file's images",
    _edge_foreground_histogram, {"points": 6, "edge_width": 1.0, "bins": 4, "visibility": "occlusion", **EDGE_MAP_OPTIONS},
    observes=("edges", "foreground", "images")))


def _template(inputs: SceneInputs, *, size: int, spacing: float) -> AbstractLikelihood:
    return make_template_likelihood(inputs.body, inputs.rig, scale=inputs.scale, size=size, spacing=spacing,
                                    dtype=inputs.body.radii.dtype)


register_likelihood(LikelihoodRecipe(
    "template", "paper 003's template likelihood (003 eq. 7): the normalised correlation of grey patches around each "
    "projected joint with the joint's template, taken at the start pose on the first frame; needs the file's images",
    _template, {"size": 7, "spacing": 1.0}, observes=("images",)))


def _silhouette_template(inputs: SceneInputs, *, edge_width: float, size: int, spacing: float) -> AbstractLikelihood:
    return ObservationPart(_silhouette(inputs, edge_width=edge_width), "silhouettes") + ObservationPart(
        _template(inputs, size=size, spacing=spacing), "images")


register_likelihood(LikelihoodRecipe(
    "silhouette+template", "the silhouettes' likelihood times 003's templates", _silhouette_template,
    {"edge_width": 1.0, "size": 7, "spacing": 1.0}, observes=("silhouettes", "images")))


def _blobs(inputs: SceneInputs, *, power: float, voxel: float, iterations: int, lost_divergence: float) -> AbstractLikelihood:
    return make_blob_likelihood(inputs.body, inputs.rig, power=power, voxel=voxel, iterations=iterations,
                                lost_divergence=lost_divergence if lost_divergence > 0 else None, dtype=inputs.body.radii.dtype)


register_likelihood(LikelihoodRecipe(
    "blobs", "paper 004's volumetric likelihood: the silhouettes' visual hull (coarse to fine) summarised by Gaussian "
    "blobs, each particle's blobs scored by their relative entropy to those (004 eqs. 6-7); a tracker that can restart "
    "(VLMM-PF) restarts where its best particle's divergence exceeds lost_divergence (0: never; 004 sec. 6.1)", _blobs,
    {"power": 1.0, "voxel": 0.05, "iterations": 5, "lost_divergence": LOST_DIVERGENCE}))


def _colour_blobs(inputs: SceneInputs, *, power: float, voxel: float, iterations: int, lost_divergence: float,
                  colour_in_score: bool) -> AbstractLikelihood:
    return make_blob_likelihood(inputs.body, inputs.rig, power=power, voxel=voxel, iterations=iterations,
                                lost_divergence=lost_divergence if lost_divergence > 0 else None, colour=True,
                                colour_in_score=colour_in_score, dtype=inputs.body.radii.dtype)


register_likelihood(LikelihoodRecipe(
    "colour-blobs", "paper 004's blobs over position and colour (004 sec. 6.1): the hull's voxels coloured by the views' "
    "images, the person's blob colours taken at the start pose on the first frame, colour guiding the blob fit "
    "(colour_in_score=true scores it as well, 004's 6-D blobs); needs the file's images",
    _colour_blobs, {"power": 1.0, "voxel": 0.05, "iterations": 5, "lost_divergence": LOST_DIVERGENCE, "colour_in_score": False},
    observes=("silhouettes", "images")))

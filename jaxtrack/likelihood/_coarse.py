"""The silhouette likelihood at a coarser resolution, for coarse-to-fine annealing (issue #13,
item 5): the observed silhouettes are area-averaged by integer factors inside the call (each
coarse pixel is foreground when at least half its block is, as ``jaxtrack.image`` does before
tracking) and scored by a ``SilhouetteLikelihood`` whose cameras see the coarse image
(``CameraRig.resized``). The soft edge keeps its width in coarse pixels, so the cost is
smoother in the pose: early annealing layers find the body with it, later ones place the limbs
at the full resolution (``APF(coarse_likelihood=..., coarse_layers=...)``).

A coarse evaluation projects the same capsules and scores a quarter of the pixels (factor 2); the
experiment still counts it as one evaluation, which does not flatter it.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp

from .._custom_types import Array, Float
from ..camera import image_shape
from ._base import AbstractLikelihood, SumLikelihood
from ._silhouette import SilhouetteLikelihood


def block_downsample(observed: Float[Array, "views height width"], factor: tuple[int, int]) -> Float[Array, "views h w"]:
    """(V, H, W) 0/1 silhouettes -> (V, H / fy, W / fx): the foreground fraction of each block,
    thresholded at one half. ``factor`` is (fx, fy) and must divide (W, H)."""
    fx, fy = factor
    views, height, width = observed.shape
    blocks = observed.reshape(views, height // fy, fy, width // fx, fx)
    return (jnp.mean(blocks, axis=(2, 4)) >= 0.5).astype(observed.dtype)


class CoarseSilhouetteLikelihood(AbstractLikelihood):
    """``coarse.log_likelihood(poses, block_downsample(observed, factor))``.

    Attributes:
        coarse: the silhouette likelihood on the coarse cameras (image size (W / fx, H / fy)).
        factor: (fx, fy) integer reduction factors from the observed image to the coarse one.
    """

    coarse: SilhouetteLikelihood
    factor: tuple[int, int] = eqx.field(static=True)

    def __check_init__(self):
        fx, fy = self.factor
        if not (isinstance(fx, int) and isinstance(fy, int) and fx >= 1 and fy >= 1):
            raise ValueError(f"factor must be two positive integers (fx, fy), got {self.factor!r}")

    def log_likelihood(self, poses, observed):
        height, width = image_shape(self.coarse.rig)
        fx, fy = self.factor
        if observed.shape[-2:] != (height * fy, width * fx):
            raise ValueError(f"observed silhouettes are {observed.shape[-1]}x{observed.shape[-2]}; this coarse likelihood "
                             f"expects {width * fx}x{height * fy} (its {width}x{height} cameras times {fx}x{fy})")
        return self.coarse.log_likelihood(poses, block_downsample(observed.astype(poses.dtype), self.factor))


def coarsen_likelihood(likelihood: AbstractLikelihood, factor: int | tuple[int, int] = 2) -> AbstractLikelihood:
    """The ``CoarseSilhouetteLikelihood`` of ``likelihood`` with its images reduced by ``factor``
    (one integer for both axes, or (fx, fy)): the same body, scale and edge width (now in coarse
    pixels), the rig ``resized``, the evaluation window shrunk with the image (one pixel of margin).
    A ``SumLikelihood`` (e.g. the silhouettes plus the ground plane's prior, the experiment's
    default) has each silhouette term coarsened and each term that ignores the frame
    (``reads_observation`` False) kept as it is.

    Raises:
        TypeError: ``likelihood`` is neither a ``SilhouetteLikelihood`` nor a sum of them and
            priors (the sampled likelihood for large images already scores a fixed number of
            pixels; another cue would need its own coarse version).
        ValueError: the factor does not divide the image size.
    """
    if isinstance(likelihood, SumLikelihood):
        terms = tuple(term if not term.reads_observation else coarsen_likelihood(term, factor) for term in likelihood.terms)
        if all(not term.reads_observation for term in likelihood.terms):
            raise TypeError("coarse-to-fine needs a silhouette term; every term of this SumLikelihood ignores the frame")
        return SumLikelihood(terms)
    if not isinstance(likelihood, SilhouetteLikelihood):
        raise TypeError(f"coarse-to-fine needs a SilhouetteLikelihood (or a sum of them and priors), got {type(likelihood).__name__}")
    fx, fy = (factor, factor) if isinstance(factor, int) else tuple(factor)
    if not all(isinstance(f, int) and not isinstance(f, bool) and f >= 1 for f in (fx, fy)):
        raise ValueError(f"factor must be a positive integer or two, got {factor!r}")
    height, width = image_shape(likelihood.rig)
    if width % fx or height % fy:
        raise ValueError(f"a factor of {fx}x{fy} does not divide the {width}x{height} images")
    rig = likelihood.rig.resized(width // fx, height // fy)
    window = likelihood.window
    if window is not None:
        window = (min(height // fy, math.ceil(window[0] / fy) + 1), min(width // fx, math.ceil(window[1] / fx) + 1))
    coarse = SilhouetteLikelihood(body=likelihood.body, rig=rig, edge_width=likelihood.edge_width, scale=likelihood.scale,
                                  window=window)
    return CoarseSilhouetteLikelihood(coarse=coarse, factor=(fx, fy))

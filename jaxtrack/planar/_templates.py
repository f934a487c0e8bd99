"""Paper 003's template likelihood in one image (003 eq. 7): ``p(z | y)`` proportional to the
normalised correlation (NCC) between the image around each SPM marker and that marker's
template, here ``ln p = scale * mean over markers of NCC`` (in [-scale, scale]).

A template is the grey-level patch of ``(2r + 1)^2`` pixels around a marker on a reference
frame (003: the first), read by bilinear sampling so a marker may sit between pixels. 003 sets
the neighbourhood to a tenth of the base-of-spine-to-neck height, "a rough estimate [of] the
ratio [of] the length of the spine and the thickness of the arm": the patch's side is that
tenth (``r`` half of it), so that a patch on an arm holds the arm rather than what lies behind
it. 003 keeps its templates; ``MarkerTemplates.updated`` blends in the patches at the estimate
with a rate ``alpha`` (0 keeps them).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ..image import sample_bilinear
from ..likelihood import normalised_correlation
from ._spm import spine_to_neck

TEMPLATE_SHARE = 0.1  # 003 sec. 4: the patch's side as a share of the spine-to-neck height


def patch_offsets(radius: int, dtype=jnp.float32) -> Float[Array, "n 2"]:
    """The (2r + 1)^2 pixel offsets of a square patch, row by row."""
    steps = jnp.arange(-radius, radius + 1, dtype=dtype)
    v, u = jnp.meshgrid(steps, steps, indexing="ij")
    return jnp.stack([u.ravel(), v.ravel()], axis=-1)


def patches(image: Float[Array, "H W"], markers: Float[Array, "m 2"], offsets: Float[Array, "n 2"]) -> Float[Array, "m n"]:
    """The grey values around each marker (bilinear; 0 outside the image)."""
    return sample_bilinear(image, markers[:, None, :] + offsets[None])


class MarkerTemplates(eqx.Module):
    """Attributes:
        templates: (M, n) each marker's patch.
        offsets: (n, 2) pixel offsets of a patch's samples.
        scale: ``ln p = scale * mean NCC``.
    """

    templates: Float[Array, "m n"]
    offsets: Float[Array, "n 2"]
    scale: Float[Array, ""]

    def correlations(self, image: Float[Array, "H W"], markers: Float[Array, "m 2"]) -> Float[Array, " m"]:
        """Each marker's NCC with its template, in [-1, 1]."""
        return normalised_correlation(patches(image, markers, self.offsets), self.templates)

    def log_likelihood(self, image: Float[Array, "H W"], markers: Float[Array, "m 2"]) -> Float[Array, ""]:
        """003 eq. 7 as ``scale * mean NCC`` (module docstring)."""
        return self.scale * jnp.mean(self.correlations(image, markers))

    def updated(self, image, markers, alpha) -> MarkerTemplates:
        """The templates blended with the patches at ``markers``: ``(1 - alpha) T + alpha patch``."""
        fresh = patches(image, markers, self.offsets)
        return eqx.tree_at(lambda t: t.templates, self, (1 - alpha) * self.templates + alpha * fresh)


def template_radius(markers) -> int:
    """003's neighbourhood: the half-side of a patch a tenth of the spine-to-neck height on a
    side, pixels (at least 2)."""
    return max(2, round(0.5 * TEMPLATE_SHARE * float(spine_to_neck(jnp.asarray(markers)))))


def marker_templates(image, markers, *, radius: int | None = None, scale: float = 20.0) -> MarkerTemplates:
    """Templates from one grey image (H, W) in [0, 1] at its markers (M, 2) pixels.

    Raises:
        ValueError: where a template would reach outside the image (naming the marker), or a
            marker is not finite.
    """
    image = jnp.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"the template image must be grey (H, W), got shape {image.shape}")
    markers = np.asarray(markers, np.float64)
    if markers.ndim != 2 or markers.shape[1] != 2 or not np.all(np.isfinite(markers)):
        raise ValueError(f"markers must be finite (M, 2) pixels, got shape {markers.shape}")
    radius = template_radius(markers) if radius is None else int(radius)
    height, width = image.shape
    outside = np.nonzero((markers[:, 0] - radius < 0) | (markers[:, 0] + radius > width - 1)
                         | (markers[:, 1] - radius < 0) | (markers[:, 1] + radius > height - 1))[0]
    if outside.size:
        return _outside(outside, markers, radius, width, height)
    offsets = patch_offsets(radius, image.dtype)
    return MarkerTemplates(templates=patches(image, jnp.asarray(markers, image.dtype), offsets), offsets=offsets,
                           scale=jnp.asarray(scale, image.dtype))


def _outside(indices, markers, radius, width, height):
    from ._spm import SPM_MARKERS

    names = [SPM_MARKERS[i] if len(markers) == len(SPM_MARKERS) else str(i) for i in indices]
    raise ValueError(f"the templates of {', '.join(names)} (radius {radius} px around "
                     f"{', '.join(str(tuple(np.round(markers[i], 1))) for i in indices)}) leave the {width}x{height} image")

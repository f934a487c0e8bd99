"""A silhouette likelihood for the SPM markers: the upper body drawn as 2-D capsules on its links,
matched both ways against a foreground mask (background subtraction of the static camera).

Paper 003 scores a pose by its marker templates alone (eq. 7). A template is a few pixels wide,
so a pose whose arm lies 10 px off scores no better than one 60 px off, and the manifold's best
pose is often farther than that (docs/planar.md, "Why no tracker holds them"). A silhouette
reaches as far as the image: this is the chamfer form of the bidirectional silhouette
likelihood the 3-D trackers use (paper 000 eq. 4), on the SPM's links.

- **model to data**: points along each link's axis (``AXIS_POINTS`` a link), each at its
  distance to the nearest foreground pixel (0 inside the silhouette; the exact distance
  transform, ``image.distance_transform``, of the mask taken at every ``stride``-th pixel, a
  block foreground where any of its pixels is: 2 by default, which cuts the transform's time
  by 4 for an error of a pixel where the cap is tens of pixels);
- **data to model**: ``samples`` foreground pixels drawn each frame, each at its distance to the
  nearest capsule (a link's segment widened by its half-width, ``HALF_WIDTHS``; the forearms
  go on past the wrist by ``HAND`` to cover the hands), counted only above the pose's pelvis
  (the legs are not in the upper-body model).

Distances are in spine-to-neck lengths of the pose, capped at ``cap``; with ``a_i`` and ``b_k``
the two kinds, ``ln p = -weight (mean_i a_i^2 + mean_k b_k^2)``. ``residuals`` gives the same
as a vector ``r`` with ``ln p = -sum r^2``, for the Gauss-Newton steps of ``mht2d``. A frame
whose mask is empty scores 0 for every pose.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Bool, Float
from ..image import distance_transform, sample_bilinear
from ._spm import _ENDS, _STARTS, SPM_LINKS

HALF_WIDTHS = {"spine": 0.32, "neck": 0.22, "lclavicle": 0.12, "lupper_arm": 0.09, "lforearm": 0.08,
               "rclavicle": 0.12, "rupper_arm": 0.09, "rforearm": 0.08}
"""Each link's half-width, a share of the spine-to-neck length (the default body's torso is about
0.3 m wide on a 0.5 m spine, an upper arm 0.09 m, a forearm 0.08 m)."""
HAND = 0.35
"""The hand's reach past the wrist, a share of the spine-to-neck length (0.18 m on a 0.5 m spine)."""
AXIS_POINTS = 8
SAMPLES = 200
STRIDE = 2
SILHOUETTE_WEIGHT = 3000.0
"""The trackers' default ``weight``: chosen on tuning takes (video keys 200-203, not the test
takes) among 300, 1000 and 3000 (docs/planar.md, "Silhouettes")."""
_FOREARMS = tuple(i for i, (name, *_rest) in enumerate(SPM_LINKS) if name.endswith("forearm"))


class SilhouetteEvidence(eqx.Module):
    """What one frame's mask offers the likelihood.

    Attributes:
        distance: (H / stride, W / stride) each block's distance to the nearest foreground
            block, pixels of the image (not blocks).
        points: (K, 2) foreground pixels (u, v) drawn at random.
        valid: (K,) False where the mask was empty.
        stride: the blocks' side, pixels (static).
    """

    distance: Float[Array, "h w"]
    points: Float[Array, "k 2"]
    valid: Bool[Array, " k"]
    stride: int = eqx.field(static=True, default=1)

    def outside(self, points: Float[Array, "n 2"]) -> Float[Array, " n"]:
        """Each point's (n, 2) pixels distance to the foreground, pixels (bilinear between blocks;
        a point beyond the image reads the border's)."""
        centre = (self.stride - 1) / 2.0  # a block's value belongs to its centre pixel
        height, width = self.distance.shape
        blocks = (points - centre) / self.stride
        blocks = jnp.clip(blocks, 0.0, jnp.asarray([width - 1, height - 1], points.dtype))
        return sample_bilinear(self.distance, blocks)


def silhouette_evidence(mask: Bool[Array, "H W"], key, *, samples: int = SAMPLES, stride: int = STRIDE,
                        dtype=jnp.float32) -> SilhouetteEvidence:
    """The evidence of one (H, W) boolean foreground mask; ``key`` draws the ``samples``
    foreground pixels (with replacement, uniformly); the distance map at every ``stride``-th
    pixel (module docstring)."""
    mask = jnp.asarray(mask, bool)
    height, width = mask.shape
    flat = mask.reshape(-1).astype(dtype)
    count = jnp.sum(flat)
    index = jax.random.choice(key, height * width, (samples,), p=flat / jnp.maximum(count, 1.0))
    points = jnp.stack([index % width, index // width], axis=-1).astype(dtype)
    stride = int(stride)
    if stride > 1:
        pad = ((0, -height % stride), (0, -width % stride))
        blocks = jnp.pad(mask, pad).reshape((height + pad[0][1]) // stride, stride, (width + pad[1][1]) // stride, stride)
        mask = jnp.any(blocks, axis=(1, 3))
    distance = jnp.where(count > 0, stride * distance_transform(mask).astype(dtype), 0.0)
    return SilhouetteEvidence(distance, points, jnp.full(samples, count > 0), stride)


def _segment_distance(points, starts, ends):
    """(K, L) distance from each point (K, 2) to each segment (L, 2) -> (L, 2)."""
    along = ends - starts
    t = jnp.sum((points[:, None] - starts[None]) * along[None], -1) / (jnp.sum(along * along, -1)[None] + 1e-9)
    nearest = starts[None] + jnp.clip(t, 0.0, 1.0)[..., None] * along[None]
    return jnp.sqrt(jnp.sum((points[:, None] - nearest) ** 2, -1) + 1e-12)


class SilhouetteChamfer(eqx.Module):
    """The likelihood (module docstring).

    Attributes:
        half_widths: (8,) the links' half-widths (``SPM_LINKS`` order), spine-to-neck lengths.
        weight: ``ln p = -weight * (mean a^2 + mean b^2)``.
        cap: the largest distance counted, spine-to-neck lengths.
        hand: the forearms' reach past the wrist.
    """

    half_widths: Float[Array, " 8"]
    weight: float = eqx.field(static=True, default=SILHOUETTE_WEIGHT)
    cap: float = eqx.field(static=True, default=0.5)
    hand: float = eqx.field(static=True, default=HAND)

    def residuals(self, evidence: SilhouetteEvidence, markers: Float[Array, "9 2"]) -> Float[Array, " n"]:
        """(8 * AXIS_POINTS + K,) ``r`` with ``ln p = -sum r^2``."""
        dtype = evidence.distance.dtype
        markers = markers.astype(dtype)
        spine = jnp.sqrt(jnp.sum((markers[1] - markers[0]) ** 2) + 1e-6)
        starts, ends = markers[jnp.asarray(_STARTS)], markers[jnp.asarray(_ENDS)]
        t = jnp.linspace(0.0, 1.0, AXIS_POINTS, dtype=dtype)
        axis = (starts[:, None] + t[None, :, None] * (ends - starts)[:, None]).reshape(-1, 2)
        outside = jnp.minimum(evidence.outside(axis) / spine, self.cap)
        present = jnp.any(evidence.valid)
        outside = jnp.where(present, outside, 0.0) / np.sqrt(axis.shape[0])
        forearms = jnp.asarray(_FOREARMS)
        direction = ends[forearms] - starts[forearms]
        direction = direction / jnp.sqrt(jnp.sum(direction**2, -1, keepdims=True) + 1e-9)
        ends = ends.at[forearms].add(self.hand * spine * direction)
        gap = _segment_distance(evidence.points, starts, ends) / spine - self.half_widths.astype(dtype)[None]
        uncovered = jnp.minimum(jnp.min(jnp.maximum(gap, 0.0), axis=1), self.cap)
        counted = evidence.valid & (evidence.points[:, 1] < markers[0, 1] + 0.1 * spine)
        uncovered = jnp.where(counted, uncovered, 0.0) / jnp.sqrt(jnp.maximum(jnp.sum(counted), 1).astype(dtype))
        return np.sqrt(self.weight) * jnp.concatenate([outside, uncovered])

    def log_likelihood(self, evidence: SilhouetteEvidence, markers: Float[Array, "9 2"]) -> Float[Array, ""]:
        r = self.residuals(evidence, markers)
        return -jnp.sum(r * r)


def silhouette_chamfer(*, weight: float = SILHOUETTE_WEIGHT, cap: float = 0.5, half_widths=None, hand: float = HAND) -> SilhouetteChamfer:
    """A ``SilhouetteChamfer`` (``half_widths``: a dict by link name, default ``HALF_WIDTHS``)."""
    widths = dict(HALF_WIDTHS, **(half_widths or {}))
    unknown = sorted(set(widths) - set(HALF_WIDTHS))
    if unknown:
        raise ValueError(f"no SPM link {', '.join(unknown)} (links: {', '.join(HALF_WIDTHS)})")
    for name, value in (("weight", weight), ("cap", cap), ("hand", hand)):
        if not (np.isfinite(value) and value >= 0):
            raise ValueError(f"the silhouette's {name} must be finite and non-negative, got {value!r}")
    return SilhouetteChamfer(jnp.asarray([widths[name] for name, *_ in SPM_LINKS], jnp.float32), float(weight), float(cap),
                             float(hand))

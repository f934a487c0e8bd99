"""The silhouette likelihood of paper 000 eq. 12 estimated on a stratified sample of pixels, so
that its cost does not grow with the image size.

Eq. 12 needs, per view, the model area ``A = sum_p S(x)_p``, the overlap
``B = sum_p S(x)_p O_p`` and the observed area ``N = sum_p O_p`` (``S(x)`` the soft model
silhouette, ``O`` the observed one). ``N`` is counted exactly. ``A`` and ``B`` are estimated by
the Horvitz-Thompson sums ``A^ = sum_s w_s S(x)_s``, ``B^ = sum_s w_s S(x)_s O_s`` over a sample
of pixels drawn once per frame, from the observation alone, and shared by every particle:

- the pixels of each view are split into four strata: the *band* within ``band`` pixels of the
  observed outline (where the hypotheses differ most), the observed *interior* beyond it, the
  *near* background within ``near`` pixels of the person, and the *far* background;
- each stratum gets a fixed share of the ``samples`` points, drawn by systematic sampling in
  raster order (one uniform offset per stratum and view, then evenly spaced), so a stratum of
  ``n_k`` pixels sampled ``m_k`` times includes every pixel ``m_k / n_k`` times on average and
  ``w = n_k / m_k`` makes both sums unbiased for every pose.

``1 - B^ / N`` is then unbiased and ``(A^ - B^) / A^`` carries a ratio bias of order
``1 / m``; because all particles see the same pixels, their *differences* in cost are what the
sample measures, which is what the weights depend on. The bias and spread against the dense
value are measured in ``benchmarks/bench_resolution.py`` and bounded in the tests.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, ArrayLike, Float, PRNGKeyArray
from ..body import BodyModel
from ..camera import CameraRig
from ..render import project_capsules, weighted_union_statistics
from ._base import AbstractLikelihood
from ._silhouette import SilhouetteLikelihood, bidirectional_silhouette_cost

STRATA = ("band", "interior", "near", "far")
DEFAULT_SHARES = (0.55, 0.2, 0.2, 0.05)


class PixelSample(NamedTuple):
    """Sampled pixels of one frame's views (a leading frame axis when stacked over frames).

    Attributes:
        u, v: (views, samples) column and row of each sampled pixel centre (pixels).
        weight: (views, samples) pixels each sample stands for (0 for an empty stratum's).
        observed: (views, samples) the observed silhouette (0/1) at the sample.
        observed_area: (views,) the exact observed area ``N`` (pixels).
    """

    u: Float[Array, "*frames views samples"]
    v: Float[Array, "*frames views samples"]
    weight: Float[Array, "*frames views samples"]
    observed: Float[Array, "*frames views samples"]
    observed_area: Float[Array, "*frames views"]


def _dilate(mask, radius: int):
    """Binary dilation of (..., H, W) float masks by a (2 radius + 1)^2 square (separable max)."""
    if radius <= 0:
        return mask
    width = 2 * radius + 1
    ones = (1,) * (mask.ndim - 2)
    zero = jnp.zeros((), mask.dtype)
    rows = jax.lax.reduce_window(mask, zero, jax.lax.max, ones + (1, width), (1,) * mask.ndim, "SAME")
    return jax.lax.reduce_window(rows, zero, jax.lax.max, ones + (width, 1), (1,) * mask.ndim, "SAME")


def pixel_strata(observed: Float[Array, "views height width"], band: int, near: int) -> Float[Array, "4 views height width"]:
    """The four strata (band, interior, near, far; see the module docstring) as 0/1 masks that
    partition every view's pixels."""
    obs = (observed > 0.5).astype(jnp.float32)
    outer = _dilate(obs, band)
    inner = 1.0 - _dilate(1.0 - obs, band)
    ring = outer * (1.0 - inner)
    interior = obs * (1.0 - ring)
    reach = jnp.maximum(_dilate(obs, near), outer)
    near_mask = reach * (1.0 - obs) * (1.0 - ring)
    far = 1.0 - reach
    return jnp.stack([ring, interior, near_mask, far])


def _systematic(mask: Float[Array, " pixels"], count: int, key: PRNGKeyArray):
    """``count`` systematic draws from the pixels where ``mask`` is 1, in raster order: indices
    (count,) and the weight each carries (pixels in the stratum / count).

    Draw i takes the stratum's pixel of rank ``floor((i n + R) / count)`` for ``n`` pixels and one
    uniform integer ``R`` in [0, n): the same draws as the real offset ``(u + i) n / count``,
    in integer arithmetic so that they do not depend on how XLA rounds (jitted or not).
    """
    cumulative = jnp.cumsum(mask.astype(jnp.int32))
    total = cumulative[-1]
    offset = jax.random.randint(key, (), 0, jnp.maximum(total, 1))
    i = jnp.arange(count, dtype=jnp.int32)
    whole, rest = total // count, total % count  # i n = i whole count + i rest, without overflow
    rank = i * whole + (i * rest + offset) // count
    index = jnp.clip(jnp.searchsorted(cumulative, rank, side="right"), 0, mask.shape[0] - 1)
    return index, jnp.full((count,), total.astype(jnp.float32) / count, jnp.float32)


# The image-size rule behind ``pixel_samples="auto"`` (docs/likelihood.md, "Large images"): measured with MRPF
# on the demo's walk and jog, every pixel is cheap up to 160x120; at 320x240, 2048 samples tracked
# within 5 % of every pixel at 7 times the speed; at 640x480, 4096 samples within 4 % (2048 lost
# 6-8 %).
EVERY_PIXEL_UP_TO = 160 * 120
SAMPLES_BY_SIZE = ((320 * 240, 2048), (None, 4096))


def default_pixel_samples(width: int, height: int) -> int | None:
    """The sampled pixels per view and frame for images of ``width`` x ``height``: None (every
    pixel of the window) up to 160x120 pixels, 2048 up to 320x240, 4096 above."""
    pixels = int(width) * int(height)
    if pixels <= EVERY_PIXEL_UP_TO:
        return None
    return next(n for limit, n in SAMPLES_BY_SIZE if limit is None or pixels <= limit)


def stratum_counts(samples: int, shares=DEFAULT_SHARES) -> tuple[int, ...]:
    """Points per stratum: ``samples`` split by ``shares`` (the rounding left-over to the band)."""
    counts = [max(1, math.floor(samples * s)) for s in shares]
    counts[0] += samples - sum(counts)
    return tuple(counts)


def default_band(height: int) -> int:
    """Half-width (pixels) of the outline band: 4 pixels at 240 rows, in proportion otherwise."""
    return max(2, round(height / 60))


def default_near(height: int) -> int:
    """Reach (pixels) of the near background: a tenth of the image height."""
    return max(4, round(height / 10))


def check_sampler(samples: int, shares, band: int, near: int) -> None:
    """Refuse settings the sampler cannot use (before anything is jitted)."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < len(STRATA):
        raise ValueError(f"samples must be an integer >= {len(STRATA)} (points per view), got {samples!r}")
    shares = tuple(float(s) for s in shares)
    if len(shares) != len(STRATA) or not all(math.isfinite(s) and s > 0 for s in shares) or abs(sum(shares) - 1) > 1e-6:
        raise ValueError(f"shares must be {len(STRATA)} positive fractions ({', '.join(STRATA)}) summing to 1, got {shares}")
    for name, value in (("band", band), ("near", near)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name} must be a positive whole number of pixels, got {value!r}")


def sample_pixels(
    key: PRNGKeyArray,
    observed: Float[Array, "views height width"],
    *,
    samples: int,
    band: int,
    near: int,
    shares=DEFAULT_SHARES,
) -> PixelSample:
    """Draw one frame's stratified pixel sample (module docstring) from its observed silhouettes.

    Args:
        key: PRNG key (the systematic offsets: one per stratum and view).
        observed: (views, H, W) observed silhouettes, 0/1.
        samples: points per view, split over the strata by ``shares``.
        band, near: the band half-width and the near-background reach, pixels.

    Jittable (``samples``, ``band``, ``near`` and ``shares`` are static); use
    ``sample_frames`` for a sequence.
    """
    views, height, width = observed.shape
    counts = stratum_counts(samples, shares)
    strata = pixel_strata(observed, band, near).reshape(len(STRATA), views, height * width)
    keys = jax.random.split(key, (len(STRATA), views))
    flat_obs = (observed > 0.5).astype(jnp.float32).reshape(views, height * width)
    indices, weights = [], []
    for k, count in enumerate(counts):
        index, weight = jax.vmap(lambda m, k_, c=count: _systematic(m, c, k_))(strata[k], keys[k])
        indices.append(index)
        weights.append(weight)
    index = jnp.concatenate(indices, axis=-1)
    weight = jnp.concatenate(weights, axis=-1)
    return PixelSample(
        u=(index % width).astype(jnp.float32),
        v=(index // width).astype(jnp.float32),
        weight=weight,
        observed=jnp.take_along_axis(flat_obs, index, axis=-1),
        observed_area=jnp.sum(flat_obs, axis=-1),
    )


SAMPLE_BATCH = 8  # frames sampled at once by sample_frames (its intermediates are a few per-pixel maps per frame)


def sample_frames(
    key: PRNGKeyArray,
    observations: ArrayLike,
    *,
    samples: int = 2048,
    band: int | None = None,
    near: int | None = None,
    shares=DEFAULT_SHARES,
) -> PixelSample:
    """``sample_pixels`` for every frame of a sequence (frame t with ``fold_in(key, t)``), the
    observations a ``SampledSilhouetteLikelihood`` scores, with a leading frame axis.

    Args:
        observations: (T, views, H, W) observed silhouettes, 0/1 (``check_silhouettes``).
        samples: points per view and frame.
        band, near: pixels; default ``default_band`` and ``default_near`` of the image height.
    """
    observations = jnp.asarray(observations)
    if observations.ndim != 4:
        raise ValueError(f"observations must be (frames, views, height, width), got shape {observations.shape}")
    height = observations.shape[-2]
    band = default_band(height) if band is None else band
    near = default_near(height) if near is None else near
    check_sampler(samples, shares, band, near)
    return _sample_frames(key, observations, samples, band, near, tuple(float(s) for s in shares))


@functools.partial(jax.jit, static_argnums=(2, 3, 4, 5))
def _sample_frames(key, observations, samples, band, near, shares):
    keys = jax.vmap(lambda t: jax.random.fold_in(key, t))(jnp.arange(observations.shape[0]))
    draw = lambda pair: sample_pixels(pair[0], pair[1], samples=samples, band=band, near=near, shares=shares)  # noqa: E731
    # SAMPLE_BATCH frames at a time: every frame's distance maps at once held 2.5 GB for 100 frames of 4 views of 272x480
    return jax.lax.map(draw, (keys, observations), batch_size=SAMPLE_BATCH)


class SampledSilhouetteLikelihood(AbstractLikelihood):
    """Paper 000 eq. 12 on sampled pixels (module docstring): the observation of a frame is a
    ``PixelSample`` (from ``sample_frames``), not the images, and the cost per particle-view is
    proportional to the number of samples whatever the image size.

    Attributes:
        body, rig, edge_width, scale: as for ``SilhouetteLikelihood``.
    """

    body: BodyModel
    rig: CameraRig
    edge_width: Float[Array, ""]
    scale: Float[Array, ""]

    @classmethod
    def from_dense(cls, likelihood: SilhouetteLikelihood) -> SampledSilhouetteLikelihood:
        """The sampled counterpart of a (dense or windowed) ``SilhouetteLikelihood``."""
        if not isinstance(likelihood, SilhouetteLikelihood):
            raise TypeError(f"from_dense needs a SilhouetteLikelihood, got {type(likelihood).__name__}")
        return cls(body=likelihood.body, rig=likelihood.rig, edge_width=likelihood.edge_width, scale=likelihood.scale)

    def log_likelihood(self, poses: Float[Array, "particles dofs"], observation: PixelSample) -> Float[Array, " particles"]:
        """Log-likelihood of each pose given one frame's ``PixelSample``."""
        return self.statistics(poses, observation)[0]

    def statistics(self, poses, observation: PixelSample):
        """``(log_likelihood, per_view_cost)`` for a batch of poses."""
        if not isinstance(observation, PixelSample):
            raise TypeError(f"SampledSilhouetteLikelihood scores a PixelSample (see sample_frames), got {type(observation).__name__}")
        views = self.rig.num_views
        if observation.u.shape[-2] != views:
            raise ValueError(f"the pixel sample has {observation.u.shape[-2]} views, the camera rig has {views}")
        dtype = poses.dtype
        sample = PixelSample(*(jnp.asarray(x, dtype) for x in observation))
        caps = project_capsules(self.body, self.rig, poses)
        area, overlap = weighted_union_statistics(
            caps.start, caps.end, caps.radius, sample.u, sample.v, sample.weight, sample.weight * sample.observed,
            self.edge_width.astype(dtype),
        )
        cost = bidirectional_silhouette_cost(area, overlap, sample.observed_area)
        loglik = -self.scale.astype(dtype) * jnp.mean(cost, axis=-1)
        return jnp.where(jnp.all(caps.in_front, axis=-1), loglik, -jnp.inf), cost


"""Background subtraction: binary silhouettes and a foreground probability map from RGB frames of
a static camera.

The background model is per pixel: the temporal median colour of background frames, or of the
video itself when there are none (the median is the background wherever the person covers a
pixel in fewer than half of the frames, so sample frames spread over a walk), and a noise
scale, the median absolute deviation of the frames' colour distance to it (1.4826 MAD, floored
at ``min_noise``, 3 levels of 255 by default: H.264 smooths the sensor noise of a static
background away, while its artefacts and the halved chroma resolution of yuv420 video shift
colours by a few levels around a moving person; with a floor of 2 levels the masks of
``jaxtrack scene --rgb`` videos at 320x240 overlapped the true silhouettes by IoU 0.80, with 3
by 0.84, docs/image.md).

A frame's pixel is then scored by its colour distance to the background in noise units, z. A
shadow is the same surface, darker: its chromaticity (r, g) stays within ``shadow_chroma`` of the
background's while its intensity falls to a ratio in ``shadow_ratio`` (Cucchiara et al.'s test,
in normalised rgb rather than HSV), and it counts as background. The silhouette keeps the
pixels with z over ``low`` connected to pixels over ``high`` (hysteresis), then an opening
can remove specks (none by default) and a closing fills small holes. The probability map is a logistic in z centred
between the two thresholds, 0 on shadows.

Lighting that changes over the take (clouds, a camera's auto-exposure) multiplies the whole
picture: with ``lighting`` on, each frame is first divided by its gain against the background,
the median of its pixels' intensity ratio on a grid of every 4th pixel (the person covers far
fewer than half).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float
from ._colour import channels, chromaticity, to_float
from ._edges import hysteresis
from ._median import median
from ._morphology import closing, opening


class BackgroundModel(eqx.Module):
    """Attributes:
        colour: (..., H, W, 3) median background colour in [0, 1] (leading axes: views).
        noise: (..., H, W) per-pixel noise scale of the colour distance, in [0, 1] units.
    """

    colour: Float[Array, "... H W 3"]
    noise: Float[Array, "... H W"]


class Foreground(eqx.Module):
    """Attributes:
        mask: (..., H, W) bool silhouettes.
        probability: (..., H, W) foreground probability in [0, 1].
        shadow: (..., H, W) bool pixels taken for the background's shadow.
    """

    mask: Array
    probability: Float[Array, "... H W"]
    shadow: Array


def _check_frames(frames, what: str):
    frames = jnp.asarray(frames)
    if frames.ndim < 4 or frames.shape[-1] != 3:
        raise ValueError(f"{what} must be (frames, ..., H, W, 3) RGB, got shape {frames.shape}")
    if frames.shape[0] < 1:
        raise ValueError(f"{what} has no frames")
    return to_float(frames)


MIN_BACKGROUND_FRAMES = 3  # a pixel's median over fewer frames free of the person is not trusted


def fit_background(frames, *, min_noise: float = 3.0 / 255.0, exclude=None) -> BackgroundModel:
    """The background of (T, ..., H, W, 3) RGB frames (uint8 or [0, 1]; T first, views may
    follow): their per-pixel median, and the noise scale (module docstring). Background frames,
    or frames spread over the video itself (the person moving).

    ``exclude``: (T, ..., H, W) bool, pixels known to show the person (e.g. around a detector's
    keypoints): each pixel's median is taken over the frames that do not exclude it (the
    excluded values set to -inf and +inf in turn, which leaves the median of the others as it
    was, exactly when they are an even number, else half a rank off), so a person who stands
    still does not become the background. A pixel left by fewer than ``MIN_BACKGROUND_FRAMES``
    frames keeps the median of all of them."""
    frames = _check_frames(frames, "frames")
    if not (np.isfinite(min_noise) and min_noise > 0):
        raise ValueError(f"min_noise must be positive, got {min_noise!r}")
    if exclude is not None:
        exclude = jnp.asarray(exclude, bool)
        if exclude.shape != frames.shape[:-1]:
            raise ValueError(f"exclude must be the frames' shape without the colour axis, {frames.shape[:-1]}, got "
                             f"{exclude.shape}")
    min_noise = jnp.asarray(min_noise, frames.dtype)
    if frames.ndim == 4:
        return _fit(frames, exclude, min_noise)
    # one view at a time: the selection's intermediates for 4 views of 272x480 at once held 1.2 GB
    views = [_fit(frames[:, v], None if exclude is None else exclude[:, v], min_noise) for v in range(frames.shape[1])]
    return jax.tree.map(lambda *xs: jnp.stack(xs), *views)


def _leaving_out(values, exclude):
    """``values`` (T, ...) with the entries ``exclude`` marks (same shape) set to -inf and +inf
    in turn, for a median over axis 0 that leaves them out (``fit_background``); where fewer
    than ``MIN_BACKGROUND_FRAMES`` would be left, none is marked (the median of all)."""
    exclude = exclude & (values.shape[0] - jnp.sum(exclude, axis=0) >= MIN_BACKGROUND_FRAMES)
    turn = jnp.cumsum(exclude, axis=0) % 2
    return jnp.where(exclude, jnp.where(turn == 1, -jnp.inf, jnp.inf), values)


@jax.jit
def _fit(frames, exclude, min_noise):
    if exclude is None:
        colour = median(frames, axis=0)
        distance = jnp.linalg.norm(frames - colour, axis=-1)
        noise = median(distance, axis=0)
    else:
        colour = median(_leaving_out(frames, jnp.broadcast_to(exclude[..., None], frames.shape)), axis=0)
        distance = jnp.linalg.norm(frames - colour, axis=-1)
        noise = median(_leaving_out(distance, exclude), axis=0)
    return BackgroundModel(colour, jnp.maximum(1.4826 * noise, min_noise))


def subtract_background(model: BackgroundModel, frames, *, low: float = 8.0, high: float = 16.0,
                        shadow_ratio: tuple[float, float] = (0.35, 0.95), shadow_chroma: float = 0.03,
                        open_radius: int = 0, close_radius: int = 1, lighting: bool = True) -> Foreground:
    """Silhouettes of (..., H, W, 3) RGB frames against ``model`` (its shape without the frame
    axis; any leading axes broadcast): each frame's lighting gain removed (``lighting``),
    hysteresis between ``low`` and ``high`` noise units, the shadow test, an opening of
    ``open_radius`` and a closing of ``close_radius`` pixels (module docstring).

    The defaults, (8, 16), no opening and a closing of 1, were chosen on the masks' IoU with the
    true silhouettes of a filmed scene (docs/image.md, "The thresholds on three films"): an
    opening of one pixel erases a forearm two or three pixels wide in a small image, and the
    hysteresis's strong seeds already drop the specks."""
    frames = jnp.asarray(frames)
    if frames.ndim < 3 or frames.shape[-1] != 3:
        raise ValueError(f"frames must be (..., H, W, 3) RGB, got shape {frames.shape}")
    if frames.shape[-3:] != model.colour.shape[-3:]:
        raise ValueError(f"frames of {frames.shape[-2]}x{frames.shape[-3]} against a background of "
                         f"{model.colour.shape[-2]}x{model.colour.shape[-3]} (width x height)")
    if not 0 < low <= high:
        raise ValueError(f"thresholds must satisfy 0 < low <= high (noise units), got {low}, {high}")
    lo, hi = shadow_ratio
    if not 0 < lo < hi <= 1:
        raise ValueError(f"shadow_ratio must be (min, max) with 0 < min < max <= 1, got {shadow_ratio}")
    return _subtract(model, frames, float(low), float(high), (float(lo), float(hi)), float(shadow_chroma),
                     int(open_radius), int(close_radius), bool(lighting))


def lighting_gain(model: BackgroundModel, frames) -> Float[Array, ...]:
    """(...,) each (..., H, W, 3) frame's brightness relative to the background: the median of
    its pixels' intensity ratio, over every 4th pixel of every 4th row (a full sort of every
    pixel cost 72 ms a frame for 3 views of 320x240 on 2 cores, a sort of the subsample 5.6 ms,
    its median by selection, ``_median``, 0.4 ms). Blank background pixels (all channels 0: the
    pixels an encoder cropped, ``io.fit_frames``) say nothing of the lighting: their ratios are
    set to -inf and +inf in turn, which leaves the median of the others as it was (exactly when
    they are an even number)."""
    background = jnp.sum(model.colour[..., ::4, ::4, :], axis=-1)
    ratio = jnp.sum(frames[..., ::4, ::4, :], axis=-1) / jnp.maximum(background, 1e-3)
    ratio = ratio.reshape(ratio.shape[:-2] + (-1,))
    blank = (background <= 0).reshape(background.shape[:-2] + (-1,))
    turn = jnp.cumsum(blank, axis=-1) % 2  # the blank pixels counted in order: -inf, +inf, -inf, ...
    ratio = jnp.where(blank, jnp.where(turn == 1, -jnp.inf, jnp.inf), ratio)
    return median(ratio, axis=-1)


@eqx.filter_jit
def _subtract(model, frames, low, high, shadow_ratio, shadow_chroma, open_radius: int, close_radius: int, lighting: bool):
    frames = to_float(frames)  # inside the program: XLA reads the uint8 frames once, fused with what follows
    gain = lighting_gain(model, frames)[..., None, None] if lighting else 1.0
    red, green, blue = (plane / gain for plane in channels(frames))  # planes: what XLA vectorises (``channels``)
    background = channels(model.colour)
    z = jnp.sqrt((red - background[0]) ** 2 + (green - background[1]) ** 2 + (blue - background[2]) ** 2) / model.noise
    chroma, background = chromaticity(red, green, blue), chromaticity(*background)
    ratio = chroma[2] / jnp.maximum(background[2], 1e-6)
    same_surface = jnp.maximum(jnp.abs(chroma[0] - background[0]), jnp.abs(chroma[1] - background[1])) <= shadow_chroma
    shadow = same_surface & (ratio >= shadow_ratio[0]) & (ratio <= shadow_ratio[1]) & (z >= low)
    strong = (z >= high) & ~shadow
    weak = (z >= low) & ~shadow
    mask = hysteresis(strong, weak)
    if open_radius:
        mask = opening(mask, open_radius)
    if close_radius:
        mask = closing(mask, close_radius)
    middle, width = 0.5 * (low + high), max(0.25 * (high - low), 1e-3)
    probability = jnp.where(shadow, 0.0, jax.nn.sigmoid((z - middle) / width))
    return Foreground(mask, probability, shadow)

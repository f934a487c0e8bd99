"""Background subtraction on a scene whose masks are known: a textured background, a person-like
coloured blob walking across it with a cast shadow, sensor noise. The background is learned
from clean background frames or from the video itself; the silhouettes match the true masks
(IoU >= 0.9) and the shadow stays background."""

import jax
import numpy as np
import pytest
from scipy import ndimage

from jaxtrack.image import fit_background, subtract_background

H, W, T = 60, 80, 16


def _scene(seed=0):
    """(T, H, W, 3) uint8 frames, (T, H, W) true masks, (T, H, W) shadow masks."""
    rng = np.random.default_rng(seed)
    background = ndimage.gaussian_filter(rng.random((H, W, 3)), (3, 3, 0))
    background = 0.25 + 0.5 * (background - background.min()) / np.ptp(background)
    y, x = np.mgrid[:H, :W]
    frames, masks, shadows = [], [], []
    for t in range(T):
        cx = 8 + t * (W - 16) / (T - 1)
        person = (((x - cx) / 6.0) ** 2 + ((y - 28) / 18.0) ** 2) <= 1.0
        shadow = ((((x - cx - 10) / 10.0) ** 2 + ((y - 50) / 3.0) ** 2) <= 1.0) & ~person
        frame = background.copy()
        frame[shadow] *= 0.55
        frame[person] = [0.85, 0.2, 0.25] + 0.05 * rng.standard_normal((person.sum(), 3))
        frame = frame + rng.normal(0, 1.5 / 255, frame.shape)
        frames.append(np.clip(np.round(frame * 255), 0, 255).astype(np.uint8))
        masks.append(person)
        shadows.append(shadow)
    clean = np.clip(np.round((background[None] + rng.normal(0, 1.5 / 255, (5, H, W, 3))) * 255), 0, 255).astype(np.uint8)
    return np.stack(frames), np.stack(masks), np.stack(shadows), clean


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


@pytest.mark.parametrize("learned_from", ["background frames", "the video itself"])
def test_silhouettes_match_the_true_masks_and_shadows_stay_background(learned_from):
    frames, masks, shadows, clean = _scene()
    model = fit_background(clean if learned_from == "background frames" else frames)
    result = subtract_background(model, frames)
    mask = np.asarray(result.mask)
    assert mask.shape == (T, H, W)
    ious = [_iou(mask[t], masks[t]) for t in range(T)]
    assert min(ious) >= 0.9, ious
    assert mask[shadows].mean() < 0.05  # the shadow is not the person
    assert np.asarray(result.shadow)[shadows].mean() > 0.8
    probability = np.asarray(result.probability)
    assert probability[masks].mean() > 0.9 and probability[~masks & ~shadows].mean() < 0.05


def test_bad_background_inputs_are_refused():
    frames, _, _, clean = _scene()
    model = fit_background(clean)
    with pytest.raises(ValueError, match="frames must be"):
        fit_background(frames[..., :2])
    with pytest.raises(ValueError, match="against a background of 80x60"):
        subtract_background(model, frames[:, :30])
    with pytest.raises(ValueError, match="thresholds must satisfy"):
        subtract_background(model, frames, low=5.0, high=2.0)
    same = subtract_background(model, frames[:3])
    again = jax.jit(lambda f: subtract_background(model, f).mask)(frames[:3])  # jittable end to end
    np.testing.assert_array_equal(np.asarray(same.mask), np.asarray(again))


def test_the_background_median_leaves_out_the_pixels_it_is_told_to():
    """``exclude``: each pixel's median over the frames that leave it free, exactly where they
    leave out an even number (the noise's median too); a pixel left by fewer than 3 frames takes
    the median of all; none left out is the plain median; a mask of another shape is refused."""
    rng = np.random.default_rng(1)
    frames = rng.integers(0, 256, (9, 2, 4, 5, 3)).astype(np.uint8)  # (T, views, H, W, 3)
    values = frames / 255.0
    plain = fit_background(frames)
    np.testing.assert_allclose(np.asarray(plain.colour), np.median(values, axis=0), atol=1e-6)
    exclude = np.zeros(frames.shape[:-1], bool)
    exclude[:4, :, :2] = True  # rows 0-1: 4 frames left out, 5 kept
    exclude[:8, :, 3] = True  # row 3: one frame kept, under 3: the median of all
    model = fit_background(frames, exclude=exclude)
    kept = np.median(values[4:, :, :2], axis=0)
    np.testing.assert_allclose(np.asarray(model.colour)[:, :2], kept, atol=1e-6)
    noise = np.maximum(1.4826 * np.median(np.linalg.norm(values[4:, :, :2] - kept, axis=-1), axis=0), 3.0 / 255.0)
    np.testing.assert_allclose(np.asarray(model.noise)[:, :2], noise, atol=1e-6)
    np.testing.assert_allclose(np.asarray(model.colour)[:, 2:], np.asarray(plain.colour)[:, 2:], atol=1e-6)
    np.testing.assert_allclose(np.asarray(model.noise)[:, 3], np.asarray(plain.noise)[:, 3], atol=1e-6)
    with pytest.raises(ValueError, match="exclude must be the frames' shape without the colour axis"):
        fit_background(frames, exclude=exclude[:, 0])

"""jaxtrack.image against SciPy and NumPy references: the blur and Sobel against
scipy.ndimage, the distance transform against distance_transform_edt exactly, morphology
against binary_dilation and binary_erosion, Canny edges on shapes whose outline is known, the
edge-proximity map, resizing, pyramids and colour conversions; jit equals no-jit, and the blur
is differentiable."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage

from jaxtrack.image import (
    canny_edges,
    closing,
    colour_canny_edges,
    dilate,
    distance_transform,
    edge_proximity,
    erode,
    gaussian_blur,
    hysteresis,
    median,
    opening,
    pyramid,
    resize,
    rgb_to_chromaticity,
    rgb_to_grey,
    sobel,
    squared_distance_transform,
    to_float,
)

from helpers import finite_difference_check


@pytest.mark.parametrize("sigma", [0.7, (2.0, 0.8), 6.0])
def test_gaussian_blur_is_scipys(sigma):
    image = np.random.default_rng(0).random((2, 17, 23))
    expected = np.stack([ndimage.gaussian_filter(x, sigma) for x in image])  # sigma 6: a kernel wider than the image
    np.testing.assert_allclose(np.asarray(gaussian_blur(image, sigma)), expected, atol=1e-12)
    np.testing.assert_allclose(np.asarray(jax.jit(lambda x: gaussian_blur(x, sigma))(image)), expected, atol=1e-12)


def test_sobel_is_scipys_and_a_step_gives_four():
    image = np.random.default_rng(1).random((3, 12, 15))
    dx, dy = sobel(image)
    np.testing.assert_allclose(np.asarray(dx), np.stack([ndimage.sobel(x, axis=1) for x in image]), atol=1e-12)
    np.testing.assert_allclose(np.asarray(dy), np.stack([ndimage.sobel(x, axis=0) for x in image]), atol=1e-12)
    step = np.zeros((5, 6))
    step[:, 3:] = 1.0
    assert float(sobel(step)[0][2, 3]) == pytest.approx(4.0) and float(sobel(step)[0][2, 2]) == pytest.approx(4.0)
    assert float(jnp.max(sobel(step)[0])) == pytest.approx(4.0)  # on both pixels either side of the step
    assert float(jnp.max(jnp.abs(sobel(step)[1]))) == 0.0


def test_the_blur_is_differentiable():
    image = np.random.default_rng(2).random((9, 11))
    finite_difference_check(lambda x: gaussian_blur(x, 1.2), jnp.asarray(image), jnp.asarray(np.random.default_rng(3).random((9, 11))))


@pytest.mark.parametrize("shape,density", [((31, 40), 0.02), ((1, 13), 0.2), ((9, 1), 0.3)])
def test_the_distance_transform_is_scipys_exactly(shape, density):
    features = np.random.default_rng(sum(shape)).random(shape) < density
    features.flat[0] = True
    expected = ndimage.distance_transform_edt(~features)
    squared = np.asarray(squared_distance_transform(features))
    np.testing.assert_array_equal(squared, np.round(expected**2))  # whole numbers, exact
    np.testing.assert_allclose(np.asarray(distance_transform(features)), expected, rtol=1e-6)


def test_the_distance_transform_within_a_radius_is_exact_up_to_it():
    features = np.random.default_rng(7).random((2, 30, 40)) < 0.01
    for radius in (1, 4):
        within = np.asarray(squared_distance_transform(features, max_distance=radius))
        for i in range(2):
            expected = np.round(ndimage.distance_transform_edt(~features[i]) ** 2)
            np.testing.assert_array_equal(within[i], np.where(expected <= radius**2, expected, np.inf))


def test_the_distance_transform_batches_and_is_infinite_without_features():
    rng = np.random.default_rng(4)
    features = rng.random((2, 3, 20, 25)) < 0.02
    features[1, 2] = False
    batched = np.asarray(jax.jit(distance_transform)(features))
    assert batched.shape == (2, 3, 20, 25) and np.all(np.isinf(batched[1, 2]))
    for index in [(0, 0), (0, 2), (1, 1)]:
        np.testing.assert_allclose(batched[index], ndimage.distance_transform_edt(~features[index]), rtol=1e-6)


def _disk(radius):
    y, x = np.mgrid[-radius : radius + 1, -radius : radius + 1]
    return x**2 + y**2 <= radius**2


@pytest.mark.parametrize("radius", [1, 2, 3, 5])  # disks up to 3 by shifted copies, of 5 through the distance transform
@pytest.mark.parametrize("shape", ["disk", "square"])
def test_morphology_is_scipys(radius, shape):
    structure = _disk(radius) if shape == "disk" else np.ones((2 * radius + 1,) * 2, bool)
    for width in (30, 70):  # one word a row; three, across the words' boundaries (the disks are packed)
        mask = np.random.default_rng(radius).random((2, 25, width)) < 0.3
        mask[:, 8:18, 10:22] = True
        for i in range(2):
            np.testing.assert_array_equal(np.asarray(dilate(mask, radius, shape))[i], ndimage.binary_dilation(mask[i], structure))
            np.testing.assert_array_equal(np.asarray(erode(mask, radius, shape))[i], ndimage.binary_erosion(mask[i], structure))
            expected_opening = ndimage.binary_dilation(ndimage.binary_erosion(mask[i], structure), structure)
            np.testing.assert_array_equal(np.asarray(opening(mask, radius, shape))[i], expected_opening)
    hole = np.ones((15, 15), bool)
    hole[7, 7] = False
    assert bool(closing(hole, 1)[7, 7]) and bool(jnp.all(closing(hole, 1)))  # the border is not eroded
    with pytest.raises(ValueError, match="radius must be a whole number"):
        dilate(mask, -1)


def test_hysteresis_keeps_the_weak_components_that_hold_a_strong_pixel():
    """Against scipy.ndimage.label with 8-connectivity, on batched random masks whose weak
    components snake over many pixels (the growth runs for dozens of steps, past several tests of
    its fixed point), and the image border connects nothing."""
    rng = np.random.default_rng(0)
    for shape in ((3, 48, 64), (2, 37, 77)):  # two words a row; three, the last one part padding
        weak = rng.random(shape) < 0.55
        strong = weak & (rng.random(weak.shape) < 0.004)
        got = np.asarray(hysteresis(strong, weak))
        for b in range(weak.shape[0]):
            labels, _ = ndimage.label(weak[b], structure=np.ones((3, 3)))
            keep = np.unique(labels[strong[b]])
            np.testing.assert_array_equal(got[b], np.isin(labels, keep[keep > 0]))
        assert got.sum() > 0 and not np.array_equal(got, weak)


def test_median_by_selection_is_jnps():
    """The selection median equals jnp.median's value on every row: odd and even counts, ties,
    negative values and zeros of both signs, float32 and float64, any axis."""
    rng = np.random.default_rng(1)
    for dtype in (np.float32, np.float64):
        for n in (1, 2, 5, 8, 4800):
            x = rng.normal(size=(6, n)).astype(dtype)
            x[0] = np.round(x[0])  # ties
            x[1] = 0.0
            x[2, : n // 2] = -0.0
            x[3] = np.abs(x[3]) * 1e-30  # tiny positive values
            x[4, ::2] = x[4, 0]
            got = np.asarray(jax.jit(median)(x))
            assert got.dtype == dtype
            np.testing.assert_array_equal(got, np.median(x, axis=-1).astype(dtype))
    frames = rng.random((31, 2, 5, 7, 3)).astype(np.float32)
    np.testing.assert_array_equal(np.asarray(median(frames, axis=0)), np.median(frames, axis=0))
    with pytest.raises(ValueError, match="float32 or float64"):
        median(np.arange(4))


def test_canny_finds_a_squares_outline_one_pixel_thin():
    image = np.zeros((40, 50))
    image[10:30, 15:35] = 1.0
    edges = np.asarray(canny_edges(image, sigma=1.0))
    inside = np.zeros_like(edges)
    inside[12:28, 17:33] = True
    outside = ~ndimage.binary_dilation(image > 0, iterations=2)
    assert not edges[inside].any() and not edges[outside].any()
    for row in (15, 20, 25):  # each side of the square crossed once, near its boundary
        assert np.flatnonzero(edges[row, :25]).size == 1 and abs(np.flatnonzero(edges[row, :25])[0] - 14.5) <= 1
        assert np.flatnonzero(edges[row, 25:]).size == 1 and abs(np.flatnonzero(edges[row, 25:])[0] + 25 - 34.5) <= 1
    assert not np.asarray(canny_edges(np.full((10, 10), 0.5))).any()  # no contrast, no edges
    weak = image.copy()
    weak[10:30, 40:45] = 0.15  # a faint bar: below the strong threshold and not connected to a strong edge
    assert not np.asarray(canny_edges(weak, sigma=1.0, low=0.1, high=0.5))[:, 38:].any()
    assert np.asarray(canny_edges(weak, sigma=1.0, low=0.1, high=0.12))[:, 38:].any()


def test_colour_canny_sees_an_edge_of_equal_brightness_and_a_region_keeps_a_faint_one():
    image = np.zeros((40, 50, 3))
    image[:, :, 0] = 1.0
    image[10:30, 15:35] = (0.0, 1.0, 0.0)  # a green square on red: the same grey
    grey = image.mean(axis=-1)
    assert not np.asarray(canny_edges(grey, sigma=1.0)).any()  # no contrast in grey
    colour = np.asarray(colour_canny_edges(image, sigma=1.0))
    square = np.zeros((40, 50))
    square[10:30, 15:35] = 1.0
    outline = np.asarray(canny_edges(square, sigma=1.0))
    assert colour.sum() == outline.sum() and np.all(ndimage.binary_dilation(outline)[colour])  # the outline, within 1 px
    np.testing.assert_array_equal(np.asarray(colour_canny_edges(np.repeat(square[..., None], 3, -1), sigma=1.0)),
                                  np.asarray(canny_edges(square, sigma=1.0)))  # a grey image: the same edges
    # a region: only edges inside it, the thresholds against the largest gradient there
    faint = square.copy()
    faint[5:35, 40:45] = 0.05  # a bar with a twentieth of the square's contrast
    region = np.zeros((40, 50), bool)
    region[:, 38:] = True
    assert not np.asarray(canny_edges(faint, sigma=1.0))[:, 38:].any()
    inside = np.asarray(canny_edges(faint, sigma=1.0, region=region))
    assert inside[:, 38:].any() and not inside[:, :38].any()
    with pytest.raises(ValueError, match="region must have"):
        canny_edges(faint, region=region[:-1])
    with pytest.raises(ValueError, match="height, width, 3"):
        colour_canny_edges(faint)


def test_edge_proximity_falls_off_with_the_distance():
    edges = np.zeros((20, 20), bool)
    edges[:, 10] = True
    p = np.asarray(edge_proximity(edges, scale=2.0))
    distance = np.abs(np.arange(20) - 10.0)
    np.testing.assert_allclose(p[5], np.where(distance <= 8, np.exp(-(distance**2) / 8.0), 0.0), rtol=1e-6)  # 0 beyond 4 scales
    assert np.all(np.asarray(edge_proximity(np.zeros((4, 4), bool))) == 0)


def test_resize_and_pyramid():
    image = np.random.default_rng(5).random((2, 16, 24))
    half = np.asarray(resize(image, 8, 12, method="linear"))
    assert half.shape == (2, 8, 12)
    np.testing.assert_allclose(half.mean(), image.mean(), atol=0.02)
    ramp = np.tile(np.arange(24.0), (16, 1))
    doubled = np.asarray(resize(ramp, 32, 48))  # pixel centres kept: (j + 0.5) / 2 - 0.5
    np.testing.assert_allclose(doubled[5, 4:44], (np.arange(4, 44) + 0.5) / 2 - 0.5, atol=1e-5)
    levels = pyramid(image, 3)
    assert [lv.shape for lv in levels] == [(2, 16, 24), (2, 8, 12), (2, 4, 6)]
    np.testing.assert_allclose(np.asarray(levels[1]), ndimage.gaussian_filter(image, (0, 1, 1))[:, ::2, ::2], atol=1e-12)
    with pytest.raises(ValueError, match="below one pixel"):
        pyramid(image, 6)


def test_colour_conversions():
    rgb = np.random.default_rng(6).integers(0, 256, (4, 5, 3), dtype=np.uint8)
    grey = np.asarray(rgb_to_grey(rgb))
    np.testing.assert_allclose(grey, (rgb.astype(np.float64) @ [0.299, 0.587, 0.114]) / 255.0, atol=1e-6)
    chroma = np.asarray(rgb_to_chromaticity(rgb))
    total = rgb.astype(np.float64).sum(-1)
    np.testing.assert_allclose(chroma[..., 0], rgb[..., 0] / np.maximum(total, 1e-9), atol=1e-6)
    np.testing.assert_allclose(chroma[..., 2], total / 765.0, atol=1e-6)
    shadow = (rgb.astype(np.float64) * 0.5).astype(np.float32) / 255.0  # a shadow: the same chromaticity, half the intensity
    np.testing.assert_allclose(np.asarray(rgb_to_chromaticity(shadow))[..., :2], chroma[..., :2], atol=2e-2)
    np.testing.assert_allclose(np.asarray(rgb_to_chromaticity(np.zeros((1, 1, 3))))[0, 0], [1 / 3, 1 / 3, 0])
    assert to_float(rgb).dtype == jnp.float32
    with pytest.raises(ValueError, match="an RGB image must be"):
        rgb_to_grey(np.zeros((4, 5)))

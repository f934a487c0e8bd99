"""The appearance likelihoods: paper 001's colour-histogram term (001 eqs. 17-18) and 003's
templates (003 eq. 7), against NumPy, best at the true pose on a rendered colour scene, their
gradients against finite differences, and their registrations."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.camera import default_rig
from jaxtrack.data import PhotoSettings, SolidBody, generate_motion, render_rgb
from jaxtrack.likelihood import (
    bhattacharyya_distance,
    get_likelihood,
    make_histogram_likelihood,
    make_template_likelihood,
    normalised_correlation,
    set_references,
    soft_histogram,
)

from helpers import finite_difference_check


def _numpy_histogram(colours, bins):
    """The soft histogram written out: per channel, weight 1 - |x bins - (k + 1/2)| on the two
    nearest centres, all of it on the end bin beyond the end centres; the joint bin is the
    product; normalised."""
    out = np.zeros(bins**3)
    for colour in colours:
        per_channel = []
        for x in colour:
            w = np.zeros(bins)
            position = x * bins - 0.5
            if position <= 0:
                w[0] = 1.0
            elif position >= bins - 1:
                w[-1] = 1.0
            else:
                k = int(np.floor(position))
                w[k], w[k + 1] = 1 - (position - k), position - k
            per_channel.append(w)
        out += np.einsum("i,j,k->ijk", *per_channel).ravel()
    return out / out.sum()


def test_soft_histogram_and_bhattacharyya_match_numpy():
    rng = np.random.default_rng(0)
    colours = rng.random((2, 7, 3))
    colours[0, 0] = [0.0, 1.0, 0.05]  # the end bins
    ours = np.asarray(soft_histogram(jnp.asarray(colours), 3))
    for i in range(2):
        np.testing.assert_allclose(ours[i], _numpy_histogram(colours[i], 3), atol=1e-6)
    p, q = ours[0], ours[1]
    np.testing.assert_allclose(float(bhattacharyya_distance(jnp.asarray(p), jnp.asarray(q))),
                               1 - np.sum(np.sqrt(p * q)), atol=1e-4)  # float32
    assert float(bhattacharyya_distance(jnp.asarray(p), jnp.asarray(p))) == pytest.approx(0.0, abs=1e-5)
    disjoint = np.eye(4)
    assert float(bhattacharyya_distance(jnp.asarray(disjoint[0]), jnp.asarray(disjoint[1]))) == pytest.approx(1.0, abs=1e-5)


@pytest.fixture(scope="module")
def coloured():  # slow tests only
    """A walk filmed in colour (the solid body, 2 views of 64x48 as test_video_path's, no noise)
    and the histogram term on the tracker's capsule body, its references at frame 0's true pose."""
    with jax.enable_x64(True):
        motion = generate_motion("walk", "S1", num_frames=4, fps=30.0, key=jax.random.key(0), dtype=jnp.float64)
        rig = default_rig(64, 48, num_views=2, dtype=jnp.float64)
        pictures, _ = render_rgb(jax.random.key(0), SolidBody(motion.body.skeleton), rig, motion.pose, chunk=2,
                                 settings=PhotoSettings(sensor_noise=0.0, lighting_change=0.0))
        images = jnp.asarray(pictures.swapaxes(0, 1), jnp.float64) / 255.0  # (T, C, H, W, 3)
        term = make_histogram_likelihood(motion.body, rig, dtype=jnp.float64)
        term = term.with_reference(motion.pose[0], images[0])
    return motion, images, term


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_histogram_term_is_best_at_the_true_pose(coloured):
    motion, images, term = coloured
    with jax.enable_x64(True):
        assert float(term.cost(motion.pose[0], {"images": images[0]})) == pytest.approx(0.0, abs=1e-4)  # sqrt(pq + 1e-12)
        truth = jnp.asarray(motion.pose[2])
        moved = [truth.at[0].add(0.15), truth.at[1].add(-0.15), truth.at[3].add(0.6), truth.at[2].add(0.12)]
        values = term(jnp.stack([truth, *moved]), {"images": images[2]})
        assert int(jnp.argmax(values)) == 0, values


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_histogram_term_gradient_matches_finite_differences(coloured):
    motion, images, term = coloured
    with jax.enable_x64(True):
        pose = jnp.asarray(motion.pose[1]).at[0].add(0.03)
        direction = jnp.zeros_like(pose).at[0].set(1.0).at[1].set(0.5).at[10].set(0.3)
        finite_difference_check(lambda p: term.cost(p, {"images": images[1]}), pose, direction, eps=1e-5, rtol=1e-3)


def test_001s_combined_weight_is_registered_and_reads_images():
    recipe = get_likelihood("edge+foreground+histogram")
    assert recipe.observes == ("edges", "foreground", "images")
    assert recipe.options["bins"] == 4
    with pytest.raises(ValueError, match="running reference needs a rate"):
        motion = generate_motion("walk", "S1", num_frames=2, fps=30.0, key=jax.random.key(0))
        rig = default_rig(32, 24, num_views=1)
        term = make_histogram_likelihood(motion.body, rig)
        term.with_reference(motion.pose[0], jnp.zeros((1, 24, 32, 3)), previous=term.reference)


def test_normalised_correlation_matches_numpy():
    rng = np.random.default_rng(1)
    a, b = rng.random((3, 49)), rng.random((3, 49))
    expected = [np.corrcoef(x, y)[0, 1] for x, y in zip(a, b)]
    np.testing.assert_allclose(np.asarray(normalised_correlation(jnp.asarray(a), jnp.asarray(b))), expected, atol=1e-5)
    np.testing.assert_allclose(np.asarray(normalised_correlation(jnp.asarray(a), jnp.asarray(2 * a + 1))), 1.0, atol=1e-5)
    assert float(normalised_correlation(jnp.asarray(a[0]), jnp.ones(49))) == pytest.approx(0.0, abs=1e-6)  # a flat patch


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_template_term_is_best_at_the_true_pose_and_its_gradient_is_right(coloured):
    motion, images, _ = coloured
    with jax.enable_x64(True):
        rig = default_rig(64, 48, num_views=2, dtype=jnp.float64)
        term = set_references(make_template_likelihood(motion.body, rig, dtype=jnp.float64), motion.pose[0], {"images": images[0]})
        assert float(term(jnp.asarray(motion.pose[:1]), {"images": images[0]})[0]) == pytest.approx(100.0, abs=1e-3)
        truth = jnp.asarray(motion.pose[2])
        moved = [truth.at[0].add(0.15), truth.at[1].add(-0.15), truth.at[3].add(0.6), truth.at[2].add(0.12)]
        values = term(jnp.stack([truth, *moved]), images[2])
        assert int(jnp.argmax(values)) == 0, values
        direction = jnp.zeros_like(truth).at[0].set(1.0).at[10].set(0.5)
        finite_difference_check(lambda p: term(p[None], images[2])[0], truth, direction, eps=1e-5, rtol=1e-3)


def test_003s_templates_are_registered():
    assert get_likelihood("template").observes == ("images",)
    assert get_likelihood("silhouette+template").observes == ("silhouettes", "images")

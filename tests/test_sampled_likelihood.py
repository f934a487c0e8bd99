"""The silhouette likelihood on stratified sample pixels (``SampledSilhouetteLikelihood``)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.likelihood import (
    PixelSample,
    SampledSilhouetteLikelihood,
    check_silhouettes,
    make_silhouette_likelihood,
    pixel_strata,
    sample_frames,
    sample_pixels,
)

from helpers import small_scene

# one worker builds the module's 64x48 scene (about 20 s cold) and runs every test that reads it
pytestmark = pytest.mark.xdist_group("sampled_likelihood_scene")


@pytest.fixture(scope="module")
def scene():
    motion, rig, seq = small_scene(num_frames=3, width=64, height=48)
    observed = jnp.asarray(check_silhouettes(seq.silhouettes, rig), jnp.float64)  # (views, frames, H, W)
    return motion, rig, jnp.moveaxis(observed, 1, 0)


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_the_strata_partition_the_image_and_the_band_holds_the_outline(scene):
    _, _, observations = scene
    obs = observations[0]
    strata = np.asarray(pixel_strata(obs, 2, 8))
    np.testing.assert_array_equal(strata.sum(axis=0), np.ones(obs.shape))
    assert set(np.unique(strata)) <= {0.0, 1.0}
    band, interior, near, far = strata
    o = np.asarray(obs) > 0.5
    # Every pixel with a 4-neighbour of the other value is on the outline, and in the band.
    outline = np.zeros_like(o)
    outline[:, 1:, :] |= o[:, 1:, :] != o[:, :-1, :]
    outline[:, :, 1:] |= o[:, :, 1:] != o[:, :, :-1]
    assert np.all(band[outline] == 1)
    assert np.all(o[interior == 1]) and not np.any(o[(near == 1) | (far == 1)])
    # Beyond the near reach, no foreground within 8 pixels (the far stratum is far).
    rows, cols = np.nonzero(far[0])
    fg_rows, fg_cols = np.nonzero(o[0])
    gap = np.maximum(np.abs(rows[:, None] - fg_rows[None]), np.abs(cols[:, None] - fg_cols[None])).min(axis=1)
    assert gap.min() > 8


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_every_pixel_is_sampled_with_unit_expected_weight(scene):
    """Horvitz-Thompson: over the draws, each pixel's weight averages 1 (so A^ and B^ are
    unbiased for every pose), and within one draw each stratum's weights sum to its size."""
    _, _, observations = scene
    obs = observations[0, :1]  # one view
    height, width = obs.shape[-2:]
    draws = 3000

    def weight_map(key):
        sample = sample_pixels(key, obs, samples=300, band=2, near=8)
        index = (sample.v * width + sample.u).astype(jnp.int32)[0]
        return jnp.zeros(height * width).at[index].add(sample.weight[0])

    maps = jax.jit(jax.vmap(weight_map))(jax.random.split(jax.random.key(0), draws))
    np.testing.assert_allclose(np.asarray(maps.sum(axis=1)), height * width, rtol=1e-5)
    mean = np.asarray(maps.mean(axis=0))
    # Each pixel's inclusion is a Bernoulli of probability m/n with weight n/m: sd sqrt((n/m - 1) / draws).
    strata = np.asarray(pixel_strata(obs, 2, 8)).reshape(4, -1)
    sizes = strata.sum(axis=1)
    ratio = (strata * (sizes / np.array([165, 60, 60, 15]))[:, None]).sum(axis=0)
    z = (mean - 1.0) / np.sqrt(np.maximum(ratio - 1.0, 1e-12) / draws)
    assert np.all(np.abs(mean[ratio <= 1.0] - 1.0) < 1e-5)  # pixels sampled at least once every draw
    assert np.abs(z).max() < 5.0, np.abs(z).max()
    assert abs(float(np.mean(z))) < 0.1


@pytest.mark.slow
def test_the_sampled_sums_are_unbiased_for_a_pose(scene, getkey):
    """A^ and B^ over many draws average to the dense A and B of the same pose."""
    motion, rig, observations = scene
    lik = make_silhouette_likelihood(motion.body, rig, window=None)
    pose = jnp.asarray(motion.pose[0]) + 0.03 * jax.random.normal(getkey(), (1, 32))
    from jaxtrack.render import project_capsules, union_statistics, weighted_union_statistics

    caps = project_capsules(lik.body, rig, pose)
    from jaxtrack.camera import pixel_grid

    v, u = pixel_grid(48, 64, jnp.float64)
    obs = observations[0].reshape(4, -1)
    dense = union_statistics(caps.start, caps.end, caps.radius, u.ravel(), v.ravel(), obs, lik.edge_width)

    def sampled(key):
        s = sample_pixels(key, observations[0], samples=512, band=2, near=8)
        return weighted_union_statistics(caps.start, caps.end, caps.radius, s.u, s.v, s.weight, s.weight * s.observed,
                                         lik.edge_width)

    area, overlap = jax.jit(jax.vmap(sampled))(jax.random.split(getkey(), 2000))
    for estimate, exact in ((area, dense[0]), (overlap, dense[1])):
        mean, sd = np.asarray(estimate.mean(0)), np.asarray(estimate.std(0)) / np.sqrt(2000)
        assert np.all(np.abs(mean - np.asarray(exact)) < 4 * sd + 1e-9), (mean, exact, sd)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_sampled_likelihood_ranks_poses_like_every_pixel(scene, getkey):
    """Around the truth the sampled cost follows the dense one (64x48, 4 views, 1024 samples
    per view): a shift shared by every pose (one draw's luck, which the weights ignore) and a
    small spread around it."""
    motion, rig, observations = scene
    dense = make_silhouette_likelihood(motion.body, rig, window=None, scale=1.0)
    sampled = SampledSilhouetteLikelihood.from_dense(dense)
    poses = jnp.asarray(motion.pose[0]) + 0.08 * jax.random.normal(getkey(), (64, 32))
    exact = -np.asarray(dense(poses, observations[0]))
    sample = jax.tree.map(lambda x: x[0], sample_frames(getkey(), observations, samples=1024))
    estimate = -np.asarray(sampled(poses, sample))
    assert abs(float(np.mean(estimate - exact))) < 0.03
    assert float(np.std(estimate - exact)) < 0.01
    assert np.corrcoef(estimate, exact)[0, 1] > 0.99


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_sampling_is_keyed_and_equal_jitted_or_not(scene):
    _, _, observations = scene
    key = jax.random.key(4)
    a = sample_frames(key, observations, samples=256)
    b = sample_frames(key, observations, samples=256)
    c = sample_frames(jax.random.key(5), observations, samples=256)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    assert not np.array_equal(np.asarray(a.u), np.asarray(c.u))
    assert a.u.shape == (3, 4, 256) and a.observed_area.shape == (3, 4)
    # Frame t is the frame's own draw with fold_in(key, t), here op by op (not jitted): the same
    # pixels and weights (the draws are integer arithmetic).
    one = sample_pixels(jax.random.fold_in(key, 2), observations[2], samples=256, band=2, near=5)  # the defaults at 48 rows
    for x, y in zip(one, a):
        np.testing.assert_array_equal(np.asarray(x), np.asarray(y[2]))


@pytest.mark.slow
def test_sampled_likelihood_jit_and_behind_camera(scene, getkey):
    motion, rig, observations = scene
    sampled = SampledSilhouetteLikelihood.from_dense(make_silhouette_likelihood(motion.body, rig, window=None))
    sample = jax.tree.map(lambda x: x[0], sample_frames(getkey(), observations, samples=512))
    poses = jnp.asarray(motion.pose[:1]) + 0.02 * jax.random.normal(getkey(), (5, 32))
    centre = np.asarray(rig.centers[0])
    poses = poses.at[0, :3].set(jnp.asarray(centre + np.asarray(rig.R[0])[2] * -0.5))  # the root behind camera 0
    eager = np.asarray(sampled(poses, sample))
    np.testing.assert_allclose(np.asarray(jax.jit(sampled.__call__)(poses, sample)), eager, rtol=1e-10)
    assert np.all(np.isfinite(eager[1:])) and eager[0] == -np.inf


@pytest.mark.slow
def test_sampled_likelihood_gradient_matches_finite_differences(scene, getkey):
    """Through the weighted statistics' backward pass (what gradient refinement uses)."""
    motion, rig, observations = scene
    sampled = SampledSilhouetteLikelihood.from_dense(make_silhouette_likelihood(motion.body, rig, window=None, edge_width=2.0))
    sample = jax.tree.map(lambda x: x[0], sample_frames(getkey(), observations, samples=1024))
    pose = jnp.asarray(motion.pose[0]) + 0.02 * jax.random.normal(getkey(), (32,))
    value = jax.jit(lambda p: sampled(p[None], sample)[0])
    grad = np.asarray(jax.jit(jax.grad(lambda p: sampled(p[None], sample)[0]))(pose))
    assert np.any(grad != 0)
    for index in (0, 2, 5, 9, 14, 20):
        step = jnp.zeros(32).at[index].set(1e-6)
        numeric = (float(value(pose + step)) - float(value(pose - step))) / 2e-6
        assert numeric == pytest.approx(grad[index], rel=1e-4, abs=1e-6), index


@pytest.mark.slow  # 9 s or more on 2 cores with an empty compilation cache (docs/testing.md, 2026-11-27)
def test_bad_sampler_settings_and_observations_are_named(scene):
    motion, rig, observations = scene
    with pytest.raises(ValueError, match="samples must be"):
        sample_frames(jax.random.key(0), observations, samples=2)
    with pytest.raises(ValueError, match="shares must be"):
        sample_frames(jax.random.key(0), observations, samples=256, shares=(0.5, 0.5, 0.5, -0.5))
    with pytest.raises(ValueError, match="band must be"):
        sample_frames(jax.random.key(0), observations, samples=256, band=0)
    with pytest.raises(ValueError, match=r"\(frames, views, height, width\)"):
        sample_frames(jax.random.key(0), observations[0], samples=256)
    sampled = SampledSilhouetteLikelihood.from_dense(make_silhouette_likelihood(motion.body, rig, window=None))
    poses = jnp.asarray(motion.pose[:2])
    with pytest.raises(TypeError, match="PixelSample"):
        sampled(poses, observations[0])
    three_views = jax.tree.map(lambda x: x[0, :3], sample_frames(jax.random.key(0), observations, samples=256))
    assert isinstance(three_views, PixelSample)
    with pytest.raises(ValueError, match="3 views, the camera rig has 4"):
        sampled(poses, three_views)
    with pytest.raises(TypeError, match="SilhouetteLikelihood"):
        SampledSilhouetteLikelihood.from_dense(sampled)


@pytest.mark.slow
def test_sampled_pixels_of_a_large_image_score_like_every_pixel():
    """320x240, 3 views, 2048 samples per view (what ``bench_resolution.py`` tracks with): over
    poses around a noisy walk's first frame and several draws, the cost's mean bias against every
    pixel, its spread across the poses within a draw and the correlation stay within the README's
    figures (measured: bias -0.000, within-draw sd 0.011, correlation 0.995 on 200 poses)."""
    from jaxtrack.camera import default_rig
    from jaxtrack.data import SilhouetteNoise, build_scene, generate_motion
    from jaxtrack.tracking import prepare_test

    motion = generate_motion("walk", "S1", num_frames=2, fps=60.0, key=jax.random.key(0))
    scene = build_scene(jax.random.key(1), motion, default_rig(320, 240, num_views=3), SilhouetteNoise())
    fine = prepare_test(scene, "walk", key=jax.random.key(2), frames=1, window=None)
    truth = fine.initial_pose
    spread = jnp.full(truth.shape, 0.1, truth.dtype).at[:3].set(0.03)
    poses = truth + spread * jax.random.normal(jax.random.key(3), (64, truth.shape[0]), truth.dtype)
    exact = -np.asarray(fine.likelihood(poses, fine.observations[0])) / float(fine.likelihood.scale)
    sampled = SampledSilhouetteLikelihood.from_dense(fine.likelihood)
    differences, correlations = [], []
    for draw in range(4):
        sample = jax.tree.map(lambda x: x[0], sample_frames(jax.random.key(10 + draw), fine.observations, samples=2048))
        estimate = -np.asarray(sampled(poses, sample)) / float(sampled.scale)
        differences.append(estimate - exact)
        correlations.append(np.corrcoef(estimate, exact)[0, 1])
    differences = np.stack(differences)
    assert abs(float(differences.mean())) < 0.02, differences.mean()
    assert float(differences.std(axis=1).mean()) < 0.02, differences.std(axis=1)
    assert min(correlations) > 0.98, correlations

"""Paper 001's edge and foreground likelihood (001 eqs. 12-16): bilinear map reading against
SciPy, the costs' bounds, its maximum at the true pose of a rendered scene, its gradient against
finite differences, and the registered recipes built by ``prepare_test``."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import ndimage

from jaxtrack.errors import ConfigurationError
from jaxtrack.image import sample_bilinear
from jaxtrack.likelihood import (
    EdgeForegroundLikelihood,
    SceneInputs,
    get_likelihood,
    make_edge_foreground_likelihood,
    maps_from_images,
    maps_from_silhouettes,
)
from jaxtrack.tracking import prepare_test

from helpers import finite_difference_check, small_scene

pytestmark = pytest.mark.xdist_group("edge_scene")  # one worker builds the scene fixture (--dist loadgroup)


def test_bilinear_reading_is_scipys_inside_and_differentiable():
    image = np.random.default_rng(0).random((6, 8))
    points = np.array([[0.0, 0.0], [2.3, 4.7], [7.0, 5.0], [3.5, 1.25], [6.9, 0.1]])
    expected = ndimage.map_coordinates(image, [points[:, 1], points[:, 0]], order=1)
    np.testing.assert_allclose(np.asarray(sample_bilinear(image, jnp.asarray(points))), expected, atol=1e-12)
    assert float(sample_bilinear(image, jnp.asarray([[9.5, 2.0]]))[0]) == 0.0  # outside: no evidence
    finite_difference_check(lambda p: sample_bilinear(jnp.asarray(image), p), jnp.asarray([[2.3, 4.7], [3.4, 1.2]]),
                            jnp.asarray([[0.3, -0.2], [0.1, 0.5]]))


@pytest.fixture(scope="module")
def scene():
    """The clean small walk (4 views, 40x30), its maps (T, C, H, W) and likelihood."""
    motion, rig, seq = small_scene(noisy=False)
    edges, foreground = maps_from_silhouettes(np.moveaxis(seq.silhouettes, 1, 0))
    likelihood = make_edge_foreground_likelihood(seq.body(dtype=jnp.float64), rig, scale=1.0, dtype=jnp.float64)
    return motion, {"edges": edges.astype(jnp.float64), "foreground": foreground.astype(jnp.float64)}, likelihood


def test_the_costs_are_bounded_by_perfect_and_absent_evidence(scene):
    motion, maps, likelihood = scene
    pose = jnp.asarray(motion.pose[0], jnp.float64)
    frame = jax.tree.map(lambda m: m[0], maps)
    ones = jax.tree.map(jnp.ones_like, frame)
    zeros = jax.tree.map(jnp.zeros_like, frame)
    costs = eqx.filter_jit(lambda lik, p, o: lik.costs(p, o))
    np.testing.assert_allclose(costs(likelihood, pose, ones), (0.0, 0.0), atol=1e-12)
    sigma_e, sigma_fg = costs(likelihood, pose, zeros)
    assert float(sigma_fg) == pytest.approx(1.0)
    assert 0.2 < float(sigma_e) < 1.0  # the outline points other parts cover (joints, overlaps) weigh less (eq. 13)
    edges_only = EdgeForegroundLikelihood(likelihood.body, likelihood.rig, likelihood.scale, use_foreground=False)
    assert float(costs(edges_only, pose, zeros)[1]) == 0.0


def test_001s_own_visibility_weighs_the_edges_by_the_foreground_at_them(scene):
    """001 eq. 13 as written: lambda = mean over a part's outline points of (1 - p_fg)^2; on
    constant maps Sigma_e = (1 - f)^2 (1 - e)^2 (every outline point inside the views)."""
    motion, maps, likelihood = scene
    pose = jnp.asarray(motion.pose[0], jnp.float64)
    written = EdgeForegroundLikelihood(likelihood.body, likelihood.rig, likelihood.scale, visibility="foreground")
    costs = eqx.filter_jit(lambda lik, p, o: lik.costs(p, o))
    for e, f in ((0.0, 0.0), (0.3, 0.6), (0.5, 1.0)):
        frame = jax.tree.map(lambda m, v: jnp.full_like(m[0], v), maps, {"edges": e, "foreground": f})
        sigma_e, sigma_fg = costs(written, pose, frame)
        assert float(sigma_e) == pytest.approx((1 - f) ** 2 * (1 - e) ** 2, abs=1e-12)
        assert float(sigma_fg) == pytest.approx((1 - f) ** 2, abs=1e-12)
    with pytest.raises(ConfigurationError, match="visibility"):
        EdgeForegroundLikelihood(likelihood.body, likelihood.rig, likelihood.scale, visibility="paper")


def test_the_foreground_weight_scales_the_foreground_term_alone(scene):
    """ln p = -scale (Sigma_e + w_fg Sigma_fg): against the two costs, on the true and perturbed
    poses of a frame; w_fg = 1 is 001's eq. 19 exactly; a weight that is not positive is refused."""
    motion, maps, likelihood = scene
    frame = jax.tree.map(lambda m: m[3], maps)
    poses = jnp.asarray(motion.pose[3], jnp.float64) + 0.05 * jax.random.normal(jax.random.key(0), (3, motion.pose.shape[1]),
                                                                                   jnp.float64)
    score = eqx.filter_jit(lambda lik, p, o: lik.log_likelihood(p, o))
    sigma_e, sigma_fg = eqx.filter_jit(lambda lik, p, o: jax.vmap(lambda q: lik.costs(q, o))(p))(likelihood, poses, frame)
    quarter = make_edge_foreground_likelihood(likelihood.body, likelihood.rig, scale=2.0, foreground_weight=0.25,
                                              dtype=jnp.float64)
    np.testing.assert_allclose(np.asarray(score(quarter, poses, frame)), -2.0 * np.asarray(sigma_e + 0.25 * sigma_fg), rtol=1e-12)
    assert np.asarray(sigma_fg).min() > 0.0  # the weight has something to scale on these poses
    np.testing.assert_array_equal(np.asarray(score(likelihood, poses, frame)), -np.asarray(sigma_e + sigma_fg))
    assert get_likelihood("edge+foreground").options["foreground_weight"] == 1.0  # 001's eq. 19
    assert get_likelihood("silhouette+edge+foreground").options["foreground_weight"] == 0.1
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ConfigurationError, match="foreground_weight"):
            make_edge_foreground_likelihood(likelihood.body, likelihood.rig, foreground_weight=bad, dtype=jnp.float64)


@pytest.mark.slow  # 15 s on 2 cores
def test_the_combined_recipes_weight_scales_001s_terms_alone(scene):
    motion, maps, likelihood = scene
    _, rig, seq = small_scene(noisy=False)
    inputs = SceneInputs(body=likelihood.body, rig=rig, silhouettes=np.asarray(seq.silhouettes, np.float32), scale=1.0,
                         window=None)
    recipe = get_likelihood("silhouette+edge+foreground")
    assert recipe.options["weight"] == 1.0 and recipe.options["visibility"] == "occlusion"
    frame = {"silhouettes": jnp.asarray(seq.silhouettes[:, 0], jnp.float64), **jax.tree.map(lambda m: m[0], maps)}
    poses = jnp.asarray(motion.pose[:3], jnp.float64)
    # the fixture's edge likelihood weighs its foreground term as 001 does (1; the recipe's default is 0.1)
    one, three = (eqx.filter_jit(lambda lik, p, o: lik.log_likelihood(p, o))(recipe.make(inputs, weight=w, foreground_weight=1.0),
                                                                             poses, frame)
                  for w in (1.0, 3.0))
    edge_part = likelihood.log_likelihood(poses, jax.tree.map(lambda m: m[0], maps))
    np.testing.assert_allclose(np.asarray(three - one), 2.0 * np.asarray(edge_part), rtol=1e-5)
    with pytest.raises(ConfigurationError, match="weight"):
        recipe.make(inputs, weight=0.0)


def test_maps_from_images_keep_edges_near_the_silhouettes_only():
    frame = np.zeros((1, 40, 60, 3), np.uint8)
    frame[0, 10:30, 10:20] = (200, 40, 40)  # the person
    frame[0, 5:35, 45:50] = (40, 200, 40)  # clutter far from them
    mask = np.zeros((1, 40, 60), bool)
    mask[0, 10:30, 10:20] = True
    everywhere, _ = maps_from_images(frame, mask)
    near, foreground = maps_from_images(frame, mask, near=3, colour=True)
    everywhere, near = np.asarray(everywhere)[0], np.asarray(near)[0]
    assert everywhere[:, 44:51].max() == pytest.approx(1.0) and near[:, 35:].max() == 0.0  # 4 scales past the region: 0
    outline = everywhere[:, :25] == 1.0  # the person's edges, as before
    assert outline.sum() > 40 and near[:, :25][outline].min() > 0.85  # within a pixel of each
    np.testing.assert_allclose(np.asarray(foreground), np.asarray(maps_from_images(frame, mask)[1]))
    with pytest.raises(ConfigurationError, match="near"):
        maps_from_images(frame, mask, near=-1)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_true_pose_beats_perturbed_ones(scene):
    motion, maps, likelihood = scene
    for t in (0, 4):
        truth = jnp.asarray(motion.pose[t], jnp.float64)
        noise = 0.12 * jax.random.normal(jax.random.key(t), (40, truth.shape[0]), jnp.float64)
        poses = jnp.concatenate([truth[None], truth + noise.at[:, :3].multiply(0.3)])
        scores = np.asarray(eqx.filter_jit(lambda lik, p, o: lik.log_likelihood(p, o))(likelihood, poses,
                                                                                      jax.tree.map(lambda m, t=t: m[t], maps)))
        assert np.mean(scores[1:] < scores[0]) >= 0.9, (t, np.mean(scores[1:] < scores[0]))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_gradient_matches_finite_differences(scene):
    motion, maps, likelihood = scene
    frame = jax.tree.map(lambda m: m[2], maps)
    pose = jnp.asarray(motion.pose[2], jnp.float64) + 0.02
    direction = jnp.asarray(np.random.default_rng(1).standard_normal(pose.shape[0]))
    finite_difference_check(lambda p: likelihood.log_likelihood(p[None], frame)[0], pose, direction, eps=1e-6, rtol=1e-4)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_prepare_test_builds_001s_maps_and_recipes():
    _, _, seq = small_scene(noisy=False)
    scene = prepare_test(seq, "edges", key=jax.random.key(0), likelihood="edge+foreground")
    assert set(scene.observations) == {"edges", "foreground"}
    assert scene.observations["edges"].shape == (8, 4, 30, 40) and float(scene.observations["edges"].max()) == pytest.approx(1.0)
    assert isinstance(scene.likelihood, EdgeForegroundLikelihood)
    both = prepare_test(seq, "both", key=jax.random.key(0), likelihood="silhouette+edge+foreground")
    assert set(both.observations) == {"silhouettes", "edges", "foreground"}
    frame = jax.tree.map(lambda x: x[0], both.observations)
    value = both.likelihood.log_likelihood(both.initial_pose[None], frame)
    parts = sum(term.log_likelihood(both.initial_pose[None], frame) for term in both.likelihood.terms)
    np.testing.assert_allclose(np.asarray(value), np.asarray(parts), rtol=1e-6)
    with pytest.raises(ValueError, match="needs silhouettes"):
        prepare_test(seq.replace(silhouettes=None), "x", key=jax.random.key(0), likelihood="edge+foreground")

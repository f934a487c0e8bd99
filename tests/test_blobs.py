"""004's volumetric likelihood: the coarse-to-fine visual hull, the blobs of a pose and of the
evidence, and the relative entropy between blob mixtures."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import humaneva_body
from jaxtrack.camera import default_rig, project_points
from jaxtrack.data import SolidBody, render_rgb
from jaxtrack.errors import TrackingError
from jaxtrack.likelihood import (
    COLOUR_FLOOR,
    blob_colours,
    carve,
    compact_voxels,
    fit_blobs,
    footprint_radii,
    gaussian_kl,
    make_blob_likelihood,
    mixture_kl,
    pose_blobs,
    visual_hull,
    voxel_colours,
    voxel_grid,
)
from jaxtrack.render import hard_silhouettes


def _random_spd(rng, n):
    a = rng.standard_normal((n, 3, 3))
    return a @ np.swapaxes(a, 1, 2) + 0.3 * np.eye(3)


def test_gaussian_kl_matches_numpy_and_flags_a_singular_covariance():
    """The closed-form 3x3 inverse and determinant behind the KL, against NumPy's."""
    rng = np.random.default_rng(0)
    cov_f, cov_g = _random_spd(rng, 50), _random_spd(rng, 50)
    mean_f, mean_g = rng.standard_normal((50, 3)), rng.standard_normal((50, 3))
    inv_g = np.linalg.inv(cov_g)
    d = mean_g - mean_f
    expected = 0.5 * (np.linalg.slogdet(cov_g)[1] - np.linalg.slogdet(cov_f)[1] - 3 + np.einsum("nij,nji->n", inv_g, cov_f)
                      + np.einsum("ni,nij,nj->n", d, inv_g, d))
    found = gaussian_kl(*map(jnp.asarray, (mean_f, cov_f, mean_g, cov_g)))
    np.testing.assert_allclose(np.asarray(found), expected, rtol=1e-4, atol=1e-4)
    singular = gaussian_kl(jnp.zeros(3), jnp.eye(3), jnp.zeros(3), jnp.zeros((3, 3)))
    assert not np.isnan(float(singular))  # flagged (infinite), never NaN


def test_gaussian_kl_against_monte_carlo():
    rng = np.random.default_rng(1)
    cov_f, cov_g = _random_spd(rng, 2)
    mean_f, mean_g = rng.standard_normal(3), rng.standard_normal(3)
    x = rng.multivariate_normal(mean_f, cov_f, 200000)

    def log_n(x, m, s):
        d = x - m
        return -0.5 * (3 * np.log(2 * np.pi) + np.linalg.slogdet(s)[1] + np.einsum("ni,ij,nj->n", d, np.linalg.inv(s), d))

    mc = np.mean(log_n(x, mean_f, cov_f) - log_n(x, mean_g, cov_g))
    exact = float(gaussian_kl(jnp.asarray(mean_f), jnp.asarray(cov_f), jnp.asarray(mean_g), jnp.asarray(cov_g)))
    assert exact == pytest.approx(mc, abs=0.02 + 0.01 * abs(mc))
    same = gaussian_kl(jnp.asarray(mean_f), jnp.asarray(cov_f), jnp.asarray(mean_f), jnp.asarray(cov_f))
    assert float(same) == pytest.approx(0, abs=1e-5)


def test_mixture_kl_against_monte_carlo_on_separated_blobs():
    """004 eq. 6 is the relative entropy of mixtures whose components do not overlap."""
    rng = np.random.default_rng(2)
    means_f = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    means_g = means_f + 0.2 * rng.standard_normal((3, 3))
    covs_f = 0.05 * _random_spd(rng, 3)
    covs_g = 0.05 * _random_spd(rng, 3)
    alpha, beta = np.array([0.5, 0.3, 0.2]), np.array([0.4, 0.4, 0.2])

    def log_mix(x, w, m, s):
        parts = [np.log(wk) - 0.5 * (3 * np.log(2 * np.pi) + np.linalg.slogdet(sk)[1]
                                     + np.einsum("ni,ij,nj->n", x - mk, np.linalg.inv(sk), x - mk)) for wk, mk, sk in zip(w, m, s)]
        return np.logaddexp.reduce(np.stack(parts), axis=0)

    counts = rng.multinomial(200000, alpha)
    x = np.concatenate([rng.multivariate_normal(m, s, c) for m, s, c in zip(means_f, covs_f, counts)])
    mc = np.mean(log_mix(x, alpha, means_f, covs_f) - log_mix(x, beta, means_g, covs_g))
    approx = float(mixture_kl(*map(jnp.asarray, (alpha, means_f, covs_f, beta, means_g, covs_g))))
    assert approx == pytest.approx(mc, rel=0.03, abs=0.02)


def test_blob_fit_recovers_blobs_placed_by_hand():
    rng = np.random.default_rng(3)
    weights = np.array([0.5, 0.3, 0.2])
    means = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, 1.2], [0.0, 0.6, 0.8]])
    covs = np.stack([np.diag([0.01, 0.004, 0.002]), np.diag([0.002, 0.01, 0.002]), np.diag([0.003, 0.003, 0.012])])
    counts = (weights * 6000).astype(int)
    points = np.concatenate([rng.multivariate_normal(m, s, c) for m, s, c in zip(means, covs, counts)])
    points = np.concatenate([points, np.zeros((500, 3))])  # masked out: they must not count
    mask = np.arange(len(points)) < counts.sum()
    start = (jnp.full(3, 1 / 3), jnp.asarray(means + 0.05), jnp.broadcast_to(0.01 * jnp.eye(3), (3, 3, 3)))
    w, m, s = fit_blobs(jnp.asarray(points), jnp.asarray(mask), *start, iterations=30)
    np.testing.assert_allclose(np.asarray(w), weights, atol=0.01)
    np.testing.assert_allclose(np.asarray(m), means, atol=0.01)
    np.testing.assert_allclose(np.asarray(s), covs, atol=0.0015)


@pytest.fixture(scope="module")
def walk_frame():
    """A pose of the default body mid-stride (hips and knees bent, arms swung) and its binary
    silhouettes in the default 4 views, 80x60."""
    body = humaneva_body()
    skeleton = body.skeleton
    pose = jnp.zeros(skeleton.num_dofs).at[2].set(0.95).at[3].set(0.4)
    for dof, angle in (("lhip_flex", 0.4), ("rhip_flex", -0.3), ("lknee_flex", 0.5), ("lshoulder_flex", -0.4),
                       ("rshoulder_flex", 0.4), ("relbow_flex", 0.6)):
        if dof in skeleton.dof_names:
            pose = pose.at[skeleton.dof_index(dof)].set(angle)
    rig = default_rig(80, 60)
    return body, rig, pose, eqx.filter_jit(hard_silhouettes)(body, rig, pose).astype(jnp.float32)


@pytest.mark.slow  # 6-7 s cold; the default suite is at its 5-minute limit
def test_visual_hull_equals_brute_force(walk_frame):
    _, rig, pose, silhouettes = walk_frame
    for voxel in (0.05,):
        radii = footprint_radii(rig, voxel)
        points, occupied = eqx.filter_jit(visual_hull)(silhouettes, rig, pose[:3], voxel=voxel, max_coarse=1024, radii=radii)
        brute = voxel_grid(pose[:3], (2.4, 2.4, 2.2), voxel)
        kept = eqx.filter_jit(carve)(silhouettes, rig, brute)
        assert int(jnp.sum(occupied)) == int(jnp.sum(kept)) > 50
        found = np.asarray(points)[np.asarray(occupied)]
        expected = np.asarray(brute)[np.asarray(kept)]
        assert set(map(tuple, np.round(found / voxel * 2).astype(int))) == set(map(tuple, np.round(expected / voxel * 2).astype(int)))
    # every occupied voxel projects inside every view's silhouette
    assert bool(jnp.all(carve(silhouettes, rig, points[occupied])))


@pytest.mark.slow  # 6-7 s cold; the default suite is at its 5-minute limit
def test_blob_likelihood_prefers_the_true_pose(walk_frame):
    body, rig, pose, silhouettes = walk_frame
    likelihood = make_blob_likelihood(body, rig)
    key = jax.random.key(0)
    poses = pose + jnp.concatenate([jnp.zeros((1, pose.shape[0])), 0.08 * jax.random.normal(key, (99, pose.shape[0]))])
    score = eqx.filter_jit(lambda p, s: likelihood(p, s))
    values = score(poses, silhouettes)
    assert np.all(np.isfinite(np.asarray(values)))
    assert int(jnp.sum(values[1:] > values[0])) <= 5  # the truth among the best
    errors = jnp.sqrt(jnp.mean((poses - pose) ** 2, axis=1))
    assert float(jnp.corrcoef(errors, values)[0, 1]) < -0.3
    # no evidence (an empty frame): every particle scores the same, finite
    empty = score(poses, jnp.zeros_like(silhouettes))
    assert np.all(np.asarray(empty) == 0.0)


def test_blob_likelihood_refuses_bad_settings(walk_frame):
    body, rig, _, _ = walk_frame
    with pytest.raises(ValueError, match="positive"):
        make_blob_likelihood(body, rig, voxel=0.0)
    with pytest.raises(ValueError, match="max_points"):
        make_blob_likelihood(body, rig, max_points=0)
    with pytest.raises(ValueError, match="box edges"):
        make_blob_likelihood(body, rig, size=(0.05, 1.0, 1.0))


def test_pose_blobs_follow_the_capsules():
    body = humaneva_body()
    pose = jnp.zeros(body.skeleton.num_dofs).at[2].set(1.0)
    weights, means, covs = pose_blobs(body, pose)
    a, b = body.capsules(pose)
    np.testing.assert_allclose(np.asarray(means), np.asarray(0.5 * (a + b)), atol=1e-6)
    np.testing.assert_allclose(float(jnp.sum(weights)), 1.0, rtol=1e-6)
    axis = np.asarray(b - a)
    length = np.linalg.norm(axis, axis=1)
    along = np.einsum("ki,kij,kj->k", axis / length[:, None], np.asarray(covs), axis / length[:, None])
    r = np.asarray(body.radii)
    np.testing.assert_allclose(along, length ** 2 / 12 + r ** 2 / 4, rtol=1e-5)


def test_voxel_colours_take_the_median_of_the_views_that_see_a_point():
    rig = default_rig(16, 12)
    rng = np.random.default_rng(4)
    images = rng.uniform(size=(4, 12, 16, 3)).astype(np.float32)
    points = np.concatenate([rng.uniform(-0.8, 0.8, (40, 3)) + [0, 0, 1.0], [[0.0, 0.0, 40.0]]])  # the last seen by no view
    colours, seen = eqx.filter_jit(voxel_colours)(jnp.asarray(images), rig, jnp.asarray(points, jnp.float32))
    uv, _, front = (np.asarray(x) for x in project_points(rig, jnp.asarray(points, jnp.float32)))
    for n, point_uv in enumerate(uv):
        values = [images[c, int(np.round(v)), int(np.round(u))] for c, (u, v) in enumerate(point_uv)
                  if front[n, c] and 0 <= np.round(u) < 16 and 0 <= np.round(v) < 12]
        assert bool(seen[n]) == bool(values)
        expected = np.median(values, axis=0) if values else np.full(3, 0.5)
        np.testing.assert_allclose(np.asarray(colours[n]), expected, atol=1e-6)
    assert 10 < int(np.sum(np.asarray(seen))) < len(points)


def _two_coloured_blobs(rng, n=3000):
    """Two blobs in one place (one position distribution), one red, one blue, 2:1."""
    colours = np.array([[0.7, 0.2, 0.15], [0.2, 0.25, 0.5]])
    labels = (rng.uniform(size=n) < 1 / 3).astype(int)
    points = rng.multivariate_normal([0.0, 0.0, 1.0], np.diag([0.01, 0.004, 0.02]), n)
    return points, colours[labels] + 0.03 * rng.standard_normal((n, 3)), labels, colours


def test_colour_separates_blobs_that_share_their_place():
    """With colour the EM tells apart two blobs in one place; where every voxel has one colour,
    the colours cancel and the positions are fitted as without them."""
    rng = np.random.default_rng(5)
    points, colours, labels, truth = _two_coloured_blobs(rng)
    mask = jnp.ones(len(points), bool)
    start = (jnp.full(2, 0.5), jnp.asarray([[0.05, 0.0, 1.0], [-0.05, 0.0, 1.0]]), jnp.broadcast_to(0.01 * jnp.eye(3), (2, 3, 3)))
    grey = (jnp.full((2, 3), 0.5), jnp.broadcast_to(0.25 * jnp.eye(3), (2, 3, 3)))
    fit = jax.jit(fit_blobs, static_argnames="iterations")
    w, m, _, cm, cc = fit(jnp.asarray(points), mask, *start, iterations=100, colours=jnp.asarray(colours),
                                colour_means=grey[0] + jnp.asarray([[0.1, 0, 0], [-0.1, 0, 0.1]]), colour_covs=grey[1])
    np.testing.assert_allclose(np.asarray(cm), truth, atol=0.01)
    np.testing.assert_allclose(np.asarray(w), [np.mean(labels == 0), np.mean(labels == 1)], atol=0.01)
    np.testing.assert_allclose(np.asarray(cc), np.broadcast_to((0.03 ** 2 + COLOUR_FLOOR) * np.eye(3), (2, 3, 3)), atol=4e-4)
    for k in range(2):  # each blob's position is its own points'
        np.testing.assert_allclose(np.asarray(m[k]), points[labels == k].mean(axis=0), atol=0.01)
    plain = fit(jnp.asarray(points), mask, *start, iterations=100)
    same = fit(jnp.asarray(points), mask, *start, iterations=100, colours=jnp.full((len(points), 3), 0.3), colour_means=grey[0],
                     colour_covs=grey[1])
    for a, b in zip(plain, same[:3]):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5, atol=1e-7)


def test_blob_colours_are_the_colours_of_each_blobs_voxels():
    rng = np.random.default_rng(6)
    means = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 1.0], [5.0, 5.0, 5.0]])  # the third far from every voxel
    covs = np.broadcast_to(0.005 * np.eye(3), (3, 3, 3))
    truth = np.array([[0.8, 0.3, 0.2], [0.1, 0.2, 0.6]])
    labels = rng.integers(0, 2, 2000)
    points = means[labels] + rng.multivariate_normal(np.zeros(3), covs[0], 2000)
    colours = truth[labels] + 0.02 * rng.standard_normal((2000, 3))
    found, spread = jax.jit(blob_colours)(*map(jnp.asarray, (points, np.ones(2000, bool), colours, np.full(3, 1 / 3), means, covs)))
    np.testing.assert_allclose(np.asarray(found[:2]), truth, atol=0.005)
    np.testing.assert_allclose(np.asarray(spread[:2]), np.broadcast_to((0.02 ** 2 + COLOUR_FLOOR) * np.eye(3), (2, 3, 3)), atol=2e-4)
    np.testing.assert_allclose(np.asarray(found[2]), 0.5)  # no voxel: mid-grey and wide
    np.testing.assert_allclose(np.asarray(spread[2]), 0.25 * np.eye(3))


def test_mixture_kl_with_colour_is_the_6d_kl_of_block_diagonal_blobs():
    rng = np.random.default_rng(7)
    parts = [_random_spd(rng, 3) for _ in range(4)]  # position f, g; colour f, g
    means = [rng.standard_normal((3, 3)) for _ in range(4)]
    alpha, beta = np.array([0.5, 0.3, 0.2]), np.array([0.4, 0.4, 0.2])
    expected = 0.0
    for k in range(3):
        cov_f = np.block([[parts[0][k], np.zeros((3, 3))], [np.zeros((3, 3)), parts[2][k]]])
        cov_g = np.block([[parts[1][k], np.zeros((3, 3))], [np.zeros((3, 3)), parts[3][k]]])
        d = np.concatenate([means[1][k] - means[0][k], means[3][k] - means[2][k]])
        kl = 0.5 * (np.linalg.slogdet(cov_g)[1] - np.linalg.slogdet(cov_f)[1] - 6 + np.trace(np.linalg.solve(cov_g, cov_f))
                    + d @ np.linalg.solve(cov_g, d))
        expected += alpha[k] * (kl + np.log(alpha[k] / beta[k]))
    found = mixture_kl(*map(jnp.asarray, (alpha, means[0], parts[0], beta, means[1], parts[1])),
                       colour=tuple(map(jnp.asarray, (means[2], parts[2], means[3], parts[3]))))
    assert float(found) == pytest.approx(expected, rel=1e-4)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_colour_blobs_take_the_persons_colours_and_prefer_the_true_pose(walk_frame):
    """The solid body filmed in colour (red shirt, blue trousers, skin): the blob colours at the
    true pose are the clothes', and the likelihood prefers the true pose."""
    body, rig, pose, _ = walk_frame
    solid = SolidBody(body.skeleton)
    pictures, masks = render_rgb(jax.random.key(1), solid, rig, pose[None])
    frame = {"silhouettes": jnp.asarray(masks[:, 0], jnp.float32), "images": jnp.asarray(pictures[:, 0], jnp.float32) / 255}
    likelihood = make_blob_likelihood(body, rig, colour=True)
    with pytest.raises(TrackingError, match="images"):
        likelihood.fit_evidence(frame["silhouettes"], pose[None])
    likelihood = likelihood.with_reference(pose, frame)
    colours = np.asarray(likelihood.colour_means)
    names = list(body.capsule_names)
    red = [colours[names.index(n)] for n in names if "torso" in n or "upper" in n]
    blue = [colours[names.index(n)] for n in names if "thigh" in n or "shin" in n]
    assert red and blue and all(c[0] > c[2] + 0.1 for c in red) and all(c[2] > c[0] + 0.03 for c in blue)
    poses = pose + jnp.concatenate([jnp.zeros((1, pose.shape[0])), 0.08 * jax.random.normal(jax.random.key(0), (99, pose.shape[0]))])
    values = eqx.filter_jit(lambda p, o: likelihood(p, o))(poses, frame)
    assert np.all(np.isfinite(np.asarray(values)))
    assert int(jnp.sum(values[1:] > values[0])) <= 5
    errors = jnp.sqrt(jnp.mean((poses - pose) ** 2, axis=1))
    assert float(jnp.corrcoef(errors, values)[0, 1]) < -0.3


def test_compact_voxels_keeps_every_occupied_voxel_or_an_even_spread():
    points = jnp.stack([jnp.arange(1000.0), jnp.zeros(1000), jnp.zeros(1000)], axis=1)
    occupied = (jnp.arange(1000) < 200) | ((jnp.arange(1000) >= 600) & (jnp.arange(1000) < 1000))  # 200 + 400 occupied
    compact = jax.jit(compact_voxels, static_argnums=2)
    kept, mask = compact(points, occupied, 700)  # room for all
    assert int(mask.sum()) == 600
    assert set(np.asarray(kept[:, 0])[np.asarray(mask)].tolist()) == set(np.asarray(points[:, 0])[np.asarray(occupied)].tolist())
    kept, mask = compact(points, occupied, 300)  # half of them, from both regions alike
    x = np.asarray(kept[:, 0])
    assert bool(mask.all()) and len(set(x.tolist())) == 300 and set(x.tolist()) <= set(np.flatnonzero(np.asarray(occupied)).tolist())
    assert abs(np.sum(x < 200) - 100) <= 5
    assert np.all(np.abs(np.histogram(x[x >= 600], bins=4, range=(600, 1000))[0] - 50) <= 5)
    same = compact_voxels(points, occupied, 1000)
    assert same[0] is points and same[1] is occupied

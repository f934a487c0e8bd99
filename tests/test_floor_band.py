"""The floor band (``likelihood.FloorBandSilhouette``): rays back to the floor, the band's pixels
left out of paper 000 eq. 12 for the model and the observation alike, dense and sampled."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import forward_kinematics, humaneva_body
from jaxtrack.camera import default_rig, project_points
from jaxtrack.likelihood import (
    FloorBandSilhouette,
    SampledSilhouetteLikelihood,
    default_band,
    default_near,
    floor_band_weights,
    floor_points,
    make_silhouette_likelihood,
    sample_pixels,
)
from jaxtrack.render import hard_silhouettes

pytestmark = pytest.mark.xdist_group("floor_band")  # one worker renders the scene (--dist loadgroup)


@pytest.fixture(scope="module")
def standing():
    """The default body standing (root 0.95 m up) in 4 views at 40x30, its hard silhouettes."""
    body = humaneva_body(dtype=jnp.float64)
    rig = default_rig(40, 30, dtype=jnp.float64)
    pose = jnp.zeros(body.skeleton.num_dofs, jnp.float64).at[2].set(0.95)
    return body, rig, pose, hard_silhouettes(body, rig, pose[None])[0]


def test_floor_points_invert_the_projection_of_floor_points(standing):
    _, rig, _, _ = standing
    points = np.array([[0.3, -0.2, 0.0], [-0.5, 0.4, 0.0], [0.0, 0.0, 0.0]])
    uv, _, in_front = project_points(rig, jnp.asarray(points))  # (3, views, 2)
    assert np.all(np.asarray(in_front))
    uv = np.swapaxes(np.asarray(uv), 0, 1)  # (views, 3, 2)
    found, hits = floor_points(rig, jnp.asarray(uv[..., 0]), jnp.asarray(uv[..., 1]), 0.0)
    assert np.all(np.asarray(hits))
    np.testing.assert_allclose(np.asarray(found), np.broadcast_to(points[:, :2], found.shape), atol=1e-9)
    # A pixel on the horizon's far side (the top row of a camera 2 m up looking down 0.9 m): its
    # ray rises and never meets the floor.
    _, hits = floor_points(rig, jnp.zeros((4, 1)), jnp.zeros((4, 1)), 0.0)
    assert not np.any(np.asarray(hits))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_the_band_leaves_out_what_lies_on_the_floor_by_the_feet(standing):
    body, rig, pose, observed = standing
    dense = make_silhouette_likelihood(body, rig, scale=1.0, window=None)
    far_band = FloorBandSilhouette(silhouette=dense, radius=jnp.asarray(1e-6), floor_height=jnp.asarray(-10.0))
    poses = jnp.stack([pose, pose.at[0].add(0.05), pose.at[5].add(0.3)])
    # With no pixel in the band it is eq. 12 itself.
    np.testing.assert_allclose(np.asarray(jax.jit(lambda p, o: far_band.log_likelihood(p, o))(poses, observed)),
                               np.asarray(jax.jit(lambda p, o: dense.log_likelihood(p, o))(poses, observed)), rtol=1e-12)
    # A shadow on the floor beside the right foot: foreground the plain likelihood pays for, the band does not.
    ankle = np.asarray(forward_kinematics(body.skeleton, pose))[body.skeleton.joint_index("rankle")]
    shadow = np.stack([ankle[:2] + np.array([0.1 * s, 0.15 * s]) for s in np.linspace(0.3, 1.6, 40)])
    shadow = np.concatenate([shadow, np.zeros((len(shadow), 1))], axis=1)
    uv = np.asarray(project_points(rig, jnp.asarray(shadow))[0])  # (points, views, 2)
    shadowed = np.array(observed)
    observed = jnp.asarray(observed)
    for view in range(4):
        for u, v in np.round(uv[:, view]).astype(int):
            shadowed[view, v, u] = True
    assert shadowed.sum() > observed.sum() + 5
    shadowed = jnp.asarray(shadowed)
    banded = FloorBandSilhouette(silhouette=dense, radius=jnp.asarray(0.45), floor_height=jnp.asarray(0.0))
    plain = jax.jit(lambda p, o: dense.log_likelihood(p, o))
    band = jax.jit(lambda p, o: banded.log_likelihood(p, o))
    plain_change = np.asarray(plain(poses, shadowed) - plain(poses, observed))
    band_change = np.asarray(band(poses, shadowed) - band(poses, observed))
    assert np.all(plain_change < -1e-3)
    np.testing.assert_allclose(band_change, 0.0, atol=1e-12)
    # The band is 0 at the floor by the feet, 1 at the head.
    feet = np.asarray(forward_kinematics(body.skeleton, pose))[[body.skeleton.joint_index(n) for n in ("lankle", "rankle")], :2]
    head = np.asarray(project_points(rig, forward_kinematics(body.skeleton, pose)[body.skeleton.joint_index("head")])[0])
    ground = np.asarray(project_points(rig, jnp.asarray([*feet[0], 0.0]))[0])
    at = np.stack([head, ground], axis=1)  # (views, 2, 2)
    w = floor_band_weights(rig, jnp.asarray(feet), jnp.asarray(at[..., 0]), jnp.asarray(at[..., 1]), 0.45, 0.0)
    np.testing.assert_array_equal(np.asarray(w), np.tile([1.0, 0.0], (4, 1)))


@pytest.mark.slow  # 24 s with an empty compilation cache (docs/testing.md)
def test_the_band_on_sampled_pixels_and_its_gradient(standing):
    body, rig, pose, observed = standing
    dense = make_silhouette_likelihood(body, rig, scale=1.0, window=None)
    sample = sample_pixels(jax.random.key(0), jnp.asarray(observed, jnp.float64), samples=300, band=default_band(30), near=default_near(30))
    sampled = SampledSilhouetteLikelihood.from_dense(dense)
    far_band = FloorBandSilhouette(silhouette=sampled, radius=jnp.asarray(1e-6), floor_height=jnp.asarray(-10.0))
    poses = jnp.stack([pose, pose.at[1].add(0.04)])
    np.testing.assert_allclose(np.asarray(jax.jit(lambda p, o: far_band.log_likelihood(p, o))(poses, sample)),
                               np.asarray(jax.jit(lambda p, o: sampled.log_likelihood(p, o))(poses, sample)), rtol=1e-12)
    # Its gradient in the pose (the band's mask held fixed) against central differences.
    banded = FloorBandSilhouette(silhouette=dense, radius=jnp.asarray(0.45), floor_height=jnp.asarray(0.0))
    moved = pose.at[0].add(0.03).at[8].add(0.2)
    f = jax.jit(lambda p: banded.log_likelihood(p[None], observed)[0])
    grad = np.asarray(jax.jit(jax.grad(f))(moved))
    for i in (0, 2, 8):
        step = jnp.zeros_like(moved).at[i].set(1e-5)
        numeric = (f(moved + step) - f(moved - step)) / 2e-5
        np.testing.assert_allclose(grad[i], float(numeric), rtol=1e-4, atol=1e-7)


def test_the_band_refuses_a_skeleton_without_ankles(standing):
    body, rig, _, _ = standing
    renamed = body.skeleton.joint_names[:10] + ("lfoot",) + body.skeleton.joint_names[11:]
    footless = eqx.tree_at(lambda b: b.skeleton, body, dataclasses.replace(body.skeleton, joint_names=renamed))
    with pytest.raises(ValueError, match="the floor band needs the ankles; the skeleton has no joint lankle"):
        FloorBandSilhouette(silhouette=make_silhouette_likelihood(footless, rig, window=None), radius=jnp.asarray(0.45),
                            floor_height=jnp.asarray(0.0))

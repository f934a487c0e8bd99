import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import humaneva_body
from jaxtrack.camera import default_rig
from jaxtrack.render import hard_silhouettes, project_capsules, soft_silhouettes

from helpers import finite_difference_check


@pytest.fixture(scope="module")
def setup():
    body = humaneva_body(dtype=jnp.float64)
    rig = default_rig(40, 30, dtype=jnp.float64)
    sk = body.skeleton
    pose = sk.zero_pose().at[2].set(0.95).at[sk.dof_index("lhip_flex")].set(0.4).at[sk.dof_index("rshoulder_abd")].set(0.6)
    return body, rig, pose


@pytest.mark.slow  # moved to the slow suite to keep the default one under 5 minutes (docs/testing.md, 2026-11-27)
def test_soft_converges_to_hard(setup):
    body, rig, pose = setup
    hard = np.asarray(hard_silhouettes(body, rig, pose), np.float64)
    assert hard.shape == (4, 30, 40) and hard.sum() > 100
    errors = [np.abs(np.asarray(soft_silhouettes(body, rig, pose, w)) - hard).mean() for w in (2.0, 0.5, 0.1, 1e-4)]
    assert errors == sorted(errors, reverse=True)
    assert errors[-1] < 1e-5
    assert np.asarray(soft_silhouettes(body, rig, pose, 1.0)).min() >= 0.0
    assert np.asarray(soft_silhouettes(body, rig, pose, 1.0)).max() <= 1.0


def test_capsule_outline_is_half_occupied():
    """A single capsule viewed head-on: occupancy 1 deep inside, 1/2 on the outline, 0 outside."""
    body, rig = humaneva_body(dtype=jnp.float64), default_rig(40, 30, dtype=jnp.float64)
    caps = project_capsules(body, rig, body.skeleton.zero_pose().at[2].set(0.95))
    torso = body.capsule_names.index("torso")
    a, b, r = (np.asarray(x[0, torso]) for x in (caps.start, caps.end, caps.radius))
    from jaxtrack.render import capsule_union

    sub = caps._replace(
        start=caps.start[:, torso : torso + 1], end=caps.end[:, torso : torso + 1], radius=caps.radius[:, torso : torso + 1]
    )
    mid = (a + b) / 2
    normal = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
    points = np.stack([mid, mid + r * normal, mid + (r + 2.0) * normal])
    occ = capsule_union(sub, jnp.asarray(points[:, 0]), jnp.asarray(points[:, 1]), 0.25)[0]
    np.testing.assert_allclose(occ, [1.0, 0.5, 0.0], atol=1e-12)
    # A capsule thinner than twice the edge width never reaches full occupancy (documented).
    assert 0.5 < float(capsule_union(sub, jnp.asarray(points[:1, 0]), jnp.asarray(points[:1, 1]), 2 * float(r))[0, 0]) < 1.0


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_soft_render_gradients(setup, getkey):
    body, rig, pose = setup
    direction = jax.random.normal(getkey(), pose.shape) * 0.1

    def total(p):  # a smooth summary of the image: area and first moments per view
        sil = soft_silhouettes(body, rig, p, 1.5)
        v, u = jnp.mgrid[0:30, 0:40]
        return jnp.stack([sil.sum((1, 2)), (sil * u).sum((1, 2)), (sil * v).sum((1, 2))])

    finite_difference_check(total, pose, direction, eps=1e-6, rtol=2e-4, atol=1e-5)
    # shape (radii) and camera (translation) too
    finite_difference_check(
        lambda r: soft_silhouettes(eqx.tree_at(lambda b: b.radii, body, r), rig, pose, 1.5).sum((1, 2)),
        body.radii,
        jax.random.normal(getkey(), body.radii.shape) * 0.01,
        rtol=2e-4,
        atol=1e-5,
    )
    finite_difference_check(
        lambda t: soft_silhouettes(body, eqx.tree_at(lambda c: c.t, rig, t), pose, 1.5).sum((1, 2)),
        rig.t,
        jax.random.normal(getkey(), rig.t.shape) * 0.05,
        rtol=2e-4,
        atol=1e-5,
    )


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_render_jit_and_vmap(setup, getkey):
    body, rig, pose = setup
    poses = pose + 0.05 * jax.random.normal(getkey(), (3,) + pose.shape)
    batched = soft_silhouettes(body, rig, poses, 1.0)
    looped = jnp.stack([soft_silhouettes(body, rig, p, 1.0) for p in poses])
    vmapped = jax.vmap(lambda p: soft_silhouettes(body, rig, p, 1.0))(poses)
    jitted = jax.jit(soft_silhouettes)(body, rig, poses, 1.0)
    for other in (looped, vmapped, jitted):
        np.testing.assert_allclose(batched, other, rtol=1e-12, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("weighted", [False, True])
def test_union_statistics_backward_pass_equals_autodiff_of_the_product(getkey, weighted):
    """The recomputing backward pass of ``union_statistics`` (and of ``weighted_union_statistics``,
    with per-pixel area and overlap weights as the sampled likelihood uses) against reverse-mode
    autodiff of the unrolled union, including pixels deep inside a capsule (an exact zero of
    ``1 - o``)."""
    from jaxtrack.render import ProjectedCapsules, capsule_union, union_statistics, weighted_union_statistics

    n, v, k, p = 3, 2, 5, 200
    start = 20 * jax.random.uniform(getkey(), (n, v, k, 2), jnp.float64)
    end = start + 6 * jax.random.normal(getkey(), (n, v, k, 2), jnp.float64)
    radius = 1.0 + 3 * jax.random.uniform(getkey(), (n, v, k), jnp.float64)
    px, py = (20 * jax.random.uniform(getkey(), (p,), jnp.float64) for _ in range(2))
    px = px.at[0].set(start[0, 0, 0, 0])  # on a capsule's axis: its occupancy is exactly 1
    py = py.at[0].set(start[0, 0, 0, 1])
    observed = (jax.random.uniform(getkey(), (v, p)) > 0.5).astype(jnp.float64)
    area_weight = 0.5 + jax.random.uniform(getkey(), (v, p), jnp.float64) if weighted else jnp.ones((1,), jnp.float64)
    edge = jnp.asarray(1.0, jnp.float64)
    a_bar, b_bar = jax.random.normal(getkey(), (2, n, v), jnp.float64)

    def loss(stats):
        return lambda s, e, r: jnp.sum(a_bar * stats(s, e, r)[0] + b_bar * stats(s, e, r)[1])

    def reference(s, e, r):
        sil = capsule_union(ProjectedCapsules(s, e, r, None), px, py, edge)
        return jnp.sum(sil * area_weight, -1), jnp.sum(sil * area_weight * observed, -1)

    def custom(s, e, r):
        if weighted:
            return weighted_union_statistics(s, e, r, px, py, area_weight, area_weight * observed, edge)
        return union_statistics(s, e, r, px, py, observed, edge)

    for a, b in zip(jax.grad(loss(custom), (0, 1, 2))(start, end, radius), jax.grad(loss(reference), (0, 1, 2))(start, end, radius)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.asarray(custom(start, end, radius)), np.asarray(reference(start, end, radius)), rtol=1e-12)

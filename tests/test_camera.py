import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.camera import (
    check_in_front,
    decompose_projection_matrix,
    default_rig,
    look_at,
    make_rig,
    project_points,
    rig_from_projection_matrices,
)

from helpers import finite_difference_check


def opencv_project(K, R, t, dist, X):
    """Reference: OpenCV's projectPoints written out in NumPy."""
    cam = X @ R.T + t
    x, y = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
    k1, k2, p1, p2, k3 = dist
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([K[0, 0] * xd + K[0, 1] * yd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=1)


@pytest.fixture
def rig():
    dist = np.array([[-0.2, 0.05, 0.001, -0.002, 0.01]] * 4)
    return default_rig(640, 480, dist=dist, dtype=jnp.float64)


def test_projection_matches_opencv_formula(rig, getkey):
    X = np.asarray(jax.random.uniform(getkey(), (20, 3), minval=-1, maxval=1)) + [0, 0, 1]
    uv, _depth, front = project_points(rig, jnp.asarray(X))
    assert uv.shape == (20, 4, 2) and bool(front.all())
    for c in range(4):
        ref = opencv_project(*(np.asarray(a[c]) for a in (rig.K, rig.R, rig.t, rig.dist)), X)
        np.testing.assert_allclose(uv[:, c], ref, rtol=1e-10)


def test_target_projects_to_principal_point():
    rig = default_rig(80, 60, dtype=jnp.float64)
    uv, depth, _ = project_points(rig, jnp.array([0.0, 0.0, 0.9]))
    np.testing.assert_allclose(uv, np.tile([[39.5, 29.5]], (4, 1)), atol=1e-9)
    np.testing.assert_allclose(depth, np.full(4, np.hypot(6.0, 1.1)), rtol=1e-10)


def test_points_behind_camera_are_flagged(rig):
    centre = np.asarray(rig.centers[0])
    R0 = np.asarray(rig.R[0])
    behind = centre - 2.0 * R0[2]  # two metres behind camera 0
    _, depth, front = project_points(rig, jnp.asarray(behind))
    assert not bool(front[0]) and float(depth[0]) < 0
    with pytest.raises(ValueError, match="camera 'C1' is behind the body"):
        check_in_front(rig, behind[None])
    check_in_front(rig, np.zeros((1, 3)))  # the centre of the area is visible to all


def test_rq_decomposition_round_trip(rig):
    K, R, t = (np.asarray(a[2]) for a in (rig.K, rig.R, rig.t))
    K = K.copy()
    K[0, 1] = 0.7  # skew
    P = K @ np.hstack([R, t[:, None]])
    for scale in (1.0, -3.5):
        K2, R2, t2 = decompose_projection_matrix(scale * P)
        np.testing.assert_allclose(K2, K, atol=1e-9)
        np.testing.assert_allclose(R2, R, atol=1e-12)
        np.testing.assert_allclose(t2, t, atol=1e-10)
    rig2 = rig_from_projection_matrices(P[None], [(640, 480)], dtype=jnp.float64)
    X = jnp.array([[0.1, 0.2, 1.0]])
    np.testing.assert_allclose(project_points(rig2, X)[0][0, 0], opencv_project(K, R, t, np.zeros(5), np.asarray(X))[0])
    with pytest.raises(ValueError, match="singular"):
        decompose_projection_matrix(np.zeros((3, 4)))


def test_projection_gradients(rig, getkey):
    X = jnp.asarray(jax.random.uniform(getkey(), (5, 3), minval=-0.5, maxval=0.5)) + jnp.array([0, 0, 1.0])
    finite_difference_check(lambda x: project_points(rig, x)[0], X, jax.random.normal(getkey(), X.shape))

    def by_translation(t):
        return project_points(make_like(rig, t=t), X)[0]

    finite_difference_check(by_translation, rig.t, jax.random.normal(getkey(), rig.t.shape))


def make_like(rig, **changes):
    import equinox as eqx

    names = list(changes)
    return eqx.tree_at(lambda r: [getattr(r, n) for n in names], rig, [changes[n] for n in names])


def test_jit_equals_no_jit(rig):
    X = jnp.array([[0.3, -0.2, 1.2], [0.0, 0.0, 0.1]])
    a = jax.jit(project_points)(rig, X)
    with jax.disable_jit():
        b = project_points(rig, X)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-12)


def test_make_rig_validation():
    K = np.array([[[100.0, 0, 40], [0, 100, 30], [0, 0, 1]]])
    R, t = look_at([3, 0, 1], [0, 0, 1])
    with pytest.raises(ValueError, match="trailing shape"):
        make_rig(K[:, :2], R[None], t[None], [(80, 60)])
    with pytest.raises(ValueError, match="not a rotation"):
        make_rig(K, 2 * R[None], t[None], [(80, 60)])
    with pytest.raises(ValueError, match="non-finite"):
        make_rig(K, R[None], np.array([[np.nan, 0, 0]]), [(80, 60)])
    with pytest.raises(ValueError, match="image_size"):
        make_rig(K, R[None], t[None], [(80, 60, 3)])
    with pytest.raises(ValueError, match="positive fx"):
        make_rig(-K, R[None], t[None], [(80, 60)])
    rig = make_rig(K, R[None], t[None], [(80, 60)])
    small = rig.resized(40, 30)
    uv_big, _, _ = project_points(rig, jnp.array([0.0, 0.1, 1.2]))
    uv_small, _, _ = project_points(small, jnp.array([0.0, 0.1, 1.2]))
    np.testing.assert_allclose((np.asarray(uv_big) + 0.5) / 2 - 0.5, uv_small, rtol=1e-6)


def test_default_rig_refuses_no_views_and_a_bad_distance():
    from jaxtrack.camera import default_rig

    with pytest.raises(ValueError, match="num_views must be a positive integer, got 0"):
        default_rig(80, 60, num_views=0)
    with pytest.raises(ValueError, match="distance must be a positive number of metres"):
        default_rig(80, 60, distance=float("nan"))
    assert default_rig(80, 60, num_views=1).num_views == 1


def test_default_rig_azimuth_turns_the_cameras_about_the_vertical(getkey):
    """A rig turned by ``azimuth`` sees the world turned by the same angle as the default rig
    sees it: the same pixels and depths; 45 degrees is the default, to the bit."""
    base = default_rig(80, 60, dtype=jnp.float64)
    same = default_rig(80, 60, azimuth=45.0, dtype=jnp.float64)
    np.testing.assert_array_equal(base.R, same.R)
    np.testing.assert_array_equal(base.t, same.t)
    turned = default_rig(80, 60, azimuth=45.0 + 30.0, dtype=jnp.float64)
    c, s = np.cos(np.deg2rad(30.0)), np.sin(np.deg2rad(30.0))
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    points = np.asarray(jax.random.uniform(getkey(), (20, 3), jnp.float64, -1.0, 1.0)) + np.array([0.0, 0.0, 1.0])
    uv, depth, _ = project_points(base, jnp.asarray(points))
    uv_turned, depth_turned, _ = project_points(turned, jnp.asarray(points @ Rz.T))
    np.testing.assert_allclose(uv_turned, uv, atol=1e-9)
    np.testing.assert_allclose(depth_turned, depth, atol=1e-12)
    centre = -np.asarray(turned.R[0]).T @ np.asarray(turned.t[0])  # the first camera, 6 m out at 75 degrees
    np.testing.assert_allclose(np.degrees(np.arctan2(centre[1], centre[0])), 75.0, atol=1e-9)
    listed = default_rig(80, 60, azimuth=[75.0, 165.0, 255.0, 345.0], dtype=jnp.float64)  # one per camera
    np.testing.assert_allclose(listed.R, turned.R, atol=1e-12)
    np.testing.assert_allclose(listed.t, turned.t, atol=1e-12)
    with pytest.raises(ValueError, match="azimuth must be a finite number of degrees"):
        default_rig(80, 60, azimuth=float("inf"))
    with pytest.raises(ValueError, match="azimuth gives 3 directions for 4 cameras"):
        default_rig(80, 60, azimuth=[0.0, 90.0, 180.0])

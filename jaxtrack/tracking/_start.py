"""The automatic start: the first frame's pose found from the images alone, no ground truth.

1. *Where*: the root's floor position by triangulation. With 2-D keypoints, each joint seen with
   confidence in two or more views is triangulated (the least-squares point nearest the
   views' rays, confidence-weighted) and the pelvis gives the position, the hips the heading.
   With silhouettes only, the views' mask centres (the median pixel: clutter and shadows move a
   mean) are triangulated, near the pelvis, and the heading is left to the search.
2. *What pose*: an annealed particle search (000 sec. 4's annealing, its rate chosen per layer
   so that ``survival`` of the particles survive, ``filters.choose_beta``) over the manifold's
   latent space (particles start at the training latent points), the root's heading (all
   around, and half of the particles within 0.5 rad of the keypoints' heading when there is
   one: in small images the hips are a few pixels apart) and its floor position (+- 0.2 m around
   the triangulated one), scored by the tracking likelihood on the first ``frames`` frames
   together. The root's height is held at ``root_height`` (``height_spread`` 0; the validation
   motion's mean, on the person's own legs where ``prepare_test`` knows them):
   one frame's silhouettes trade the height for the knees' bend, and a search that moved it
   left the root 4-7 cm low on filmed silhouettes, an offset the tracker then carried for the
   whole take (docs/video.md); the tracker moves it from there. The noise of each layer
   shrinks geometrically (``shrink``). The best particle seen wins.
3. *Polish*: ``polish_steps`` steps of Adam on the whole pose vector (every joint angle, the
   root's position and orientation), ascending the same log-likelihood by autodiff, the angles
   kept within the skeleton's limits: the search's pose lies on the manifold, the person's a
   little off it.

The body calibration (``likelihood.calibrate_body``) then starts from it, as it would from a
ground-truth pose.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array
from .._tree import cast_floating
from ..body import GLOBAL_DOFS, HUMANEVA_JOINTS, Skeleton, forward_kinematics
from ..camera import CameraRig
from ..filters import choose_beta, systematic

START_CHOICES = ("truth", "auto")  # where tracking starts: frame 0's ground truth, or ``automatic_start``
_POSITION_SPREAD = 0.2  # metres: the floor position's first spread around the triangulated one
_HEADING_SPREAD = 0.5  # radians around the keypoints' heading


@dataclasses.dataclass(frozen=True)
class StartSearch:
    """Settings of the automatic start's annealed search.

    Attributes:
        particles: particles per layer.
        layers: annealing layers.
        survival: the fraction of effective particles each layer keeps (the annealing rate).
        shrink: the factor on every noise scale per layer.
        frames: the first frames scored together (the pose is held, the root moved by nothing).
        height_spread: the root height's search spread (metres, a standard deviation around
            ``root_height``; its moves are two thirds of it); 0 holds the height (the default).
        polish_steps: Adam steps on the whole pose after the search (0: none).
        polish_rate: their learning rate (radians and metres).
    """

    particles: int = 1024
    layers: int = 12
    survival: float = 0.5
    shrink: float = 0.75
    frames: int = 1
    height_spread: float = 0.0
    polish_steps: int = 0
    polish_rate: float = 0.01

    def __post_init__(self):
        for name in ("particles", "layers", "frames"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"StartSearch.{name} must be a whole number >= 1, got {value!r}")
        if not 0 < self.survival < 1:
            raise ValueError(f"StartSearch.survival must be in (0, 1), got {self.survival}")
        if not (isinstance(self.polish_steps, int) and self.polish_steps >= 0):
            raise ValueError(f"StartSearch.polish_steps must be a whole number >= 0, got {self.polish_steps!r}")
        if not self.polish_rate > 0:
            raise ValueError(f"StartSearch.polish_rate must be positive, got {self.polish_rate}")
        if not (np.isfinite(self.height_spread) and self.height_spread >= 0):
            raise ValueError(f"StartSearch.height_spread must be a length >= 0 in metres, got {self.height_spread!r}")
        if not 0 < self.shrink <= 1:
            raise ValueError(f"StartSearch.shrink must be in (0, 1], got {self.shrink}")


def camera_rays(rig: CameraRig, pixels) -> tuple[np.ndarray, np.ndarray]:
    """Per view, the camera centre (C, 3) and the unit world direction (C, ..., 3) through
    pixels (C, ..., 2) (lens distortion ignored)."""
    K, R, t = (np.asarray(x, np.float64) for x in (rig.K, rig.R, rig.t))
    pixels = np.asarray(pixels, np.float64)
    homogeneous = np.concatenate([pixels, np.ones(pixels.shape[:-1] + (1,))], axis=-1)
    camera = np.einsum("cij,c...j->c...i", np.linalg.inv(K), homogeneous)
    world = np.einsum("cji,c...j->c...i", R, camera)
    centres = -np.einsum("cji,cj->ci", R, t)
    return centres, world / np.linalg.norm(world, axis=-1, keepdims=True)


def triangulate(rig: CameraRig, pixels, weights) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares points nearest the views' rays: pixels (C, ..., 2), weights (C, ...) >= 0
    (0: not seen). Returns ``(points (..., 3), seen (...) bool)``, seen by two views or more."""
    centres, directions = camera_rays(rig, pixels)
    weights = np.asarray(weights, np.float64)
    eye = np.eye(3)
    project = eye - directions[..., :, None] * directions[..., None, :]  # (C, ..., 3, 3)
    w = weights[..., None, None]
    A = np.sum(w * project, axis=0)
    b = np.sum(w * np.einsum("c...ij,cj->c...i", project, centres)[..., :, None], axis=0)[..., 0]
    seen = np.asarray(np.sum(weights > 0, axis=0) >= 2)
    A = np.where(seen[..., None, None], A, eye)
    return np.linalg.solve(A, b[..., None])[..., 0], seen


def mask_centroids(masks) -> tuple[np.ndarray, np.ndarray]:
    """(C, 2) robust centres (u, v) of (C, H, W) masks, the median of their pixels' columns and
    rows (a blob of clutter or a shadow moves a mean, not a median), and (C,) their areas."""
    masks = np.asarray(masks) > 0
    centres = np.zeros((masks.shape[0], 2))
    for c, mask in enumerate(masks):
        rows, cols = np.nonzero(mask)
        if rows.size:
            centres[c] = np.median(cols), np.median(rows)
    return centres, masks.sum(axis=(1, 2)).astype(np.float64)


def _heading_of_left(left_xy) -> float:
    return float(np.arctan2(left_xy[1], left_xy[0]))


def root_guess(rig: CameraRig, skeleton: Skeleton, *, silhouettes=None, keypoints=None) -> tuple[np.ndarray, float | None, str]:
    """The root's floor position (2,) and heading (radians, or None when unknown) of the first
    frame from its keypoints (C, 15, 3) or, failing them, its silhouettes (C, H, W), and how.

    Raises:
        ValueError: when neither places the person (fewer than two views see them).
    """
    if keypoints is not None:
        keypoints = np.asarray(keypoints, np.float64)
        points, seen = triangulate(rig, keypoints[..., :2], keypoints[..., 2])
        pelvis, lhip, rhip = (HUMANEVA_JOINTS.index(n) for n in ("pelvis", "lhip", "rhip"))
        if seen[pelvis] or (seen[lhip] and seen[rhip]):
            root = points[pelvis] if seen[pelvis] else 0.5 * (points[lhip] + points[rhip])
            heading = None
            if seen[lhip] and seen[rhip]:
                rest = np.asarray(forward_kinematics(skeleton, jnp.zeros(skeleton.num_dofs, jnp.float64)), np.float64)
                index = skeleton.joint_index
                rest_left = rest[index("lhip"), :2] - rest[index("rhip"), :2]
                left = points[lhip, :2] - points[rhip, :2]
                heading = _heading_of_left(left) - _heading_of_left(rest_left)
            return root[:2], heading, "keypoints"
    if silhouettes is not None:
        centroids, area = mask_centroids(silhouettes)
        point, seen = triangulate(rig, centroids, area > 0)
        if seen:
            return point[:2], None, "silhouette centroids"
    raise ValueError("the automatic start cannot place the person: fewer than two cameras see them in the first frame")


class PoseSamples(eqx.Module):
    """What the automatic start searches when the tracker has no manifold (SIR or APF with no
    model file): the motion's (N, A) joint angles stand for latent points and decode to
    themselves (``training_latent`` and ``predictor`` as a manifold's)."""

    angles: Array

    def training_latent(self):
        return self.angles

    def predictor(self):
        return _Identity()


class _Identity(eqx.Module):
    def __call__(self, x):
        return x, jnp.zeros(x.shape[:-1], x.dtype)


def automatic_start(key, likelihood, observations, model, rig: CameraRig, skeleton: Skeleton, *, root_height: float,
                    silhouettes=None, keypoints=None, search: StartSearch = StartSearch(), dtype=jnp.float32):
    """The first frame's pose (D,) from the images (module docstring).

    Args:
        key: PRNG key of the search.
        likelihood: the tracking likelihood (``AbstractLikelihood``).
        observations: the frames' observations, a pytree with a leading frame axis (at least
            ``search.frames``).
        model: the manifold (``predictor()`` decodes latent points into joint angles;
            ``training_latent`` seeds the particles).
        rig, skeleton: the cameras and the body's skeleton (its pose layout).
        root_height: the root's height above the floor, metres (e.g. the validation motion's mean).
        silhouettes, keypoints: the first frame's (C, H, W) masks and (C, 15, 3) keypoints, for
            ``root_guess``.

    Returns ``(pose (D,) float64 NumPy, info dict)``: the info holds how the root was placed,
    the heading found and the best log-likelihood.
    """
    position, heading, how = root_guess(rig, skeleton, silhouettes=silhouettes, keypoints=keypoints)
    frames = jax.tree.map(lambda x: jnp.asarray(x[: search.frames]), observations)
    with jax.enable_x64(True):  # the predictive map factorised in float64 (a fitted model's own), then searched in dtype
        latent = jnp.asarray(np.asarray(model.training_latent(), np.float64), dtype)
        predict = cast_floating(model.predictor(), dtype)
    spread = jnp.std(latent, axis=0)
    layout = list(skeleton.pose_layout)
    slots = [layout.index(n) for n in ("root_x", "root_y", "root_z", "root_yaw")]
    n = search.particles
    k_pick, k_yaw, k_xy, k_z, k_run = jax.random.split(key, 5)
    state = {
        "latent": latent[jax.random.randint(k_pick, (n,), 0, latent.shape[0])],
        "yaw": _headings(k_yaw, n, heading, dtype),
        "xy": jnp.asarray(position, dtype) + _POSITION_SPREAD * jax.random.normal(k_xy, (n, 2), dtype),
        "z": root_height + search.height_spread * jax.random.normal(k_z, (n,), dtype),
    }
    scales = {"latent": 0.25 * spread, "yaw": 0.3 if heading is None else 0.15, "xy": 0.08, "z": search.height_spread * 2.0 / 3.0}
    found, best = _search(k_run, state, scales, frames, likelihood, predict, slots, skeleton.num_dofs, search)
    polished, value = found, best
    if search.polish_steps:
        polished, value = _polish(found, frames, likelihood, skeleton.lower.astype(dtype), skeleton.upper.astype(dtype),
                                  search.polish_steps, search.polish_rate)
    better = bool(value >= best)  # kept only if it scores better
    pose = np.asarray(polished if better else found, np.float64)
    info = {"placed_by": how, "heading": float(pose[slots[3]]), "log_likelihood": float(max(value, best) if better else best),
            "searched_log_likelihood": float(best)}
    return pose, info


def _headings(key, n: int, heading, dtype):
    """Headings all around, and with a measured heading, half of them within +-0.5 rad of it (a
    detector's hips a few pixels apart can point the wrong way: the likelihood decides)."""
    around = jax.random.uniform(key, (n,), dtype, -jnp.pi, jnp.pi)
    if heading is None:
        return around
    near = heading + _HEADING_SPREAD / jnp.pi * around
    return jnp.where(jnp.arange(n) % 2 == 0, near, around)


def _assemble(state, predict, slots, num_dofs, dtype):
    angles, _ = predict(state["latent"])
    n = angles.shape[0]
    pose = jnp.zeros((n, num_dofs), dtype).at[:, GLOBAL_DOFS:].set(angles.astype(dtype))
    pose = pose.at[:, slots[0]].set(state["xy"][:, 0]).at[:, slots[1]].set(state["xy"][:, 1])
    return pose.at[:, slots[2]].set(state["z"]).at[:, slots[3]].set(state["yaw"])


@eqx.filter_jit
def _search_jit(key, state, scales, frames, likelihood, predict, slots, num_dofs, search):
    dtype = state["xy"].dtype

    def score(s):
        pose = _assemble(s, predict, slots, num_dofs, dtype)
        total = jax.vmap(lambda obs: likelihood(pose, obs))(frames).sum(axis=0)
        return pose, jnp.where(jnp.isfinite(total), total, -jnp.inf)

    def layer(carry, inputs):
        s, best_pose, best_value = carry
        k, level = inputs
        pose, value = score(s)
        top = jnp.argmax(value)
        better = value[top] > best_value
        best_pose = jnp.where(better, pose[top], best_pose)
        best_value = jnp.where(better, value[top], best_value)
        beta = choose_beta(value, search.survival)
        k_resample, k_noise = jax.random.split(k)
        chosen = systematic(k_resample, jnp.where(jnp.isfinite(value), beta * value, -jnp.inf))
        s = jax.tree.map(lambda x: x[chosen], s)
        factor = search.shrink ** level
        keys = dict(zip(s, jax.random.split(k_noise, len(s))))
        s = {name: x + factor * scales[name] * jax.random.normal(keys[name], x.shape, dtype) for name, x in s.items()}
        return (s, best_pose, best_value), None

    levels = jnp.arange(search.layers, dtype=dtype)
    start = (state, jnp.zeros(num_dofs, dtype), jnp.asarray(-jnp.inf, dtype))
    (s, best_pose, best_value), _ = jax.lax.scan(layer, start, (jax.random.split(key, search.layers), levels))
    pose, value = score(s)  # the last layer's moves, scored
    top = jnp.argmax(value)
    better = value[top] > best_value
    return jnp.where(better, pose[top], best_pose), jnp.where(better, value[top], best_value)


def _search(key, state, scales, frames, likelihood, predict, slots, num_dofs, search):
    return _search_jit(key, state, scales, frames, likelihood, predict, tuple(slots), num_dofs, search)


@eqx.filter_jit
def _polish(pose, frames, likelihood, lower, upper, steps: int, rate: float):
    """Adam ascent of the frames' summed log-likelihood over the whole pose, within the limits."""
    import optax

    def objective(p):
        total = jax.vmap(lambda obs: likelihood(p[None], obs)[0])(frames).sum()
        return -jnp.where(jnp.isfinite(total), total, -1e30)

    optimiser = optax.adam(rate)

    def step(carry, _):
        p, state = carry
        grad = jax.grad(objective)(p)
        grad = jnp.where(jnp.isfinite(grad), grad, 0.0)
        updates, state = optimiser.update(grad, state, p)
        return (jnp.clip(optax.apply_updates(p, updates), lower, upper), state), None

    (pose, _), _ = jax.lax.scan(step, (pose, optimiser.init(pose)), None, length=steps)
    return pose, -objective(pose)

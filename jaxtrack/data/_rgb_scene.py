"""RGB test scenes: the solid body (``SolidBody``, never the tracker's capsules) ray-cast in
colour over a real photograph, the way a camera sees a person, for the video path's tests.

Per pixel (supersampled ``samples`` x ``samples``), the ray from the camera meets the nearest
ellipsoid in front of it, or none. A body pixel takes its part's albedo (shirt, trousers, skin,
shoes: ``PART_COLOURS``), striped along the shirt's bones (a simple texture), shaded by a
directional light: ``ambient + (1 - ambient) max(0, n . l)`` with ``n`` the ellipsoid's
normal at the hit. A background pixel is the photograph, per camera a different crop
(``background_photo``), darkened by ``shadow_strength`` where its ray meets the floor (z = 0)
at a point from which the light is blocked by the body: exact cast shadows of the whole body,
falling wherever the floor would be. The whole image is then multiplied by a slow per-camera
lighting change, ``1 + lighting_change sin(2 pi t / lighting_period + phase)``, and Gaussian
sensor noise is added before rounding to 8 bits. The true silhouette is the body's coverage of
the pixel's sub-samples, kept at one half (``render_solid_silhouettes``'s rule).

Everything random is drawn from the PRNG key with ``jax.random.fold_in(key, frame)``, so a
scene is the same for one key whatever the chunking.
"""

from __future__ import annotations

import dataclasses
import os

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..camera import CameraRig, image_shape
from ._solid_body import SolidBody, _rays

# Albedo (linear RGB in [0, 1]) of each solid's clothing, by ``SolidBody.names``.
_SHIRT, _TROUSERS, _SKIN, _SHOES = (0.72, 0.20, 0.16), (0.20, 0.27, 0.47), (0.86, 0.64, 0.50), (0.12, 0.11, 0.10)
PART_COLOURS = {
    "pelvis": _TROUSERS, "torso": _SHIRT, "neck": _SKIN, "head": _SKIN,
    "lupper_arm": _SHIRT, "lforearm": _SKIN, "lhand": _SKIN, "rupper_arm": _SHIRT, "rforearm": _SKIN, "rhand": _SKIN,
    "lthigh": _TROUSERS, "lshin": _TROUSERS, "lfoot": _SHOES, "rthigh": _TROUSERS, "rshin": _TROUSERS, "rfoot": _SHOES,
    "girdle": _SHIRT, "ldeltoid": _SHIRT, "rdeltoid": _SHIRT, "lelbow": _SKIN, "relbow": _SKIN, "lknee": _TROUSERS, "rknee": _TROUSERS,
}
_STRIPED = ("torso", "lupper_arm", "rupper_arm")


@dataclasses.dataclass(frozen=True)
class PhotoSettings:
    """How the camera sees the scene (module docstring); 0 switches an effect off.

    Attributes:
        sensor_noise: standard deviation of the per-pixel Gaussian noise, 8-bit levels.
        lighting_change: relative amplitude of the slow brightness change of each camera.
        lighting_period: its period, seconds.
        shadow_strength: the fraction of light the body's shadow takes from the floor.
        light_direction: (x, y, z) towards the light, world (z up).
        ambient: the share of light that reaches surfaces facing away from it.
        stripes: contrast of the shirt's stripes (0: plain).
        samples: rays per pixel along each axis (anti-aliasing).
    """

    sensor_noise: float = 2.0
    lighting_change: float = 0.05
    lighting_period: float = 3.0
    shadow_strength: float = 0.45
    light_direction: tuple[float, float, float] = (0.35, -0.25, 1.0)
    ambient: float = 0.45
    stripes: float = 0.25
    samples: int = 2

    def __post_init__(self):
        for name in ("sensor_noise", "lighting_change", "shadow_strength", "ambient", "stripes"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"PhotoSettings.{name} must be >= 0, got {value}")
        for name in ("shadow_strength", "ambient", "stripes", "lighting_change"):
            if getattr(self, name) > 1:
                raise ValueError(f"PhotoSettings.{name} must be at most 1, got {getattr(self, name)}")
        if not self.lighting_period > 0:
            raise ValueError(f"PhotoSettings.lighting_period must be positive seconds, got {self.lighting_period}")
        if np.asarray(self.light_direction, np.float64)[2] <= 0:
            raise ValueError(f"PhotoSettings.light_direction must point up (z > 0) to cast shadows on the floor, "
                             f"got {self.light_direction}")
        if not (isinstance(self.samples, int) and self.samples >= 1):
            raise ValueError(f"PhotoSettings.samples must be a whole number >= 1, got {self.samples!r}")


def default_background_path() -> str:
    """A real photograph shipped with matplotlib (``sample_data/grace_hopper.jpg``, 512 x 600)."""
    import matplotlib

    return os.path.join(matplotlib.get_data_path(), "sample_data", "grace_hopper.jpg")


def background_photo(width: int, height: int, view: int, *, path: str | None = None) -> np.ndarray:
    """(H, W, 3) uint8: a crop of the photograph at ``path`` (default ``default_background_path``)
    resized to the image, a different crop per ``view`` (slid along the picture, mirrored for
    odd views), so that no two cameras see the same background."""
    import imageio.v3 as iio

    from ..image import resize

    photo = np.asarray(iio.imread(path or default_background_path()))
    if photo.ndim == 2:
        photo = np.repeat(photo[..., None], 3, axis=-1)
    photo = photo[..., :3]
    rows, cols = photo.shape[:2]
    aspect = width / height
    crop_h = int(min(rows, cols / aspect) * 0.8)
    crop_w = int(crop_h * aspect)
    golden = 0.6180339887
    fy, fx = (view * golden) % 1.0, (view * golden * golden + 0.3) % 1.0
    top, left = int(fy * (rows - crop_h)), int(fx * (cols - crop_w))
    crop = photo[top : top + crop_h, left : left + crop_w].astype(np.float32) / 255.0
    if view % 2:
        crop = crop[:, ::-1]
    out = np.moveaxis(np.asarray(resize(jnp.asarray(np.moveaxis(crop, -1, 0)), height, width)), 0, -1)
    return np.clip(np.round(out * 255.0), 0, 255).astype(np.uint8)


def _quadric(inverse):
    """``M = A^-T A^-1`` of an ellipsoid ``c + A u`` (|u| <= 1): its points have (p-c)^T M (p-c) <= 1."""
    return inverse.T @ inverse


def _form(M, x, y):
    """``x^T M y`` of (3, ...) component stacks (elementwise, so XLA fuses it over the pixels)."""
    return sum(M[i, j] * x[i] * y[j] for i in range(3) for j in range(3))


def _near_hit(origin, dirs, centre, M):
    """Distance along each ray to the ellipsoid's near side (inf: missed or behind); ``dirs``
    (3, ...) ray directions from ``origin`` (3,)."""
    o = origin - centre
    a = _form(M, dirs, dirs)
    b = sum((M @ o)[i] * dirs[i] for i in range(3))
    disc = b * b - a * (o @ M @ o - 1.0)
    root = jnp.sqrt(jnp.maximum(disc, 0.0))
    near = (-b - root) / a
    far = (-b + root) / a
    t = jnp.where(near > 0, near, far)  # a camera inside an ellipsoid sees its far side
    return jnp.where((disc >= 0) & (far > 0), t, jnp.inf)


def _blocked(points, light, centres, quadrics):
    """Whether the ray from each point (3, ...) towards the light meets any ellipsoid."""

    def one(k, out):
        M = quadrics[k]
        q = [points[i] - centres[k, i] for i in range(3)]
        a = light @ M @ light
        Ml = M @ light
        b = sum(Ml[i] * q[i] for i in range(3))
        disc = b * b - a * (_form(M, q, q) - 1.0)
        return out | ((disc >= 0) & (-b + jnp.sqrt(jnp.maximum(disc, 0.0)) > 0))

    # fori_loop, not a Python loop: one ellipsoid's code compiled once (3x faster to compile)
    return jax.lax.fori_loop(0, centres.shape[0], one, jnp.zeros(points[0].shape, bool))


def _shade_view(origin, dirs, background, centres, axes, albedo, striped, settings: dict):
    """(H, W, s*s, 3) rays of one camera -> colour (H, W, 3) in [0, 1] and coverage (H, W)."""
    inverses = jnp.linalg.inv(axes)
    quadrics = jax.vmap(_quadric)(inverses)
    d = jnp.moveaxis(dirs, -1, 0)  # (3, H, W, s*s)

    def nearer(k, carry):  # the nearest ellipsoid along each ray
        nearest, part = carry
        t = _near_hit(origin, d, centres[k], quadrics[k])
        closer = t < nearest
        return jnp.where(closer, t, nearest), jnp.where(closer, k, part)

    nearest, part = jax.lax.fori_loop(0, centres.shape[0], nearer,
                                      (jnp.full(d.shape[1:], jnp.inf, d.dtype), jnp.zeros(d.shape[1:], jnp.int32)))
    hit = jnp.isfinite(nearest)
    reach = jnp.where(hit, nearest, 0.0)
    point = [origin[i] + reach * d[i] for i in range(3)]

    def surface(k, carry):  # the normal A^-T A^-1 (p - c) and the coordinate along the bone at the hit
        n0, n1, n2, along = carry
        mine = part == k
        q = [point[i] - centres[k, i] for i in range(3)]
        n = [jnp.where(mine, sum(quadrics[k, i, j] * q[j] for j in range(3)), old) for i, old in enumerate((n0, n1, n2))]
        return (*n, jnp.where(mine, sum(inverses[k, 2, j] * q[j] for j in range(3)), along))

    zero = jnp.zeros_like(reach)
    *normal, along = jax.lax.fori_loop(0, centres.shape[0], surface, (zero, zero, zero, zero))
    length = jnp.sqrt(sum(n * n for n in normal))
    light = settings["light"]
    facing = sum(light[i] * normal[i] for i in range(3)) / jnp.maximum(length, 1e-12)
    shade = settings["ambient"] + (1.0 - settings["ambient"]) * jnp.maximum(facing, 0.0)
    stripe = 1.0 - settings["stripes"] * striped[part] * (jnp.sin(6.0 * jnp.pi * along) > 0)
    body = albedo[part] * (shade * stripe)[..., None]
    # The floor behind the person: darkened where the body blocks the light.
    down = (d[2] < 0) & (origin[2] > 0)
    t_floor = jnp.where(down, -origin[2] / jnp.where(down, d[2], -1.0), 0.0)
    floor = [origin[i] + t_floor * d[i] + 1e-3 * light[i] for i in range(3)]
    shadow = down & _blocked(floor, light, centres, quadrics)
    behind = background[:, :, None, :] * (1.0 - settings["shadow_strength"] * shadow)[..., None]
    colour = jnp.where(hit[..., None], body, behind)
    return jnp.mean(colour, axis=-2), jnp.mean(hit, axis=-1)


@eqx.filter_jit
def _render_frames(key, frame_ids, skeleton, girth, joints, poses, backgrounds, origins, directions, albedo, striped, settings,
                   fps, drop):
    """(frames, views, H, W, 3) uint8 pictures and (frames, views, H, W) bool true masks."""

    def frame(frame_id, pose):
        centres, axes = SolidBody(skeleton, girth, joints).ellipsoids(pose)
        centres = centres.at[:, 2].add(-drop)  # an empty scene: the solids far below the floor, out of every ray's way
        # lax.map, not vmap: one view at a time keeps every per-ray array fused and in cache (8x faster).
        colour, coverage = jax.lax.map(lambda odb: _shade_view(*odb, centres, axes, albedo, striped, settings),
                                       (origins, directions, backgrounds))
        phase = 2.0 * jnp.pi * jnp.arange(colour.shape[0], dtype=colour.dtype) / colour.shape[0]
        gain = 1.0 + settings["lighting_change"] * jnp.sin(2.0 * jnp.pi * frame_id / (settings["lighting_period"] * fps) + phase)
        noise = settings["sensor_noise"] / 255.0 * jax.random.normal(jax.random.fold_in(key, frame_id), colour.shape, colour.dtype)
        pixels = jnp.clip(jnp.round((colour * gain[:, None, None, None] + noise) * 255.0), 0, 255).astype(jnp.uint8)
        return pixels, coverage >= 0.5

    return jax.lax.map(lambda fp: frame(*fp), (frame_ids, poses))


def render_rgb(key, solid: SolidBody, rig: CameraRig, poses, *, settings: PhotoSettings = PhotoSettings(), fps: float = 60.0,
               backgrounds=None, first_frame: int = 0, with_body: bool = True, chunk: int = 8):
    """Pictures of the solid body at each pose over each camera's background (module docstring).

    Args:
        key: PRNG key of the sensor noise (frame ``first_frame + i`` draws ``fold_in(key, first_frame + i)``).
        solid: the body drawn.
        rig: the cameras (no lens distortion: the rays are cast through undistorted pixels).
        poses: (T, D) poses on ``solid.skeleton``.
        fps: frame rate (the lighting change is periodic in seconds).
        backgrounds: (C, H, W, 3) uint8 per camera (default ``background_photo`` per view).
        first_frame: the index of the first pose in the take (noise and lighting follow it).
        with_body: False draws the empty scene (background frames for ``fit_background``).

    Returns:
        ``(pictures (C, T, H, W, 3) uint8, masks (C, T, H, W) bool)``, the true silhouettes.
    """
    if np.any(np.asarray(rig.dist) != 0):
        raise ValueError("render_rgb casts rays through undistorted pixels: give it a rig without lens distortion")
    height, width = image_shape(rig)
    dtype = jnp.float32
    if backgrounds is None:
        backgrounds = np.stack([background_photo(width, height, c) for c in range(rig.num_views)])
    backgrounds = np.asarray(backgrounds)
    if backgrounds.shape != (rig.num_views, height, width, 3):
        raise ValueError(f"backgrounds must be (views, H, W, 3) = {(rig.num_views, height, width, 3)}, got {backgrounds.shape}")
    rig32 = jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, rig)
    origins, directions = _rays(rig32, height, width, settings.samples)
    albedo = jnp.asarray([PART_COLOURS[name] for name in solid.names], dtype)
    striped = jnp.asarray([name in _STRIPED for name in solid.names], dtype)
    light = np.asarray(settings.light_direction, np.float64)
    values = {"light": light / np.linalg.norm(light), "ambient": settings.ambient, "stripes": settings.stripes,
              "shadow_strength": settings.shadow_strength, "lighting_change": settings.lighting_change,
              "lighting_period": settings.lighting_period, "sensor_noise": settings.sensor_noise}
    values = {k: jnp.asarray(v, dtype) for k, v in values.items()}
    poses = jnp.asarray(poses, dtype)
    if poses.ndim != 2 or poses.shape[0] < 1:
        raise ValueError(f"poses must be (T, D) with T >= 1, got shape {poses.shape}")
    backgrounds = jnp.asarray(backgrounds, dtype) / 255.0
    chunk = max(1, min(int(chunk), poses.shape[0]))
    skeleton = jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, solid.skeleton)

    def render(k, ids, p):
        return _render_frames(k, ids, skeleton, float(solid.girth), bool(solid.joints), p, backgrounds, origins, directions, albedo,
                              striped, values, jnp.asarray(fps, dtype), jnp.asarray(0.0 if with_body else 1e4, dtype))

    pictures, masks = [], []
    for s in range(0, poses.shape[0], chunk):
        p = poses[s : s + chunk]
        size = p.shape[0]
        if size < chunk:  # one compiled shape
            p = jnp.concatenate([p, jnp.repeat(p[-1:], chunk - size, axis=0)])
        ids = first_frame + s + jnp.arange(chunk)
        pics, hits = render(key, ids, p)
        pictures.append(np.asarray(pics)[:size])
        masks.append(np.asarray(hits)[:size])
    return np.concatenate(pictures).swapaxes(0, 1), np.concatenate(masks).swapaxes(0, 1)


def write_rgb_scene(folder, key, scene, *, settings: PhotoSettings = PhotoSettings(), detector=None, background_frames: int = 30,
                    chunk: int = 8, progress: bool = False) -> dict:
    """Film a test scene (a ``Sequence`` with ``pose``, cameras and a skeleton, e.g. from
    ``scene_from_sequence``) as the files a user of real cameras has, in ``folder``:

    - ``{camera}.mp4``: one video per camera (``render_rgb`` of the solid body);
    - ``background/{camera}.mp4``: ``background_frames`` frames of the empty scene (0: none);
    - ``calibration.json``: the cameras (``io.save_calibration``);
    - ``keypoints.npz``: 2-D detections of the true joints with ``detector``'s noise
      (``detect_keypoints``; None: ``DetectorNoise()``), in ``io.save_keypoints``' layout;
    - ``truth.npz``: the scene with the true silhouettes of the solid body (the clean
      silhouettes a background subtraction should find), its poses and joints.

    Returns the paths by role. Frames are rendered ``chunk`` at a time and written as they come.
    """
    from ..io import VideoWriter, save_calibration, save_keypoints, save_sequence
    from ._detections import DetectorNoise, detect_keypoints

    folder = os.fspath(folder)
    os.makedirs(folder, exist_ok=True)
    rig = scene.rig()
    names = [str(n) for n in rig.names]
    solid = SolidBody(scene.body().skeleton)
    height, width = image_shape(rig)
    backgrounds = np.stack([background_photo(width, height, c) for c in range(rig.num_views)])
    videos = [os.path.join(folder, f"{name}.mp4") for name in names]
    masks = []
    starts = range(0, scene.num_frames, chunk)
    if progress:
        from tqdm.auto import tqdm

        starts = tqdm(starts, desc="filming", unit="chunk")
    with VideoWriter(videos, scene.fps) as writer:
        for s in starts:
            pictures, hits = render_rgb(key, solid, rig, scene.pose[s : s + chunk], settings=settings, fps=scene.fps,
                                        backgrounds=backgrounds, first_frame=s, chunk=chunk)
            writer.write(pictures)
            masks.append(hits)
    paths = {"videos": videos}
    if background_frames:
        os.makedirs(os.path.join(folder, "background"), exist_ok=True)
        paths["background"] = [os.path.join(folder, "background", f"{name}.mp4") for name in names]
        empty = np.repeat(scene.pose[:1], background_frames, axis=0)
        with VideoWriter(paths["background"], scene.fps) as writer:
            for s in range(0, background_frames, chunk):
                pictures, _ = render_rgb(jax.random.fold_in(key, 2), solid, rig, empty[s : s + chunk], settings=settings,
                                         fps=scene.fps, backgrounds=backgrounds, first_frame=s, with_body=False, chunk=chunk)
                writer.write(pictures)
    paths["calibration"] = save_calibration(os.path.join(folder, "calibration.json"), rig)
    keypoints = detect_keypoints(jax.random.fold_in(key, 1), scene.joints3d, rig, detector or DetectorNoise())
    paths["keypoints"] = os.path.join(folder, "keypoints.npz")
    save_keypoints(paths["keypoints"], keypoints, names)
    truth = scene.replace(silhouettes=np.concatenate(masks, axis=1).astype(np.uint8), keypoints2d=None)
    paths["truth"] = os.path.join(folder, "truth.npz")
    save_sequence(paths["truth"], truth)
    return paths

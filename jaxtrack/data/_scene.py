"""Synthetic multi-view scenes: a motion + a camera rig -> noisy background-subtraction silhouettes.

The noise imitates what background subtraction produces on real footage (paper 000 sec. 6
blames its noisy silhouettes for APF's losses):

- *body shape*: capsule radii jittered per frame (clothing, segmentation threshold);
- *shadows at the feet*: a dark patch cast on the ground from each foot near the floor,
  along a light direction, segmented as foreground;
- *boundary jitter*: pixels on the silhouette boundary flipped at random;
- *holes*: disks removed from the silhouette (foreground that matches the background colour);
- *false positives*: disks of clutter added anywhere in the image.

Everything is drawn from the PRNG key with ``jax.random.fold_in(key, frame)``, so a scene is
identical for the same key whatever the chunking of frames.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._validation import check_key
from ..body import check_poses
from ..camera import CameraRig, check_in_front, image_shape, pixel_grid, project_points
from ..io import Sequence
from ..render import ProjectedCapsules, hard_from_capsules, project_capsules
from ._gait import SyntheticMotion
from ._solid_body import SolidBody, render_solid_silhouettes

_MAX_DISKS = 6  # static upper bound on holes / blobs drawn per frame and view


@dataclasses.dataclass(frozen=True)
class SilhouetteNoise:
    """Background-subtraction noise settings (set a field to 0 to switch that effect off).

    Attributes:
        radius_jitter: relative standard deviation of every capsule radius, per frame.
        boundary_flip: probability of flipping each silhouette-boundary pixel.
        holes: mean number of holes per frame and view (Poisson, at most 6).
        hole_radius: (min, max) hole radius, pixels.
        blobs: mean number of false-positive blobs per frame and view (Poisson, at most 6).
        blob_radius: (min, max) blob radius, pixels.
        shadow_length: length of each foot's shadow on the ground, metres (0: no shadows).
        shadow_width: half-width of the shadow, metres.
        shadow_direction: (x, y) direction of the shadow on the ground.
    """

    radius_jitter: float = 0.08
    boundary_flip: float = 0.2
    holes: float = 0.8
    hole_radius: tuple[float, float] = (0.8, 2.0)
    blobs: float = 0.8
    blob_radius: tuple[float, float] = (0.8, 2.5)
    shadow_length: float = 0.35
    shadow_width: float = 0.07
    shadow_direction: tuple[float, float] = (0.6, 0.8)

    def __post_init__(self):
        for name in ("radius_jitter", "boundary_flip", "holes", "blobs", "shadow_length", "shadow_width"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"SilhouetteNoise.{name} must be >= 0, got {value}")
        if self.boundary_flip > 1:
            raise ValueError(f"SilhouetteNoise.boundary_flip is a probability, got {self.boundary_flip}")
        for name in ("hole_radius", "blob_radius"):
            lo, hi = getattr(self, name)
            if not (0 <= lo <= hi):
                raise ValueError(f"SilhouetteNoise.{name} must be (min, max) with 0 <= min <= max, got {(lo, hi)}")


    def as_arrays(self, dtype) -> dict:
        """The settings as arrays, so that changing them does not recompile the renderer."""
        direction = np.asarray(self.shadow_direction, np.float64)
        norm = np.linalg.norm(direction)
        if not norm > 0:
            raise ValueError("SilhouetteNoise.shadow_direction must be a non-zero (x, y) vector")
        values = dataclasses.asdict(self)
        values["shadow_direction"] = direction / norm
        return {k: jnp.asarray(v, dtype) for k, v in values.items()}


NO_NOISE = SilhouetteNoise(0.0, 0.0, 0.0, (0.0, 0.0), 0.0, (0.0, 0.0), 0.0, 0.0)


def _shadow_capsules(rig: CameraRig, joints, ankle_index, noise: dict, dtype):
    """Ground-plane shadow capsules of each foot, projected: (views, feet, ...)."""
    direction = noise["shadow_direction"]
    ankles = joints[jnp.asarray(ankle_index)]  # (feet, 3)
    lift = ankles[:, 2]
    start = ankles.at[:, 2].set(0.01)
    end = start + jnp.concatenate([direction * noise["shadow_length"], jnp.zeros(1, dtype)])
    ua, za, fa = project_points(rig, start)
    ub, zb, fb = project_points(rig, end)
    depth = jnp.maximum(0.5 * (za + zb), 1e-2)
    # Shadows fade (shrink) as the foot leaves the ground.
    fade = jnp.clip(1.0 - (lift - 0.08) / 0.25, 0.0, 1.0)[:, None]
    f = 0.5 * (rig.K[:, 0, 0] + rig.K[:, 1, 1])
    radius = f * noise["shadow_width"] * fade / depth
    return ProjectedCapsules(
        start=jnp.swapaxes(ua, 0, 1),
        end=jnp.swapaxes(ub, 0, 1),
        radius=jnp.swapaxes(radius, 0, 1),
        in_front=jnp.all(fa & fb, axis=0),
    )


def _disks(key, image_shape_hw, rate, radius_range, centre_logits, dtype):
    """Union of a Poisson number (<= _MAX_DISKS) of disks, centres drawn from ``centre_logits``."""
    height, width = image_shape_hw
    k_num, k_centre, k_radius, k_jitter = jax.random.split(key, 4)
    count = jnp.minimum(jax.random.poisson(k_num, rate), _MAX_DISKS)
    flat = jax.random.categorical(k_centre, centre_logits.ravel(), shape=(_MAX_DISKS,))
    cy = (flat // width).astype(dtype) + jax.random.uniform(k_jitter, (_MAX_DISKS,), dtype, -0.5, 0.5)
    cx = (flat % width).astype(dtype)
    radius = radius_range[0] + (radius_range[1] - radius_range[0]) * jax.random.uniform(k_radius, (_MAX_DISKS,), dtype)
    active = (jnp.arange(_MAX_DISKS) < count) & (radius > 0)
    v, u = pixel_grid(height, width, dtype)
    d2 = (u[None] - cx[:, None, None]) ** 2 + (v[None] - cy[:, None, None]) ** 2
    return jnp.any((d2 <= radius[:, None, None] ** 2) & active[:, None, None], axis=0)


def _boundary(mask):
    """Pixels whose 3x3 neighbourhood holds both foreground and background."""
    padded = jnp.pad(mask, 1)
    window = (3, 3)
    dilated = jax.lax.reduce_window(padded, False, jax.lax.bitwise_or, window, (1, 1), "VALID")
    eroded = jax.lax.reduce_window(padded, True, jax.lax.bitwise_and, window, (1, 1), "VALID")
    return dilated & ~eroded


def _noisy_frame(key, body, rig, pose, joints, noise: dict, ankle_index, mask=None):
    """(views, H, W) bool silhouettes of one frame with background-subtraction noise; ``mask``
    (views, H, W): the body already rendered (another renderer's), else the capsules are."""
    dtype = pose.dtype
    height, width = image_shape(rig)
    k_radius, k_views = jax.random.split(key)
    shadow = _shadow_capsules(rig, joints, ankle_index, noise, dtype)
    if mask is None:
        jitter = 1.0 + noise["radius_jitter"] * jax.random.normal(k_radius, body.radii.shape, dtype)
        caps = project_capsules(body, rig, pose)
        caps = caps._replace(radius=caps.radius * jnp.maximum(jitter, 0.3))
        caps = ProjectedCapsules(
            start=jnp.concatenate([caps.start, shadow.start], axis=-2),
            end=jnp.concatenate([caps.end, shadow.end], axis=-2),
            radius=jnp.concatenate([caps.radius, shadow.radius], axis=-1),
            in_front=caps.in_front & shadow.in_front,
        )
        clean = hard_from_capsules(caps, height, width)  # (views, H, W)
    else:
        clean = mask | hard_from_capsules(shadow, height, width)

    def corrupt(k, mask):
        k_flip, k_holes, k_blobs = jax.random.split(k, 3)
        flip = _boundary(mask) & jax.random.bernoulli(k_flip, noise["boundary_flip"], mask.shape)
        mask = mask ^ flip
        inside_logits = jnp.where(mask, 0.0, -jnp.inf)
        inside_logits = jnp.where(jnp.any(mask), inside_logits, 0.0)
        holes = _disks(k_holes, (height, width), noise["holes"], noise["hole_radius"], inside_logits, dtype)
        blobs = _disks(k_blobs, (height, width), noise["blobs"], noise["blob_radius"], jnp.zeros((height, width), dtype), dtype)
        return (mask & ~holes) | blobs

    keys = jax.random.split(k_views, rig.num_views)
    return jax.vmap(corrupt)(keys, clean)


# Compiled at XLA's backend optimisation level 0: a scene is rendered once, where compiling it at
# the default level costs more than it saves, and the silhouettes are the same bit for bit
# (docs/testing.md, "Cold start").
@eqx.filter_jit(compiler_options={"xla_backend_optimization_level": 0})
def _render_chunk(key, frame_ids, body, rig, poses, joints, noise, ankle_index, masks=None):
    """Noisy silhouettes (frames, views, H, W) of a chunk of frames; one compile per shape."""
    keys = jax.vmap(lambda f: jax.random.fold_in(key, f))(frame_ids)
    if masks is None:
        return jax.vmap(lambda k, p, j: _noisy_frame(k, body, rig, p, j, noise, ankle_index))(keys, poses, joints)
    return jax.vmap(lambda k, p, j, m: _noisy_frame(k, body, rig, p, j, noise, ankle_index, m))(keys, poses, joints, masks)


def build_scene(
    key,
    motion: SyntheticMotion,
    rig: CameraRig,
    noise: SilhouetteNoise = SilhouetteNoise(),
    *,
    chunk: int = 32,
    progress: bool = False,
    solid: SolidBody | None = None,
) -> Sequence:
    """Render a motion into noisy multi-view silhouettes and pack everything as a ``Sequence``.

    Args:
        key: PRNG key; the same key gives the same scene.
        motion: poses and joints to render (e.g. from ``generate_motion``).
        rig: cameras (all views of one image size).
        noise: background-subtraction noise settings (``NO_NOISE`` for clean silhouettes).
        chunk: frames rendered per jitted call; a shorter scene (and the last chunk) is padded to
            it, so scenes of any length at one image size share one compiled renderer.
        progress: show a progress bar.
        solid: render the person as this ``SolidBody`` (ellipsoids ray-cast exactly: feet, an
            elliptical torso, tapered limbs) instead of the motion's capsules, so that the test
            data are not drawn by the tracker's own body model; the noise's radius jitter then
            does not apply, the rest (shadows, flips, holes, blobs) does. The sequence keeps the
            motion's ``skeleton_offsets`` and ``capsule_radii`` (drop them to hide the body).

    Raises:
        ValueError: if a camera is behind the body in some frame, or the body leaves a view
            entirely (empty silhouette).
    """
    check_key(key)
    if not isinstance(motion, SyntheticMotion):
        raise TypeError(f"build_scene renders a SyntheticMotion (from generate_motion; data.scene_from_sequence renders a "
                        f"sequence file's poses), got {type(motion).__name__}")
    check_poses(motion.body.skeleton, motion.pose, "motion poses")
    check_in_front(rig, motion.joints3d, what="the body")
    _height, _width = image_shape(rig)
    body = motion.body
    dtype = body.radii.dtype
    poses = jnp.asarray(motion.pose, dtype)
    joints = jnp.asarray(motion.joints3d, dtype)
    skeleton = body.skeleton
    ankle_index = (skeleton.joint_index("lankle"), skeleton.joint_index("rankle"))
    frames = jnp.arange(poses.shape[0])
    noise_arrays = noise.as_arrays(dtype)
    chunk = max(1, int(chunk))

    out = []
    starts = range(0, poses.shape[0], chunk)
    if progress:
        from tqdm.auto import tqdm

        starts = tqdm(starts, desc="rendering silhouettes", unit="chunk")
    for s in starts:
        ids, p, j = frames[s : s + chunk], poses[s : s + chunk], joints[s : s + chunk]
        size = ids.shape[0]
        if size < chunk:  # pad the last chunk to keep one compiled shape
            pad = chunk - size
            ids, p, j = (jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) for x in (ids, p, j))
        masks = None if solid is None else jnp.asarray(render_solid_silhouettes(solid, rig, p))
        out.append(np.asarray(_render_chunk(key, ids, body, rig, p, j, noise_arrays, ankle_index, masks))[:size])
    silhouettes = np.concatenate(out, axis=0).transpose(1, 0, 2, 3).astype(np.uint8)  # (C, T, H, W)
    area = silhouettes.sum(axis=(2, 3))
    if np.any(area == 0):
        c, t = np.argwhere(area == 0)[0]
        raise ValueError(f"the body leaves the image of camera {rig.names[c]!r} at frame {t}: empty silhouette")
    return motion_sequence(motion).replace(
        camera_K=np.asarray(rig.K, np.float64),
        camera_R=np.asarray(rig.R, np.float64),
        camera_t=np.asarray(rig.t, np.float64),
        camera_dist=np.asarray(rig.dist, np.float64),
        image_size=np.array(rig.image_size, np.int64),
        camera_names=np.array(rig.names),
        silhouettes=silhouettes,
    )


def motion_sequence(motion: SyntheticMotion) -> Sequence:
    """A motion as a ``Sequence`` without cameras or images: fps, joints, poses and the body
    (training and validation data for the manifold and the dynamics)."""
    skeleton = motion.body.skeleton
    return Sequence.create(
        fps=motion.fps,
        joint_names=np.array(skeleton.joint_names),
        parents=np.array(skeleton.parents),
        joints3d=np.asarray(motion.joints3d, np.float64),
        pose=np.asarray(motion.pose, np.float64),
        pose_layout=np.array(skeleton.pose_layout),
        skeleton_offsets=np.asarray(skeleton.offsets, np.float64),
        capsule_radii=np.asarray(motion.body.radii, np.float64),
    )


def scene_from_sequence(
    key,
    sequence: Sequence,
    rig: CameraRig,
    noise: SilhouetteNoise = SilhouetteNoise(),
    *,
    start: int = 0,
    frames: int | None = None,
    centre: bool = True,
    progress: bool = False,
    solid: SolidBody | None = None,
) -> Sequence:
    """Render recorded motion (e.g. CMU or Bandai after ``jaxtrack convert``) into a synthetic
    multi-view silhouette scene with the sequence's own body: the HumanEva-like test setting on
    real motion.

    Args:
        key: PRNG key of the silhouette noise.
        sequence: a sequence with ``pose`` (the rendered body follows it) and optionally
            ``joints3d`` (kept as the ground truth; otherwise forward kinematics of ``pose``).
        rig: the cameras.
        start, frames: the frame range to keep (``frames=None``: to the end).
        centre: shift the root's horizontal path so its midpoint is the capture area's
            centre (recorded takes cross several metres of floor).
        solid: render this body instead of the sequence's capsules (``build_scene``).
    Raises:
        ValueError: no ``pose``, an empty frame range, or the body outside a view
            (``build_scene``'s checks).
    """
    from ..body import forward_kinematics

    if sequence.pose is None:
        raise ValueError("the sequence has no 'pose' to render (make one with 'jaxtrack convert')")
    stop = sequence.num_frames if frames is None else start + int(frames)
    if not (0 <= start < stop <= sequence.num_frames):
        raise ValueError(f"frames {start}..{stop - 1} are outside the sequence's {sequence.num_frames} frames")
    body = sequence.body()
    layout = [str(n) for n in sequence.pose_layout]
    pose = np.array(sequence.pose[start:stop], np.float64)
    if sequence.joints3d is not None:
        joints = np.array(sequence.joints3d[start:stop], np.float64)
    else:
        joints = np.asarray(forward_kinematics(body.skeleton, jnp.asarray(pose, body.radii.dtype)), np.float64)
    if centre:
        horizontal = [layout.index("root_x"), layout.index("root_y")]
        path = pose[:, horizontal]
        shift = 0.5 * (path.min(axis=0) + path.max(axis=0))
        pose[:, horizontal] -= shift
        joints[..., :2] -= shift
    speed = float(np.mean(np.linalg.norm(np.diff(joints[:, 0, :2], axis=0), axis=1)) * sequence.fps) if len(joints) > 1 else 0.0
    motion = SyntheticMotion(
        body=body, pose=pose, joints3d=joints, fps=float(sequence.fps), gait="recorded", subject="recorded", speed=speed
    )
    return build_scene(key, motion, rig, noise, progress=progress, solid=solid)

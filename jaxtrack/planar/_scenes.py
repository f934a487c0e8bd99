"""Monocular test videos for paper 003's setting: a person signalling (``data.signalling_motion``)
drawn by the solid body (``data.SolidBody``: ellipsoids, hands, an egg-shaped head; never the
tracker's SPM) in colour over a photograph (``data.render_rgb``), by one camera at a viewpoint
that is not among the training view sphere's, with the markers' true image positions.
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from ..body import HUMANEVA_JOINTS
from ._training import TRAINING_AZIMUTHS, TRAINING_ELEVATIONS, project_markers, view_sphere_rig

TEST_VIEWS = ((15.0, 10.0), (75.0, 10.0), (345.0, 30.0), (105.0, 5.0))
"""(azimuth, elevation) degrees of the test cameras: between the training views (every 30 degrees
at 0 and 20 degrees of elevation)."""
TEST_LIMBS = {"spine": 0.54, "neck": 0.2, "shoulder": 0.2, "upper_arm": 0.26, "forearm": 0.28}
"""The test subject's limb lengths (metres; the default body's: 0.50, 0.22, 0.18, 0.29, 0.26)."""


@dataclasses.dataclass(frozen=True)
class GestureVideo:
    """A rendered test video.

    Attributes:
        images: (T, H, W, 3) uint8 frames.
        markers: (T, 9, 2) the SPM markers' true positions, pixels.
        view: (azimuth, elevation) of the camera, degrees.
        fps: frame rate.
        background: (B, H, W, 3) uint8 frames of the empty scene (for ``image.fit_background``).
        masks: (T, H, W) bool the person's true silhouettes (what a background subtraction should find).
    """

    images: np.ndarray
    markers: np.ndarray
    view: tuple[float, float]
    fps: float
    background: np.ndarray
    masks: np.ndarray


def plain_wall(width: int, height: int, key) -> np.ndarray:
    """(H, W, 3) uint8: a plain wall (blue-grey, a faint smooth texture): 003's lab setting."""
    rng = np.random.default_rng(np.asarray(jax.random.key_data(key)).ravel().astype(np.uint32))
    coarse = rng.normal(size=(height // 16 + 2, width // 16 + 2))
    from ..image import resize

    texture = np.asarray(resize(coarse.astype(np.float32), height, width))
    base = np.array([150.0, 160.0, 175.0])
    return np.clip(base + 8.0 * texture[..., None], 0, 255).astype(np.uint8)


BACKGROUNDS = ("photo", "wall")


def gesture_video(key, *, view=TEST_VIEWS[0], frames: int = 150, fps: float = 30.0, width: int = 320, height: int = 240,
                  distance: float = 2.2, target_height: float = 1.45, limb_lengths=TEST_LIMBS, background: str = "photo",
                  transition=(0.4, 1.2), chunk: int = 8, background_frames: int = 10,
                  sidestep: float = 0.0) -> GestureVideo:
    """A monocular video of ``signalling_motion`` (module docstring), over a photograph
    (``background="photo"``: ``data.background_photo``, busy, with a face) or a plain wall
    (``"wall"``, ``plain_wall``); ``transition``: ``signalling_motion``'s (seconds between key
    postures); ``background_frames`` frames of the empty scene are filmed too (sensor noise
    and lighting as in the video). ``sidestep`` (metres): the person also steps from side to side
    across the camera's view, the pelvis moving by ``sidestep * sin(2 pi t / 4 s)`` along the
    horizontal perpendicular to the camera's direction (0: standing in place, as 003's subjects).

    Raises:
        ValueError: if the view is one of the training views (it would not test generalisation).
    """
    from ..data import PhotoSettings, SolidBody, render_rgb, signalling_motion

    azimuth, elevation = (float(v) for v in view)
    if any(np.isclose(azimuth % 360, a) for a in TRAINING_AZIMUTHS) and any(np.isclose(elevation, e) for e in TRAINING_ELEVATIONS):
        raise ValueError(f"view {view} is a training view of the view sphere; choose another")
    if background not in BACKGROUNDS:
        raise ValueError(f"background must be one of {BACKGROUNDS}, got {background!r}")
    motion = signalling_motion(jax.random.fold_in(key, 0), num_frames=frames, fps=fps, limb_lengths=limb_lengths,
                               transition=transition)
    if sidestep:
        shift = float(sidestep) * np.sin(2 * np.pi * np.arange(frames) / (4.0 * fps))
        pose, joints3d = np.array(motion.pose, copy=True), np.array(motion.joints3d, copy=True)
        across = np.array([-np.sin(np.radians(azimuth)), np.cos(np.radians(azimuth))])  # the camera is at azimuth
        pose[:, 0:2] += shift[:, None] * across  # root_x, root_y
        joints3d[..., 0:2] += shift[:, None, None] * across
        motion = dataclasses.replace(motion, pose=pose, joints3d=joints3d)
    rig = view_sphere_rig((azimuth,), (elevation,), distance=distance, target_height=target_height, width=width,
                          height=height, dtype=np.float32)
    solid = SolidBody(motion.body.skeleton)
    backgrounds = None if background == "photo" else plain_wall(width, height, jax.random.fold_in(key, 2))[None]
    pictures, masks = render_rgb(jax.random.fold_in(key, 1), solid, rig, motion.pose, settings=PhotoSettings(), fps=fps,
                                 backgrounds=backgrounds, chunk=chunk)
    empty, _ = render_rgb(jax.random.fold_in(key, 3), solid, rig, motion.pose[: max(1, int(background_frames))],
                          settings=PhotoSettings(), fps=fps, backgrounds=backgrounds, chunk=chunk, with_body=False)
    markers, _scale = project_markers(rig, motion.joints3d, HUMANEVA_JOINTS)
    return GestureVideo(images=pictures[0], markers=markers[0], view=(azimuth, elevation), fps=float(fps),
                        background=np.asarray(empty[0]), masks=np.asarray(masks[0], bool))

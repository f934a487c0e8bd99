"""An overlay video: the estimated skeleton drawn over each camera's frames, the views side by
side, written as one H.264 video while the source videos are decoded chunk by chunk."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..camera import CameraRig, project_points
from ..io import MultiViewVideo, VideoWriter

ESTIMATE_COLOUR = (255, 60, 40)
JOINT_COLOUR = (255, 230, 40)


def draw_skeleton(picture: np.ndarray, points: np.ndarray, parents, *, colour=ESTIMATE_COLOUR, thickness: int = 1) -> None:
    """Draw bones between (J, 2) pixel points (NaN: not drawn) on an (H, W, 3) uint8 picture, in place."""
    height, width = picture.shape[:2]
    for child, parent in enumerate(parents):
        if parent < 0:
            continue
        a, b = points[parent], points[child]
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            continue
        steps = int(np.ceil(np.max(np.abs(b - a)))) + 1
        line = a + np.linspace(0.0, 1.0, steps)[:, None] * (b - a)
        for du in range(-(thickness // 2), thickness - thickness // 2):
            for dv in range(-(thickness // 2), thickness - thickness // 2):
                u = np.round(line[:, 0]).astype(int) + du
                v = np.round(line[:, 1]).astype(int) + dv
                inside = (u >= 0) & (u < width) & (v >= 0) & (v < height)
                picture[v[inside], u[inside]] = colour
    joints = np.round(points[np.all(np.isfinite(points), axis=-1)]).astype(int)
    inside = (joints[:, 0] >= 0) & (joints[:, 0] < width) & (joints[:, 1] >= 0) & (joints[:, 1] < height)
    picture[joints[inside, 1], joints[inside, 0]] = JOINT_COLOUR


def write_overlay_video(path, videos, rig: CameraRig, joints3d, parents, *, fps: float, chunk: int = 32) -> str:
    """Write the (T, J, 3) joints projected into every camera over its video's first T frames,
    the cameras side by side (same height), as ``path`` (.mp4). Returns the path."""
    joints3d = np.asarray(joints3d, np.float64)
    frames = joints3d.shape[0]
    uv, _, front = project_points(rig, jnp.asarray(joints3d, rig.K.dtype))
    uv = np.array(uv, np.float64)  # (T, J, C, 2), a copy to write into (a float64 rig's is read-only)
    uv[~np.asarray(front)] = np.nan
    thickness = 1 if int(rig.image_size[0][1]) <= 240 else 2
    with MultiViewVideo(videos, names=rig.names) as video, VideoWriter([path], fps) as writer:
        for first, block in video.chunks(chunk, frames=frames):
            block = np.array(block)  # (C, t, H, W, 3), writable
            for c in range(block.shape[0]):
                for i in range(block.shape[1]):
                    draw_skeleton(block[c, i], uv[first + i, :, c], parents, thickness=thickness)
            side_by_side = np.concatenate(list(block), axis=2)  # (t, H, C W, 3)
            writer.write(side_by_side[None])
    return str(path)

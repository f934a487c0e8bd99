"""A monocular video in, 2-D marker tracks out (``jaxtrack track2d``).

``read_first_markers`` reads the first frame's markers from ``{"markers": {"head": [x, y], ...}}``
(pixels; every name of ``SPM_MARKERS``); ``track_video`` reads the video in chunks (never whole
in memory), tracks each chunk with one jitted scan, and hands each chunk's tracks to a callback
(the command writes the tracks so far after each); given a video of the empty scene, it also
subtracts the background (``image.fit_background``, ``subtract_background``) and the trackers
score each frame's silhouette too (``SilhouetteChamfer``); ``draw_markers`` draws the SPM's links
over frames for an overlay video.
"""

from __future__ import annotations

import json
import os

import jax.numpy as jnp
import numpy as np

from ..image import fit_background, rgb_to_grey, subtract_background
from ._base import get_tracker2d, start_tracking, track_frames
from ._spm import SPM_LINKS, SPM_MARKERS


def read_first_markers(path) -> np.ndarray:
    """(9, 2) pixels in ``SPM_MARKERS`` order from a JSON marker file.

    Raises:
        ValueError: naming the file and what is wrong (not JSON, a missing or unknown marker, a
            position that is not two finite numbers).
    """
    path = os.fspath(path)
    try:
        with open(path) as handle:
            record = json.load(handle)
    except json.JSONDecodeError as err:
        raise ValueError(f"{path}: not JSON (line {err.lineno}: {err.msg})") from None
    markers = record.get("markers") if isinstance(record, dict) else None
    if not isinstance(markers, dict):
        raise ValueError(f'{path}: expected {{"markers": {{"head": [x, y], ...}}}} in pixels')
    missing = [m for m in SPM_MARKERS if m not in markers]
    unknown = sorted(set(markers) - set(SPM_MARKERS))
    if missing or unknown:
        raise ValueError(f"{path}: the markers do not match the model's: "
                         + "; ".join(filter(None, [f"missing {', '.join(missing)}" if missing else "",
                                                   f"unknown {', '.join(unknown)}" if unknown else ""]))
                         + f" (the model's markers: {', '.join(SPM_MARKERS)})")
    out = []
    for name in SPM_MARKERS:
        value = markers[name]
        try:
            point = np.asarray(value, np.float64)
        except (TypeError, ValueError):
            point = np.full(1, np.nan)
        if point.shape != (2,) or not np.all(np.isfinite(point)):
            raise ValueError(f"{path}: marker {name!r} must be [x, y], two finite numbers in pixels, got {value!r}")
        out.append(point)
    return np.stack(out)


def track_video(method: str, model, video_path, first_markers, *, key, frames: int | None = None, chunk: int = 64,
                options=None, on_chunk=None, background=None) -> np.ndarray:
    """Track a monocular video (file or image folder) from its first frame's markers.

    Args:
        method: a registered 2-D tracker (``tracker2d_names()``).
        model: an ``SPMModel``.
        first_markers: (9, 2) pixels on frame 0.
        key: the run's PRNG key.
        frames: track the first ``frames`` frames (None: all); more than the video has is refused.
        chunk: frames decoded and tracked at a time.
        background: a video file or image folder of the empty scene from the same camera, or
            None (the templates alone, as 003).
        on_chunk: called as ``on_chunk(first_frame, rgb_frames (t, H, W, 3) uint8, markers so far
            (T', 9, 2))`` after each chunk.

    Returns:
        (T, 9, 2) the markers of every frame (frame 0's are ``first_markers``).
    """
    from ..io import MultiViewVideo

    recipe = get_tracker2d(method)
    first_markers = np.asarray(first_markers, np.float64)
    scene = None
    if background is not None:
        with MultiViewVideo([background]) as empty:
            pictures = np.concatenate([c[0] for _, c in empty.chunks(chunk)])
        scene = fit_background(pictures)
    with MultiViewVideo([video_path]) as video:
        if frames is not None:
            if int(frames) < 2:
                raise ValueError(f"frames must be at least 2 (the first frame and one to track), got {frames}")
            if int(frames) > video.num_frames:
                raise ValueError(f"{video_path}: has {video.num_frames} frames, fewer than the {frames} asked for")
        width, height = video.sizes[0]
        if scene is not None and scene.colour.shape[:2] != (height, width):
            raise ValueError(f"{background}: the empty scene is {scene.colour.shape[1]}x{scene.colour.shape[0]}, the video "
                             f"{width}x{height}")
        u, v = first_markers[:, 0], first_markers[:, 1]
        outside = (u < 0) | (u > width - 1) | (v < 0) | (v > height - 1)
        if np.any(outside):
            names = [SPM_MARKERS[i] for i in np.nonzero(outside)[0]]
            raise ValueError(f"the first frame's markers {', '.join(names)} lie outside the {width}x{height} video")
        tracks, tracker, carry = [first_markers[None]], None, None
        for first, pictures in video.chunks(chunk, frames=frames):
            rgb = pictures[0]
            grey = jnp.asarray(rgb_to_grey(rgb), jnp.float32)
            masks = None if scene is None else subtract_background(scene, rgb).mask
            offset = 0
            if tracker is None:
                tracker = recipe.build(model, grey[0], first_markers, **(options or {}))
                carry = start_tracking(tracker, key)
                grey, offset = grey[1:], 1
                masks = None if masks is None else masks[1:]
            if len(grey):
                carry, markers = track_frames(tracker, grey, key, masks=masks, carry=carry, first_index=first + offset)
                tracks.append(np.asarray(markers, np.float64))
            if on_chunk is not None:
                on_chunk(first, rgb, np.concatenate(tracks))
    out = np.concatenate(tracks)
    if len(out) < 2:
        raise ValueError(f"{video_path}: has a single frame; tracking needs at least two")
    return out


def draw_markers(rgb, markers, colour=(60, 255, 60)) -> np.ndarray:
    """Frames (t, H, W, 3) uint8 with the SPM's links between ``markers`` (t, 9, 2) drawn on them."""
    from ..camera import pixel_grid

    frames = np.array(rgb, copy=True)
    height, width = frames.shape[1:3]
    v, u = (np.asarray(g) for g in pixel_grid(height, width, jnp.float32))
    links = [(SPM_MARKERS.index(a), SPM_MARKERS.index(b)) for _, _, a, b in SPM_LINKS]
    for t in range(len(frames)):
        mask = np.zeros((height, width), bool)
        for a, b in links:
            p, q = markers[t, a], markers[t, b]
            d = q - p
            s = np.clip(((u - p[0]) * d[0] + (v - p[1]) * d[1]) / max(float(d @ d), 1e-9), 0, 1)
            mask |= (u - p[0] - s * d[0]) ** 2 + (v - p[1] - s * d[1]) ** 2 <= 1.5**2
        frames[t][mask] = colour
    return frames



"""From a user's files to a test sequence: calibrated videos (and background videos, and a
detector's keypoints) -> silhouettes by background subtraction -> a ``Sequence`` to track.

The videos are decoded in chunks (``io.MultiViewVideo``); the background model comes from the
background videos when given, else from frames spread over the videos themselves
(``io.sample_frames_evenly``, the person moving). Each chunk's silhouettes are kept as bits of
one byte per pixel; the pictures are kept only when asked (001's edge likelihood reads them).

Nothing is lost to bad frames: a frame that cannot be decoded, or a camera that sees nobody
(an empty silhouette), ends the sequence before that frame, and the reason is returned with
the frames before it, which can still be tracked.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..camera import CameraRig
from ..image import fit_background, subtract_background
from ..io import MultiViewVideo, Sequence, VideoFileError, sample_frames_evenly

BACKGROUND_SAMPLES = 40  # frames spread over the video for its own background model


@dataclasses.dataclass
class VideoInput:
    """What ``sequence_from_video`` read.

    Attributes:
        sequence: the cameras, fps, silhouettes (C, T, H, W) and keypoints (if given) of the
            frames read, T of them.
        total_frames: the videos' length.
        stopped: why reading stopped before the end (None: it did not): the frame and camera.
        seconds: time spent decoding ("decode"), fitting the background model ("background
            model", once per video) and on the subtraction ("background": dispatching it and
            waiting for its masks; it runs while the next chunk is decoded, so the two add up to
            the wall time, not to each stage's cost alone), "silhouettes", the wall time from the
            first chunk's decoding to the last chunk's masks, and "open and close", the videos'
            (once per video: ffmpeg counting each video's frames, starting and stopping).
    """

    sequence: Sequence
    total_frames: int
    stopped: str | None
    seconds: dict


@jax.jit
def _silhouettes(model, block):
    """(C, t, H, W) bool masks of a (C, t, H, W, 3) uint8 chunk and their (C, t) areas in
    pixels. A ``jax.jit`` of its own: ``eqx.filter_jit`` (under ``subtract_background``) waits
    for its result before returning, and this call must return at once, the masks computed
    while the next chunk decodes."""
    # frames first (the model broadcast over them): a model with a frame axis of 1 against the
    # (C, t) chunk ran a quarter slower
    mask = jnp.swapaxes(subtract_background(model, jnp.moveaxis(block, 1, 0)).mask, 0, 1)
    return mask, jnp.sum(mask, axis=(2, 3), dtype=jnp.int32)


def _frame_sizes(rig: CameraRig) -> list[tuple[int, int]]:
    return [(int(w), int(h)) for w, h in np.asarray(rig.image_size)]


def sequence_from_video(videos, rig: CameraRig, *, fps: float | None = None, background=None, keypoints=None,
                        frames: int | None = None, chunk: int = 32, keep_images: bool = False, say=None) -> VideoInput:
    """Read calibrated videos into a test sequence (module docstring).

    Args:
        videos: one video file or image folder per camera, in the rig's order.
        rig: the cameras (``io.read_calibration``); each video's frame size must be its
            camera's image size, or within an encoder's crop or pad of it (``io.MultiViewVideo``'s
            ``frame_sizes``: cropped or padded at the right and bottom edges, with a warning).
        fps: the frame rate when the sources do not say (image folders); else the videos'.
        background: one video or folder of the empty scene per camera, or None.
        keypoints: (C, T', 15, 3) detections (``io.read_keypoint_sources``), T' >= the frames read.
        frames: read at most this many frames.
        keep_images: keep the pictures as the sequence's ``images``.

    Raises:
        VideoFileError: videos of different lengths or sizes, or sizes that are not the rig's.
        ValueError: a count of videos that is not the rig's, or keypoints of other cameras.
    """
    say = say or (lambda *a, **k: None)
    if len({tuple(int(v) for v in size) for size in rig.image_size}) != 1:
        raise ValueError("the cameras' images must share one size (the silhouette likelihood scores them together); "
                         f"the calibration has {[tuple(int(v) for v in s) for s in rig.image_size]}")
    if len(videos) != rig.num_views:
        raise ValueError(f"the calibration has {rig.num_views} cameras ({', '.join(rig.names)}): give one video per camera "
                         f"in that order (got {len(videos)})")
    seconds = {"decode": 0.0, "background model": 0.0, "background": 0.0, "silhouettes": 0.0, "open and close": 0.0}
    if background is not None:
        if len(background) != rig.num_views:
            raise ValueError(f"give one background video per camera ({rig.num_views}), got {len(background)}")
        with MultiViewVideo(background, names=rig.names, frame_sizes=_frame_sizes(rig)) as empty:
            for line in empty.adjusted:
                say(f"warning: background {line}")
            start = time.perf_counter()
            pictures = np.concatenate([c for _, c in empty.chunks(chunk)], axis=1).swapaxes(0, 1)  # (t, C, H, W, 3)
            seconds["decode"] += time.perf_counter() - start
        source = f"{pictures.shape[0]} background frames per camera"
    else:
        start = time.perf_counter()
        pictures = sample_frames_evenly(videos, BACKGROUND_SAMPLES, names=rig.names, frame_sizes=_frame_sizes(rig))  # (t, C, H, W, 3)
        seconds["decode"] += time.perf_counter() - start
        source = f"the median of {pictures.shape[0]} frames spread over the videos"
    start = time.perf_counter()
    model = jax.block_until_ready(fit_background(pictures))
    seconds["background model"] += time.perf_counter() - start
    say(f"background model: {source}")
    masks, images, stopped = [], [], None
    start = time.perf_counter()
    video = MultiViewVideo(videos, names=rig.names, frame_sizes=_frame_sizes(rig))
    seconds["open and close"] += time.perf_counter() - start
    with video:
        for line in video.adjusted:
            say(f"warning: {line}")
        total = video.num_frames
        wanted = total if frames is None else min(int(frames), total)
        if keypoints is not None:
            keypoints = np.asarray(keypoints)
            if keypoints.shape[0] != rig.num_views or keypoints.shape[1] < wanted:
                raise ValueError(f"keypoints of {keypoints.shape[0]} cameras x {keypoints.shape[1]} frames, but the videos have "
                                 f"{rig.num_views} cameras x {wanted} frames")
        fps = float(fps if fps is not None else (video.fps or 0.0))
        if not fps > 0:
            raise ValueError("the sources do not say their frame rate (image folders): give it (--fps)")
        chunks = video.chunks(chunk, frames=wanted)
        looped = time.perf_counter()

        def finish(first, block, foreground):
            """Keep a chunk's silhouettes (waiting for them); the reason to stop, if any."""
            start = time.perf_counter()
            mask, area = (np.asarray(x) for x in foreground)  # (C, t, H, W), (C, t)
            seconds["background"] += time.perf_counter() - start
            empty = np.argwhere(area == 0)
            t = int(empty[:, 1].min()) if len(empty) else mask.shape[1]
            masks.append(mask[:, :t])
            if keep_images:
                images.append(block[:, :t])
            if len(empty):
                c = int(empty[np.argmin(empty[:, 1]), 0])
                return f"camera {rig.names[c]!r} sees nobody at frame {first + t} (an empty silhouette)"
            return None

        # Each chunk's subtraction is dispatched (XLA runs it on its own threads) before the next
        # chunk is decoded, and waited for after: decoding and subtraction run side by side. On
        # 2 cores both stages already use both (no gain measured, docs/video.md); with more
        # cores, or the subtraction on a GPU, decoding runs on what would be idle.
        pending = None
        while True:
            start = time.perf_counter()
            try:
                first, block = next(chunks)
            except StopIteration:
                block, failure = None, None
            except VideoFileError as err:
                block, failure = None, str(err)
            finally:
                seconds["decode"] += time.perf_counter() - start
            if block is not None:
                start = time.perf_counter()
                foreground = _silhouettes(model, block)
                seconds["background"] += time.perf_counter() - start
            if pending is not None:
                stopped = finish(*pending)
                if stopped:
                    break
            if block is None:
                stopped = failure
                break
            pending = (first, block, foreground)
        seconds["silhouettes"] = time.perf_counter() - looped
        closing = time.perf_counter()
    seconds["open and close"] += time.perf_counter() - closing
    count = sum(m.shape[1] for m in masks)
    if count == 0:
        raise VideoFileError(f"nothing to track: {stopped}")
    silhouettes = np.concatenate(masks, axis=1).astype(np.uint8)
    sequence = Sequence.create(
        fps=fps, camera_K=np.asarray(rig.K, np.float64), camera_R=np.asarray(rig.R, np.float64),
        camera_t=np.asarray(rig.t, np.float64), camera_dist=np.asarray(rig.dist, np.float64),
        image_size=np.asarray(rig.image_size, np.int64), camera_names=np.asarray(rig.names), silhouettes=silhouettes,
        images=np.concatenate(images, axis=1) if keep_images else None,
        keypoints2d=None if keypoints is None else np.asarray(keypoints[:, :count], np.float32))
    return VideoInput(sequence=sequence, total_frames=total, stopped=stopped, seconds=seconds)

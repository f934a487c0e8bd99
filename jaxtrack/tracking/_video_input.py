"""From a user's files to a test sequence, in stages: calibrated videos (and background videos,
and a detector's keypoints) -> decoded and averaged down to the tracking resolution -> a
background model -> silhouettes by background subtraction -> a ``Sequence`` to track.

The videos are decoded in chunks (``io.MultiViewVideo``), each frame averaged down to the tracking
resolution as it is decoded (``reduce``; ``"auto"`` chooses it from the person's height in
pixels), so no full-resolution frame outlives its chunk. The background model comes from frames
spread over the background videos when given, else over the videos themselves
(``io.sample_frames_evenly``, the person moving), at that resolution. Each chunk's silhouettes
are kept as one byte per pixel; the pictures are kept only when asked (001's edge likelihood
reads them).

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
from ..image import fit_background, resolution_factors, subtract_background
from ..io import MultiViewVideo, Sequence, VideoFileError, reduce_frames

BACKGROUND_SAMPLES = 40  # frames spread over the video for its own background model
PREVIEW_LONG_SIDE = 640  # the background samples' longer side before the tracking resolution is chosen (pixels)
PERSON_PIXELS = 120  # the person's height at the resolution "auto" chooses (pixels)
HEIGHT_FRAMES = 8  # the videos' first frames the person's height is measured on, given an empty-scene video
PERSON_MARGIN = 0.15  # a keypoint box grows by this share of its height on every side to hold the whole body
MIN_COVERAGE = 0.2  # the median share of a keypoint box the silhouettes must fill to be trusted
BOX_CONFIDENCE = 0.3  # keypoints more confident than this bound the person's box (generous: a box left out is lost)


@dataclasses.dataclass
class VideoInput:
    """What ``sequence_from_video`` read.

    Attributes:
        sequence: the cameras, fps, silhouettes (C, T, H, W) and keypoints (if given) of the
            frames read, T of them, at the tracking resolution (the cameras and keypoints
            rescaled with it).
        total_frames: the videos' length.
        stopped: why reading stopped before the end (None: it did not): the frame and camera.
        seconds: time spent decoding ("decode"), fitting the background model ("background
            model", once per video) and on the subtraction ("background": dispatching it and
            waiting for its masks; it runs while the next chunk is decoded, so the two add up to
            the wall time, not to each stage's cost alone), "silhouettes", the wall time from the
            first chunk's decoding to the last chunk's masks, and "open and close", the videos'
            (once per video: ffmpeg counting each video's frames, starting and stopping).
        reduce: the videos' pixels per tracking pixel, on each side (1: full resolution).
        source: the same sequence at the videos' resolution, without silhouettes or pictures:
            the calibration's cameras, the keypoints in the videos' pixels (what an estimate
            file keeps, and what an overlay draws over).
        coverage: (t, C) the share of the keypoints' box the silhouettes fill on the background
            samples (``silhouette_coverage``), or None without keypoints or with an empty-scene
            video (its samples are not of the person).
        empty_frames: (C,) per camera, the frames read whose silhouette is empty (with
            ``through_empty`` they do not stop the reading: the keypoints carry them).
    """

    sequence: Sequence
    total_frames: int
    stopped: str | None
    seconds: dict
    reduce: int
    source: Sequence
    coverage: np.ndarray | None
    empty_frames: np.ndarray

    def camera_coverage(self) -> np.ndarray:
        """(C,) per camera, the median over the background samples of ``coverage`` (NaN where no
        sample shows keypoints, or without ``coverage``)."""
        if self.coverage is None:
            return np.full(len(self.empty_frames), np.nan)
        return np.array([np.median(c[np.isfinite(c)]) if np.isfinite(c).any() else np.nan for c in self.coverage.T])

    def untrusted_cameras(self, minimum: float = MIN_COVERAGE) -> list[str]:
        """The cameras whose silhouettes fill under ``minimum`` of the keypoints' boxes
        (``camera_coverage``: a background model that holds the person, or a person the
        subtraction misses), or are empty on some frame read."""
        names = [str(n) for n in self.sequence.camera_names]
        return [n for n, m, e in zip(names, self.camera_coverage(), self.empty_frames) if m < minimum or e > 0]


class VideoStream:
    """Calibrated videos open for reading, with their tracking resolution and background model
    (``open_video``): ``read(frames)`` gives the next frames' ``Sequence`` at the tracking
    resolution (silhouettes, the pictures when kept, the keypoints), so a long video is tracked
    a segment at a time in the memory of one segment."""

    def __init__(self, *, video, chunks, model, reduce: int, source: Sequence, total_frames: int, wanted: int,
                 keep_images: bool, through_empty: bool, coverage, seconds: dict):
        self.video, self._chunks, self.model, self.reduce = video, chunks, model, reduce
        self.source = source  # the calibration's cameras and every frame's keypoints, at the videos' size
        self.total_frames, self.wanted = total_frames, wanted
        self.keep_images, self.through_empty = keep_images, through_empty
        self.coverage, self.seconds = coverage, seconds
        self.frames_read = 0
        self.stopped: str | None = None  # why reading stopped before the end
        self.empty_frames = np.zeros(len(source.camera_names), int)  # per camera, frames read with an empty silhouette
        self._left: list = []  # (masks, pictures) decoded past the last segment's end
        self._ended = False

    def __enter__(self) -> VideoStream:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        start = time.perf_counter()
        self.video.close()
        self.seconds["open and close"] += time.perf_counter() - start

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of the tracking resolution."""
        width, height = (int(v) for v in self.source.image_size[0])
        return width // self.reduce, height // self.reduce

    def _finish(self, first: int, block, foreground) -> tuple[np.ndarray, np.ndarray | None, str | None]:
        """A chunk's silhouettes (waiting for them) up to any empty one, its pictures when kept,
        and the reason to stop, if any."""
        start = time.perf_counter()
        mask, area = (np.asarray(x) for x in foreground)  # (C, t, H, W), (C, t)
        self.seconds["background"] += time.perf_counter() - start
        empty = np.argwhere(area == 0)
        self.empty_frames[:] += (area == 0).sum(axis=1)
        if self.through_empty:  # the keypoints carry the frames the silhouettes miss
            empty = empty[:0]
        t = int(empty[:, 1].min()) if len(empty) else mask.shape[1]
        reason = None
        if len(empty):
            c = int(empty[np.argmin(empty[:, 1]), 0])
            reason = f"camera {str(self.source.camera_names[c])!r} sees nobody at frame {first + t} (an empty silhouette)"
        return mask[:, :t], (block[:, :t] if self.keep_images else None), reason

    def read(self, frames: int) -> Sequence | None:
        """The next ``frames`` frames (fewer at the end, or where a frame cannot be decoded or
        a camera sees nobody: ``stopped`` then says why) as a ``Sequence`` at the tracking
        resolution; None when there are none left.

        Each chunk's subtraction is dispatched (XLA runs it on its own threads) before the next
        chunk is decoded, and waited for after: decoding and subtraction run side by side. On 2
        cores both stages already use both (no gain measured, docs/video.md); with more cores,
        or the subtraction on a GPU, decoding runs on what would be idle.
        """
        if frames < 1:
            raise ValueError(f"read at least one frame, got {frames}")
        pieces, self._left = self._left, []
        have = sum(m.shape[1] for m, _ in pieces)
        pending, looped = None, time.perf_counter()
        while True:
            block = failure = None
            queued = have + (pending[1].shape[1] if pending is not None else 0)
            if queued < frames and not self._ended and self.stopped is None:
                start = time.perf_counter()
                try:
                    first, block = next(self._chunks)
                except StopIteration:
                    self._ended = True
                except VideoFileError as err:
                    failure = str(err)
                finally:
                    self.seconds["decode"] += time.perf_counter() - start
                if block is not None:
                    start = time.perf_counter()
                    foreground = _silhouettes(self.model, block)
                    self.seconds["background"] += time.perf_counter() - start
            if pending is not None:
                mask, pictures, reason = self._finish(*pending)
                pieces.append((mask, pictures))
                have += mask.shape[1]
                if reason:
                    self.stopped = reason
                    break
            if block is None:
                if failure:
                    self.stopped = failure
                break
            pending = (first, block, foreground)
        self.seconds["silhouettes"] += time.perf_counter() - looped
        if not have:
            return None
        masks = np.concatenate([m for m, _ in pieces], axis=1)
        pictures = np.concatenate([p for _, p in pieces], axis=1) if self.keep_images else None
        if have > frames:  # the last chunk ran past the segment: kept for the next
            self._left = [(masks[:, frames:], None if pictures is None else pictures[:, frames:])]
            masks = masks[:, :frames]
            pictures = None if pictures is None else pictures[:, :frames]
        first, count = self.frames_read, masks.shape[1]
        self.frames_read += count
        keypoints = self.source.keypoints2d
        segment = self.source.replace(keypoints2d=None if keypoints is None else keypoints[:, first:first + count])
        # the cameras and keypoints at the tracking resolution (Sequence.resized: pixel centres at integers)
        return segment.resized(*self.size).replace(silhouettes=masks.view(np.uint8), images=pictures)  # bool and uint8 share a byte

    def input(self, sequence: Sequence) -> VideoInput:
        """What has been read as a ``VideoInput`` with ``sequence`` (a segment read, or several
        joined) as its tracking sequence."""
        count = self.frames_read
        keypoints = self.source.keypoints2d
        return VideoInput(sequence=sequence, total_frames=self.total_frames, stopped=self.stopped, seconds=self.seconds,
                          reduce=self.reduce, coverage=self.coverage, empty_frames=self.empty_frames.copy(),
                          source=self.source.replace(keypoints2d=None if keypoints is None else keypoints[:, :count]))


def common_reductions(sizes) -> list[int]:
    """The whole factors that divide every camera's width and height, (width, height) each,
    ascending (1 first)."""
    sides = [int(v) for size in sizes for v in size]
    return [f for f in range(1, min(sides) + 1) if all(side % f == 0 for side in sides)]


def preview_reduction(sizes, long_side: int = PREVIEW_LONG_SIDE) -> int:
    """The smallest common reduction that brings every camera's longer side to ``long_side``
    pixels or under (the largest there is, when none does)."""
    factors = common_reductions(sizes)
    return next((f for f in factors if max(max(size) for size in sizes) / f <= long_side), factors[-1])


def reduction_for_resolution(size, resolution) -> int:
    """The whole factor from a camera's ``size`` to ``resolution``, both (width, height): it
    must divide both sides (``image.resolution_factors``'s error names sizes that do) and be the
    same on both (the pixels stay square)."""
    fx, fy = resolution_factors(tuple(size), tuple(int(v) for v in resolution))
    if fx != fy:
        raise ValueError(f"cannot track {size[0]}x{size[1]} videos at {resolution[0]}x{resolution[1]}: the width would be "
                         f"averaged over {fx} pixels and the height over {fy}; keep the aspect (e.g. "
                         f"{size[0] // fy}x{size[1] // fy} or {size[0] // fx}x{size[1] // fx} where it divides)")
    return fx


def choose_reduction(sizes, preview: int, person_height: float, person_pixels: int = PERSON_PIXELS) -> int:
    """The largest common reduction, a multiple of ``preview``, at which a person
    ``person_height`` pixels tall in the videos stays ``person_pixels`` tall or more
    (``preview`` when even that is smaller)."""
    factors = [f for f in common_reductions(sizes) if f % preview == 0 and person_height / f >= person_pixels]
    return max(factors, default=preview)


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


def keypoint_boxes(keypoints, reduce: int, size, *, margin: float = 0.0) -> np.ndarray:
    """(C, h, w) bool: per camera, the bounding box of one frame's confident keypoints (C, K, 3),
    in the videos' pixels, grown by ``margin`` of its height on every side, on the grid of
    ``size`` = (w, h) tracking pixels ``reduce`` times smaller. A camera that sees fewer than
    two keypoints marks nothing."""
    width, height = size
    boxes = np.zeros((len(keypoints), height, width), bool)
    for c, points in enumerate(np.asarray(keypoints)):
        seen = points[points[:, 2] > BOX_CONFIDENCE, :2]
        if len(seen) < 2:
            continue
        low, high = seen.min(axis=0), seen.max(axis=0)
        grow = margin * (high[1] - low[1])
        x0, y0 = np.floor((low - grow + 0.5) / reduce).astype(int)
        x1, y1 = np.ceil((high + grow + 0.5) / reduce).astype(int)
        boxes[c, max(y0, 0):max(min(y1, height), 0), max(x0, 0):max(min(x1, width), 0)] = True
    return boxes


def silhouette_coverage(masks, keypoints, reduce: int) -> np.ndarray:
    """(t, C) the share of each frame's keypoint box (``keypoint_boxes``, no margin) that the
    silhouettes ``masks`` (t, C, h, w) fill; NaN where a camera sees no keypoints."""
    masks = np.asarray(masks, bool)
    size = (masks.shape[-1], masks.shape[-2])
    coverage = np.full(masks.shape[:2], np.nan)
    for t, (mask, points) in enumerate(zip(masks, keypoints)):
        boxes = keypoint_boxes(points, reduce, size)
        area = boxes.sum(axis=(1, 2))
        coverage[t] = np.where(area > 0, (mask & boxes).sum(axis=(1, 2)) / np.maximum(area, 1), np.nan)
    return coverage


def _person_height(model, frames, keypoints, reduce: int) -> tuple[float, str]:
    """The person's height in the videos' pixels, and what measured it: the keypoints' extent
    (over 0.9: the head joint is not the crown) on the first frames that show them, else the
    silhouettes of ``frames`` (t, C, h, w, 3), frames of the videos at ``reduce``, median over
    the frames of the median over the views."""
    from ._pipeline import keypoint_height_pixels, person_height_pixels

    if keypoints is not None:
        heights = [keypoint_height_pixels(keypoints[:, t]) for t in range(min(keypoints.shape[1], 30))]
        heights = [h for h in heights if h > 0]
        if heights:
            return float(np.median(heights)) / 0.9, "keypoints"
    masks = np.asarray(subtract_background(model, frames).mask)  # (t, C, h, w)
    return float(np.median([person_height_pixels(frame) for frame in masks])) * reduce, "silhouettes"


def _keypoints_for(keypoints, frames: int, say) -> np.ndarray:
    """(C, ``frames``, 15, 3) keypoints: those given, with missing frames (confidence 0) after
    their end where they hold fewer than the videos, said with the frames where no camera sees
    anyone (the filter goes through them on what else it has)."""
    held = keypoints.shape[1]
    if held < frames:
        say(f"warning: the keypoints hold {held} frames, the videos {frames}: frames {held}-{frames - 1} have no keypoints "
            "(check that the detector ran on every frame)")
        keypoints = np.concatenate([keypoints, np.zeros((keypoints.shape[0], frames - held) + keypoints.shape[2:],
                                                        keypoints.dtype)], axis=1)
    keypoints = keypoints[:, :frames]
    nobody = np.flatnonzero(~(keypoints[..., 2] > 0).any(axis=(0, 2))[:held])
    if nobody.size:
        say(f"warning: no camera's keypoints see the person in {nobody.size} of {min(held, frames)} frames (from frame "
            f"{nobody[0]}): those frames are tracked through on the silhouettes, or on the dynamics alone")
    return keypoints


def open_video(videos, rig: CameraRig, *, fps: float | None = None, background=None, keypoints=None,
               frames: int | None = None, chunk: int = 32, keep_images: bool = False, resolution=None,
               through_empty: bool = False, say=None) -> VideoStream:
    """Open calibrated videos for reading in segments (``VideoStream.read``): the tracking
    resolution chosen, the background model fitted, the keypoints checked (module docstring).
    Use as a context manager, or close it.

    Args:
        videos: one video file or image folder per camera, in the rig's order.
        rig: the cameras (``io.read_calibration``); each video's frame size must be its
            camera's image size, or within an encoder's crop or pad of it (``io.MultiViewVideo``'s
            ``frame_sizes``: cropped or padded at the right and bottom edges, with a warning).
        fps: the frame rate when the sources do not say (image folders); else the videos'.
        background: one video or folder of the empty scene per camera, or None.
        keypoints: (C, T', 15, 3) detections (``io.read_keypoint_sources``); where T' is under the
            frames read, the frames after them have none (said).
        frames: read at most this many frames.
        keep_images: keep the pictures as the sequence's ``images``.
        resolution: None: the videos' own; (width, height): frames averaged down to it as they are
            decoded (a whole factor of the videos' size on both sides); ``"auto"``: the largest
            whole reduction at which the person is still ``PERSON_PIXELS`` tall, measured on the
            keypoints, else on silhouettes of the background samples (of the first
            ``HEIGHT_FRAMES`` frames, given an empty-scene video) at ``PREVIEW_LONG_SIDE``.
            The background model, the silhouettes and the pictures are made at that resolution:
            no full-resolution frame is held beyond the chunk being decoded.
        through_empty: with keypoints, an empty silhouette does not stop the reading (the
            keypoints carry those frames; ``empty_frames`` counts them); else the frames before
            it are returned with the reason.

    Raises:
        VideoFileError: videos of different lengths or sizes, or sizes that are not the rig's.
        ValueError: a count of videos that is not the rig's, keypoints of other cameras, or a
            resolution that is not a whole reduction of the videos'.
    """
    say = say or (lambda *a, **k: None)
    if len({tuple(int(v) for v in size) for size in rig.image_size}) != 1:
        raise ValueError("the cameras' images must share one size (the silhouette likelihood scores them together); "
                         f"the calibration has {[tuple(int(v) for v in s) for s in rig.image_size]}")
    if len(videos) != rig.num_views:
        raise ValueError(f"the calibration has {rig.num_views} cameras ({', '.join(rig.names)}): give one video per camera "
                         f"in that order (got {len(videos)})")
    if background is not None and len(background) != rig.num_views:
        raise ValueError(f"give one background video per camera ({rig.num_views}), got {len(background)}")
    sizes = _frame_sizes(rig)
    if resolution is None:
        reduce = preview = 1
    elif isinstance(resolution, str):
        if resolution != "auto":
            raise ValueError(f"resolution must be (width, height), 'auto' or None, got {resolution!r}")
        reduce, preview = None, preview_reduction(sizes)
    else:
        reduce = preview = reduction_for_resolution(sizes[0], resolution)
    through_empty = bool(through_empty) and keypoints is not None
    if keypoints is not None:
        keypoints = np.asarray(keypoints)
        if keypoints.ndim != 4 or keypoints.shape[0] != rig.num_views:
            raise ValueError(f"keypoints of shape {keypoints.shape}: expected one (T, 15, 3) array per camera ({rig.num_views})")
    seconds = {"decode": 0.0, "background model": 0.0, "background": 0.0, "silhouettes": 0.0, "open and close": 0.0}
    start = time.perf_counter()
    with MultiViewVideo(background if background is not None else videos, names=rig.names, frame_sizes=sizes,
                        reduce=preview) as sampled:
        if background is not None:
            for line in sampled.adjusted:
                say(f"warning: background {line}")
        indices, pictures = sampled.sample(BACKGROUND_SAMPLES)  # (t,), (t, C, h, w, 3)
    seconds["decode"] += time.perf_counter() - start
    source = (f"{pictures.shape[0]} frames of the empty scene per camera" if background is not None
              else f"the median of {pictures.shape[0]} frames spread over the videos")
    person = sampled_keypoints = None  # where the keypoints say the person is on the sampled frames of the videos
    if background is None and keypoints is not None:
        nobody = np.zeros(keypoints.shape[:1] + keypoints.shape[2:], keypoints.dtype)  # a frame past the keypoints' end
        sampled_keypoints = [keypoints[:, i] if i < keypoints.shape[1] else nobody for i in indices]  # t of (C, K, 3)
        size = (pictures.shape[-2], pictures.shape[-3])
        person = np.stack([keypoint_boxes(k, preview, size, margin=PERSON_MARGIN) for k in sampled_keypoints])  # (t, C, h, w)
        source += ", each pixel's over the frames whose keypoints leave it free"
    start = time.perf_counter()
    model = jax.block_until_ready(fit_background(pictures, exclude=person))
    if reduce is None:  # chosen from the person's size
        seen = pictures
        if background is not None and keypoints is None:  # the empty scene's samples show nobody: the videos' first frames
            with MultiViewVideo(videos, names=rig.names, frame_sizes=sizes, reduce=preview) as first:
                seen = next(first.chunks(HEIGHT_FRAMES))[1].swapaxes(0, 1)  # (t, C, h, w, 3)
        height, measured = _person_height(model, seen, keypoints, preview)
        del seen
        reduce = choose_reduction(sizes, preview, height)
        width_, height_ = sizes[0][0] // reduce, sizes[0][1] // reduce
        if reduce == 1:
            say(f"tracking at the videos' {width_}x{height_}: the person is about {height:.0f} px tall ({measured}); no whole "
                f"reduction keeps {PERSON_PIXELS} px (--resolution to choose)")
        else:
            say(f"tracking at {width_}x{height_} (the videos' {sizes[0][0]}x{sizes[0][1]} averaged over {reduce}x{reduce} pixels): "
                f"the person is about {height:.0f} px tall in the videos ({measured}), {height / reduce:.0f} px at that size "
                f"(the largest reduction that keeps {PERSON_PIXELS} px; --resolution to choose)")
        if reduce != preview:
            factor = reduce // preview
            pictures = reduce_frames(pictures, factor)
            if person is not None:  # a tracking pixel is the person's where any of its video pixels is
                t, c, h, w = person.shape
                person = person.reshape(t, c, h // factor, factor, w // factor, factor).any(axis=(3, 5))
            model = jax.block_until_ready(fit_background(pictures, exclude=person))
    seconds["background model"] += time.perf_counter() - start
    coverage = None
    if sampled_keypoints is not None:  # do the silhouettes show the person the keypoints place?
        coverage = silhouette_coverage(np.asarray(subtract_background(model, pictures).mask), sampled_keypoints, reduce)
    del pictures, person
    say(f"background model: {source}")
    start = time.perf_counter()
    try:
        video = MultiViewVideo(videos, names=rig.names, frame_sizes=sizes, reduce=reduce)
    finally:
        seconds["open and close"] += time.perf_counter() - start
    try:
        for line in video.adjusted:
            say(f"warning: {line}")
        total = video.num_frames
        wanted = total if frames is None else min(int(frames), total)
        if keypoints is not None:
            keypoints = _keypoints_for(keypoints, wanted, say)
        fps = float(fps if fps is not None else (video.fps or 0.0))
        if not fps > 0:
            raise ValueError("the sources do not say their frame rate (image folders): give it (--fps)")
    except BaseException:
        video.close()
        raise
    source = Sequence.create(
        fps=fps, camera_K=np.asarray(rig.K, np.float64), camera_R=np.asarray(rig.R, np.float64),
        camera_t=np.asarray(rig.t, np.float64), camera_dist=np.asarray(rig.dist, np.float64),
        image_size=np.asarray(rig.image_size, np.int64), camera_names=np.asarray(rig.names),
        keypoints2d=None if keypoints is None else np.asarray(keypoints, np.float32))
    return VideoStream(video=video, chunks=video.chunks(chunk, frames=wanted), model=model, reduce=reduce, source=source,
                       total_frames=total, wanted=wanted, keep_images=keep_images, through_empty=through_empty,
                       coverage=coverage, seconds=seconds)


def sequence_from_video(videos, rig: CameraRig, *, fps: float | None = None, background=None, keypoints=None,
                        frames: int | None = None, chunk: int = 32, keep_images: bool = False, resolution=None,
                        through_empty: bool = False, say=None) -> VideoInput:
    """Read calibrated videos into a test sequence (module docstring): ``open_video`` and one
    ``VideoStream.read`` of every frame. Arguments and errors as ``open_video``'s.

    Raises:
        VideoFileError: nothing to track (the first frame cannot be decoded, or a camera sees
            nobody in it).
    """
    with open_video(videos, rig, fps=fps, background=background, keypoints=keypoints, frames=frames, chunk=chunk,
                    keep_images=keep_images, resolution=resolution, through_empty=through_empty, say=say) as stream:
        sequence = stream.read(stream.wanted)
        if sequence is None:
            raise VideoFileError(f"nothing to track: {stream.stopped}")
        return stream.input(sequence)

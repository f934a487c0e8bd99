"""Multi-view video input: one video file or image folder per camera, synchronised by frame
index and read in chunks, never a whole video in memory.

A video file is decoded by imageio's ffmpeg plugin (the ``imageio-ffmpeg`` package, in the
``video`` extra); an image folder holds one picture per frame (PNG, JPEG, BMP or TIFF, read in
name order). Grey pictures become RGB, an alpha channel is dropped. ``MultiViewVideo`` checks
before any decoding that every camera's source exists and has the same number of frames, and
reads each camera's frame size; ``chunks`` yields ``(first_frame, frames (C, t, H, W, 3) uint8)``
when the cameras share one size, else one list entry per camera. A frame that cannot be decoded
raises ``VideoFileError`` naming the camera, the file and the frame, after the chunks before it
were handed out (a caller that saves as it goes keeps them).
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterator

import numpy as np

from ..errors import JaxtrackError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


class VideoFileError(JaxtrackError):
    """A video or image folder that cannot be read; the message names the file and the frame."""


def _rgb(frame, where: str) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim == 2:
        frame = np.repeat(frame[..., None], 3, axis=-1)
    if frame.ndim != 3 or frame.shape[-1] not in (3, 4):
        raise VideoFileError(f"{where}: not an RGB or grey picture (shape {frame.shape})")
    if frame.dtype != np.uint8:
        if np.issubdtype(frame.dtype, np.integer) and frame.max(initial=0) > 255:
            frame = (frame // 256).astype(np.uint8)  # 16-bit pictures
        else:
            frame = np.clip(frame, 0, 255).astype(np.uint8)
    return frame[..., :3]


class _Folder:
    def __init__(self, path: str):
        self.path = path
        self.files = sorted(n for n in os.listdir(path) if n.lower().endswith(IMAGE_SUFFIXES))
        if not self.files:
            raise VideoFileError(f"{path}: no pictures ({', '.join(IMAGE_SUFFIXES)}) in the folder")
        self.num_frames = len(self.files)
        self.fps = None  # pictures do not say
        first = self._read(0)
        self.size = (first.shape[1], first.shape[0])
        self.position = 0

    def _read(self, index: int) -> np.ndarray:
        import imageio.v3 as iio

        where = os.path.join(self.path, self.files[index])
        try:
            with open(where, "rb") as handle:  # decoded from memory: a failing decoder leaves no file open
                data = handle.read()
            return _rgb(iio.imread(data, extension=os.path.splitext(where)[1].lower()), where)
        except VideoFileError:
            raise
        except Exception as err:  # noqa: BLE001 - a truncated or corrupt picture fails in the decoder, whatever its type
            raise VideoFileError(f"{where}: frame {index} cannot be decoded ({type(err).__name__}: {err})") from None

    def read(self, count: int) -> list[np.ndarray]:
        frames = []
        for _ in range(count):
            frame = self._read(self.position)
            if (frame.shape[1], frame.shape[0]) != self.size:
                raise VideoFileError(f"{os.path.join(self.path, self.files[self.position])}: frame {self.position} is "
                                     f"{frame.shape[1]}x{frame.shape[0]}, the folder's first {self.size[0]}x{self.size[1]}")
            frames.append(frame)
            self.position += 1
        return frames

    def close(self):
        pass


@contextlib.contextmanager
def _ffmpeg_subprocess():
    """Quiet JAX's warning that a process forked: imageio starts ffmpeg as a subprocess (fork then
    exec at once), which cannot deadlock JAX's threads."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        yield


class _VideoFile:
    def __init__(self, path: str):
        import imageio

        self.path = path
        self.reader = None
        try:
            with _ffmpeg_subprocess():
                self.reader = imageio.get_reader(path, format="FFMPEG")
                self.num_frames = int(self.reader.count_frames())
            width, height = self.reader.get_meta_data()["size"]
        except ImportError as err:
            raise VideoFileError(f"{path}: reading video files needs imageio's ffmpeg plugin: pip install 'jaxtrack[video]' "
                                 f"({err})") from None
        except Exception as err:  # noqa: BLE001 - ffmpeg's failures on a bad file come as OSError, IndexError, RuntimeError...
            self.close()
            raise VideoFileError(f"{path}: not a readable video ({type(err).__name__}: {err})") from None
        if self.num_frames < 1:
            raise VideoFileError(f"{path}: the video has no frames")
        self.size = (int(width), int(height))
        self.fps = float(self.reader.get_meta_data().get("fps") or 0.0) or None
        self.frames = iter(self.reader)
        self.position = 0

    def read(self, count: int) -> list[np.ndarray]:
        frames = []
        for _ in range(count):
            try:
                with _ffmpeg_subprocess():
                    frame = next(self.frames)
            except StopIteration:
                raise VideoFileError(f"{self.path}: ends at frame {self.position}, before the {self.num_frames} it declared") from None
            except Exception as err:  # noqa: BLE001 - a decoder's failure on a corrupt frame, whatever its type
                raise VideoFileError(f"{self.path}: frame {self.position} cannot be decoded ({type(err).__name__}: {err})") from None
            frames.append(_rgb(frame, f"{self.path} frame {self.position}"))
            self.position += 1
        return frames

    def close(self):
        if self.reader is not None:
            self.reader.close()
            self.reader = None


class MultiViewVideo:
    """One source per camera (video files or image folders), read together by frame index.

    Use as a context manager; ``num_frames``, ``sizes`` ((width, height) per camera), ``fps``
    and ``names`` are known on opening, before any frame is decoded beyond the first."""

    def __init__(self, paths, names=None):
        paths = [os.fspath(p) for p in paths]
        if not paths:
            raise ValueError("a video needs at least one camera's source")
        self.paths = paths
        self.names = tuple(names) if names is not None else tuple(f"C{i + 1}" for i in range(len(paths)))
        if len(self.names) != len(paths):
            raise ValueError(f"{len(self.names)} camera names for {len(paths)} sources")
        self.sources = []
        try:
            for path in paths:
                if not os.path.exists(path):
                    raise FileNotFoundError(f"no video or image folder at {path!r}")
                self.sources.append(_Folder(path) if os.path.isdir(path) else _VideoFile(path))
        except BaseException:
            self.close()
            raise
        counts = [s.num_frames for s in self.sources]
        if len(set(counts)) != 1:
            self.close()
            raise VideoFileError("the cameras' sources have different numbers of frames: "
                                 + ", ".join(f"{p} {n}" for p, n in zip(paths, counts)) + " (they are synchronised by frame index)")
        self.num_frames = counts[0]
        self.sizes = tuple(s.size for s in self.sources)
        rates = [s.fps for s in self.sources if s.fps]
        self.fps = rates[0] if rates else None  # frames per second the first video file says (None: image folders)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        for source in self.sources:
            source.close()

    def chunks(self, size: int = 32, *, frames: int | None = None) -> Iterator[tuple[int, np.ndarray | list]]:
        """``(first_frame, frames)`` of up to ``size`` frames at a time, from the sources' current
        position to frame ``frames`` (default: the end): a (C, t, H, W, 3) uint8 array when the
        cameras share one size, else a list of (t, H_c, W_c, 3) arrays."""
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"size must be a positive whole number of frames, got {size!r}")
        stop = self.num_frames if frames is None else min(int(frames), self.num_frames)
        while self.sources[0].position < stop:
            first = self.sources[0].position
            count = min(size, stop - first)
            views = [np.stack(source.read(count)) for source in self.sources]
            yield first, (np.stack(views) if len(set(self.sizes)) == 1 else views)


def sample_frames_evenly(paths, count: int = 30) -> np.ndarray:
    """(count, C, H, W, 3) uint8 frames spread evenly over the sources (for a background model
    learned from the video itself, ``image.fit_background``), read in one pass."""
    with MultiViewVideo(paths) as video:
        if len(set(video.sizes)) != 1:
            raise VideoFileError("sampling frames needs cameras of one image size")
        wanted = set(np.linspace(0, video.num_frames - 1, min(count, video.num_frames)).round().astype(int).tolist())
        picked = []
        for first, frames in video.chunks(32):
            picked += [frames[:, i] for i in range(frames.shape[1]) if first + i in wanted]
        return np.stack(picked)


class VideoWriter:
    """Write one H.264 video per camera, frame chunks at a time (never a whole video in memory).

    ``write(frames)`` takes (C, t, H, W, 3) uint8. The files are near-lossless (``quality`` 8 of
    imageio's 0-10 scale, x264's constant rate factor about 10) and in the yuv420p pixel format
    every player reads, so width and height must be even. A context manager: the files are
    closed (complete) on exit, also after an error."""

    def __init__(self, paths, fps: float, *, quality: int = 8):
        import imageio

        self.paths = [os.fspath(p) for p in paths]
        self.writers = []
        try:
            for path in self.paths:
                with _ffmpeg_subprocess():
                    self.writers.append(imageio.get_writer(path, format="FFMPEG", fps=float(fps), codec="libx264",
                                                           quality=quality, macro_block_size=2))
        except ImportError as err:
            self.close()
            raise VideoFileError(f"{self.paths[len(self.writers)]}: writing video files needs imageio's ffmpeg plugin: "
                                 f"pip install 'jaxtrack[video]' ({err})") from None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def write(self, frames) -> None:
        frames = np.asarray(frames)
        if frames.ndim != 5 or frames.shape[0] != len(self.writers) or frames.shape[-1] != 3 or frames.dtype != np.uint8:
            raise ValueError(f"frames must be ({len(self.writers)}, t, H, W, 3) uint8, got {frames.shape} {frames.dtype}")
        if frames.shape[2] % 2 or frames.shape[3] % 2:
            raise ValueError(f"video frames must have an even width and height (yuv420p), got {frames.shape[3]}x{frames.shape[2]}")
        with _ffmpeg_subprocess():
            for writer, camera in zip(self.writers, frames):
                for frame in camera:
                    writer.append_data(frame)

    def close(self):
        with _ffmpeg_subprocess():
            for writer in self.writers:
                writer.close()
        self.writers = []

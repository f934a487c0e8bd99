"""Multi-view video input: one video file or image folder per camera, synchronised by frame
index and read in chunks, never a whole video in memory.

A video file is decoded by imageio's ffmpeg plugin (the ``imageio-ffmpeg`` package, in the
``video`` extra); an image folder holds one picture per frame (PNG, JPEG, BMP or TIFF, read in
name order). Grey pictures become RGB, an alpha channel is dropped. ``MultiViewVideo`` checks
before any decoding that every camera's source exists and has the same number of frames, and
reads each camera's frame size; ``chunks`` yields ``(first_frame, frames (C, t, H, W, 3) uint8)``
when the cameras share one size, else one list entry per camera. With ``reduce`` = f the frames
come out f times smaller on each side, each pixel the mean of an f x f block (area averaging; a
video file is scaled by its ffmpeg process, so only the small frames cross the pipe): a tracker
that works at a tenth of an HD camera's resolution never holds its full frames beyond one
chunk. A frame that cannot be decoded
raises ``VideoFileError`` naming the camera, the file and the frame, after the chunks before it
were handed out (a caller that saves as it goes keeps them).
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import warnings
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

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
        self.out_size = self.size  # what read_into writes: the pictures as they are (MultiViewVideo fits them)
        self.position = 0

    def shape_output(self, wanted, reduce: int) -> bool:
        """Pictures are fitted and reduced by the caller: False."""
        return False

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

    def read_into(self, out: np.ndarray) -> None:
        for i in range(len(out)):
            frame = self._read(self.position)
            if (frame.shape[1], frame.shape[0]) != self.size:
                raise VideoFileError(f"{os.path.join(self.path, self.files[self.position])}: frame {self.position} is "
                                     f"{frame.shape[1]}x{frame.shape[0]}, the folder's first {self.size[0]}x{self.size[1]}")
            out[i] = frame
            self.position += 1

    def close(self):
        pass


@contextlib.contextmanager
def _ffmpeg_subprocess():
    """Quiet JAX's warning that a process forked: imageio starts ffmpeg as a subprocess (fork then
    exec at once), which cannot deadlock JAX's threads."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        yield


def _count_frames(path: str) -> int:
    """The video stream's number of packets, read without decoding them (ffmpeg's stream copy):
    a frame each for the codecs cameras and encoders write. imageio's ``count_frames`` decodes
    the whole video to count its frames, 3 times as long (105 against 32 ms for a 96-frame
    320x240 H.264 file); a video that decodes to fewer frames than it has packets stops where
    its frames end, with a message (``read_into``)."""
    import subprocess

    import imageio_ffmpeg

    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", "-i", path, "-map", "0:v:0", "-c", "copy", "-f", "null", "-"]
    done = subprocess.run(command, capture_output=True, check=False)
    said = done.stderr.decode(errors="replace")
    counts = re.findall(r"frame=\s*(\d+)", said)
    if done.returncode != 0 or not counts:
        raise RuntimeError(f"ffmpeg failed with {done.returncode}:\n{said}")
    return int(counts[-1])


class _QuietResize(logging.Filter):
    """imageio-ffmpeg warns that a scaled reader's frames differ from the source's size: they are
    meant to."""

    def filter(self, record):
        return "is different from the source frame size" not in record.getMessage()


logging.getLogger("imageio_ffmpeg").addFilter(_QuietResize())


class _VideoFile:
    """A video file decoded to RGB frames by one ffmpeg process (``imageio_ffmpeg.read_frames``,
    the reader under imageio's ffmpeg plugin, used directly: the plugin's reader starts ffmpeg
    once more to read what the counting run below already said)."""

    def __init__(self, path: str):
        self.path = path
        self.frames = None
        try:
            # counted first: a file ffmpeg cannot read fails here, before a reader is started
            self.num_frames = _count_frames(path)
            if self.num_frames < 1:
                raise VideoFileError(f"{path}: the video has no frames")
            width, height = self._start([])
        except ImportError as err:
            raise VideoFileError(f"{path}: reading video files needs imageio's ffmpeg plugin: pip install 'jaxtrack[video]' "
                                 f"({err})") from None
        except VideoFileError:
            raise
        except Exception as err:  # noqa: BLE001 - ffmpeg's failures on a bad file come as OSError, IndexError, RuntimeError...
            self.close()
            said = [line.strip() for line in str(err).splitlines() if line.strip()]
            said = " / ".join(said[:1] + said[-2:] if len(said) > 3 else said)  # not ffmpeg's banner and build options
            raise VideoFileError(f"{path}: not a readable video ({type(err).__name__}: {said})") from None
        self.size = self.out_size = (int(width), int(height))
        self.position = 0

    def _start(self, output_params) -> tuple[int, int]:
        """Start the ffmpeg reader; the (width, height) of the frames it writes."""
        import imageio_ffmpeg

        self.frames = imageio_ffmpeg.read_frames(self.path, pix_fmt="rgb24", output_params=output_params)
        meta = next(self.frames)
        self.fps = float(meta.get("fps") or 0.0) or None
        return meta["size"]

    def shape_output(self, wanted, reduce: int) -> bool:
        """Let ffmpeg crop or pad the frames to ``wanted`` (width, height) at the right and bottom
        edges (black, as ``fit_frames``'s zeros) and average them over ``reduce`` x ``reduce``
        blocks (its area scaler): True, the frames then come out at ``out_size``. Before any
        frame is read."""
        (w, h), (W, H) = self.size, (int(v) for v in wanted)
        filters = [f"pad={max(w, W)}:{max(h, H)}:0:0:black", f"crop={W}:{H}:0:0"] if (w, h) != (W, H) else []
        if reduce > 1:
            filters.append(f"scale={W // reduce}:{H // reduce}:flags=area")
        if not filters:
            return True
        self.close()
        try:  # in planar RGB: averaged as RGB pixels are (yuv420's halved chroma bled into the blank edge)
            found = tuple(int(v) for v in self._start(["-vf", ",".join(["format=gbrp", *filters])]))
        except Exception as err:  # noqa: BLE001 - as on opening
            self.close()
            raise VideoFileError(f"{self.path}: ffmpeg could not scale the video ({type(err).__name__}: {err})") from None
        self.out_size = (W // reduce, H // reduce)
        if found != self.out_size:
            self.close()
            raise VideoFileError(f"{self.path}: ffmpeg scaled the frames to {found[0]}x{found[1]}, not "
                                 f"{self.out_size[0]}x{self.out_size[1]}")
        return True

    def read_into(self, out: np.ndarray) -> None:
        width, height = self.out_size
        for i in range(len(out)):
            try:
                data = next(self.frames)
            except StopIteration:
                raise VideoFileError(f"{self.path}: ends at frame {self.position}, before the {self.num_frames} it declared") from None
            except Exception as err:  # noqa: BLE001 - a decoder's failure on a corrupt frame, whatever its type
                raise VideoFileError(f"{self.path}: frame {self.position} cannot be decoded ({type(err).__name__}: {err})") from None
            if len(data) != width * height * 3 or out.shape[1:] != (height, width, 3):
                raise VideoFileError(f"{self.path}: frame {self.position} holds {len(data)} bytes, not the {width}x{height} RGB "
                                     f"frame the video declares")
            out[i] = np.frombuffer(data, np.uint8).reshape(height, width, 3)
            self.position += 1

    def close(self):
        if self.frames is not None:
            self.frames.close()  # stops ffmpeg
            self.frames = None


def _raise_failure(outcomes: list) -> None:
    """Raise the first exception among ``outcomes``, taken out of the list: a frame that holds
    the exception it raises makes a reference cycle, and what the exception's traceback holds
    (a half-opened reader's files) waits for the garbage collector."""
    for i, outcome in enumerate(outcomes):
        if isinstance(outcome, BaseException):
            del outcome
            raise outcomes.pop(i)


class MultiViewVideo:
    """One source per camera (video files or image folders), read together by frame index.

    Use as a context manager; ``num_frames``, ``sizes`` ((width, height) per camera), ``fps``
    and ``names`` are known on opening, before any frame is decoded beyond the first.

    ``frame_sizes``: per camera, the (width, height) its frames must have (its calibration's). A
    file a few pixels off (``encoder_size_difference``) is read as an encoder's crop or pad and its frames cropped
    or padded at the right and bottom edges (``fit_frames``; ``adjusted`` holds a line per such
    camera); a larger difference raises ``VideoFileError`` (``encoder_size_difference``).
    ``source_sizes`` are the files' own. ``reduce``: the frames averaged over blocks of that many
    pixels a side after the fit (``reduce_frames``; it must divide every frame size); ``sizes``
    are the sizes the chunks come out at, ``frame_sizes`` the sizes before the reduction."""

    def __init__(self, paths, names=None, *, frame_sizes=None, reduce: int = 1):
        paths = [os.fspath(p) for p in paths]
        if isinstance(reduce, bool) or not isinstance(reduce, (int, np.integer)) or reduce < 1:
            raise ValueError(f"reduce must be a whole number of pixels, 1 or more, got {reduce!r}")
        self.reduce = int(reduce)
        if not paths:
            raise ValueError("a video needs at least one camera's source")
        self.paths = paths
        self.names = tuple(names) if names is not None else tuple(f"C{i + 1}" for i in range(len(paths)))
        if len(self.names) != len(paths):
            raise ValueError(f"{len(self.names)} camera names for {len(paths)} sources")
        for path in paths:
            if not os.path.exists(path):
                raise FileNotFoundError(f"no video or image folder at {path!r}")
        self.sources = []
        self._pool = ThreadPoolExecutor(len(paths), thread_name_prefix="jaxtrack-video")
        try:
            # opened side by side: each video's opening starts ffmpeg twice (its frame count is exact)
            opened = self._each(lambda path: _Folder(path) if os.path.isdir(path) else _VideoFile(path), paths)
            self.sources = [source for source in opened if not isinstance(source, BaseException)]
            _raise_failure(opened)
        except BaseException:
            self.close()
            raise
        counts = [s.num_frames for s in self.sources]
        if len(set(counts)) != 1:
            self.close()
            raise VideoFileError("the cameras' sources have different numbers of frames: "
                                 + ", ".join(f"{p} {n}" for p, n in zip(paths, counts)) + " (they are synchronised by frame index)")
        self.num_frames = counts[0]
        self.source_sizes = tuple(tuple(int(v) for v in s.size) for s in self.sources)
        self.adjusted = []  # one line per camera whose frames are cropped or padded to its frame size
        if frame_sizes is None:
            self.frame_sizes = self.source_sizes
        else:
            if len(frame_sizes) != len(paths):
                self.close()
                raise ValueError(f"{len(frame_sizes)} frame sizes for {len(paths)} sources")
            self.frame_sizes = tuple((int(w), int(h)) for w, h in frame_sizes)
            try:
                for path, name, found, wanted in zip(paths, self.names, self.source_sizes, self.frame_sizes):
                    line = encoder_size_difference(path, name, found, wanted)
                    if line:
                        self.adjusted.append(line)
            except VideoFileError:
                self.close()
                raise
        for path, (w, h) in zip(paths, self.frame_sizes):
            if w % self.reduce or h % self.reduce:
                self.close()
                raise ValueError(f"{path}: {w}x{h} frames cannot be reduced {self.reduce} times (it must divide both sides)")
        self.sizes = tuple((w // self.reduce, h // self.reduce) for w, h in self.frame_sizes)
        try:  # video files fitted and reduced by their ffmpeg; image folders here, after decoding
            self._shaped = self._each(lambda pair: pair[0].shape_output(pair[1], self.reduce),
                                      list(zip(self.sources, self.frame_sizes)))
            _raise_failure(self._shaped)
        except BaseException:
            self.close()
            raise
        rates = [s.fps for s in self.sources if s.fps]
        self.fps = rates[0] if rates else None  # frames per second the first video file says (None: image folders)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        self._each(lambda source: source.close(), self.sources)  # side by side: each ffmpeg takes 20 ms to stop
        self._pool.shutdown()

    def _each(self, work, items) -> list:
        """``work`` on each camera's item in its own thread (ffmpeg decodes in a process of its
        own, and reading its pipe frees the GIL), in camera order: its result or the exception it
        raised. JAX's warning that a process forked is quieted here, in the calling thread
        (warnings' filters are process-wide and not thread-safe to change)."""

        def outcome(item):
            try:
                return work(item)
            except BaseException as err:  # noqa: BLE001 - handed back to the calling thread, in camera order
                return err

        with _ffmpeg_subprocess():
            return list(self._pool.map(outcome, items))

    def chunks(self, size: int = 32, *, frames: int | None = None) -> Iterator[tuple[int, np.ndarray | list]]:
        """``(first_frame, frames)`` of up to ``size`` frames at a time, from the sources' current
        position to frame ``frames`` (default: the end): a (C, t, H, W, 3) uint8 array when the
        cameras share one size, else a list of (t, H_c, W_c, 3) arrays. The cameras are decoded
        side by side, each straight into the chunk's array."""
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"size must be a positive whole number of frames, got {size!r}")
        stop = self.num_frames if frames is None else min(int(frames), self.num_frames)
        shared = len(set(self.sizes)) == 1
        while self.sources[0].position < stop:
            first = self.sources[0].position
            count = min(size, stop - first)
            views = [np.empty((count, height, width, 3), np.uint8) for width, height in self.sizes]
            if shared:
                block = np.empty((len(self.sources), count) + views[0].shape[1:], np.uint8)
                views = list(block)
            # a video file comes out of its ffmpeg at the chunk's size; image folders (and a
            # camera whose pictures are a few pixels off) are decoded at their own size, then
            # cropped or padded and reduced into the chunk
            decoded = [view if shaped or source.size == size else np.empty((count, source.size[1], source.size[0], 3), np.uint8)
                       for view, source, shaped, size in zip(views, self.sources, self._shaped, self.sizes)]
            _raise_failure(self._each(lambda pair: pair[0].read_into(pair[1]), list(zip(self.sources, decoded))))
            for view, frames_, wanted in zip(views, decoded, self.frame_sizes):
                if frames_ is not view:
                    view[...] = reduce_frames(fit_frames(frames_, *wanted), self.reduce)
            yield first, (block if shared else views)

    def sample(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """``(indices (t,), frames (t, C, H, W, 3) uint8)``: ``count`` frames spread evenly over the
        sources (``sampled_frame_indices``), read in one pass from the start; the cameras must
        share one size."""
        if len(set(self.sizes)) != 1:
            raise VideoFileError("sampling frames needs cameras of one image size")
        indices = sampled_frame_indices(self.num_frames, count)
        wanted = set(indices.tolist())
        picked = []
        for first, frames in self.chunks(32):
            picked += [frames[:, i].copy() for i in range(frames.shape[1]) if first + i in wanted]  # not views of the chunk
        return indices, np.stack(picked)


ENCODER_SLACK_PX = 15  # encoders crop a side to a multiple of 8 or pad it to one of 16 pixels: 15 at most


def encoder_size_difference(path: str, name: str, found, wanted) -> str | None:
    """None when a video's frames are ``wanted`` (width, height); a warning line when each side
    is at most ``ENCODER_SLACK_PX`` off and, where it differs, a multiple of 8 (what an encoder's
    crop or pad leaves, which ``fit_frames`` undoes at the right and bottom edges); else
    ``VideoFileError`` saying what to check."""
    (w, h), (W, H) = (int(v) for v in found), (int(v) for v in wanted)
    if (w, h) == (W, H):
        return None
    if all(a == b or (abs(a - b) <= ENCODER_SLACK_PX and a % 8 == 0) for a, b in ((w, W), (h, H))):
        parts = [f"{abs(d)} px {'padded' if d > 0 else 'cropped'} at the {edge}, {'cut off' if d > 0 else 'read as blank'}"
                 for d, edge in ((w - W, "right"), (h - H, "bottom")) if d]
        return (f"{path}: camera {name!r}: frames of {w}x{h}, its calibration says {W}x{H}: read as the encoder's "
                f"({'; '.join(parts)})")
    raise VideoFileError(f"{path}: camera {name!r}: frames of {w}x{h}, but its calibration is for {W}x{H} images (not "
                         f"an encoder's crop or pad: a side a multiple of 8, at most {ENCODER_SLACK_PX} px off): check that "
                         "the videos are given in the calibration's camera order and that the calibration was made at this "
                         "resolution and orientation (a resized or rotated video needs its cameras scaled or rotated too)")


def fit_frames(frames: np.ndarray, width: int, height: int) -> np.ndarray:
    """(..., h, w, 3) frames cropped or zero-padded at the right and bottom edges to
    (..., height, width, 3): the pixel grid's origin (the top-left corner, where the intrinsics
    count from) is kept."""
    h, w = frames.shape[-3:-1]
    out = np.zeros(frames.shape[:-3] + (height, width, frames.shape[-1]), frames.dtype)
    out[..., : min(h, height), : min(w, width), :] = frames[..., : min(h, height), : min(w, width), :]
    return out


def reduce_frames(frames: np.ndarray, factor: int) -> np.ndarray:
    """(..., H, W, 3) uint8 frames -> (..., H / factor, W / factor, 3): each pixel the rounded
    mean of a ``factor`` x ``factor`` block (area averaging; ``factor`` must divide H and W)."""
    if factor == 1:
        return frames
    h, w = frames.shape[-3:-1]
    if h % factor or w % factor:
        raise ValueError(f"{w}x{h} frames cannot be reduced {factor} times (it must divide both sides)")
    blocks = frames.reshape(frames.shape[:-3] + (h // factor, factor, w // factor, factor, frames.shape[-1]))
    total = blocks.sum(axis=(-4, -2), dtype=np.uint32)
    return ((total + factor * factor // 2) // (factor * factor)).astype(np.uint8)


def sampled_frame_indices(num_frames: int, count: int) -> np.ndarray:
    """The frames ``sample_frames_evenly`` picks: ``count`` (at most ``num_frames``) spread evenly
    from the first frame to the last, ascending."""
    return np.unique(np.linspace(0, num_frames - 1, min(count, num_frames)).round().astype(int))


def sample_frames_evenly(paths, count: int = 30, *, names=None, frame_sizes=None, reduce: int = 1) -> np.ndarray:
    """(count, C, H, W, 3) uint8 frames spread evenly over the sources (for a background model
    learned from the video itself, ``image.fit_background``), read in one pass; ``names``,
    ``frame_sizes`` and ``reduce`` as ``MultiViewVideo``'s. The frames are
    ``sampled_frame_indices(num_frames, count)`` (``MultiViewVideo.sample`` says which)."""
    with MultiViewVideo(paths, names, frame_sizes=frame_sizes, reduce=reduce) as video:
        return video.sample(count)[1]


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

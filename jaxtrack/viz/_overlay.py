"""Pictures of sequences: a contact sheet (PNG) and an animation (GIF) of the silhouettes with
the projected skeleton overlaid (ground truth in green, an estimate in red)."""

from __future__ import annotations

import os

import numpy as np

from ..camera import project_points
from ..io import Sequence

_TRUTH = (40, 200, 60)
_ESTIMATE = (230, 40, 40)


def _projected(sequence: Sequence, joints) -> np.ndarray:
    """(T, C, J, 2) pixel coordinates of joints (NaN where behind a camera)."""
    import jax.numpy as jnp

    rig = sequence.rig()
    uv, _, front = project_points(rig, jnp.asarray(joints, rig.K.dtype))
    uv = np.asarray(uv, np.float64)  # (T, J, C, 2)
    uv[~np.asarray(front)] = np.nan
    return uv.transpose(0, 2, 1, 3)


def _checked_estimate(sequence: Sequence, estimate) -> np.ndarray:
    """The estimate as (T, J, 3) float64, refused unless it has the sequence's frames and joints."""
    estimate = np.asarray(estimate, np.float64)
    frames = sequence.num_frames
    joints = None if sequence.joints3d is None else sequence.joints3d.shape[1]
    if estimate.ndim != 3 or estimate.shape[2] != 3:
        raise ValueError(f"the estimate must be (frames, joints, 3) joint positions, got shape {estimate.shape}")
    if estimate.shape[0] != frames:
        raise ValueError(f"the estimate has {estimate.shape[0]} frames and the sequence {frames}: draw it over the sequence "
                         "it was tracked on (the same frames)")
    if joints is not None and estimate.shape[1] != joints:
        raise ValueError(f"the estimate has {estimate.shape[1]} joints and the sequence {joints}")
    if not np.all(np.isfinite(estimate)):
        raise ValueError("the estimate has non-finite joint positions")
    return estimate


def _background(sequence: Sequence) -> np.ndarray:
    """(C, T, H, W, 3) uint8 frames: images if present, else silhouettes in grey, else (2-D
    keypoints only) a dark canvas of the cameras' size."""
    if sequence.images is not None:
        return sequence.images
    if sequence.silhouettes is None:
        sizes = {tuple(int(v) for v in size) for size in (sequence.image_size if sequence.has_cameras else [])}
        if len(sizes) != 1:
            raise ValueError("the sequence has neither silhouettes nor images to draw on, nor cameras of one image size")
        (width, height), = sizes
        return np.full((len(sequence.image_size), sequence.num_frames, height, width, 3), 40, np.uint8)
    sil = sequence.binary_silhouettes()
    grey = (40 + 170 * sil).astype(np.uint8)
    return np.repeat(grey[..., None], 3, axis=-1)


def _parents(sequence: Sequence) -> np.ndarray:
    if sequence.parents is None:
        raise ValueError("drawing a skeleton needs the sequence's 'parents' key")
    return sequence.parents


def _pick_frames(num_frames: int, frames) -> list[int]:
    if frames is None:
        count = min(num_frames, 6)
        return sorted(set(np.linspace(0, num_frames - 1, count).round().astype(int).tolist()))
    frames = [int(f) for f in frames]
    for f in frames:
        if not 0 <= f < num_frames:
            raise ValueError(f"frame {f} is outside the sequence's {num_frames} frames")
    return frames


def contact_sheet(sequence: Sequence, path: str, *, frames=None, estimate=None, dpi: int = 110) -> str:
    """Write a PNG grid (rows: frames, columns: views) of silhouettes with projected skeletons.

    Args:
        sequence: needs cameras, ``parents``, and silhouettes or images; ``joints3d`` is drawn
            in green when present.
        path: output PNG path.
        frames: frame indices to show (default: up to 6 evenly spaced).
        estimate: optional (T, J, 3) estimated joints (metres), drawn in red.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    background = _background(sequence)
    parents = _parents(sequence)
    frames = _pick_frames(background.shape[1], frames)
    layers = []
    if sequence.joints3d is not None:
        layers.append((_projected(sequence, sequence.joints3d), _TRUTH, "truth"))
    if estimate is not None:
        layers.append((_projected(sequence, _checked_estimate(sequence, estimate)), _ESTIMATE, "estimate"))
    views = background.shape[0]
    height, width = background.shape[2:4]
    fig, axes = plt.subplots(
        len(frames), views, figsize=(2.2 * views * width / height, 2.2 * len(frames)), squeeze=False
    )
    names = sequence.camera_names if sequence.camera_names is not None else [f"cam{c}" for c in range(views)]
    for row, t in enumerate(frames):
        for c in range(views):
            ax = axes[row, c]
            ax.imshow(background[c, t], interpolation="nearest")
            for uv, colour, _ in layers:
                for j, p in enumerate(parents):
                    if p >= 0:
                        seg = uv[t, c, [p, j]]
                        ax.plot(seg[:, 0], seg[:, 1], "-", color=np.array(colour) / 255, lw=1.2)
            ax.set_xlim(-0.5, width - 0.5)
            ax.set_ylim(height - 0.5, -0.5)
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(str(names[c]), fontsize=9)
            if c == 0:
                ax.set_ylabel(f"frame {t}", fontsize=9)
    fig.tight_layout()
    _ensure_dir(path)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def animation(
    sequence: Sequence, path: str, *, estimate=None, scale: int = 3, every: int = 1, fps: float | None = None
) -> str:
    """Write a GIF: every view side by side per frame, skeletons drawn over the silhouettes.

    Args:
        scale: integer upscaling of the images (nearest neighbour) so the lines are visible.
        every: keep every ``every``-th frame.
        fps: playback rate (default: the sequence's, divided by ``every``).
    """
    import imageio.v3 as iio
    from PIL import Image, ImageDraw

    if scale < 1 or every < 1:
        raise ValueError("scale and every must be positive integers")
    background = _background(sequence)
    parents = _parents(sequence)
    layers = []
    if sequence.joints3d is not None:
        layers.append((_projected(sequence, sequence.joints3d), _TRUTH))
    if estimate is not None:
        layers.append((_projected(sequence, _checked_estimate(sequence, estimate)), _ESTIMATE))
    views, num_frames, height, width = background.shape[:4]
    out = []
    for t in range(0, num_frames, every):
        tiles = []
        for c in range(views):
            image = Image.fromarray(background[c, t]).resize((width * scale, height * scale), Image.NEAREST)
            draw = ImageDraw.Draw(image)
            for uv, colour in layers:
                for j, p in enumerate(parents):
                    if p >= 0:
                        a, b = uv[t, c, p] * scale + scale / 2, uv[t, c, j] * scale + scale / 2
                        if np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
                            draw.line([tuple(a), tuple(b)], fill=colour, width=max(1, scale // 2))
            tiles.append(np.asarray(image))
        out.append(np.concatenate(tiles, axis=1))
    _ensure_dir(path)
    rate = (fps or sequence.fps / every)
    iio.imwrite(path, np.stack(out), duration=1000.0 / rate, loop=0)
    return path


def _ensure_dir(path):
    directory = os.path.dirname(os.fspath(path))
    if directory:
        os.makedirs(directory, exist_ok=True)

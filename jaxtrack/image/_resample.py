"""Silhouettes at a lower resolution: each output pixel is the fraction of foreground in its
block of input pixels, thresholded at one half (area averaging), so a 320x240 or 640x480
background-subtraction mask can be tracked at 80x60 or 160x120. The cameras go with it through
``CameraRig.resized``."""

from __future__ import annotations

import numpy as np


def resolution_factors(size: tuple[int, int], target: tuple[int, int]) -> tuple[int, int]:
    """Integer (column, row) reduction factors from ``size`` = (width, height) to ``target``;
    raises ``ValueError`` when ``target`` does not divide ``size`` (or is larger)."""
    (width, height), (new_width, new_height) = size, target
    if new_width < 1 or new_height < 1 or width % new_width or height % new_height:
        raise ValueError(
            f"cannot resample {width}x{height} images to {new_width}x{new_height}: the target must divide the size "
            f"(e.g. {width // 2}x{height // 2} or {width // 4}x{height // 4})"
        )
    return width // new_width, height // new_height


def downsample_silhouettes(silhouettes, width: int, height: int) -> np.ndarray:
    """(..., H, W) masks (0/1 or 0/255) -> (..., height, width) uint8 0/1 masks by block
    averaging and a 0.5 threshold; ``width`` and ``height`` must divide W and H."""
    masks = np.asarray(silhouettes)
    fx, fy = resolution_factors((masks.shape[-1], masks.shape[-2]), (width, height))
    binary = (masks > (127 if masks.max(initial=0) > 1 else 0.5)).astype(np.float32)
    blocks = binary.reshape(masks.shape[:-2] + (height, fy, width, fx)).mean(axis=(-3, -1))
    return (blocks >= 0.5).astype(np.uint8)

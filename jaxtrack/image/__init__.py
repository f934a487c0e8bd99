"""Image operations on (views, [frames,] height, width) arrays: the start of the video path
(resampling silhouettes to the resolution a tracker runs at)."""

from ._resample import downsample_silhouettes as downsample_silhouettes
from ._resample import resolution_factors as resolution_factors

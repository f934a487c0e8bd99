"""Image operations in JAX on (..., H, W) arrays (any leading axes: views, frames), jittable and
differentiable where the maths is: the filters (Gaussian blur, Sobel), Canny edges and 001's
edge-proximity map, the exact Euclidean distance transform, binary morphology, resizing and
pyramids, colour conversions, a median by selection (XLA's CPU sort is slow), and silhouettes
resampled to the resolution a tracker runs at.

Written here rather than taken from dm-pix, which has a Gaussian blur and colour conversions but
no Sobel, edges, distance transform or morphology (docs/libraries.md)."""

from ._background import BackgroundModel as BackgroundModel
from ._background import Foreground as Foreground
from ._background import fit_background as fit_background
from ._background import lighting_gain as lighting_gain
from ._background import subtract_background as subtract_background
from ._colour import LUMA_WEIGHTS as LUMA_WEIGHTS
from ._colour import rgb_to_chromaticity as rgb_to_chromaticity
from ._colour import rgb_to_grey as rgb_to_grey
from ._colour import to_float as to_float
from ._distance import distance_transform as distance_transform
from ._distance import squared_distance_transform as squared_distance_transform
from ._edges import canny_edges as canny_edges
from ._edges import colour_canny_edges as colour_canny_edges
from ._edges import edge_proximity as edge_proximity
from ._edges import hysteresis as hysteresis
from ._edges import non_maximum_suppression as non_maximum_suppression
from ._filters import correlate1d as correlate1d
from ._filters import gaussian_blur as gaussian_blur
from ._filters import gaussian_kernel as gaussian_kernel
from ._filters import gradient_magnitude as gradient_magnitude
from ._filters import sobel as sobel
from ._median import median as median
from ._morphology import closing as closing
from ._morphology import dilate as dilate
from ._morphology import erode as erode
from ._morphology import opening as opening
from ._pyramid import pyramid as pyramid
from ._pyramid import resize as resize
from ._resample import downsample_silhouettes as downsample_silhouettes
from ._resample import resolution_factors as resolution_factors
from ._sample import sample_bilinear as sample_bilinear

"""jaxtrack: articulated human motion tracking in multi-camera video, in JAX.

Data flows one way: motion data (``io``, ``data``) -> pose manifold (``manifold``) -> dynamics
(``dynamics``) + likelihood (``likelihood``, on ``body``, ``camera``, ``render``) -> particle
filter (``filters``) -> estimates (``tracking``, the pipeline and the tracker registry) ->
evaluation (``evaluation``) -> experiment reports (``experiment``); ``viz`` draws any stage and
``demo`` runs the embedded synthetic default.
"""

from importlib.metadata import PackageNotFoundError, version

from . import body as body
from . import camera as camera
from . import data as data
from . import dynamics as dynamics
from . import errors as errors
from . import evaluation as evaluation
from . import experiment as experiment
from . import filters as filters
from . import image as image
from . import io as io
from . import likelihood as likelihood
from . import manifold as manifold
from . import render as render
from . import tracking as tracking
from . import viz as viz

try:
    __version__ = version("jaxtrack")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

"""jaxtrack: articulated human motion tracking in multi-camera video, in JAX.

Data flows one way: motion data (``io``, ``data``) -> body model (``body``) -> cameras and
rendering (``camera``, ``render``) -> likelihood (``likelihood``) -> evaluation
(``evaluation``); ``viz`` draws any stage.
"""

from importlib.metadata import PackageNotFoundError, version

from . import body as body
from . import camera as camera
from . import data as data
from . import evaluation as evaluation
from . import io as io
from . import likelihood as likelihood
from . import render as render
from . import viz as viz

try:
    __version__ = version("jaxtrack")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

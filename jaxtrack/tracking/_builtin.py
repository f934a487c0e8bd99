"""The built-in trackers, registered in this order when ``jaxtrack.tracking`` is imported (the
order of ``available_trackers()`` and of the tables; each tracker's keys follow its name,
``tracker_stream``). Adding a tracker: its recipe module in this package, and one line here."""

from . import _apf, _glegbpf, _gpapf, _latentpf, _mrpf, _sir, _velocity, _vlmmpf
from ._registry import register_tracker

BUILTIN_RECIPES = (
    _sir.RECIPE,
    _apf.RECIPE,
    _mrpf.RECIPE,
    _gpapf.RECIPE,
    _latentpf.RECIPE,
    _mrpf.PRINTED,
    _velocity.SIR_RECIPE,
    _velocity.APF_RECIPE,
    _glegbpf.RECIPE,
    _vlmmpf.RECIPE,
)
PAPER_TRACKERS = ("sir", "apf", "mrpf", "gpapf", "latentpf", "glegbpf")  # what an experiment runs by default (000-003)

for _recipe in BUILTIN_RECIPES:
    register_tracker(_recipe, replace=True)

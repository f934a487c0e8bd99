"""jaxtrack: articulated human motion tracking in multi-camera video, in JAX.

Data flows one way: motion data (``io``, ``data``) -> pose manifold (``manifold``) -> dynamics
(``dynamics``) + likelihood (``likelihood``, on ``body``, ``camera``, ``render``) -> particle
filter (``filters``) -> estimates (``tracking``, the pipeline and the tracker registry) ->
evaluation (``evaluation``) -> experiment reports (``experiment``); ``viz`` draws any stage and
``demo`` runs the embedded synthetic default.

The top level holds the names most programs need (``__all__``), grouped here by stage; each
subpackage keeps the rest.

- Motion data and files: ``load_sequence``, ``save_sequence``, ``Sequence``,
  ``generate_motion``, ``build_scene``.
- Body and cameras: ``BodyModel``, ``humaneva_body``, ``forward_kinematics``,
  ``inverse_kinematics``, ``CameraRig``, ``default_rig``.
- Manifolds: ``AbstractManifold``, ``ManifoldKind``, ``register_manifold_kind``,
  ``fit_manifold``, ``to_prior``, ``load_model``, ``save_model``.
- Dynamics: ``AbstractDynamics``, ``fit_pose_random_walk``.
- Likelihoods: ``AbstractLikelihood``, ``LikelihoodRecipe``, ``register_likelihood``,
  ``make_silhouette_likelihood``, ``check_silhouettes``.
- Filters: ``AbstractFilter``, ``SIR``, ``APF``, ``run_filter``.
- Trackers: ``TrackingSpec`` (how to track, validated once), ``TrackerRecipe``,
  ``register_tracker``, ``available_trackers``, ``prepare_test``, ``track``,
  ``track_sequence``.
- Experiments and scores: ``ExperimentConfig``, ``run_experiment``, ``mean_joint_error_mm``,
  ``run_demo``.
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
from .body import BodyModel as BodyModel
from .body import forward_kinematics as forward_kinematics
from .body import humaneva_body as humaneva_body
from .body import inverse_kinematics as inverse_kinematics
from .camera import CameraRig as CameraRig
from .camera import default_rig as default_rig
from .data import build_scene as build_scene
from .data import generate_motion as generate_motion
from .demo import run_demo as run_demo
from .dynamics import AbstractDynamics as AbstractDynamics
from .dynamics import fit_pose_random_walk as fit_pose_random_walk
from .evaluation import mean_joint_error_mm as mean_joint_error_mm
from .experiment import ExperimentConfig as ExperimentConfig
from .experiment import run_experiment as run_experiment
from .filters import APF as APF
from .filters import SIR as SIR
from .filters import AbstractFilter as AbstractFilter
from .filters import run_filter as run_filter
from .io import Sequence as Sequence
from .io import load_sequence as load_sequence
from .io import save_sequence as save_sequence
from .likelihood import AbstractLikelihood as AbstractLikelihood
from .likelihood import LikelihoodRecipe as LikelihoodRecipe
from .likelihood import check_silhouettes as check_silhouettes
from .likelihood import make_silhouette_likelihood as make_silhouette_likelihood
from .likelihood import register_likelihood as register_likelihood
from .manifold import AbstractManifold as AbstractManifold
from .manifold import ManifoldKind as ManifoldKind
from .manifold import load_model as load_model
from .manifold import register_manifold_kind as register_manifold_kind
from .manifold import save_model as save_model
from .manifold import to_prior as to_prior
from .tracking import TrackerRecipe as TrackerRecipe
from .tracking import TrackingSpec as TrackingSpec
from .tracking import available_trackers as available_trackers
from .tracking import fit_manifold as fit_manifold
from .tracking import prepare_test as prepare_test
from .tracking import register_tracker as register_tracker
from .tracking import track as track
from .tracking import track_sequence as track_sequence

__all__ = [
    "APF",
    "SIR",
    "AbstractDynamics",
    "AbstractFilter",
    "AbstractLikelihood",
    "AbstractManifold",
    "BodyModel",
    "CameraRig",
    "ExperimentConfig",
    "LikelihoodRecipe",
    "ManifoldKind",
    "Sequence",
    "TrackerRecipe",
    "TrackingSpec",
    "available_trackers",
    "build_scene",
    "check_silhouettes",
    "default_rig",
    "fit_manifold",
    "fit_pose_random_walk",
    "forward_kinematics",
    "generate_motion",
    "humaneva_body",
    "inverse_kinematics",
    "load_model",
    "load_sequence",
    "make_silhouette_likelihood",
    "mean_joint_error_mm",
    "prepare_test",
    "register_likelihood",
    "register_manifold_kind",
    "register_tracker",
    "run_demo",
    "run_experiment",
    "run_filter",
    "save_model",
    "save_sequence",
    "to_prior",
    "track",
    "track_sequence",
]

try:
    __version__ = version("jaxtrack")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

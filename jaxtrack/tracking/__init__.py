"""The tracking pipeline and the tracker registry: sequence -> poses -> manifold -> dynamics ->
likelihood -> tracker -> estimates, over the pure core (``filters``, ``dynamics``,
``likelihood``, ``manifold``). Trackers are registered recipes; ``available_trackers()`` lists
them and ``register_tracker`` adds your own. Each paper tracker is defined once, in its recipe
module: the filter it composes (``sir_filter``, ``apf_filter``, ``gpapf_filter``,
``latent_pf_filter``), the same filter from noise scales given directly (``make_sir``,
``make_apf``, ``make_mrpf``, ``make_gpapf``, ``make_latent_pf``) and its registered recipe."""

from ._apf import apf_filter as apf_filter
from ._apf import make_apf as make_apf
from ._builtin import BUILTIN_RECIPES as BUILTIN_RECIPES
from ._builtin import PAPER_TRACKERS as PAPER_TRACKERS
from ._gpapf import gpapf_filter as gpapf_filter
from ._gpapf import make_gpapf as make_gpapf
from ._latentpf import latent_pf_filter as latent_pf_filter
from ._latentpf import latent_random_walk as latent_random_walk
from ._latentpf import make_latent_pf as make_latent_pf
from ._limb_measurement import LimbMeasurement as LimbMeasurement
from ._limb_measurement import measure_limb_lengths as measure_limb_lengths
from ._mrpf import make_mrpf as make_mrpf
from ._off_manifold import OFF_MANIFOLD_START_MM as OFF_MANIFOLD_START_MM
from ._off_manifold import start_off_manifold_mm as start_off_manifold_mm
from ._pipeline import CALIBRATION_CLEARANCE as CALIBRATION_CLEARANCE
from ._pipeline import CALIBRATION_FRAMES as CALIBRATION_FRAMES
from ._pipeline import RADII_FRAMES as RADII_FRAMES
from ._pipeline import TRACKING_DTYPE as TRACKING_DTYPE
from ._pipeline import TestScene as TestScene
from ._pipeline import add_ground_prior as add_ground_prior
from ._pipeline import build_for_start as build_for_start
from ._pipeline import build_tracker as build_tracker
from ._pipeline import check_frame_rates as check_frame_rates
from ._pipeline import check_model_layout as check_model_layout
from ._pipeline import check_test_sequence as check_test_sequence
from ._pipeline import fit_manifold as fit_manifold
from ._pipeline import fit_tracker as fit_tracker
from ._pipeline import fit_velocity as fit_velocity
from ._pipeline import ground_truth_joints as ground_truth_joints
from ._pipeline import manifold_problem as manifold_problem
from ._pipeline import method_problems as method_problems
from ._pipeline import motion_clearance as motion_clearance
from ._pipeline import motion_data as motion_data
from ._pipeline import prepare_test as prepare_test
from ._pipeline import sequence_poses as sequence_poses
from ._pipeline import track as track
from ._pipeline import track_runs as track_runs
from ._pipeline import track_sequence as track_sequence
from ._pipeline import track_sequences as track_sequences
from ._pipeline import tracker_keys as tracker_keys
from ._pipeline import tracker_stream as tracker_stream
from ._refine_body import REFINE_FRAMES as REFINE_FRAMES
from ._refine_body import REFINE_PROPORTION_SD as REFINE_PROPORTION_SD
from ._refine_body import refine_body as refine_body
from ._refine_body import refine_frame_count as refine_frame_count
from ._refine_body import spread_frames as spread_frames
from ._refine_body import track_and_refine_body as track_and_refine_body
from ._registry import FADING_START as FADING_START
from ._registry import GRADIENT_COST as GRADIENT_COST
from ._registry import Budget as Budget
from ._registry import MotionData as MotionData
from ._registry import TrackerRecipe as TrackerRecipe
from ._registry import available_trackers as available_trackers
from ._registry import get_tracker as get_tracker
from ._registry import register_tracker as register_tracker
from ._registry import tracker_index as tracker_index
from ._registry import unregister_tracker as unregister_tracker
from ._sir import make_sir as make_sir
from ._sir import sir_filter as sir_filter
from ._spec import TrackingSpec as TrackingSpec
from ._start import START_CHOICES as START_CHOICES
from ._start import StartSearch as StartSearch
from ._start import automatic_start as automatic_start
from ._start import mask_centroids as mask_centroids
from ._start import root_guess as root_guess
from ._start import triangulate as triangulate
from ._subject import BODY_CHOICES as BODY_CHOICES
from ._subject import BODY_SOURCES as BODY_SOURCES
from ._subject import CALIBRATION_PRIORS as CALIBRATION_PRIORS
from ._subject import OWN_BODY_SOURCES as OWN_BODY_SOURCES
from ._subject import SubjectBody as SubjectBody
from ._subject import check_offsets_match_joints as check_offsets_match_joints
from ._subject import leg_length as leg_length
from ._subject import limb_lengths_of as limb_lengths_of
from ._subject import motion_subjects_prior as motion_subjects_prior
from ._subject import subject_body as subject_body
from ._video_input import VideoInput as VideoInput
from ._video_input import sequence_from_video as sequence_from_video

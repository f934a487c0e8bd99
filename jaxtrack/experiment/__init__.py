"""The HumanEva-style experiment (paper 000 sec. 6): registered trackers x test sequences x
runs, the joint error of 000 eq. 31, and the reports (results.json, 000 Table 1's table, the
error curves of 000 Fig. 6, overlay animations)."""

from ._config import ExperimentConfig as ExperimentConfig
from ._protocols import FOLD_MODES as FOLD_MODES
from ._protocols import OTHER_RADII as OTHER_RADII
from ._protocols import PROTOCOLS as PROTOCOLS
from ._protocols import RENDERERS as RENDERERS
from ._protocols import Fold as Fold
from ._protocols import ProtocolSubject as ProtocolSubject
from ._protocols import SubjectProtocol as SubjectProtocol
from ._protocols import Take as Take
from ._protocols import centre_subjects as centre_subjects
from ._protocols import convert_takes as convert_takes
from ._protocols import drift_ratio as drift_ratio
from ._protocols import fold_takes as fold_takes
from ._protocols import fold_test_scene as fold_test_scene
from ._protocols import get_protocol as get_protocol
from ._protocols import nearest_pose_floor_mm as nearest_pose_floor_mm
from ._protocols import plot_protocol as plot_protocol
from ._protocols import protocol_table as protocol_table
from ._protocols import render_test_take as render_test_take
from ._protocols import run_protocol as run_protocol
from ._protocols import shift_joint_angles as shift_joint_angles
from ._report import method_label as method_label
from ._report import plot_error_curves as plot_error_curves
from ._report import results_table as results_table
from ._report import write_outputs as write_outputs
from ._report import write_progress as write_progress
from ._run import ExperimentInputs as ExperimentInputs
from ._run import dynamics_parameters as dynamics_parameters
from ._run import fit_methods as fit_methods
from ._run import new_results as new_results
from ._run import prepare_inputs as prepare_inputs
from ._run import prepare_scenes as prepare_scenes
from ._run import run_experiment as run_experiment
from ._run import shared_window as shared_window
from ._run import start_manifold as start_manifold
from ._run import track_methods as track_methods
from ._run import validation_root_height as validation_root_height

"""The HumanEva-style experiment (paper 000 sec. 6): registered trackers x test sequences x
runs, the joint error of 000 eq. 31, and the reports (results.json, 000 Table 1's table, the
error curves of 000 Fig. 6, overlay animations)."""

from ._config import ExperimentConfig as ExperimentConfig
from ._report import method_label as method_label
from ._report import plot_error_curves as plot_error_curves
from ._report import results_table as results_table
from ._report import write_outputs as write_outputs
from ._report import write_progress as write_progress
from ._run import ExperimentInputs as ExperimentInputs
from ._run import dynamics_parameters as dynamics_parameters
from ._run import fit_methods as fit_methods
from ._run import prepare_inputs as prepare_inputs
from ._run import run_experiment as run_experiment
from ._run import shared_window as shared_window
from ._run import track_methods as track_methods

"""Calibrated pinhole cameras (OpenCV distortion), rigs of synchronised views and projection."""

from ._pinhole import NEAR_PLANE as NEAR_PLANE
from ._pinhole import CameraRig as CameraRig
from ._pinhole import check_in_front as check_in_front
from ._pinhole import check_in_view as check_in_view
from ._pinhole import decompose_projection_matrix as decompose_projection_matrix
from ._pinhole import default_rig as default_rig
from ._pinhole import distort as distort
from ._pinhole import focal_lengths as focal_lengths
from ._pinhole import image_shape as image_shape
from ._pinhole import look_at as look_at
from ._pinhole import make_rig as make_rig
from ._pinhole import pixel_grid as pixel_grid
from ._pinhole import project_points as project_points
from ._pinhole import rig_from_projection_matrices as rig_from_projection_matrices
from ._pinhole import world_to_camera as world_to_camera

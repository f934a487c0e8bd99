"""Evaluation against ground truth in millimetres (paper 000 eq. 31, Table 2, Fig. 6)."""

from ._joint_metrics import joint_errors_mm as joint_errors_mm
from ._joint_metrics import mean_joint_error_mm as mean_joint_error_mm
from ._joint_metrics import per_frame_error_mm as per_frame_error_mm
from ._joint_metrics import per_group_error_mm as per_group_error_mm

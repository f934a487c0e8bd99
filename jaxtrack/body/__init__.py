"""Body model: kinematic tree, pose vectors, joint limits, forward kinematics and capsule shape."""

from ._ik import IKResult as IKResult
from ._ik import fit_limb_lengths as fit_limb_lengths
from ._ik import inverse_kinematics as inverse_kinematics
from ._ik import solve_poses as solve_poses
from ._kinematics import forward_kinematics as forward_kinematics
from ._kinematics import global_rotation_matrices as global_rotation_matrices
from ._retarget import BANDAI_TO_HUMANEVA as BANDAI_TO_HUMANEVA
from ._retarget import CMU_TO_HUMANEVA as CMU_TO_HUMANEVA
from ._retarget import guess_mapping as guess_mapping
from ._retarget import retarget_positions as retarget_positions
from ._shape import BodyModel as BodyModel
from ._shape import humaneva_body as humaneva_body
from ._skeleton import DEFAULT_LIMB_LENGTHS as DEFAULT_LIMB_LENGTHS
from ._skeleton import GLOBAL_DOFS as GLOBAL_DOFS
from ._skeleton import HUMANEVA_JOINTS as HUMANEVA_JOINTS
from ._skeleton import HUMANEVA_PARENTS as HUMANEVA_PARENTS
from ._skeleton import HUMANEVA_PART_GROUPS as HUMANEVA_PART_GROUPS
from ._skeleton import Skeleton as Skeleton
from ._skeleton import check_joint_names as check_joint_names
from ._skeleton import check_poses as check_poses
from ._skeleton import humaneva_offsets as humaneva_offsets
from ._skeleton import humaneva_skeleton as humaneva_skeleton
from ._skeleton import joint_angles as joint_angles
from ._skeleton import mirrored_groups as mirrored_groups
from ._skeleton import part_group_indices as part_group_indices
from ._skeleton import with_offsets as with_offsets

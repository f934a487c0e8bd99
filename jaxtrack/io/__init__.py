"""File input and output: multi-view sequence files (``.npz``) and motion capture (ASF/AMC, BVH,
3-D joint arrays) in metres, world frame, Z up; 2-D keypoints as pose detectors write them
(OpenPose, COCO), mapped onto the 15 HumanEva joints."""

from ._asf_amc import AsfSkeleton as AsfSkeleton
from ._asf_amc import amc_channels as amc_channels
from ._asf_amc import load_asf_amc as load_asf_amc
from ._asf_amc import motion_from_amc_values as motion_from_amc_values
from ._asf_amc import read_amc as read_amc
from ._asf_amc import read_asf as read_asf
from ._bvh import load_bvh as load_bvh
from ._bvh import read_bvh as read_bvh
from ._calibration import CalibrationFileError as CalibrationFileError
from ._calibration import read_calibration as read_calibration
from ._calibration import rodrigues as rodrigues
from ._calibration import save_calibration as save_calibration
from ._joints import load_joints3d as load_joints3d
from ._joints import resample as resample
from ._keypoints import KEYPOINT_FORMATS as KEYPOINT_FORMATS
from ._keypoints import KEYPOINT_LAYOUTS as KEYPOINT_LAYOUTS
from ._keypoints import KeypointLayout as KeypointLayout
from ._keypoints import check_keypoints as check_keypoints
from ._keypoints import follow_person as follow_person
from ._keypoints import get_keypoint_layout as get_keypoint_layout
from ._keypoints import load_keypoints as load_keypoints
from ._keypoints import read_coco_keypoints as read_coco_keypoints
from ._keypoints import read_keypoint_sources as read_keypoint_sources
from ._keypoints import read_openpose_folder as read_openpose_folder
from ._keypoints import save_keypoints as save_keypoints
from ._mocap import MotionCapture as MotionCapture
from ._mocap import MotionFileError as MotionFileError
from ._output import OutputPathError as OutputPathError
from ._output import atomic_write as atomic_write
from ._output import check_folder as check_folder
from ._output import check_output as check_output
from ._output import output_file as output_file
from ._sequence import ARRAY_KEYS as ARRAY_KEYS
from ._sequence import CAMERA_KEYS as CAMERA_KEYS
from ._sequence import Sequence as Sequence
from ._sequence import SequenceFileError as SequenceFileError
from ._sequence import load_sequence as load_sequence
from ._sequence import save_sequence as save_sequence
from ._video import MultiViewVideo as MultiViewVideo
from ._video import VideoFileError as VideoFileError
from ._video import VideoWriter as VideoWriter
from ._video import sample_frames_evenly as sample_frames_evenly

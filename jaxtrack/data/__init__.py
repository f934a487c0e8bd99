"""Embedded synthetic data: procedural gait for synthetic subjects, and multi-view scenes."""

from ._detections import DetectorNoise as DetectorNoise
from ._detections import detect_keypoints as detect_keypoints
from ._gait import ANKLE_HEIGHT as ANKLE_HEIGHT
from ._gait import GAITS as GAITS
from ._gait import SUBJECTS as SUBJECTS
from ._gait import GaitParameters as GaitParameters
from ._gait import SubjectStyle as SubjectStyle
from ._gait import SyntheticMotion as SyntheticMotion
from ._gait import generate_motion as generate_motion
from ._gait import random_subject as random_subject
from ._gestures import SIGNALS as SIGNALS
from ._gestures import signalling_motion as signalling_motion
from ._rgb_scene import PART_COLOURS as PART_COLOURS
from ._rgb_scene import PhotoSettings as PhotoSettings
from ._rgb_scene import background_photo as background_photo
from ._rgb_scene import default_background_path as default_background_path
from ._rgb_scene import render_rgb as render_rgb
from ._rgb_scene import write_rgb_scene as write_rgb_scene
from ._scene import NO_NOISE as NO_NOISE
from ._scene import SilhouetteNoise as SilhouetteNoise
from ._scene import build_scene as build_scene
from ._scene import motion_sequence as motion_sequence
from ._scene import scene_from_sequence as scene_from_sequence
from ._solid_body import SolidBody as SolidBody
from ._solid_body import render_solid_silhouettes as render_solid_silhouettes

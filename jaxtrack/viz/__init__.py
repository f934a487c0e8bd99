"""Pictures: contact sheets, animations and overlay videos of sequences with projected skeletons."""

from ._overlay import animation as animation
from ._overlay import contact_sheet as contact_sheet
from ._video_overlay import draw_skeleton as draw_skeleton
from ._video_overlay import write_overlay_video as write_overlay_video

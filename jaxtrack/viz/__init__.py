"""Pictures: contact sheets and animations of sequences with projected skeletons."""

from ._overlay import animation as animation
from ._overlay import contact_sheet as contact_sheet

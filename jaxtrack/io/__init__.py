"""File input and output: multi-view sequence files (``.npz``)."""

from ._sequence import ARRAY_KEYS as ARRAY_KEYS
from ._sequence import Sequence as Sequence
from ._sequence import SequenceFileError as SequenceFileError
from ._sequence import load_sequence as load_sequence
from ._sequence import save_sequence as save_sequence

"""The errors jaxtrack raises for bad input, one family each, all caught by the command line.

Every family derives from ``JaxtrackError``, itself a ``ValueError`` (so code written against
the older ``ValueError`` contract keeps working). A message names the file (and the line or
key where it has one) and the reason, and is meant to be printed as it is: ``jaxtrack`` prints
one line per error and exits with status 2; ``jaxtrack --debug ...`` shows the traceback.

| family | raised for |
|---|---|
| ``SequenceFileError`` | a sequence file (``.npz``) or in-memory ``Sequence`` with a missing, misshapen or invalid key |
| ``MotionFileError`` | a malformed motion-capture file (ASF/AMC, BVH, joint arrays), with its line |
| ``ModelFileError`` | a model file of another format, version or class, truncated or edited |
| ``OutputPathError`` | an output that cannot or must not be written (found before any work) |
| ``ConfigurationError`` | options that do not fit together or do not fit the data (budgets, methods, frame rates, mappings) |
| ``TrackingError`` | a tracker or likelihood that breaks its contract at run time (a wrong output shape, say) |
"""

from __future__ import annotations


class JaxtrackError(ValueError):
    """Bad input that jaxtrack refuses; the message names the file or option and the reason."""


class SequenceFileError(JaxtrackError):
    """A sequence file or in-memory sequence with a missing, misshapen or invalid entry."""


class MotionFileError(JaxtrackError):
    """A malformed motion file; the message names the file and the line."""

    def __init__(self, path: str, line: int | None, message: str):
        where = f"{path}:{line}" if line is not None else str(path)
        super().__init__(f"{where}: {message}")
        self.path = path
        self.line = line

    def __reduce__(self):  # picklable, for worker processes and hypothesis' reports
        return (_motion_file_error, (self.path, self.line, str(self)))


def _motion_file_error(path, line, text):
    error = MotionFileError.__new__(MotionFileError)
    JaxtrackError.__init__(error, text)
    error.path, error.line = path, line
    return error


class ModelFileError(JaxtrackError):
    """A model file that cannot be loaded (wrong format, version or class, truncated, edited)."""


class OutputPathError(JaxtrackError):
    """An output location that cannot or must not be written, found before any work."""


class ConfigurationError(JaxtrackError):
    """Options that do not fit together, or do not fit the data they are applied to."""


class TrackingError(JaxtrackError):
    """A tracker, dynamics or likelihood that breaks its contract (shapes, dtypes) when traced."""

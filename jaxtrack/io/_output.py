"""Where a command writes, checked before any work, and written so a failure loses nothing.

``check_output`` is called by every command first: it resolves the file that will be written
(``np.savez`` appends ``.npz`` to a name without it), and refuses a missing or read-only
folder, a folder in the file's place, and a file that is one of the command's own inputs
(``jaxtrack track T.npz --out T.npz`` would otherwise replace the ground truth with
estimates under the same keys). ``atomic_write`` writes through a temporary file in the same
folder and renames it over the target, so an interrupted write leaves the old file whole.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterable, Iterator

from ..errors import OutputPathError


def output_file(path: str | os.PathLike, suffix: str | None = None) -> str:
    """The file a writer will create for ``path``: ``suffix`` appended unless already there."""
    path = os.fspath(path)
    if suffix and not path.endswith(suffix):
        path += suffix
    return path


def _same_file(a: str, b: str) -> bool:
    if os.path.exists(a) and os.path.exists(b):
        return os.path.samefile(a, b)
    return os.path.realpath(a) == os.path.realpath(b)


def check_output(path: str | os.PathLike, inputs: Iterable[str | os.PathLike | None] = (), *, suffix: str | None = None,
                 create_folder: bool = True) -> str:
    """Check an output file before the work that produces it; returns the file that will be
    written (``output_file``).

    Raises:
        OutputPathError: if the path is a folder, is one of ``inputs`` (the same file under any
            name), or its folder is missing (with ``create_folder=False``), cannot be created,
            or is not writable.
    """
    target = output_file(path, suffix)
    if os.path.isdir(target):
        raise OutputPathError(f"{target}: is a folder; give a file name for the output")
    for source in inputs:
        if source is not None and _same_file(target, os.fspath(source)):
            raise OutputPathError(f"{target}: is also an input of this command; refusing to write over it (choose another --out)")
    check_folder(os.path.dirname(target) or ".", create=create_folder)
    return target


def check_folder(folder: str | os.PathLike, *, create: bool = True) -> str:
    """Check (and with ``create`` make) an output folder; raises ``OutputPathError`` if it is
    a file, cannot be made or is not writable."""
    folder = os.fspath(folder)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise OutputPathError(f"{folder}: exists and is not a folder")
    if not os.path.exists(folder):
        if not create:
            raise OutputPathError(f"{folder}: no such folder")
        try:
            os.makedirs(folder, exist_ok=True)
        except OSError as err:
            raise OutputPathError(f"{folder}: cannot create the output folder ({err.strerror or err})") from err
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{folder}: the output folder is not writable")
    try:  # what access() says is not always what the file system does (/proc, read-only mounts)
        probe = tempfile.NamedTemporaryFile(dir=folder, prefix=".jaxtrack-write-test.", delete=True)
        probe.close()
    except OSError as err:
        raise OutputPathError(f"{folder}: cannot write files in the output folder ({err.strerror or err})") from err
    return folder


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike) -> Iterator:
    """``with atomic_write(path) as handle:`` a binary handle on a temporary file in ``path``'s
    folder, renamed over ``path`` when the block ends without an error and removed otherwise."""
    path = os.fspath(path)
    folder = os.path.dirname(path) or "."
    handle = tempfile.NamedTemporaryFile(dir=folder, prefix="." + os.path.basename(path) + ".", suffix=".part", delete=False)
    try:
        with handle:
            yield handle
        os.chmod(handle.name, 0o666 & ~_umask())  # as open() would make it (the temporary file is 0600)
        os.replace(handle.name, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(handle.name)
        raise

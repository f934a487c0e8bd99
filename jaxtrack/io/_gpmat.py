"""CMU subject 35's trials as GPmat stores them (``cmu35WalkJog.mat``: AMC channel values of 33
trials at 30 Hz, one-hot trial labels), read as one ``MotionCapture`` per trial."""

from __future__ import annotations

import os

import numpy as np

from ._asf_amc import amc_channels, motion_from_amc_values, read_asf
from ._mocap import MotionCapture

GPMAT_TRAIN_TRIALS = (*range(1, 18), *range(19, 27), 28, *range(30, 35))
"""Trial numbers of the columns of the file's ``lbls`` (its ``Y`` rows), in order."""
GPMAT_TEST_TRIALS = (18, 29)
"""Trial numbers of the columns of ``lblstest`` (its ``Ytest`` rows): a jog and a walk."""
GPMAT_FPS = 30.0


def read_gpmat_trials(mat_path: str | os.PathLike, asf_path: str | os.PathLike, trials=None) -> dict[str, MotionCapture]:
    """The trials of GPmat's ``cmu35WalkJog.mat`` as motion capture.

    Args:
        mat_path: the ``.mat`` file (``Y``, ``lbls``, ``Ytest``, ``lblstest``; MATLAB v5).
        asf_path: subject 35's skeleton (``35.asf``): the columns are its AMC channels.
        trials: trial names to read (``"35_02"``, ...); None: all 33.

    Returns:
        ``{"35_NN": MotionCapture}`` at 30 Hz (every 4th frame of the 120 Hz capture).

    Raises:
        ValueError: a trial the file does not hold, or columns that are not the skeleton's
            channels.
    """
    from scipy.io import loadmat

    skeleton = read_asf(asf_path)
    data = loadmat(os.fspath(mat_path))
    width = len(amc_channels(skeleton))
    names = {f"35_{t:02d}": ("Y", "lbls", i) for i, t in enumerate(GPMAT_TRAIN_TRIALS)}
    names |= {f"35_{t:02d}": ("Ytest", "lblstest", i) for i, t in enumerate(GPMAT_TEST_TRIALS)}
    wanted = list(names) if trials is None else list(trials)
    unknown = [t for t in wanted if t not in names]
    if unknown:
        raise ValueError(f"{mat_path}: holds no trial {', '.join(unknown)}; it holds {', '.join(sorted(names))}")
    motions = {}
    for trial in wanted:
        values_key, labels_key, column = names[trial]
        values, labels = np.asarray(data[values_key]), np.asarray(data[labels_key])
        if values.shape[1] != width or labels.shape[1] <= column:
            raise ValueError(f"{mat_path}: {values_key} is {values.shape} with {labels.shape[1]} trials; "
                             f"{os.fspath(asf_path)} has {width} AMC channels")
        rows = values[labels[:, column] == 1]
        motions[trial] = motion_from_amc_values(skeleton, rows, GPMAT_FPS, source=f"{os.fspath(mat_path)} trial {trial}")
    return motions

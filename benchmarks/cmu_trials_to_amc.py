"""Write the CMU subject 35 trials stored in GPmat's ``cmu35WalkJog.mat`` (30 Hz, AMC channel
values in ASF order; ../shared/data/README.md) back out as one AMC file per trial, so that
``jaxtrack convert`` reads them like any CMU download.

    python benchmarks/cmu_trials_to_amc.py OUT_DIR [--data ../shared/data/cmu35]

(``jaxtrack.io.read_gpmat_trials`` reads the same trials in memory; ``jaxtrack protocol`` uses it.)
Writes ``35_NN.amc`` (and a copy of ``35.asf``) for the 31 training trials and the two test
trials (35_18 jog, 35_29 walk); convert them with ``--source-fps 30``.
"""

from __future__ import annotations

import argparse
import os
import shutil

import numpy as np


def write_amc(path: str, skeleton, values: np.ndarray) -> None:
    """One AMC file (``:FULLY-SPECIFIED``, degrees) from (T, channels) values in ``amc_channels`` order."""
    from jaxtrack.io import amc_channels

    channels = amc_channels(skeleton)
    bones = {}
    for i, channel in enumerate(channels):
        bones.setdefault(channel.split(".", 1)[0], []).append(i)
    with open(path, "w", encoding="ascii") as handle:
        handle.write(":FULLY-SPECIFIED\n:DEGREES\n")
        for t, row in enumerate(values, start=1):
            handle.write(f"{t}\n")
            for bone, columns in bones.items():
                handle.write(bone + " " + " ".join(f"{row[c]:.6g}" for c in columns) + "\n")


def main(argv=None) -> int:
    from scipy.io import loadmat

    from jaxtrack.io import GPMAT_TEST_TRIALS, GPMAT_TRAIN_TRIALS, read_asf

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out")
    parser.add_argument("--data", default=os.path.join("..", "shared", "data", "cmu35"))
    args = parser.parse_args(argv)
    asf_path = os.path.join(args.data, "35.asf")
    skeleton = read_asf(asf_path)
    data = loadmat(os.path.join(args.data, "cmu35WalkJog.mat"))
    os.makedirs(args.out, exist_ok=True)
    shutil.copy(asf_path, os.path.join(args.out, "35.asf"))
    for values, labels, trials in ((data["Y"], data["lbls"], GPMAT_TRAIN_TRIALS), (data["Ytest"], data["lblstest"], GPMAT_TEST_TRIALS)):
        if labels.shape[1] != len(trials):
            raise ValueError(f"expected {len(trials)} sequences in the .mat, found {labels.shape[1]}")
        for column, trial in enumerate(trials):
            rows = values[labels[:, column] == 1]
            path = os.path.join(args.out, f"35_{trial:02d}.amc")
            write_amc(path, skeleton, rows)
            print(f"wrote {path}: {len(rows)} frames at 30 Hz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

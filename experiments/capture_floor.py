"""The floor under the protocols' takes, as captured and levelled (docs/floor.md, "A tilted
capture"), and what the tilt did to the trackers.

Left: each walk's stance ankle (the lower ankle of each frame) against the distance walked, as
the capture gives it (solid) and levelled by ``io.fit_floor`` / ``io.level_joints`` (dotted):
CMU 07's four walks climb 6-9 cm, CMU 16's and 35's stay flat. Right, with two ``protocol.json``
files of the walks (one run with ``--no-level-floor``, one levelled): the per-frame error of the
chosen trackers within CMU 07, whose pelvis sank below the climbing truth before.

    taskset -c 0,1 jaxtrack protocol walk-loso --data ../shared/data --runs 5 --no-level-floor --out walk5
    taskset -c 0,1 jaxtrack protocol walk-loso --data ../shared/data --runs 5 --out walk5_lev
    python experiments/capture_floor.py --data ../shared/data --work /tmp/capture_floor \\
        --curves walk5/protocol.json walk5_lev/protocol.json --out docs/figures/floor_tilt.png
"""

from __future__ import annotations

import argparse
import json
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from jaxtrack.body import HUMANEVA_JOINTS
from jaxtrack.experiment import convert_takes, get_protocol, method_label
from jaxtrack.io import fit_floor

ANKLES = [HUMANEVA_JOINTS.index("lankle"), HUMANEVA_JOINTS.index("rankle")]


def stance_profile(joints):
    """Distance walked (m) and the lower ankle's height (m) per frame."""
    joints = np.asarray(joints, np.float64)
    pelvis = joints[:, 0, :2]
    walked = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pelvis, axis=0), axis=1))])
    return walked, joints[:, ANKLES, 2].min(axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="../shared/data", help="the shared motion-capture folder")
    parser.add_argument("--work", required=True, help="where the takes are converted (raw/ and levelled/)")
    parser.add_argument("--curves", nargs=2, metavar=("AS_CAPTURED", "LEVELLED"),
                        help="protocol.json of the walks as captured and levelled (the right-hand panel)")
    parser.add_argument("--methods", nargs="+", default=["mrpf", "glegbpf"])
    parser.add_argument("--out", required=True, help="the PNG to write")
    args = parser.parse_args()

    takes = get_protocol("walk-loso").takes()
    raw = convert_takes(takes, args.data, os.path.join(args.work, "raw"))
    level = convert_takes(takes, args.data, os.path.join(args.work, "levelled"), level_floor=True)
    panels = 2 if args.curves else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.0 * panels, 4.0), squeeze=False)
    ax = axes[0, 0]
    colours = {"cmu07": "C3", "cmu16": "C0", "cmu35": "C2"}
    for take in takes:
        for sequences, style in ((raw, "-"), (level, ":")):
            walked, ankle = stance_profile(sequences[take.name].joints3d)
            label = None
            if style == "-":
                floor = fit_floor(sequences[take.name].joints3d)
                label = f"{take.name} ({floor.tilt_degrees:.2f} deg)"
                print(f"{take.subject} {take.name}: {floor.describe()}")
            ax.plot(walked, 1000 * ankle, style, color=colours.get(take.subject, "C7"), lw=1.0, label=label)
    ax.set(xlabel="distance walked (m)", ylabel="lower ankle's height (mm)",
           title="the stance ankle as captured (solid) and levelled (dotted)")
    ax.legend(fontsize=6, ncol=2)
    if args.curves:
        draw_own_takes(axes[0, 1], args.curves, args.methods)
    fig.savefig(args.out, dpi=120, bbox_inches="tight")
    print(f"wrote {args.out}")


def draw_own_takes(ax, paths, methods) -> None:
    """Per-frame error within CMU 07 of each method, from the walks as captured and levelled."""
    for k, (path, label) in enumerate(zip(paths, ("as captured", "levelled"))):
        with open(path, encoding="utf-8") as handle:
            rows = json.load(handle)["rows"]
        row = next(r for r in rows if r["subject"] == "cmu07" and r["mode"] == "within")
        for j, method in enumerate(methods):
            entry = row["methods"][method]
            ax.plot(entry["per_frame_error_mm"], ["-", "--"][j % 2], color=f"C{k}", lw=1.2,
                    label=f"{method_label(method)}, {label}: {entry['error_mm_mean']:.1f} mm "
                          f"(d{entry['last_over_first_quarter']:.2f})")
    ax.set(xlabel="frame (60 Hz)", ylabel="mean joint error (mm)", title="CMU 07 tracked on its own takes")
    ax.legend(fontsize=7)


if __name__ == "__main__":
    main()

"""Per-run error curves from ``real_motion.py --json`` (or ``tracker_variants.py``, or
``gle_cross_subject.py``, whose test takes are named by ``--sequence`` too): one panel per
(setting, tracker), one line per run, so a run that drifts is seen apart from the mean.

    python benchmarks/plot_runs.py real_motion.json --sequence cmu-jog --views 4 --out runs.png
    python benchmarks/plot_runs.py cross.json --sequence cmu-35_29 bandai-run_normal_005 --out cross.png
"""

from __future__ import annotations

import argparse
import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def row_name(row: dict) -> str:
    """The test take of a row: ``sequence`` (real_motion.py) or ``test`` (gle_cross_subject.py)."""
    return row.get("sequence") or row["test"]


def setting_label(row: dict) -> str:
    parts = [f"{row['protocol']}:\n{row['test']}\n"] if "protocol" in row else []
    parts.append(f"{row['views']} views")
    if row.get("latent_dim", 2) not in (2, None):  # None: each manifold kind's own
        parts.append(f"latent dim {row['latent_dim']}")
    if row.get("velocity") not in (None, "own"):
        parts.append(f"velocity {'on' if row['velocity'] in (True, 'on') else 'off'}")
    residuals = {r.get("residual") for r in row["methods"].values()} - {None, 0.0}
    if residuals:
        parts.append(f"residual {', '.join(f'{r:g}' for r in sorted(residuals))}")
    return ", ".join(parts).replace("\n, ", "\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("json", nargs="+", help="JSON files written by real_motion.py --json")
    parser.add_argument("--sequence", nargs="+", required=True, help="test takes (rows in this order)")
    parser.add_argument("--views", type=int, nargs="+", help="only these view counts (default: all)")
    parser.add_argument("--methods", nargs="+", help="only these trackers (default: all)")
    parser.add_argument("--out", required=True, help="output PNG")
    args = parser.parse_args()
    rows = [row for path in args.json for row in json.load(open(path)) if row_name(row) in args.sequence
            and (args.views is None or row["views"] in args.views)]
    rows.sort(key=lambda row: args.sequence.index(row_name(row)))
    if not rows:
        parser.error(f"no rows for {args.sequence}")
    methods = args.methods or list(dict.fromkeys(m for row in rows for m in row["methods"]))
    fig, axes = plt.subplots(len(rows), len(methods), figsize=(3.2 * len(methods), 2.4 * len(rows)), sharey=True,
                             squeeze=False)
    top = max(max(max(c) for c in row["methods"][m]["per_frame_error_mm_per_run"]) for row in rows for m in methods
              if m in row["methods"])
    for i, row in enumerate(rows):
        for j, method in enumerate(methods):
            ax = axes[i, j]
            result = row["methods"].get(method)
            if result is None:
                ax.axis("off")
                continue
            for curve in result["per_frame_error_mm_per_run"]:
                ax.plot(np.arange(len(curve)), curve, lw=0.9)
            quarter = max(1, len(curve) // 4)
            ax.axvspan(len(curve) - quarter, len(curve), color="0.92", zorder=0)
            ax.set_title(f"{method}: {result['error_mm_mean']:.0f} mm, drift {result['last_over_first_quarter']:.2f}", fontsize=8)
            ax.set_ylim(0, min(top, 200) * 1.05)
            if j == 0:
                ax.set_ylabel(f"{setting_label(row)}\nerror (mm)", fontsize=7)
            if i == len(rows) - 1:
                ax.set_xlabel("frame", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.suptitle(f"{', '.join(args.sequence)}: each run's error (last quarter shaded)", fontsize=9)
    fig.tight_layout()
    fig.savefig(args.out, dpi=90)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

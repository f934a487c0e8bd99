"""Per-frame error curves of two runs of one protocol side by side: where the error starts, and
whether it grows (issue #46's drift: the last quarter's error over the first quarter's).

Reads the ``protocol.json`` that ``jaxtrack protocol`` writes, e.g. the walks started from the
truth and started automatically (``--start auto``), and draws, per left-out subject, each chosen
tracker's mean curve over the runs across people (solid) and within the subject (dotted), one
colour per file. The quarters' boundaries are marked.

    taskset -c 0,1 jaxtrack protocol walk-loso --data ../shared/data --runs 5 --out walk5_az45
    taskset -c 0,1 jaxtrack protocol walk-loso --data ../shared/data --runs 5 --start auto --out walk5_auto
    python experiments/start_curves.py walk5_az45/protocol.json walk5_auto/protocol.json --labels "from the truth" \
        "started automatically" --methods glegbpf --out docs/figures/subjects_walk5_start.png
"""

from __future__ import annotations

import argparse
import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from jaxtrack.experiment import method_label


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="protocol.json files of the same protocol")
    parser.add_argument("--labels", nargs="+", help="one label per file (default: the file names)")
    parser.add_argument("--methods", nargs="+", default=["glegbpf"], help="trackers to draw (default: glegbpf)")
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--out", required=True, help="the PNG to write")
    args = parser.parse_args()
    labels = args.labels or args.files
    if len(labels) != len(args.files):
        raise SystemExit("give one label per file")
    documents = []
    for path in args.files:
        with open(path, encoding="utf-8") as handle:
            documents.append(json.load(handle))
    subjects = list(dict.fromkeys(r["subject"] for d in documents for r in d["rows"]))
    fig, axes = plt.subplots(len(args.methods), len(subjects), figsize=(3.6 * len(subjects), 2.8 * len(args.methods)),
                             squeeze=False, sharey="row")
    for i, method in enumerate(args.methods):
        for j, subject in enumerate(subjects):
            ax = axes[i, j]
            for k, (document, label) in enumerate(zip(documents, labels)):
                for mode, style in (("cross", "-"), ("within", ":")):
                    row = next((r for r in document["rows"] if r["subject"] == subject and r["mode"] == mode
                                and r["budget"] == args.budget), None)
                    if row is None or method not in row["methods"]:
                        continue
                    curve = np.asarray(row["methods"][method]["per_frame_error_mm"])
                    drift = row["methods"][method]["last_over_first_quarter"]
                    ax.plot(curve, style, color=f"C{k}", lw=1.2,
                            label=f"{label}, {'others' if mode == 'cross' else 'own takes'} (d{drift:.2f})")
            frames = max(len(line.get_xdata()) for line in ax.get_lines()) if ax.get_lines() else 0
            for q in (frames // 4, frames - frames // 4):
                ax.axvline(q, color="0.7", lw=0.8)
            ax.set_title(f"{subject}, {method_label(method)}", fontsize=9)
            ax.set_xlabel("frame (60 Hz)")
            ax.legend(fontsize=6)
        axes[i, 0].set_ylabel("mean joint error (mm)")
    fig.suptitle(f"budget {args.budget}: solid = trained on other people, dotted = on the subject's own takes; grey lines = the "
                 "first and last quarters (d = last / first)", fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

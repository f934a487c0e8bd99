"""How much a protocol's table owes to where the cameras stand (docs/subjects.md, "The rig's azimuth").

Reads the ``protocol.json`` of several ``jaxtrack protocol`` runs that differ only in their rig
(``--views``, ``--azimuth``), each given as ``LABEL=PATH``, prints each tracker's error per
left-out subject and rig with the spread between the rigs, and draws one panel per tracker:

    taskset -c 0,1 jaxtrack protocol jog-loso --data ../shared/data --runs 3 --views 4 --azimuth 0 --modes cross --out jog4_az0
    taskset -c 0,1 jaxtrack protocol jog-loso --data ../shared/data --runs 3 --views 3 --azimuth 105 --modes cross --out jog3_az105
    python experiments/rig_azimuth.py "4 views at 45=jog4/protocol.json" "4 views at 0=jog4_az0/protocol.json" \\
        "3 views at 105=jog3_az105/protocol.json" --out docs/figures/subjects_jog_azimuth.png

A file may hold only some subjects (a protocol run with ``--subjects``); several files with the
same label are read as one run.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from jaxtrack.experiment import method_label


def read_rows(specs: list[str], mode: str) -> dict[str, dict[str, dict[str, float]]]:
    """``{label: {subject: {method: mean error mm}}}`` of the ``mode`` folds."""
    table: dict[str, dict[str, dict[str, float]]] = {}
    for spec in specs:
        label, _, path = spec.rpartition("=")
        if not label:
            raise SystemExit(f"{spec!r}: expected LABEL=PATH")
        with open(path, encoding="utf-8") as handle:
            rows = json.load(handle)["rows"]
        for row in rows:
            if row["mode"] == mode:
                table.setdefault(label, {})[row["subject"]] = {m: r["error_mm_mean"] for m, r in row["methods"].items()}
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="LABEL=PATH")
    parser.add_argument("--mode", default="cross", choices=("cross", "within"))
    parser.add_argument("--out", help="the figure (PNG)")
    args = parser.parse_args()
    table = read_rows(args.runs, args.mode)
    labels = list(table)
    subjects = sorted({s for rows in table.values() for s in rows})
    methods = list(dict.fromkeys(m for rows in table.values() for r in rows.values() for m in r))
    print("| tracker | subject | " + " | ".join(labels) + " | largest - smallest |")
    print("|---|---|" + "---:|" * (len(labels) + 1))
    for m in methods:
        for s in subjects:
            cells = [table[label].get(s, {}).get(m) for label in labels]
            known = [c for c in cells if c is not None]
            spread = f"{max(known) - min(known):.1f}" if len(known) > 1 else "-"
            print(f"| {method_label(m)} | {s} | " + " | ".join("-" if c is None else f"{c:.1f}" for c in cells) + f" | {spread} |")
    if not args.out:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    columns = min(3, len(methods))
    rows = -(-len(methods) // columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.2 * rows), sharey=True, squeeze=False)
    width = 0.8 / len(labels)
    x = np.arange(len(subjects))
    for axis, m in zip(axes.flat, methods):
        for i, label in enumerate(labels):
            values = [table[label].get(s, {}).get(m, np.nan) for s in subjects]
            axis.bar(x + (i - (len(labels) - 1) / 2) * width, np.minimum(values, 200.0), width, label=label)
        axis.set_title(method_label(m))
        axis.set_xticks(x, [s.replace("hdm05-", "") for s in subjects])
        axis.grid(axis="y", alpha=0.3)
    for axis in axes[:, 0]:
        axis.set_ylabel("mean joint error, mm (clipped at 200)")
    for axis in list(axes.flat)[len(methods):]:
        axis.set_visible(False)
    axes.flat[0].legend(fontsize=8)
    figure.suptitle(f"the same trackers and takes, {args.mode} folds, the cameras placed differently")
    figure.tight_layout()
    figure.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

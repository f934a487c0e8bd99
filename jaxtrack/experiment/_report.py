"""What an experiment writes: results.json, the table of 000 Table 1, the error curves of
000 Fig. 6, and overlay animations."""

from __future__ import annotations

import json
import os

from ..io import atomic_write
from ..tracking import get_tracker


def method_label(name: str) -> str:
    """A tracker's column label (its registered label; the name if no longer registered)."""
    try:
        return get_tracker(name).label
    except ValueError:
        return name


def results_table(results: dict) -> str:
    """Markdown table in the layout of 000 Table 1: one row per test sequence, one column per
    method, ``mean (std)`` of the eq. 31 error in mm over the runs."""
    methods = list(results["config"]["methods"])
    refused = results.get("refused", {})
    lines = ["| Sequence | " + " | ".join(method_label(m) for m in methods) + " |", "|---|" + "---:|" * len(methods)]
    for name, per_method in results["sequences"].items():
        cells = [f"{per_method[m]['error_mm_mean']:.0f} ({per_method[m]['error_mm_std']:.0f})" if m in per_method
                 else "refused" if m in refused else "not run" for m in methods]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += [""] + [f"- {method_label(m)} refused: {why}" for m, why in refused.items()] if refused else []
    return "\n".join(lines) + "\n"


def plot_error_curves(results: dict, path: str) -> str:
    """Per-frame error of each method (mean over runs), one panel per test sequence (000 Fig. 6)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sequences = list(results["sequences"])
    fig, axes = plt.subplots(len(sequences), 1, figsize=(7, 2.8 * len(sequences)), squeeze=False)
    for ax, name in zip(axes[:, 0], sequences):
        for method, values in results["sequences"][name].items():
            ax.plot(values["per_frame_error_mm"], label=method_label(method), lw=1.2)
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("frame")
        ax.set_ylabel("error (mm)")
        if results["sequences"][name]:  # every method may have been refused
            ax.legend(fontsize=7, ncol=len(results["sequences"][name]))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_progress(results: dict, out_dir: str) -> dict:
    """``results.json`` and ``table.md`` of the results so far, each written atomically (the
    experiment calls this after every tracker on every test sequence, so an interruption loses
    the tracker in progress at most; ``results["complete"]`` says whether the run finished)."""
    os.makedirs(out_dir, exist_ok=True)
    paths = {"results": os.path.join(out_dir, "results.json"), "table": os.path.join(out_dir, "table.md")}
    serialisable = {k: v for k, v in results.items() if k != "estimates"}
    with atomic_write(paths["results"]) as handle:
        handle.write(json.dumps(serialisable, indent=1).encode())
    with atomic_write(paths["table"]) as handle:
        handle.write(results_table(results).encode())
    return paths


def write_outputs(results: dict, test, test_names, out_dir: str, *, animations: bool = True) -> dict:
    """``results.json``, ``table.md``, ``error_curves.png`` and one overlay GIF per test sequence
    (the estimate of the method with the lowest error, first run) under ``out_dir``."""
    from ..viz import animation

    paths = write_progress(results, out_dir)
    paths["curves"] = os.path.join(out_dir, "error_curves.png")
    plot_error_curves(results, paths["curves"])
    if animations:
        for seq, name in zip(test, test_names):
            per_method = results["sequences"][name]
            best = min(per_method, key=lambda m: per_method[m]["error_mm_mean"])
            joints = results["estimates"][name][best][1]
            frames = joints.shape[0]
            clipped = seq.cropped(min(frames, seq.num_frames)).replace(images=None, pose=None, pose_layout=None)
            stem = os.path.splitext(os.path.basename(name))[0].replace(" ", "_")
            paths[f"animation {name}"] = animation(clipped, os.path.join(out_dir, f"{stem}_{best}.gif"), estimate=joints, every=2)
    return paths

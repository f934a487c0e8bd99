"""Where a GPDM puts the takes it was trained on: one arc per take, or one cycle (issue #13).

For the GPDM and the back-constrained GPDM (``--kinds``) fitted on the training takes of each
protocol of ``real_motion.py``, in each latent dimension, two numbers in units of the median
latent step between consecutive frames:

- ``end gap``: per take, the distance from its last latent point to the nearest point of another
  take (a large gap leaves the dynamics GP no transition out of the take's end);
- ``largest step``: the largest step between consecutive frames of one take (a jump in the arc).

    taskset -c 0,1 python experiments/gpdm_arcs.py --cmu /tmp/cmu --bandai /tmp/bandai \\
        --json arcs.json --figure docs/figures/gpdm_arcs.png

``--figure`` draws the first sequence's 2-D latent points of each kind, coloured by take.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import write_json
from real_motion import PROTOCOLS, add_protocol_arguments, load_protocol_takes, protocol_names


def arc_statistics(latent, starts):
    """Per take the end gap, and the largest step, both in median steps (module docstring)."""
    import numpy as np

    takes = [latent[a:b] for a, b in itertools.pairwise(starts)]
    median = np.median(np.concatenate([np.linalg.norm(np.diff(t, axis=0), axis=1) for t in takes]))
    gaps = []
    for i, take in enumerate(takes):
        if len(takes) > 1:
            others = np.concatenate([t for j, t in enumerate(takes) if j != i])
            gaps.append(float(np.min(np.linalg.norm(others - take[-1], axis=1)) / median))
    largest = max(float(np.max(np.linalg.norm(np.diff(t, axis=0), axis=1))) for t in takes) / median
    return gaps, float(largest)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_protocol_arguments(parser)
    parser.add_argument("--latent-dim", type=int, nargs="+", default=[2, 3])
    parser.add_argument("--kinds", nargs="+", default=["gpdm", "bc-gpdm"], choices=["gpdm", "bc-gpdm"])
    parser.add_argument("--fit-steps", type=int, default=200)
    parser.add_argument("--json", help="also write the results to this JSON file")
    parser.add_argument("--figure", help="draw the first sequence's 2-D latent points of each kind to this PNG")
    args = parser.parse_args()
    import jax
    import numpy as np

    from jaxtrack.tracking import fit_manifold, sequence_poses

    folders = {"cmu": args.cmu, "bandai": args.bandai}
    rows, drawn = [], {}
    print("| sequence | latent dim | kind | end gap per take | largest step |")
    print("|---|---:|---|---|---:|")
    names = protocol_names(args.sequences)
    for name in names:
        train_takes = PROTOCOLS[name][1]
        key = jax.random.key(0)
        train = [sequence_poses(s, t, key=key) for t, s in load_protocol_takes(parser, folders, name, train_takes).items()]
        for latent_dim in args.latent_dim:
            for kind in args.kinds:
                model, _info, starts = fit_manifold(train, latent_dim, args.fit_steps, kind=kind)
                latent = np.asarray(model.training_latent())
                gaps, largest = arc_statistics(latent, starts)
                print(f"| {name} | {latent_dim} | {kind} | {', '.join(f'{g:.1f}' for g in gaps)} | {largest:.1f} |", flush=True)
                rows.append({"sequence": name, "latent_dim": latent_dim, "kind": kind, "takes": list(train_takes),
                             "end_gap_median_steps": gaps, "largest_step_median_steps": largest,
                             "objective": float(model.objective())})
                write_json(rows, args.json)
                if args.figure and name == names[0] and latent_dim == 2:
                    drawn[kind] = (latent, starts, train_takes)
    if args.figure and drawn:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, len(drawn), figsize=(5 * len(drawn), 4.5), squeeze=False)
        for ax, (kind, (latent, starts, takes)) in zip(axes[0], drawn.items()):
            for (a, b), take in zip(itertools.pairwise(starts), takes):
                line, = ax.plot(latent[a:b, 0], latent[a:b, 1], ".-", ms=3, lw=0.8, label=take)
                ax.plot(*latent[b - 1, :2], "x", ms=9, mew=2, color=line.get_color())
            ax.set_title(f"{kind}, {names[0]} training takes (x: each take's end)")
            ax.set_xlabel("latent 1")
            ax.set_ylabel("latent 2")
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()

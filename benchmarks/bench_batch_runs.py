"""An experiment's runs one call each against all in one vmapped call (``batch_runs``), on the
demo's first test scene (40 frames, 4 noisy 80x60 views): wall time, each tracker's first-run
and compile time, and the errors (which must agree up to float rounding).

    taskset -c 0,1 python benchmarks/bench_batch_runs.py --json batch_runs.json

The manifold fit is compiled before either timing (a warm-up fit of the same shapes), so the
per-tracker figures compare tracking alone, compilation included.
"""

from __future__ import annotations

import argparse
import json
import time

from bench_output import write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--methods", nargs="+", default=["sir", "mrpf", "gpapf"])
    parser.add_argument("--budget", type=int, default=300)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--fit-steps", type=int, default=100)
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args()
    import jax

    from jaxtrack.demo import demo_sequences
    from jaxtrack.experiment import ExperimentConfig, run_experiment
    from jaxtrack.tracking import fit_manifold, sequence_poses

    train, validation, test, _ = demo_sequences(jax.random.key(0))
    common = {"budget": args.budget, "fit_steps": args.fit_steps}
    # Warm-up: the manifold fit's compilation (the same shapes as the experiments'), no tracker.
    fit_manifold([sequence_poses(s, "train", key=jax.random.key(0)) for s in train], 2, args.fit_steps, kind="gpdm")
    rows = []
    for batch in (False, True):
        config = ExperimentConfig(methods=tuple(args.methods), runs=args.runs, batch_runs=batch, **common)
        start = time.perf_counter()
        results = run_experiment(train, validation, test[:1], config, progress=False)
        wall = time.perf_counter() - start
        per_method = results["sequences"]["test0"]
        row = {"batch_runs": batch, "wall_s": wall, "runs": args.runs, "budget": args.budget,
               "methods": {}}
        for method, values in per_method.items():
            first, steady = values["first_run_s (includes compile)"], 40 / values["frames_per_second"]
            row["methods"][method] = {
                "error_mm_mean": values["error_mm_mean"], "error_mm_per_run": values["error_mm_per_run"],
                "compile_s": values["compile_s"], "first_run_s": first,
                # all runs of the tracker: batched, one call (its share per run times the runs); else the first plus the rest
                "tracking_s": first * args.runs if batch else first + (args.runs - 1) * steady,
            }
        rows.append(row)
        print(json.dumps(row), flush=True)
    write_json(rows, args.json)


if __name__ == "__main__":
    main()

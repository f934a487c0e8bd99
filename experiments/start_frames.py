"""The automatic start scored on more than the first frame: does it land nearer the person?

``tracking.StartSearch.frames`` scores each candidate pose on the first N frames together (the
pose held, the root not moved). For every fold of a ``jaxtrack protocol`` protocol (levelled
takes, the protocol's scenes and keys, 3 noisy 80x60 views of the solid body), the start is
searched on the fold's GLE (GLE-GbPF's 3-D manifold, fitted as the experiment fits it) with N = 1
(the default), 3 and 6, and its mean joint error against frame 0's truth printed (mm), one JSON
line per fold.

    taskset -c 0,1 python experiments/start_frames.py --data ../shared/data    # walk-loso; 12 minutes
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--protocol", default="walk-loso")
    parser.add_argument("--data", default="../shared/data")
    parser.add_argument("--frames", type=int, nargs="+", default=[1, 3, 6], help="the first frames each search scores")
    parser.add_argument("--json")
    args = parser.parse_args()
    import jax

    from jaxtrack import experiment
    from jaxtrack.tracking import StartSearch, prepare_test

    protocol = experiment.get_protocol(args.protocol)
    converted = os.path.join(tempfile.gettempdir(), f"jaxtrack_start_frames_{args.protocol}")
    sequences = experiment.convert_takes(protocol.takes(), args.data, converted, say=lambda *a, **k: None, level_floor=True)
    quiet = lambda *a, **k: None  # noqa: E731
    rows = []
    for fold in protocol.folds(("cross", "within"), None):
        train, validation = experiment.fold_takes(protocol, fold, sequences)
        test = experiment.fold_test_scene(protocol, fold, sequences)
        config = experiment.ExperimentConfig(methods=("glegbpf",), budget=500, runs=1, seed=0, start="auto")
        results = experiment.new_results(config)
        inputs = experiment.prepare_inputs(train, validation, [test], config, results, names=fold.names, say=quiet)
        experiment.fit_methods(inputs, config, results, progress=False, say=quiet)
        model = experiment.start_manifold(inputs, config, results, progress=False, say=quiet)
        row = {"fold": fold.label, "start_error_mm": {}}
        for frames in args.frames:
            scene = prepare_test(inputs.tests[0], inputs.test_names[0], key=jax.random.key(config.seed), frames=config.frames,
                                 window=inputs.window, donors=inputs.donors, say=quiet, ground_clearance=inputs.clearance,
                                 start="auto", start_model=model, root_height=inputs.root_height,
                                 root_height_legs=inputs.root_height_legs, start_search=StartSearch(frames=frames),
                                 **config.scene_options())
            row["start_error_mm"][frames] = round(scene.start_error_mm, 1)
        print(json.dumps(row), flush=True)
        rows.append(row)
        if args.json:  # rewritten after every fold: an interruption keeps the folds done
            with open(args.json, "w", encoding="utf-8") as handle:
                json.dump(rows, handle, indent=1)
        jax.clear_caches()


if __name__ == "__main__":
    main()

"""Can the silhouettes tell the truth from a tracker's estimate? On ``real_motion.py``'s
protocols (the test take rendered with another body into noisy 80x60 views), each tracker's
first run is scored frame by frame under the silhouette likelihood it tracked with (000 eq. 12
at the experiment's scale; the ground plane's prior, which the trackers also carry by default,
is left out: the question is what the silhouettes see):
``ln p(I_t | truth_t) - ln p(I_t | estimate_t)``, the truth being the inverse-kinematics pose
every run starts from. A gap near 0 nats while the estimate is tens of
millimetres off means the estimate sits where the likelihood cannot see the difference, so a
better sampler cannot lower that error; only the prior (the dynamics, the manifold) can.

Prints, per protocol, view count and tracker, the joint error and the gap by quarter of the
frames, and the share of frames in which the truth scores higher. ``--demo`` adds the demo's two
test scenes with the demo's settings (4 views, budget 300, 100 fit steps; rendered with the
tracker's own body). ``--silhouettes clean`` and ``--size WxH`` render the protocols' views
without noise or larger (``real_motion.py``'s options). ``--plot`` draws the error and the gap
per frame for the first protocol and view count.

    taskset -c 0,1 python experiments/likelihood_gap.py --cmu /tmp/cmu --bandai /tmp/bandai --json likelihood_gap.json
    taskset -c 0,1 python experiments/likelihood_gap.py --cmu /tmp/cmu --sequences cmu-jog --views 4 \\
        --methods sir apf mrpf gpapf latentpf --plot docs/figures/likelihood_gap.png
    taskset -c 0,1 python experiments/likelihood_gap.py --demo --methods sir apf mrpf gpapf latentpf
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))  # bench_output, real_motion
from bench_output import add_output_arguments, pin_threads, write_json
from real_motion import PROTOCOLS, add_protocol_arguments, add_scene_arguments, load_protocol_takes, other_body_scene, protocol_names

DEMO_BUDGET, DEMO_FIT_STEPS = 300, 100  # jaxtrack demo's
FIT_STEPS = 300  # the experiment's default


def quarters(values) -> list[float]:
    """Means of ``values`` over the first three quarters of the frames and the last quarter
    (the quarters of ``real_motion.drift_ratio``)."""
    import numpy as np

    values = np.asarray(values, np.float64)
    q = max(1, len(values) // 4)
    return [round(float(np.mean(v)), 2) for v in (values[:q], values[q : 2 * q], values[2 * q : 3 * q], values[-q:])]


def likelihood_gaps(scene, poses):
    """Per frame, ``ln p(I_t | truth_t) - ln p(I_t | poses_t)`` under ``scene.likelihood`` (T,)."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    score = eqx.filter_jit(jax.vmap(lambda likelihood, pair, observation: likelihood(pair, observation), in_axes=(None, 0, 0)))
    dtype = scene.initial_pose.dtype
    pairs = jnp.stack([jnp.asarray(scene.truth_poses, dtype), jnp.asarray(poses, dtype)], axis=1)
    scores = np.asarray(score(scene.likelihood, pairs, scene.observations), np.float64)
    return scores[:, 0] - scores[:, 1]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_protocol_arguments(parser)
    parser.add_argument("--methods", nargs="+", default=["mrpf", "gpapf", "latentpf"])
    parser.add_argument("--views", type=int, nargs="+", default=[4, 3])
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    add_scene_arguments(parser)
    parser.add_argument("--demo", action="store_true", help="also the demo's S1 walk and S2 jog (jaxtrack demo --seed's scenes)")
    add_output_arguments(parser, plot="draw the error and the likelihood gap per frame (first protocol and view count)")
    args = parser.parse_args()
    pin_threads(args.threads)

    import jax
    import numpy as np

    from jaxtrack.experiment import ExperimentConfig, run_experiment
    from jaxtrack.tracking import prepare_test

    folders = {"cmu": args.cmu, "bandai": args.bandai}
    key = jax.random.key(args.seed)
    setups = []  # (name, views, training, validation, test scene, budget, fit steps)
    if args.demo:
        from jaxtrack.demo import demo_sequences

        train, validation, tests, names = demo_sequences(key)  # as run_demo(seed=args.seed)
        setups += [(name, 4, train, validation, test, DEMO_BUDGET, DEMO_FIT_STEPS) for name, test in zip(names["test"], tests)]
    for name in protocol_names(args.sequences) if args.cmu or args.bandai else []:
        _dataset, train_takes, validation_takes, test_take, frames = PROTOCOLS[name]
        takes = load_protocol_takes(parser, folders, name, train_takes + validation_takes + [test_take])
        setups += [(name, views, [takes[t] for t in train_takes], [takes[t] for t in validation_takes],
                    other_body_scene(jax.random.fold_in(key, views), takes[test_take], views, frames,
                                     clean=args.silhouettes == "clean", size=args.size), args.budget, FIT_STEPS)
                   for views in args.views]
    rows, curves = [], []
    for name, views, train, validation, test, budget, fit_steps in setups:
        config = ExperimentConfig(methods=tuple(args.methods), budget=budget, runs=1, fit_steps=fit_steps, seed=args.seed)
        results = run_experiment(train, validation, [test], config, names={"test": [name]}, progress=False, animations=False)
        scene = prepare_test(test, name, key=key, likelihood_scale=config.likelihood_scale)
        for method in args.methods:
            poses, joints = results["estimates"][name][method]
            error = 1000 * np.linalg.norm(joints - scene.truth_joints, axis=-1).mean(axis=-1)
            gap = likelihood_gaps(scene, poses)
            rows.append({"sequence": name, "views": views, "method": method, "silhouettes": args.silhouettes,
                         "size": list(args.size), "error_mm_by_quarter": quarters(error),
                         "gap_nats_by_quarter": quarters(gap), "truth_higher_fraction": round(float(np.mean(gap > 0)), 3),
                         "error_mm": error.round(2).tolist(), "gap_nats": gap.round(3).tolist()})
            print(f"{name:12s} {views} views {method:9s} error {quarters(error)} mm, ln p(truth) - ln p(estimate) "
                  f"{quarters(gap)} nats, truth higher in {100 * np.mean(gap > 0):.0f} % of frames", flush=True)
            if not curves or curves[0][:2] == (name, views):
                curves.append((name, views, method, error, gap))
            write_json(rows, args.json)
        jax.clear_caches()
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        for _name, _views, method, error, gap in curves:
            top.plot(error, label=method)
            bottom.plot(gap, label=method)
        bottom.axhline(0.0, color="k", lw=0.8)
        top.set_ylabel("joint error (mm)")
        bottom.set_ylabel("ln p(I | truth) - ln p(I | estimate)")
        bottom.set_xlabel("frame")
        top.set_title(f"{curves[0][0]}, {curves[0][1]} views: the estimate's error and what the silhouettes say of it")
        top.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()

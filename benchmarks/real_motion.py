"""Paper 000's protocol on real motion, seen as the issue's figures must be: CMU subject 35's
walk and jog and the Bandai walk and run, the test takes rendered into noisy 80x60 views with a
body that is not the tracker's (torso 20 % thicker, legs 15 % thinner, arms 10 % thicker than
the converted subject's capsules; the test files carry no radii, so the trackers use the
defaults), in 4 views and in 3, every tracker with its own defaults or with the Kalman-tracked
velocity on or off for all (``--velocity``), on each tracker's own manifold or on one named for
all (``--manifold``).

The converted sequences come from the two shell scripts' first steps (``jaxtrack convert`` of
the shared data at 60 Hz); point ``--cmu`` and ``--bandai`` at their output folders:

    bash benchmarks/cmu_experiment.sh /tmp/cmu       # or only its conversion lines
    taskset -c 0,1 python benchmarks/real_motion.py --cmu /tmp/cmu --bandai /tmp/bandai \\
        --runs 5 --budget 500 --json real_motion.json

``--likelihood-scale`` sets the silhouette likelihood's temperature (several: one table each),
``--body known`` gives the trackers the rendered body's radii (the check that the mismatched
body is not what limits them), ``--silhouettes clean`` renders the views without
background-subtraction noise and ``--size 160x120`` renders (and tracks) them larger: the checks
that the noise and the pixel size are not what limits them. ``--ground-prior on off`` runs each
setting with the ground plane's prior (the experiment's default) and without it.

``--sequences mixed`` trains on walks and jogs (runs) together and tests each activity's take
(paper 004's setting). ``--sequences held-out`` runs the same protocols on four takes that no setting of the library
was ever chosen on (CMU walk 35_04 and jog 35_22, Bandai walk 004 and run 006): the check that
the defaults were not tuned to the four test takes above. ``--sequences validation`` tracks each
protocol's validation take instead of its test take: where a setting may be chosen.

Prints one table per (views, velocity) setting and, with ``--json PATH``, writes every
result there: per sequence and tracker the mean, sd and per-run errors (mm) and the ratio of
the mean error over the last quarter of the frames to the first quarter (a divergence check),
of the mean curve and of each run's own curve. Under each table, how many runs' own ratio is
over 1.3: a tracker whose runs split into kept and lost shows it there before the mean does.
"""

from __future__ import annotations

import argparse
import itertools
import os
import time

from bench_output import write_json

# name: (dataset, training takes, validation takes, test take, test frames (None: all))
PROTOCOLS = {
    "cmu-walk": ("cmu", ["35_01", "35_02"], ["35_03"], "35_29", 200),
    "cmu-jog": ("cmu", ["35_17", "35_19", "35_20"], ["35_21"], "35_18", None),
    "bandai-walk": ("bandai", ["walk_normal_001"], ["walk_normal_002"], "walk_normal_003", 200),
    "bandai-run": ("bandai", ["run_normal_001", "run_normal_002"], ["run_normal_003"], "run_normal_005", 80),
}
# The same training and validation takes, tested on a take that no setting was ever chosen on:
# the first unused take of each activity. (Bandai run 004 is skipped: inverse kinematics cannot
# fit its first 20 frames, 28 mm on average with the shoulders 40-95 mm off, from any start.)
# ``--sequences held-out``.
HELD_OUT = {
    "cmu-walk-35_04": ("cmu", ["35_01", "35_02"], ["35_03"], "35_04", 200),
    "cmu-jog-35_22": ("cmu", ["35_17", "35_19", "35_20"], ["35_21"], "35_22", None),
    "bandai-walk-004": ("bandai", ["walk_normal_001"], ["walk_normal_002"], "walk_normal_004", 200),
    "bandai-run-006": ("bandai", ["run_normal_001", "run_normal_002"], ["run_normal_003"], "run_normal_006", 80),
}
# Walks and jogs (runs) together in training, as paper 004 trains its prototypes on several
# activities: each activity's test take tracked on the joint model. ``--sequences mixed``.
MIXED = {
    "cmu-mixed-walk": ("cmu", ["35_01", "35_02", "35_17", "35_19", "35_20"], ["35_03", "35_21"], "35_29", 200),
    "cmu-mixed-jog": ("cmu", ["35_01", "35_02", "35_17", "35_19", "35_20"], ["35_03", "35_21"], "35_18", None),
    "bandai-mixed-walk": ("bandai", ["walk_normal_001", "run_normal_001", "run_normal_002"], ["walk_normal_002", "run_normal_003"],
                          "walk_normal_003", 200),
    "bandai-mixed-run": ("bandai", ["walk_normal_001", "run_normal_001", "run_normal_002"], ["walk_normal_002", "run_normal_003"],
                         "run_normal_005", 80),
}
TUNED = list(PROTOCOLS)
# Each tuned protocol tracking its own validation take, on which a setting may be chosen without
# looking at any test take (the dynamics are fitted on that take too, so its errors flatter every
# setting alike). ``--sequences validation``.
VALIDATION = {f"{name}-validation": (ds, train, valid, valid[0], frames)
              for name, (ds, train, valid, _, frames) in PROTOCOLS.items()}
PROTOCOLS.update(HELD_OUT)
PROTOCOLS.update(VALIDATION)
PROTOCOLS.update(MIXED)
GROUPS = {"held-out": HELD_OUT, "validation": VALIDATION, "mixed": MIXED}


def add_protocol_arguments(parser) -> None:
    """``--cmu`` and ``--bandai`` (the converted takes' folders) and ``--sequences`` (protocols)."""
    parser.add_argument("--cmu", help="folder with the converted CMU takes (35_01.npz, ...)")
    parser.add_argument("--bandai", help="folder with the converted Bandai takes (walk_normal_001.npz, ...)")
    parser.add_argument("--sequences", nargs="+", default=TUNED, choices=[*PROTOCOLS, *GROUPS],
                        help="protocols (default: the four the defaults were measured on; held-out: the four on takes "
                             "no setting was chosen on; validation: the four tracking their validation takes)")


def add_scene_arguments(parser) -> None:
    """``--silhouettes`` (noisy or clean) and ``--size`` (the rendered views' WxH)."""
    parser.add_argument("--silhouettes", choices=["noisy", "clean"], default="noisy",
                        help="noisy: the default background-subtraction noise (SilhouetteNoise()); clean: none (NO_NOISE)")
    parser.add_argument("--size", default="80x60", type=image_size, help="width x height of the rendered views, pixels")


def image_size(text: str) -> tuple[int, int]:
    """``"WxH"`` as ``(W, H)``, both positive (an argparse type)."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 160x120, got {text!r}") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"width and height must be positive, got {text!r}")
    return width, height


def protocol_names(sequences) -> list[str]:
    """``--sequences`` with "held-out" and "validation" expanded into their protocols."""
    return [n for name in sequences for n in GROUPS.get(name, [name])]


def load_protocol_takes(parser, folders: dict, name: str, takes) -> dict:
    """The named takes of protocol ``name`` as ``{take: Sequence}``, read from the folder of its
    dataset (``folders``: dataset -> folder or None); a parser error naming the missing option or
    file otherwise."""
    from jaxtrack.io import load_sequence

    dataset = PROTOCOLS[name][0]
    if folders[dataset] is None:
        parser.error(f"{name} needs --{dataset} (the folder of the converted takes)")
    paths = {t: os.path.join(folders[dataset], t + ".npz") for t in takes}
    missing = [p for p in paths.values() if not os.path.exists(p)]
    if missing:
        parser.error(f"{name}: missing {missing[0]}; convert the shared data first (see the shell scripts)")
    return {t: load_sequence(p) for t, p in paths.items()}


def other_body_scene(key, sequence, views: int, frames, *, withhold: bool = True, clean: bool = False,
                     size: tuple[int, int] = (80, 60)):
    """The test take rendered with the mismatched body (the subject's capsules in
    ``body_factors()`` radii) into ``size`` (W, H) views, its radii withheld from the tracker
    (``withhold=False``: given to it), with the default silhouette noise (``clean``: none)."""
    from jaxtrack.experiment import render_test_take

    return render_test_take(key, sequence, views=views, size=size, frames=frames, renderer="capsules", clean=clean,
                            withhold=withhold)


def body_factors() -> dict:
    """The mismatched radii, per capsule group (``jaxtrack.experiment.OTHER_RADII``; imported
    here, not at the top, so that ``--threads`` pins XLA before JAX starts)."""
    from jaxtrack.experiment import OTHER_RADII

    return dict(OTHER_RADII)


def drift_ratio(curve) -> float:
    """``jaxtrack.experiment.drift_ratio``: the last quarter's mean error over the first's."""
    from jaxtrack.experiment import drift_ratio as ratio

    return ratio(curve)


DIVERGED_RATIO = 1.3  # issue #13's divergence check: last quarter over first, at most 1.3


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_protocol_arguments(parser)
    parser.add_argument("--methods", nargs="+", default=["sir", "apf", "mrpf", "gpapf", "latentpf"])
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--views", type=int, nargs="+", default=[4, 3])
    parser.add_argument("--velocity", nargs="+", choices=["own", "on", "off"], default=["own"],
                        help="Kalman-tracked velocity for every tracker (on), none (off), or each tracker's own default")
    parser.add_argument("--manifold", nargs="+", default=["own"], choices=["own", "bc-gplvm", "gpdm", "bc-gpdm"],
                        help="the manifold of every manifold tracker (own: each tracker's paper's)")
    parser.add_argument("--latent-dim", type=int, nargs="+", default=[None],
                        help="latent dimensions of the manifolds (several: one table each; default: each tracker's own, "
                             "MRPF 2, GPAPF and LatentPF 3; else 2 for the GP models and 3 for GLE)")
    parser.add_argument("--residual", nargs="+", default=["own"],
                        help="scales of the off-manifold pose residual of LatentPF and GLE-GbPF (several: one table each; "
                             "0: none; own: each tracker's default)")
    parser.add_argument("--fit-steps", type=int, default=300)
    parser.add_argument("--fit-optimiser", choices=["optax", "lbfgs"], default="optax",
                        help="the manifold fit's L-BFGS (optax, the experiment's default: the README's tables)")
    parser.add_argument("--likelihood-scale", type=float, nargs="+", default=[100.0],
                        help="temperatures of the silhouette likelihood (several: one table each; ExperimentConfig's default 100)")
    parser.add_argument("--ground-prior", nargs="+", choices=["on", "off"], default=["on"],
                        help="the ground plane's prior on every tracker's likelihood (several: one table each; default on, "
                             "ExperimentConfig's)")
    parser.add_argument("--body", choices=["other", "known"], default="other",
                        help="other: the trackers keep the default capsules; known: they are given the rendered body's radii")
    add_scene_arguments(parser)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="also write the results to this JSON file")
    args = parser.parse_args()
    import jax

    from jaxtrack.experiment import ExperimentConfig, results_table, run_experiment

    folders = {"cmu": args.cmu, "bandai": args.bandai}
    velocities = [{"own": None, "on": True, "off": False}[v] for v in args.velocity]
    key = jax.random.key(args.seed)
    rows = []
    for name in protocol_names(args.sequences):
        _dataset, train_takes, validation_takes, test_take, frames = PROTOCOLS[name]
        takes = load_protocol_takes(parser, folders, name, train_takes + validation_takes + [test_take])
        train = [takes[t] for t in train_takes]
        validation = [takes[t] for t in validation_takes]
        for views in args.views:
            test = [other_body_scene(jax.random.fold_in(key, views), takes[test_take], views, frames, withhold=args.body == "other",
                                     clean=args.silhouettes == "clean", size=args.size)]
            residuals = [None if r == "own" else float(r) for r in args.residual]
            settings = itertools.product(velocities, args.manifold, args.latent_dim, residuals, args.likelihood_scale,
                                         args.ground_prior)
            for velocity, manifold, latent_dim, residual, likelihood_scale, ground in settings:
                config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, fit_steps=args.fit_steps,
                                          fit_optimiser=args.fit_optimiser,
                                          seed=args.seed, velocity=velocity, manifold=None if manifold == "own" else manifold,
                                          latent_dim=latent_dim, residual=residual, likelihood_scale=likelihood_scale,
                                          ground_prior=ground == "on")
                start = time.perf_counter()
                results = run_experiment(train, validation, test, config, names={"test": [name]}, progress=False)
                seconds = time.perf_counter() - start
                label = "own" if velocity is None else velocity
                print(f"\n{name}, {views} views, other body, velocity={label}, manifold={manifold}, latent dim {latent_dim or 'own'}, "
                      f"residual {residual if residual is not None else 'own'}, likelihood scale {likelihood_scale:g}, "
                      f"ground prior {ground}, body {args.body}, "
                      f"{args.silhouettes} {args.size[0]}x{args.size[1]} silhouettes ({seconds:.0f} s)\n")
                print(results_table(results))
                per_method = results["sequences"][name]
                run_ratios = {m: [drift_ratio(c) for c in per_method[m]["per_frame_error_mm_per_run"]] for m in args.methods}
                print("runs whose own last-over-first-quarter ratio is over " f"{DIVERGED_RATIO}: "
                      + ", ".join(f"{m} {sum(r > DIVERGED_RATIO for r in ratios)}/{len(ratios)}" for m, ratios in run_ratios.items()),
                      flush=True)
                rows.append({
                    "sequence": name, "views": views, "velocity": velocity, "manifold": manifold, "latent_dim": latent_dim,
                    "residual": residual, "likelihood_scale": likelihood_scale, "ground_prior": ground == "on", "body": args.body,
                    "silhouettes": args.silhouettes, "size": list(args.size),
                    "frames": test[0].num_frames,
                    "seconds": seconds, "budget": args.budget, "runs": args.runs, "body_factors": body_factors(),
                    "methods": {m: {"error_mm_mean": per_method[m]["error_mm_mean"], "error_mm_std": per_method[m]["error_mm_std"],
                                    "error_mm_per_run": per_method[m]["error_mm_per_run"],
                                    "last_over_first_quarter": drift_ratio(per_method[m]["per_frame_error_mm"]),
                                    "last_over_first_quarter_per_run": run_ratios[m],
                                    "mean_ess": per_method[m]["mean_ess"],
                                    "per_frame_error_mm": per_method[m]["per_frame_error_mm"],
                                    "per_frame_error_mm_per_run": per_method[m]["per_frame_error_mm_per_run"],
                                    "velocity": config.velocity_of(m), "manifold": config.manifold_of(m),
                                    "latent_dim": config.latent_dim_of(m), "residual": config.residual_of(m),
                                    "residual_decay": config.residual_decay_of(m)}
                                for m in args.methods},
                })
                write_json(rows, args.json)
                # Every experiment compiles its own trackers; keeping them all exhausted the
                # process's memory maps (LLVM "Cannot allocate memory") after about ten.
                jax.clear_caches()


if __name__ == "__main__":
    main()

"""Command-line entry point: ``jaxtrack demo``, ``render SEQUENCE.npz`` and ``convert SOURCE OUT.npz``."""

from __future__ import annotations

import argparse
import os
import sys


def _demo(args) -> int:
    from ._demo import run_demo

    run_demo(args.out, seed=args.seed, num_frames=args.frames, particles=args.particles)
    return 0


def _render(args) -> int:
    from .io import load_sequence
    from .viz import animation, contact_sheet

    sequence = load_sequence(args.sequence)
    stem = args.out or os.path.splitext(args.sequence)[0]
    estimate = None
    if args.estimate:
        estimate = load_sequence(args.estimate).joints3d
        if estimate is None:
            raise ValueError(f"{args.estimate}: has no joints3d to draw as the estimate")
    sheet = contact_sheet(sequence, stem + "_sheet.png", estimate=estimate)
    gif = animation(sequence, stem + ".gif", estimate=estimate, scale=args.scale, every=args.every)
    print(f"wrote {sheet} and {gif}")
    return 0


def _convert(args) -> int:
    import json

    from ._convert import convert_motion

    mapping = None
    if args.mapping:
        with open(args.mapping, encoding="utf-8") as handle:
            mapping = json.load(handle)
    report = convert_motion(
        args.source, args.out, fps=args.fps, asf=args.asf, source_fps=args.source_fps, mapping=mapping, seed=args.seed, verbose=True
    )
    print(
        f"wrote {args.out}: {report.num_frames} frames at {report.sequence.fps:g} Hz; inverse-kinematics residual "
        f"mean {report.mean_residual_mm:.1f} mm, max {report.max_residual_mm:.1f} mm"
    )
    return 0


def _fit(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)  # GP training in float64
    import numpy as np

    from .io import load_sequence
    from .manifold import fit_model, make_bc_gplvm, make_gpdm, make_gplvm, save_model

    sequences, names = [], []
    for path in args.motion:
        seq = load_sequence(path)
        if seq.pose is None:
            raise ValueError(f"{path}: has no 'pose' key (make one with 'jaxtrack convert')")
        layout = [str(n) for n in seq.pose_layout]
        # The manifold models joint angles only, not the global position and orientation.
        keep = [i for i, n in enumerate(layout) if not n.startswith("root_")]
        sequences.append(seq.pose[:, keep])
        names.append(os.path.basename(path))
    layouts = {len(s[0]) for s in sequences}
    if len(layouts) != 1:
        raise ValueError("the motion files have different pose layouts")
    Y = np.concatenate(sequences)
    starts = tuple(int(v) for v in np.cumsum([0] + [len(s) for s in sequences]))
    if args.model == "gplvm":
        model = make_gplvm(Y, args.latent_dim)
    elif args.model == "bc-gplvm":
        model = make_bc_gplvm(Y, args.latent_dim)
    else:
        model = make_gpdm(sequences, args.latent_dim)
    fitted, info = fit_model(model, max_steps=args.steps, progress=True)
    kept_layout = [n for n in layout if not n.startswith("root_")]
    save_model(args.out, fitted, sequence_starts=starts, extra={"pose_layout": kept_layout, "sequences": names})
    print(f"wrote {args.out}: {type(fitted).__name__}, {Y.shape[0]} frames, objective {info.objective:.6g} after {info.steps} steps")
    return 0


def _plot_latent(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)  # models are saved in float64
    from .manifold import load_model, plot_latent

    model, header = load_model(args.model)
    out = args.out or os.path.splitext(args.model)[0] + "_latent.png"
    plot_latent(model, out, sequence_starts=header["sequence_starts"], labels=header["extra"].get("sequences"))
    print(f"wrote {out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxtrack", description="Articulated human motion tracking with particle filters and pose manifolds, in JAX."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="run the pipeline end to end on the embedded synthetic default")
    demo.add_argument("--out", default="jaxtrack_demo", help="output folder (default: %(default)s)")
    demo.add_argument("--seed", type=int, default=0, help="PRNG seed (default: %(default)s)")
    demo.add_argument("--frames", type=int, default=60, help="frames to synthesise (default: %(default)s)")
    demo.add_argument("--particles", type=int, default=500, help="poses scored per frame (default: %(default)s)")
    demo.set_defaults(run=_demo)

    render = sub.add_parser("render", help="write a contact sheet (PNG) and an animation (GIF) of a sequence file")
    render.add_argument("sequence", help="a jaxtrack .npz sequence file with cameras and silhouettes or images")
    render.add_argument("--out", help="output path stem (default: next to the sequence)")
    render.add_argument("--estimate", help="a second sequence file whose joints3d are drawn in red")
    render.add_argument("--scale", type=int, default=3, help="GIF upscaling factor (default: %(default)s)")
    render.add_argument("--every", type=int, default=1, help="keep every n-th frame in the GIF (default: %(default)s)")
    render.set_defaults(run=_render)

    convert = sub.add_parser("convert", help="turn ASF/AMC, BVH or 3-D joint files into a sequence file with joints3d and pose")
    convert.add_argument("source", help="a .amc (with --asf), .bvh or .npz (joints3d + joint_names) motion file")
    convert.add_argument("out", help="output sequence file (.npz)")
    convert.add_argument("--fps", type=float, help="output frame rate (default: the source's)")
    convert.add_argument("--asf", help="skeleton of an AMC file (default: the only .asf beside it)")
    convert.add_argument("--source-fps", type=float, help="frame rate of the source (required for AMC; CMU: 120)")
    convert.add_argument("--mapping", help="JSON file: HumanEva joint -> source joint name(s) (CMU and Bandai are built in)")
    convert.add_argument("--seed", type=int, default=0, help="PRNG seed for the IK restarts (default: %(default)s)")
    convert.set_defaults(run=_convert)

    fit = sub.add_parser("fit", help="fit a pose manifold to one or more sequence files with 'pose'")
    fit.add_argument("motion", nargs="+", help="sequence files (.npz) with pose vectors")
    fit.add_argument("--model", choices=("gplvm", "bc-gplvm", "gpdm"), default="bc-gplvm")
    fit.add_argument("--latent-dim", type=int, default=2)
    fit.add_argument("--steps", type=int, default=500, help="L-BFGS iterations at most (default: %(default)s)")
    fit.add_argument("--out", required=True, help="output model file (e.g. model.eqx)")
    fit.set_defaults(run=_fit)

    plot = sub.add_parser("plot-latent", help="draw a fitted model's latent space over its predictive variance")
    plot.add_argument("model", help="a model file written by 'jaxtrack fit'")
    plot.add_argument("--out", help="output PNG (default: MODEL_latent.png)")
    plot.set_defaults(run=_plot_latent)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.run(args)
    except (ValueError, FileNotFoundError, OSError) as err:
        print(f"jaxtrack {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

"""VLMM-PF against single-model latent trackers on real motion that changes activity, the manifold
trained on several people's walks and jogs together (docs/vlmm.md, "Real motion that changes
activity"; issue #44).

    taskset -c 0,1 python experiments/vlmm_switch_real.py --data ../shared/data --actors bd dg --runs 5 \\
        --json vlmm_switch_real.json       # about 15 minutes an actor on 2 cores

Data: HDM05's five actors in ``multi_subject/``, each with takes of a sneaking walk
(``sneak2StepsLStart``) and of jogging on a left circle (``jogLeftCircle4StepsRstart``), converted
by the library's loaders at 60 Hz (once, into ``--work``).

Training, "trained together": one sneak and one jog of every actor, none of them the test
actor's test takes or validation take (the test actor's jog left out where it has only two);
validation: the test actor's last jog. Test, per actor: its other sneak followed by
its first jog, the jog's root turned and moved to carry on from where the sneak ends, the two
joined by a 12-frame cross-fade of the pose vectors, rendered by the solid body (not the
tracker's capsules) in 4 noisy 80x60 views (``render_test_take``). Prints each tracker's mean
error on the sneak, the fade and the jog over ``--runs`` runs, budget ``--budget``.
"""

import argparse
import json
import os
import pathlib

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.body import forward_kinematics
from jaxtrack.experiment import ExperimentConfig, Take, convert_takes, render_test_take, run_experiment

ACTORS = ("bd", "bk", "dg", "mm", "tr")
FADE = 12


def takes_of(data: str, actor: str) -> dict[str, list[Take]]:
    """The actor's sneak and jog takes, by activity, in file order."""
    folder = os.path.join(data, "multi_subject", f"hdm05_{actor}")
    out = {"sneak": [], "jog": []}
    for name in sorted(os.listdir(folder)):
        if name.endswith(".amc"):
            activity = "sneak" if "sneak" in name else "jog"
            out[activity].append(Take(f"hdm05-{actor}", name[:-4], f"multi_subject/hdm05_{actor}/{name}", 120.0,
                                      f"multi_subject/hdm05_{actor}/HDM_{actor}.asf"))
    return out


def switching_take(first, second):
    """``first``'s motion then ``second``'s, ``second``'s root turned about the vertical and moved
    so that it carries on from ``first``'s last frame, the two joined by a FADE-frame cross-fade
    of the pose vectors (the join in ``first``'s last FADE frames). Ground truth: the blended
    poses' forward kinematics on ``first``'s skeleton."""
    a, b = np.asarray(first.pose, np.float64), np.asarray(second.pose, np.float64)
    join = len(a) - FADE
    turn = a[join, 3] - b[0, 3]
    c, s = np.cos(turn), np.sin(turn)
    xy = b[:, :2] - b[0, :2]
    b = b.copy()
    b[:, :2] = np.stack([c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]], axis=1) + a[join, :2]
    b[:, 3] += turn
    weight = ((np.arange(FADE) + 0.5) / FADE)[:, None]
    pose = np.concatenate([a[:join], (1 - weight) * a[join:] + weight * b[:FADE], b[FADE:]])
    skeleton = first.body().skeleton
    joints = np.asarray(forward_kinematics(skeleton, jnp.asarray(pose, jnp.float32)), np.float64)
    return first.replace(pose=pose, joints3d=joints), join


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", default="../shared/data")
    parser.add_argument("--work", default="/tmp/vlmm_switch_real", help="converted takes are kept here")
    parser.add_argument("--actors", nargs="+", default=list(ACTORS), choices=ACTORS)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--budget", type=int, default=500)
    parser.add_argument("--methods", nargs="+", default=["latentpf", "mrpf", "vlmmpf"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the per-segment errors here")
    args = parser.parse_args()
    key = jax.random.key(args.seed)
    takes = {actor: takes_of(args.data, actor) for actor in ACTORS}
    everything = [t for actor in ACTORS for activity in ("sneak", "jog") for t in takes[actor][activity]]
    sequences = convert_takes(everything, args.data, os.path.join(args.work, "converted"), seed=args.seed)
    rows = []
    for actor in args.actors:
        own = takes[actor]
        test_sneak, test_jog, validation_jog = own["sneak"][-1], own["jog"][0], own["jog"][-1]
        train = [sequences[takes[a]["sneak"][0].name] for a in ACTORS]  # the test actor's last sneak is its test
        for a in ACTORS:  # the test actor's first jog is its test and its last its validation: a middle one if it has one
            jogs = takes[a]["jog"] if a != actor else takes[a]["jog"][1:-1]
            train += [sequences[jogs[0].name]] if jogs else []
        blended, join = switching_take(sequences[test_sneak.name], sequences[test_jog.name])
        scene = render_test_take(jax.random.fold_in(key, 900), blended, views=4)
        total = scene.num_frames
        config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, seed=args.seed)
        names = {"train": [f"{s.subject} {i}" for i, s in enumerate(train)], "validation": [f"{actor} validation"],
                 "test": [f"{actor} sneak to jog"]}
        results = run_experiment(train, [sequences[validation_jog.name]], [scene], config, names=names, progress=False)
        segments = {"sneak": slice(0, join), "fade": slice(join, join + FADE), "jog": slice(join + FADE, total)}
        for method in args.methods:
            entry = results["sequences"][f"{actor} sneak to jog"].get(method)
            if entry is None:
                print(f"{actor} {method}: refused: {results['refused'].get(method)}", flush=True)
                continue
            curves = np.asarray(entry["per_frame_error_mm_per_run"])
            row = {"actor": actor, "method": method, "frames": [join, FADE, total - join - FADE]}
            row |= {name: round(float(curves[:, part].mean()), 1) for name, part in segments.items()}
            row["all"] = round(float(curves.mean()), 1)
            row["sd_over_runs"] = round(float(curves.mean(axis=1).std()), 1)
            print(json.dumps(row), flush=True)
            rows.append(row)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()

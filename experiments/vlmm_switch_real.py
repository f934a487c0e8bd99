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

``--activities sneak`` trains on the sneaks alone (one of every actor, as above), for the
single-activity trackers 004 compares the VLMM-PF with; validation is then the test actor's
middle sneak, or, for an actor with two sneaks (bk), its first, which is also in training.

    taskset -c 0,1 python experiments/vlmm_switch_real.py --data ../shared/data --activities sneak --methods latentpf mrpf

``--plot PNG`` draws each tracker's error per frame (the median over the runs, shaded from the
best run to the worst) with the switch marked, this run's rows and those of the ``--with`` JSON
files of earlier runs on the same actor (docs/figures/vlmm_switch_bk.png).
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
    parser.add_argument("--activities", nargs="+", default=["sneak", "jog"], choices=["sneak", "jog"],
                        help="what the trackers are trained on: both (the default) or the sneaks alone (single-activity)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the per-segment errors here")
    parser.add_argument("--plot", help="draw the first actor's error curves to this PNG")
    parser.add_argument("--with", dest="with_json", nargs="+", default=[],
                        help="JSON files of earlier runs (--json) whose rows of that actor the plot adds")
    args = parser.parse_args()
    if args.activities not in (["sneak", "jog"], ["jog", "sneak"], ["sneak"]):
        parser.error("--activities: 'sneak jog' (trained together) or 'sneak' (the test take's first activity alone)")
    both = "jog" in args.activities
    key = jax.random.key(args.seed)
    takes = {actor: takes_of(args.data, actor) for actor in ACTORS}
    everything = [t for actor in ACTORS for activity in ("sneak", "jog") for t in takes[actor][activity]]
    sequences = convert_takes(everything, args.data, os.path.join(args.work, "converted"), seed=args.seed)
    rows = []
    for actor in args.actors:
        own = takes[actor]
        test_sneak, test_jog, validation_jog = own["sneak"][-1], own["jog"][0], own["jog"][-1]
        train = [sequences[takes[a]["sneak"][0].name] for a in ACTORS]  # the test actor's last sneak is its test
        for a in ACTORS if both else ():  # the test actor's first jog is its test, its last its validation: a middle one if any
            jogs = takes[a]["jog"] if a != actor else takes[a]["jog"][1:-1]
            train += [sequences[jogs[0].name]] if jogs else []
        if not both:  # single-activity: validated on a sneak (the middle one, else the first, which is also in training)
            sneaks = own["sneak"]
            validation_take = sneaks[1] if len(sneaks) > 2 else sneaks[0]
        else:
            validation_take = validation_jog
        blended, join = switching_take(sequences[test_sneak.name], sequences[test_jog.name])
        scene = render_test_take(jax.random.fold_in(key, 900), blended, views=4)
        total = scene.num_frames
        config = ExperimentConfig(methods=tuple(args.methods), budget=args.budget, runs=args.runs, seed=args.seed)
        names = {"train": [f"{s.subject} {i}" for i, s in enumerate(train)], "validation": [f"{actor} validation"],
                 "test": [f"{actor} sneak to jog"]}
        results = run_experiment(train, [sequences[validation_take.name]], [scene], config, names=names, progress=False)
        segments = {"sneak": slice(0, join), "fade": slice(join, join + FADE), "jog": slice(join + FADE, total)}
        for method in args.methods:
            entry = results["sequences"][f"{actor} sneak to jog"].get(method)
            if entry is None:
                print(f"{actor} {method}: refused: {results['refused'].get(method)}", flush=True)
                continue
            curves = np.asarray(entry["per_frame_error_mm_per_run"])
            row = {"actor": actor, "method": method, "trained_on": "+".join(args.activities), "frames": [join, FADE, total - join - FADE]}
            row |= {name: round(float(curves[:, part].mean()), 1) for name, part in segments.items()}
            row["all"] = round(float(curves.mean()), 1)
            row["sd_over_runs"] = round(float(curves.mean(axis=1).std()), 1)
            print(json.dumps(row), flush=True)
            row["curves_mm"] = np.round(curves, 1).tolist()  # (runs, frames), for --plot
            rows.append(row)
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(rows, indent=1))
    if args.plot:
        earlier = [row for path in args.with_json for row in json.loads(pathlib.Path(path).read_text())]
        plot_curves([r for r in earlier + rows if r["actor"] == args.actors[0] and "curves_mm" in r], args.plot)


def plot_curves(rows, path: str, ceiling: float = 400.0) -> None:
    """Each row's error per frame: the median over its runs, shaded from the best run to the worst,
    with the cross-fade between the two activities shaded grey; errors over ``ceiling`` mm (a
    tracker that has left the person) run off the top."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from jaxtrack.tracking import get_tracker

    fig, ax = plt.subplots(figsize=(7.5, 3.8))
    for row in rows:
        curves = np.asarray(row["curves_mm"])
        frames = np.arange(curves.shape[1])
        label = f"{get_tracker(row['method']).label}, trained on {row['trained_on'].replace('+', ' and ')}"
        line, = ax.plot(frames, np.median(curves, axis=0), lw=1.4, label=label)
        ax.fill_between(frames, curves.min(axis=0), curves.max(axis=0), color=line.get_color(), alpha=0.15, lw=0)
    join, fade, _ = rows[0]["frames"]
    ax.axvspan(join, join + fade, color="0.85", zorder=0)
    ax.text(join / 2, 0.92 * ceiling, "sneak", ha="center")
    ax.text(join + fade + (len(frames) - join - fade) / 2, 0.92 * ceiling, "jog", ha="center")
    ax.set_ylim(0, ceiling)
    ax.set_xlabel("frame (60 Hz)")
    ax.set_ylabel("mean joint error (mm)")
    ax.set_title(f"HDM05 {rows[0]['actor']}: a sneak into a jog, 4 views of 80x60 (median of the runs, range shaded)", fontsize=9)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=len(rows), frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()

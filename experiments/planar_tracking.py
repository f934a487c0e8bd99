"""Paper 003 sec. 5.2 on rendered monocular videos (docs/planar.md): the latent Condensation
(``latentpf2d``) against standard Condensation (``condensation2d``) and the multiple-hypothesis
tracker (``mht2d``) on the shoulder-anchored arm chain.

    taskset -c 0,1 python experiments/planar_tracking.py --runs 5 --frames 150 --json planar.json \
        --plot docs/figures/planar_errors.png --overlay docs/figures/planar_overlay.png

Training: two takes of ``data.signalling_motion`` (keys 0 and 1, 300 frames at 30 Hz, the default
body) seen from the training view sphere, every 3rd frame (``planar.fit_spm_model``). Test: takes
of another key (100 + i) by a subject with other limb lengths (``planar.TEST_LIMBS``), drawn by
the solid body over a photograph by one 320x240 camera at each of ``planar.TEST_VIEWS`` (none a
training view), 2.2 m away and looking at a point 1.45 m high. Every tracker starts at the true markers of frame 0 and takes its
templates there. Errors are mean distances in pixels over the 9 markers and over the 4 arm
markers (elbows, wrists); a frame counts as tracked when its arm markers' mean error is under a
quarter of the true spine-to-neck height in that frame (about 22 px). Each row also says in how
many frames the template likelihood scores the true markers above the tracker's estimate (a
tracker that loses the arms while the truth scores higher lost them for want of a particle near
the truth, not because the likelihood preferred its estimate).

``--test-body default --train-on-test`` is 003's own regime: the person is the training body and
the test takes' motion is among the training takes (the viewpoints stay unseen).
"""

import argparse
import json
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxtrack.planar as planar
from jaxtrack.data import signalling_motion
from jaxtrack.image import fit_background, rgb_to_grey, subtract_background

METHODS = ("latentpf2d", "condensation2d", "mht2d")
TRACKED_SHARE = 0.25
ARM_MARKERS = [planar.SPM_MARKERS.index(m) for m in ("lelbow", "lwrist", "relbow", "rwrist")]


def test_motion(v, frames, body, transition=(0.4, 1.2)):
    """The 3-D motion of test video ``v`` (as ``planar.gesture_video`` makes it)."""
    limbs = planar.TEST_LIMBS if body == "test" else None
    return signalling_motion(jax.random.fold_in(jax.random.key(100 + v), 0), num_frames=frames, limb_lengths=limbs,
                             transition=transition)


def fit_model(latent_dim=3, every=3, extra=()):
    """The SPM model of two training takes (keys 0 and 1) and ``extra`` 3-D joint sequences."""
    train = [signalling_motion(jax.random.key(s), num_frames=300).joints3d for s in range(2)] + list(extra)
    return planar.fit_spm_model(train, latent_dim=latent_dim, every=every)


def run(method, model, video, key, options=None, masks=None):
    grey = np.asarray(rgb_to_grey(video.images), np.float32)
    tracker = planar.get_tracker2d(method).build(model, grey[0], video.markers[0], **(options or {}))
    start = time.perf_counter()
    _carry, markers = planar.track_frames(tracker, grey[1:], key, masks=None if masks is None else masks[1:])
    markers = np.asarray(markers)
    seconds = time.perf_counter() - start
    markers = np.concatenate([np.asarray(video.markers[:1]), markers])
    distances = np.linalg.norm(markers - video.markers, axis=-1)
    errors = distances.mean(axis=-1)
    arm_errors = distances[:, ARM_MARKERS].mean(axis=-1)
    size = np.asarray(planar.spine_to_neck(jnp.asarray(video.markers)))
    # Does the likelihood rank the truth above the estimate? (frames 1..T-1, the first frame's templates)
    score = jax.jit(jax.vmap(tracker.templates.log_likelihood))
    truth_higher = float(np.mean(np.asarray(score(jnp.asarray(grey[1:]), jnp.asarray(video.markers[1:], grey.dtype)))
                                 > np.asarray(score(jnp.asarray(grey[1:]), jnp.asarray(markers[1:], grey.dtype)))))
    return markers, errors, arm_errors, arm_errors < TRACKED_SHARE * size, seconds, truth_higher


def manifold_floor(model, video, every=5, candidates=(1.0, 0.95, 0.9, 0.85, 0.8, 0.75, 0.7)):
    """The best the latent tracker can do on this manifold: each true frame's markers encoded
    as ``planar.start_state`` does (the pose projected onto the manifold, the scale searched; all
    frames in one batched ``encode``) and decoded; mean errors (px) over 9 markers and over the
    arm markers."""
    markers = jnp.asarray(video.markers[::every], jnp.float64)  # (T, 9, 2)
    spine = planar.spine_to_neck(markers)  # (T,)
    shares = jnp.asarray(candidates, jnp.float64)
    scales = spine[:, None] / (planar.SPM_REFERENCE_LENGTHS[0] * shares[None])  # (T, K)
    states = jax.vmap(lambda m, s: jax.vmap(lambda x: planar.spm_from_markers(m, x))(s))(markers, scales)  # (T, K, 19)
    flat = states.reshape(-1, planar.SPM_STATE_DIM)
    latent = model.manifold.encode(planar.spm_features(flat))
    features, _ = model.manifold.predictor()(latent)
    decoded = planar.spm_forward(planar.spm_state(features, flat[:, :2], flat[:, 2])).reshape(states.shape[:2] + (9, 2))
    distance = jnp.linalg.norm(decoded - markers[:, None], axis=-1)  # (T, K, 9)
    best = jnp.argmin(distance.mean(-1), axis=1)
    chosen = np.asarray(jnp.take_along_axis(distance, best[:, None, None], axis=1)[:, 0])  # (T, 9)
    return float(chosen.mean()), float(chosen[:, ARM_MARKERS].mean())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--views", type=int, nargs="*", default=list(range(len(planar.TEST_VIEWS))))
    parser.add_argument("--methods", nargs="*", default=list(METHODS))
    parser.add_argument("--model", help="a saved SPM model (else fitted, and saved to --save-model)")
    parser.add_argument("--save-model")
    parser.add_argument("--latent-dim", type=int, default=3)
    parser.add_argument("--every", type=int, default=3, help="training frames kept (every n-th)")
    parser.add_argument("--option", action="append", default=[], help="METHOD:KEY=VALUE, a tracker option")
    parser.add_argument("--background", choices=planar.BACKGROUNDS, default="photo")
    parser.add_argument("--transition", type=float, nargs=2, default=(0.4, 1.2), metavar=("SHORTEST", "LONGEST"),
                        help="the test takes' seconds between key postures (training keeps 0.4 1.2)")
    parser.add_argument("--test-body", choices=("test", "default"), default="test",
                        help="the person in the test videos: the test subject (planar.TEST_LIMBS) or the training body")
    parser.add_argument("--train-on-test", action="store_true",
                        help="003's own regime: the test takes' 3-D motion is added to the training takes (the test "
                             "videos' viewpoints stay unseen)")
    parser.add_argument("--silhouettes", action="store_true",
                        help="beyond 003: every tracker also scores the silhouette of a background subtraction (the "
                             "video's frames of the empty scene as the background)")
    parser.add_argument("--sidestep", type=float, default=0.0,
                        help="metres: the test person steps from side to side (planar.gesture_video's sidestep)")
    parser.add_argument("--key-base", type=int, default=100,
                        help="test video v is made with key KEY_BASE + v (100: the test takes; 200: the tuning takes)")
    parser.add_argument("--floor", action="store_true", help="also print the manifold's encode-decode error of each video")
    parser.add_argument("--json")
    parser.add_argument("--plot")
    parser.add_argument("--overlay")
    args = parser.parse_args()
    jax.config.update("jax_enable_x64", True)

    if args.model:
        model = planar.load_spm_model(args.model)
    else:
        start = time.perf_counter()
        extra = [test_motion(v, args.frames, args.test_body, tuple(args.transition)).joints3d
                 for v in args.views] if args.train_on_test else ()
        model, starts = fit_model(args.latent_dim, args.every, extra)
        print(f"fitted the SPM model in {time.perf_counter() - start:.0f} s: nu {np.asarray(model.step_sd).round(3)}")
        if args.save_model:
            planar.save_spm_model(args.save_model, model, starts)
    options = {}
    for item in args.option:
        method, setting = item.split(":", 1)
        key, value = setting.split("=", 1)
        options.setdefault(method, {})[key] = value if key in ("estimate", "start") else float(value)
    results, curves = {}, {}
    for v in args.views:
        view = planar.TEST_VIEWS[v]
        video = planar.gesture_video(jax.random.key(args.key_base + v), view=view, sidestep=args.sidestep, frames=args.frames,
                                     background=args.background,
                                     transition=tuple(args.transition),
                                     limb_lengths=planar.TEST_LIMBS if args.test_body == "test" else None)
        masks = None
        if args.silhouettes:
            masks = np.asarray(subtract_background(fit_background(video.background), video.images).mask)
            iou = np.sum(masks & video.masks, axis=(1, 2)) / np.maximum(np.sum(masks | video.masks, axis=(1, 2)), 1)
            print(f"{args.background}, az {view[0]:g} el {view[1]:g}: background subtraction, IoU with the true "
                  f"silhouettes {iou.mean():.3f} (median {np.median(iou):.3f})")
        if args.floor:
            floor, floor_arms = manifold_floor(model, video)
            print(f"{args.background}, az {view[0]:g} el {view[1]:g}: the manifold's floor (true markers encoded and decoded, "
                  f"every 5th frame): {floor:.1f} px, arms {floor_arms:.1f} px")
        slow = "" if tuple(args.transition) == (0.4, 1.2) else f", {args.transition[0]:g}-{args.transition[1]:g} s"
        regime = (", training body" if args.test_body == "default" else "") + (", poses trained" if args.train_on_test else "")
        regime += (f", sidestep {args.sidestep:g} m" if args.sidestep else "")
        regime += (", silhouettes" if args.silhouettes else "") + ("" if args.key_base == 100 else f", keys {args.key_base}+")
        name = f"{args.background}{slow}{regime}, az {view[0]:g} el {view[1]:g}"
        for method in args.methods:
            rows = []
            for r in range(args.runs):
                markers, errors, arm_errors, tracked, seconds, truth_higher = run(method, model, video, jax.random.key(1000 * v + r),
                                                                                  options.get(method), masks)
                rows.append({"mean_px": float(errors.mean()), "arm_px": float(arm_errors.mean()), "tracked": float(tracked.mean()),
                             "truth_scores_higher": truth_higher,
                             "first_lost": int(np.argmin(tracked)) if not tracked.all() else len(tracked),
                             "ms_per_frame": 1000 * seconds / (len(errors) - 1)})
                curves.setdefault((name, method), []).append(arm_errors)
                if args.overlay and r == 0 and v == args.views[0]:
                    curves.setdefault(("overlay", method), markers)
            results.setdefault(name, {})[method] = rows
            mean = np.mean([x["mean_px"] for x in rows])
            arm = np.mean([x["arm_px"] for x in rows])
            tracked = np.mean([x["tracked"] for x in rows])
            ms = np.median([x["ms_per_frame"] for x in rows[1:]] or [rows[0]["ms_per_frame"]])
            higher = np.mean([x["truth_scores_higher"] for x in rows])
            print(f"{name:30s} {method:15s} {mean:6.1f} px, arms {arm:6.1f} px, tracked {100 * tracked:5.1f} %, "
                  f"{ms:7.2f} ms/frame (median, warm); the truth scores above the estimate in {100 * higher:.0f} % of the frames")
        if args.overlay and v == args.views[0]:
            overlay(args.overlay, video, {m: curves[("overlay", m)] for m in args.methods})
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"tracked_share": TRACKED_SHARE, "results": results}, handle, indent=1)
    if args.plot:
        plot(args.plot, curves, args.methods)


def plot(path, curves, methods):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = sorted({n for n, _ in curves if n != "overlay"})
    fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names), 3.2), sharey=True, squeeze=False)
    for ax, name in zip(axes[0], names):
        for method in methods:
            errors = np.stack(curves[(name, method)])
            ax.plot(np.median(errors, 0), label=method)
            ax.fill_between(np.arange(errors.shape[1]), errors.min(0), errors.max(0), alpha=0.2)
        ax.set_title(name)
        ax.set_xlabel("frame")
    axes[0, 0].set_ylabel("arm markers' mean error (px)")
    axes[0, 0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def overlay(path, video, tracks):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = np.linspace(0, len(video.images) - 1, 5).astype(int)
    fig, axes = plt.subplots(len(tracks), len(frames), figsize=(2.6 * len(frames), 2.1 * len(tracks)), squeeze=False)
    links = [(planar.SPM_MARKERS.index(a), planar.SPM_MARKERS.index(b)) for _, _, a, b in planar.SPM_LINKS]
    for row, (method, markers) in enumerate(tracks.items()):
        for ax, f in zip(axes[row], frames):
            ax.imshow(video.images[f])
            for a, b in links:
                ax.plot(*video.markers[f, [a, b]].T, color="white", lw=1)
                ax.plot(*markers[f, [a, b]].T, color="lime", lw=1.5)
            ax.set_xticks([])
            ax.set_yticks([])
            if row == 0:
                ax.set_title(f"frame {f}")
        axes[row, 0].set_ylabel(method)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()

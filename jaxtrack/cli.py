"""Command-line entry point: ``jaxtrack demo``, ``render``, ``convert``, ``scene``, ``fit``,
``plot-latent``, ``experiment`` and ``track``. Tracker names come from the registry
(``jaxtrack.tracking.available_trackers()``); ``--plugin`` imports a module that registers more."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import sys
import threading


def _demo(args) -> int:
    from .demo import run_demo, run_likelihood_demo
    from .io import check_folder

    check_folder(args.out)

    if args.show_likelihood:
        run_likelihood_demo(args.out, seed=args.seed, num_frames=args.frames or 60, particles=args.budget or 500)
    else:
        run_demo(args.out, seed=args.seed, frames=args.frames or 40, budget=args.budget or 300, runs=args.runs,
                 ground_prior=args.ground_prior)
    return 0


def _render(args) -> int:
    from .errors import SequenceFileError
    from .io import check_output, load_sequence
    from .viz import animation, contact_sheet

    stem = args.out or os.path.splitext(args.sequence)[0]
    for suffix in ("_sheet.png", ".gif"):
        check_output(stem + suffix, [args.sequence, args.estimate])
    sequence = load_sequence(args.sequence)
    estimate = None
    if args.estimate:
        estimate = load_sequence(args.estimate).joints3d
        if estimate is None:
            raise SequenceFileError(f"{args.estimate}: has no joints3d to draw as the estimate")
        if estimate.shape[:2] != (sequence.num_frames, sequence.joints3d.shape[1] if sequence.joints3d is not None else estimate.shape[1]):
            raise SequenceFileError(f"{args.estimate}: its joints3d are {estimate.shape[0]} frames of {estimate.shape[1]} joints, but "
                                    f"{args.sequence} has {sequence.num_frames} frames"
                                    + (f" of {sequence.joints3d.shape[1]} joints" if sequence.joints3d is not None else "")
                                    + ": draw an estimate over the sequence it was tracked on")
    sheet = contact_sheet(sequence, stem + "_sheet.png", estimate=estimate)
    gif = animation(sequence, stem + ".gif", estimate=estimate, scale=args.scale, every=args.every)
    print(f"wrote {sheet} and {gif}")
    return 0


def _convert(args) -> int:
    import json

    from .errors import ConfigurationError
    from .io import check_output, convert_motion

    args.out = check_output(args.out, [args.source, args.asf, args.mapping], suffix=".npz")
    mapping = None
    if args.mapping:
        with open(args.mapping, encoding="utf-8") as handle:
            try:
                mapping = json.load(handle)
            except json.JSONDecodeError as err:
                raise ConfigurationError(f"{args.mapping}:{err.lineno}: not valid JSON ({err.msg}, column {err.colno})") from None
    report = convert_motion(
        args.source, args.out, fps=args.fps, asf=args.asf, source_fps=args.source_fps, mapping=mapping, seed=args.seed,
        level_floor=args.level_floor, verbose=True
    )
    print(
        f"wrote {args.out}: {report.num_frames} frames at {report.sequence.fps:g} Hz; inverse-kinematics residual "
        f"mean {report.mean_residual_mm:.1f} mm, max {report.max_residual_mm:.1f} mm"
    )
    print(f"{'warning: ' if report.residual.pattern != 'floor' else ''}{report.residual.describe()}")
    if not report.levelled and report.floor.worth_levelling:
        print(f"note: {report.floor.describe()}; the trackers' floor is level (pass --level-floor to level the motion)")
    return 0


def _scene(args) -> int:
    import jax

    from .camera import default_rig
    from .data import NO_NOISE, SilhouetteNoise, scene_from_sequence
    from .io import check_folder, check_output, load_sequence, save_sequence

    if args.rgb != bool(args.video):
        raise ValueError("--rgb films the scene into videos: give both --rgb and --video OUTDIR")
    if args.video:
        if args.out:
            raise ValueError(f"--video writes its files into {args.video}; drop the output file {args.out}")
        check_folder(args.video)
    elif not args.out:
        raise ValueError("give the output sequence file (or --rgb --video OUTDIR)")
    else:
        args.out = check_output(args.out, [args.source], suffix=".npz")
    sequence = load_sequence(args.source)
    rig = default_rig(args.width, args.height, num_views=args.views)
    noise = NO_NOISE if args.clean or args.video else SilhouetteNoise()
    detector = None
    if args.keypoints or args.video:
        from .data import DetectorNoise, detect_keypoints

        detector = DetectorNoise(noise_px=args.keypoint_noise, dropped=args.keypoint_dropped, swapped=args.keypoint_swapped)
    scene = scene_from_sequence(jax.random.key(args.seed), sequence, rig, noise, start=args.start, frames=args.frames,
                                centre=not args.no_centre, progress=not args.video)
    if args.video:
        from .data import write_rgb_scene

        paths = write_rgb_scene(args.video, jax.random.key(args.seed), scene, detector=detector,
                                background_frames=args.background_frames, progress=True)
        print(f"wrote {scene.num_frames} frames at {scene.fps:g} Hz of {args.views} {args.width}x{args.height} cameras into "
              f"{args.video}: videos {', '.join(os.path.basename(p) for p in paths['videos'])}"
              + (f", {args.background_frames} background frames per camera in background/" if args.background_frames else "")
              + f", calibration.json, keypoints.npz ({detector.noise_px:g} px noise, {detector.dropped:.0%} dropped) and truth.npz "
              "(poses, joints and the true silhouettes)")
        return 0
    if detector is not None:
        scene = scene.replace(keypoints2d=detect_keypoints(jax.random.fold_in(jax.random.key(args.seed), 1), scene.joints3d,
                                                           scene.rig(), detector))
    save_sequence(args.out, scene)
    print(f"wrote {args.out}: {scene.num_frames} frames at {scene.fps:g} Hz in {args.views} "
          f"{'clean' if args.clean else 'noisy'} {args.width}x{args.height} silhouette views"
          + ("" if detector is None else f", with 2-D keypoints ({detector.noise_px:g} px noise, {detector.dropped:.0%} dropped, "
                                         f"{detector.swapped:.0%} of views' frames left-right swapped)"))
    return 0


def _keypoints(args) -> int:
    from .io import check_output, keypoint_format_of, load_sequence, read_keypoint_sources, save_sequence

    args.out = check_output(args.out, [args.sequence, *args.sources, *(args.calibration or [])], suffix=".npz")
    sequence = load_sequence(args.sequence)
    if args.calibration:
        import numpy as np

        from .io import read_calibration

        rig = read_calibration(args.calibration, units=args.units, up=args.up, dtype=np.float64)
        sequence = sequence.replace(camera_K=np.asarray(rig.K), camera_R=np.asarray(rig.R), camera_t=np.asarray(rig.t),
                                    camera_dist=np.asarray(rig.dist), image_size=np.asarray(rig.image_size),
                                    camera_names=np.asarray(rig.names))
        print(f"cameras from {', '.join(args.calibration)}: {', '.join(rig.names)}")
    if not sequence.has_cameras:
        raise ValueError(f"{args.sequence}: has no cameras; give the calibration (--calibration), 2-D keypoints are read per camera")
    views = len(sequence.image_size)
    names = None if sequence.camera_names is None else [str(n) for n in sequence.camera_names]
    one_file = (args.format or keypoint_format_of(args.sources)) == "npz"  # its camera names are its own
    keypoints = read_keypoint_sources(args.sources, args.format, layout=args.layout, say=print,
                                      camera_names=names or (None if one_file else [str(c) for c in range(views)]))
    if keypoints.shape[0] != views:
        raise ValueError(f"{args.sources[0]}: keypoints of {keypoints.shape[0]} cameras, {args.sequence} has {views}")
    if keypoints.shape[1] != sequence.num_frames:
        raise ValueError(f"the keypoints hold {keypoints.shape[1]} frames, {args.sequence} {sequence.num_frames}")
    save_sequence(args.out, sequence.replace(keypoints2d=keypoints))
    seen = float((keypoints[..., 2] > 0).mean())
    print(f"wrote {args.out}: {args.sequence} with 2-D keypoints of {views} cameras x {keypoints.shape[1]} frames "
          f"({seen:.0%} of the joints detected)")
    return 0


def _fit(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)  # GP training in float64
    import numpy as np

    from .body import GLOBAL_DOFS
    from .io import check_output, load_sequence
    from .manifold import check_training_data, get_manifold_kind, save_model
    from .tracking import MOTION_KEY, fit_manifold, motion_record

    args.out = check_output(args.out, args.motion)
    if args.model == "spm-gplvm":
        return _fit_spm(args)
    with_vlmm = args.model == "vlmm"  # 004: a BC-GPLVM, its prototypes and their automaton in one file
    kind = get_manifold_kind(args.vlmm_manifold if with_vlmm else args.model)
    options = _options(args.manifold_option, kind.options, f"manifold kind {kind.name!r}")
    if args.inducing is not None:
        if "num_inducing" not in kind.options:
            raise ValueError(f"--inducing is an option of sparse-gplvm and sparse-bc-gplvm, not of {kind.name}")
        options["num_inducing"] = args.inducing
    poses, names, layouts, takes = [], [], set(), []
    for path in args.motion:
        seq = load_sequence(path)
        takes.append(seq)
        if seq.pose is None:
            raise ValueError(f"{path}: has no 'pose' key (make one with 'jaxtrack convert')")
        layouts.add(tuple(str(n) for n in seq.pose_layout))
        check_training_data(seq.pose, 1, name=f"{path}: 'pose'")  # before any fitting, naming the file
        poses.append(np.asarray(seq.pose, np.float64))
        names.append(os.path.basename(path))
    if len(layouts) != 1 or len({p.shape[1] for p in poses}) != 1:
        raise ValueError("the motion files have different pose layouts")
    # The manifold models joint angles only, not the global position and orientation: the same
    # fit as ``jaxtrack experiment``'s (tracking.fit_manifold, the key from --seed).
    latent_dim = args.latent_dim
    if with_vlmm and latent_dim is None:
        from .tracking import get_tracker

        latent_dim = get_tracker("vlmmpf").latent_dim
    fitted, info, starts = fit_manifold(poses, latent_dim, args.steps, kind=kind.name, progress=True,
                                        optimiser=args.optimiser, key=jax.random.key(args.seed), **options)
    kept_layout = list(next(iter(layouts)))[GLOBAL_DOFS:]
    extra = {"pose_layout": kept_layout, "sequences": names,
             MOTION_KEY: motion_record(takes, names)}  # what track fits the dynamics on when no --validation is given
    if with_vlmm:
        from .dynamics import fit_vlmm_dynamics, vlmm_to_record
        from .manifold import make_manifold_prior

        # The global entries' walk is fitted on the same motion (experiment and track fit it on
        # their validation files instead).
        prior = make_manifold_prior(fitted, poses[0].shape[1])
        dynamics, _ = fit_vlmm_dynamics(prior, poses, starts, key=jax.random.key(args.seed))
        extra["vlmm"] = vlmm_to_record(dynamics)
        print(f"{dynamics.prototypes.num_components} motion prototypes, a VLMM of {dynamics.vlmm.num_states} states "
              f"(004 sec. 5)")
    save_model(args.out, fitted, sequence_starts=starts, extra=extra)
    print(f"wrote {args.out}: {type(fitted).__name__}, {starts[-1]} frames, objective {info.objective:.6g} after {info.steps} steps")
    return 0


def _fit_spm(args) -> int:
    """``jaxtrack fit --model spm-gplvm``: 3-D joints seen from the view sphere as SPM poses, 003's
    active-set GPLVM, its latent random walk and the baselines' AR(2), in one file."""
    import numpy as np

    from .io import load_sequence
    from .planar import fit_spm_model, save_spm_model

    options = _options(args.manifold_option, {"active": 200, "every": 3, "iterations": 3}, "spm-gplvm")
    joints = []
    for path in args.motion:
        seq = load_sequence(path)
        if seq.joints3d is None:
            raise ValueError(f"{path}: has no 'joints3d' key (3-D joints are what the view sphere projects)")
        names = [str(n) for n in seq.joint_names]
        from .planar import SPM_MARKERS

        missing = [m for m in SPM_MARKERS if m not in names]
        if missing:
            raise ValueError(f"{path}: its joints lack the SPM markers {', '.join(missing)}")
        full = np.asarray(seq.joints3d, np.float64)
        from .body import HUMANEVA_JOINTS

        index = [names.index(m) if m in names else 0 for m in HUMANEVA_JOINTS]
        joints.append(full[:, index])
    model, starts = fit_spm_model(joints, latent_dim=args.latent_dim or 3, active=options.get("active", 200),
                                  every=options.get("every", 3), iterations=options.get("iterations", 3), max_steps=args.steps,
                                  progress=True)
    save_spm_model(args.out, model, starts)
    print(f"wrote {args.out}: ActiveSetGPLVM of {starts[-1]} SPM poses (active set {model.manifold.active.shape[0]}), "
          f"latent step sd {np.round(np.asarray(model.step_sd), 4).tolist()}")
    return 0


def _track2d(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)  # models are saved in float64
    import numpy as np

    from .io import VideoWriter, atomic_write, check_output
    from .planar import SPM_MARKERS, draw_markers, get_tracker2d, load_spm_model, read_first_markers, track_video

    out = check_output(args.out, [args.video, args.markers, args.model] + ([args.background] if args.background else []),
                       suffix=".npz")
    overlay = None if args.no_overlay else check_output(os.path.splitext(out)[0] + "_overlay.mp4", [args.video])
    model = load_spm_model(args.model)
    first = read_first_markers(args.markers)

    def save(markers):
        with atomic_write(out) as handle:
            np.savez(handle, markers2d=np.asarray(markers, np.float64), marker_names=np.array(SPM_MARKERS))

    writer = None
    try:
        def on_chunk(first_frame, rgb, markers):
            nonlocal writer
            save(markers)
            if overlay is not None:
                if writer is None:
                    writer = VideoWriter([overlay], fps=args.fps)
                drawn = draw_markers(rgb[: len(markers) - first_frame], markers[first_frame:])
                even = drawn[:, : drawn.shape[1] // 2 * 2, : drawn.shape[2] // 2 * 2]
                writer.write(even[None])

        options = _options(args.option, get_tracker2d(args.method).options, args.method)
        markers = track_video(args.method, model, args.video, first, key=jax.random.key(args.seed), frames=args.frames,
                              chunk=args.chunk_frames, on_chunk=on_chunk, options=options, background=args.background)
    finally:
        if writer is not None:
            writer.close()
    print(f"wrote {out}: {len(markers)} frames of {len(SPM_MARKERS)} markers ({args.method})"
          + (f", and {overlay}" if overlay else ""))
    return 0


def _options(pairs, defaults, what: str) -> dict:
    """``KEY=VALUE`` strings as options of ``what``, each value parsed as the type of its default."""
    options = {}
    for pair in pairs or ():
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ValueError(f"an option is KEY=VALUE, got {pair!r}")
        if key not in defaults:
            raise ValueError(f"{what} takes no option {key!r} (it takes: {', '.join(defaults) or 'none'})")
        default = defaults[key]
        try:
            if isinstance(default, bool):
                if value.lower() not in ("true", "false", "1", "0", "yes", "no"):
                    raise ValueError(value)
                options[key] = value.lower() in ("true", "1", "yes")
            elif isinstance(default, (int, float)):
                options[key] = type(default)(value)
            else:
                options[key] = value
        except ValueError:
            raise ValueError(f"option {key} of {what} must be a {type(default).__name__}, got {value!r}") from None
    return options


def _plot_latent(args) -> int:
    import jax

    jax.config.update("jax_enable_x64", True)  # models are saved in float64
    import numpy as np

    from .body import GLOBAL_DOFS
    from .io import check_output
    from .manifold import load_model, plot_latent

    out = check_output(args.out or os.path.splitext(args.model)[0] + "_latent.png", [args.model])
    model, header = load_model(args.model)
    plot_latent(model, out, sequence_starts=header["sequence_starts"], labels=header["extra"].get("sequences"))
    print(f"wrote {out}")
    record = header["extra"].get("vlmm")
    if record is not None:  # a file of jaxtrack fit --model vlmm: its prototypes too
        from .dynamics import augmented_latent, plot_prototypes, vlmm_from_record
        from .manifold import make_manifold_prior

        prior = make_manifold_prior(model, GLOBAL_DOFS + model.data_dim)
        dynamics = vlmm_from_record(record, prior)
        augmented = augmented_latent(np.asarray(prior.training_latent), header["sequence_starts"])
        labels = np.asarray(dynamics.prototypes.labels(jax.numpy.asarray(augmented)))
        path = check_output(os.path.splitext(out)[0] + "_prototypes.png", [args.model])
        plot_prototypes(dynamics, augmented, labels, path)
        print(f"wrote {path}")
    return 0


def _load_sequences(paths):
    from .io import load_sequence

    return [load_sequence(p) for p in paths], [os.path.basename(p) for p in paths]


def _experiment(args) -> int:
    from .experiment import ExperimentConfig, results_table, run_experiment

    config = ExperimentConfig(
        methods=tuple(args.methods), runs=args.runs, frames=args.frames, seed=args.seed, batch_runs=args.batch_runs,
        latent_dim=args.latent_dim, fit_steps=args.fit_steps, fit_optimiser=args.fit_optimiser, manifold=args.manifold,
        start=args.start, **_spec_fields(args),
    )
    from .io import check_folder

    inputs = [*args.train, *args.validation, *args.test]
    if any(os.path.exists(p) and os.path.exists(args.out) and os.path.samefile(p, args.out) for p in inputs):
        raise ValueError(f"{args.out}: is one of the input files; --out names the output folder")
    check_folder(args.out)
    train, train_names = _load_sequences(args.train)
    validation, validation_names = _load_sequences(args.validation)
    test, test_names = _load_sequences(args.test)
    names = {"train": train_names, "validation": validation_names, "test": test_names}
    results = run_experiment(train, validation, test, config, out_dir=args.out, names=names, animations=not args.no_animation)
    print()
    print(results_table(results))
    print(f"wrote {os.path.join(args.out, 'results.json')}, table.md, error_curves.png")
    if results["refused"]:
        print("jaxtrack experiment: error: " + "; ".join(f"{m} refused: {why}" for m, why in results["refused"].items())
              + " (the other methods' results are written)", file=sys.stderr)
        return 2
    return 0


def _image_size(text: str) -> tuple[int, int]:
    """``WxH`` in pixels, each side 8..``MAX_IMAGE_SIDE``."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels (e.g. 80x60), got {text!r}") from None
    if not all(8 <= v <= MAX_IMAGE_SIDE for v in (width, height)):
        raise argparse.ArgumentTypeError(f"each side must be 8 to {MAX_IMAGE_SIDE} pixels, got {text!r}")
    return width, height


def _protocol(args) -> int:
    from .experiment import ExperimentConfig, get_protocol, run_protocol
    from .io import check_folder

    config = ExperimentConfig(
        methods=tuple(args.methods), runs=args.runs, seed=args.seed, batch_runs=args.batch_runs, latent_dim=args.latent_dim,
        fit_steps=args.fit_steps, fit_optimiser=args.fit_optimiser, manifold=args.manifold, start=args.start,
        **_spec_fields(args),
    )
    protocol = get_protocol(args.name)
    if args.without:
        protocol = protocol.without(*args.without)
    if args.subjects:
        for subject in args.subjects:
            protocol.subject(subject)  # unknown names refused before any work
    if not os.path.isdir(args.data):
        raise FileNotFoundError(f"{args.data}: no such folder (--data: the shared motion capture, with cmu35/ and multi_subject/)")
    check_folder(args.out)
    rows = run_protocol(protocol, args.data, args.out, config, modes=tuple(args.modes), subjects=args.subjects, views=args.views,
                        size=args.image_size, renderer=args.renderer,
                        azimuth=args.azimuth[0] if len(args.azimuth) == 1 else args.azimuth, centre=args.centre_subjects,
                        level_floor=args.level_floor, progress=True)
    from .experiment import protocol_table

    print()
    print(protocol_table(rows, title=f"{protocol.name}: {protocol.description}"))
    print(f"wrote {os.path.join(args.out, 'protocol.json')} and table.md (each fold's experiment in its own folder)")
    refused = sorted({f"{r['mode']}-{r['subject']} {m}" for r in rows for m in r["refused"]})
    if refused:
        print("jaxtrack protocol: error: refused: " + "; ".join(refused) + " (the other methods' results are written)", file=sys.stderr)
        return 2
    return 0


def _body_choice(args) -> str:
    """``--body``, or "calibrate" with ``--calibrate-body``."""
    if args.calibrate_body:
        if args.body not in (None, "calibrate"):
            raise ValueError(f"--calibrate-body and --body {args.body} contradict each other")
        return "calibrate"
    return args.body or "auto"


def _video_test(args):
    """``track --video``: the calibration, keypoints and videos read into a test sequence."""
    import numpy as np

    from .io import MultiViewVideo, VideoFileError, read_calibration, read_keypoint_people
    from .likelihood import DEFAULT_LIKELIHOOD, get_likelihood
    from .tracking import associated_keypoints, open_video

    if args.test:
        raise ValueError(f"give a test sequence file ({args.test}) or --video, not both")
    if not args.calibration:
        raise ValueError("--video needs the cameras: --calibration FILE [FILE ...] (JSON, OpenCV YAML/XML or TOML)")
    with MultiViewVideo(args.video) as video:  # each video's size, for a calibration that gives none
        sizes = video.sizes
    rig = read_calibration(args.calibration, units=args.units, up=args.up, dtype=np.float64, image_sizes=sizes, say=print)
    print(f"cameras from {', '.join(args.calibration)}: {', '.join(rig.names)}")
    keypoints = None
    if args.keypoints:
        keypoints, file_format = read_keypoint_people(args.keypoints, args.keypoint_format, layout=args.keypoint_layout,
                                                      camera_names=rig.names, say=print)
        if file_format != "npz":  # every person each detector found: one followed across the cameras
            fps = args.fps or video.fps
            if fps is None:
                raise ValueError("image folders do not say their frame rate: give --fps")
            keypoints = associated_keypoints(rig, keypoints, fps=fps, person=args.person, say=print)
    elif args.person:
        raise ValueError("--person chooses among the people the keypoints hold: it needs --keypoints")
    observes = get_likelihood(args.likelihood or DEFAULT_LIKELIHOOD).observes
    stream = open_video(args.video, rig, fps=args.fps, background=args.background, keypoints=keypoints, frames=args.frames,
                        keep_images=bool({"edges", "foreground", "images"} & set(observes)),
                        resolution=args.resolution or "auto", say=print,
                        through_empty=args.likelihood is None)  # the keypoints alone then carry empty frames
    try:
        first = stream.read(args.chunk_frames or stream.wanted)  # a segment at a time: the memory of one segment
        if first is None:
            raise VideoFileError(f"nothing to track: {stream.stopped}")
    except BaseException:
        stream.close()
        raise
    read = stream.input(first)
    segments = "" if first.num_frames >= stream.wanted else f" (the first {first.num_frames} of {stream.wanted}: --chunk-frames at a time)"
    print(f"silhouettes of {first.num_frames} frames{segments} by background subtraction in {read.seconds['silhouettes']:.1f} s, "
          f"decoding side by side (its model {read.seconds['background model']:.1f} s, opening the videos "
          f"{read.seconds['open and close']:.1f} s)")
    if read.coverage is not None:
        print("silhouettes against the keypoints (the share of each camera's keypoint box they fill, median over the "
              "background samples): " + ", ".join(f"{n} {c:.2f}" for n, c in zip(rig.names, read.camera_coverage())))
    return stream, read


def _video_likelihood(args, read) -> str | None:
    """The likelihood ``track --video`` uses where ``--likelihood`` is not given: with keypoints,
    the silhouettes and the keypoints, or the keypoints alone where a camera's silhouettes miss
    the person its keypoints place (None: the default)."""
    from .tracking import MIN_COVERAGE

    if args.likelihood is not None or read.sequence.keypoints2d is None:
        return None
    untrusted = read.untrusted_cameras()
    if untrusted:
        empty = {str(n): int(e) for n, e in zip(read.sequence.camera_names, read.empty_frames) if e}
        print(f"warning: the silhouettes of {', '.join(untrusted)} fill under {MIN_COVERAGE:.0%} of the keypoints' box or are "
              "empty on some frames (the background model holds the person, or the subtraction misses them"
              + (f"; empty: {', '.join(f'{n} on {e} frames' for n, e in empty.items())}" if empty else "")
              + "): tracking on the keypoints alone (--likelihood to choose)", file=sys.stderr)
        return "keypoints"
    return "silhouette+keypoints"


@contextlib.contextmanager
def _interrupt_between_chunks():
    """Hold the first Ctrl-C until the chunk being tracked is done and saved: inside, SIGINT only
    marks a stop, and the ``stop_here()`` this yields (called after each chunk's partial file is
    written) raises ``KeyboardInterrupt`` then, from Python code, with no XLA program running. A
    second Ctrl-C stops at once. Outside the main thread it changes nothing."""
    pending = []

    def stop_here():
        if pending:
            raise KeyboardInterrupt

    if threading.current_thread() is not threading.main_thread():
        yield stop_here
        return

    def mark(signum, frame):
        if pending:
            raise KeyboardInterrupt
        pending.append(signum)
        print("jaxtrack: stopping once this chunk is saved (Ctrl-C again to stop now)", file=sys.stderr, flush=True)

    previous = signal.signal(signal.SIGINT, mark)
    try:
        yield stop_here
    finally:
        signal.signal(signal.SIGINT, previous)


def _track(args) -> int:
    import dataclasses

    import jax

    jax.config.update("jax_enable_x64", True)  # the model is float64; the tracker casts to float32
    import numpy as np

    from .evaluation import mean_joint_error_mm
    from .io import check_output, load_sequence, save_sequence
    from .likelihood import get_likelihood
    from .manifold import load_model
    from .tracking import TrackingSpec, get_tracker, track_sequence

    spec = TrackingSpec(**_spec_fields(args))  # checked before any file is read
    spec.check_method(args.method)
    inputs = [path for path in (args.test, args.validation, args.model) if path] + [
        *(args.video or []), *(args.background or []), *(args.calibration or []), *(args.keypoints or [])]
    args.out = check_output(args.out, inputs, suffix=".npz")
    partial = args.out[: -len(".npz")] + ".partial.npz"
    check_output(partial, inputs)
    if args.overlay:
        if not args.video:
            raise ValueError("--overlay draws the estimate over the videos: it needs --video")
        args.overlay = check_output(args.overlay, inputs, suffix=".mp4")
    if args.video and not args.calibration:  # before any file is read
        raise ValueError("--video needs the cameras: --calibration FILE [FILE ...] (JSON, OpenCV YAML/XML or TOML)")
    if args.model is None and get_tracker(args.method).needs_manifold:  # before any file is read
        raise ValueError(f"--method {args.method} tracks on a manifold: give --model (a file from 'jaxtrack fit'); "
                         "sir and apf need none")
    validation = None if args.validation is None else load_sequence(args.validation)
    model, header = load_model(args.model) if args.model else (None, None)
    if validation is None and header is not None:
        from .tracking import stored_motion

        stored_motion(header, args.model)  # raises before the videos are read where the file stores none
    stream = None
    if args.video:
        stream, read = _video_test(args)
        sequence = read.sequence  # the first segment, at the tracking resolution, which the spec then leaves as it is
        spec = dataclasses.replace(spec, resolution=None)
        chosen = _video_likelihood(args, read)
        if chosen is not None:
            spec = dataclasses.replace(spec, likelihood=chosen, likelihood_options={})
        if "silhouettes" not in get_likelihood(spec.likelihood).observes:  # not read, and not checked (some may be empty)
            sequence = sequence.replace(silhouettes=None)
        print(f"cues: {spec.likelihood}" + (" (chosen from what was given; --likelihood to choose)" if args.likelihood is None else ""))
        name = os.path.basename(args.video[0])
    elif args.test:
        sequence = load_sequence(args.test)
        name = os.path.basename(args.test)
    else:
        raise ValueError("give a test sequence file, or the videos (--video ... --calibration ...)")
    has_truth = sequence.joints3d is not None or sequence.pose is not None
    spec = dataclasses.replace(spec, start=args.start or ("truth" if has_truth else "auto"))
    kept = stream.source if args.video else sequence  # the estimate file: the calibration's cameras
    total = stream.wanted if args.video else sequence.num_frames

    def save_so_far(poses, joints):  # a valid sequence of the frames tracked so far, replaced after each chunk
        done = len(poses)
        # videos with no keypoints keep nothing per frame once the silhouettes are dropped: the
        # estimates are then the partial file's only frames
        so_far = kept.cropped(done) if kept.num_frames else kept
        save_sequence(partial, _estimate_sequence(so_far, poses, joints))
        print(f"  {done}/{total} frames tracked; estimates so far in {partial}", flush=True)
        stop_here()

    chunked = args.chunk_frames and args.chunk_frames < total
    with contextlib.ExitStack() as held:
        if stream is not None:
            held.enter_context(stream)
        stop_here = held.enter_context(_interrupt_between_chunks() if chunked else contextlib.nullcontext(lambda: None))
        if args.video:
            poses, joints, info = _track_video(stream, sequence, model, header, validation, spec, args, name,
                                               save_so_far if chunked else None)
        else:
            poses, joints, info = track_sequence(
                sequence, model, header, args.method, validation, spec, seed=args.seed, name=name,
                chunk_frames=args.chunk_frames if chunked else None, on_chunk=save_so_far if chunked else None,
            )
    stopped = stream.stopped if stream is not None else None
    if stopped:
        print(f"warning: the videos' frames from {len(poses)} on are not tracked: {stopped}", file=sys.stderr)
    if sequence.joints3d is not None:
        print(f"{args.method}: error {float(mean_joint_error_mm(joints, sequence.joints3d)):.1f} mm (000 eq. 31) over {len(poses)} frames")
    save_sequence(args.out, _estimate_sequence(kept.cropped(len(poses)) if kept.num_frames > len(poses) else kept, poses, joints))
    if os.path.exists(partial):
        os.remove(partial)
    degenerate = float(np.mean(np.asarray(info.degenerate)))
    print(f"wrote {args.out}: estimated pose {poses.shape} and joints3d {joints.shape}; mean ESS {float(np.mean(info.ess)):.1f}; "
          f"degenerate frames {100 * degenerate:.0f} %")
    if args.overlay:
        from .body import humaneva_skeleton
        from .viz import write_overlay_video

        write_overlay_video(args.overlay, args.video, read.source.rig(dtype=np.float64), joints,  # the videos' cameras
                            humaneva_skeleton().parents, fps=sequence.fps)
        print(f"wrote {args.overlay}: the estimate over the videos")
    if degenerate > args.max_degenerate:
        print(f"jaxtrack track: error: on {100 * degenerate:.0f} % of the frames every particle's likelihood was -inf or NaN, "
              f"so the filter ran on uniform weights (tracked blind; --max-degenerate {args.max_degenerate:g}); check that every "
              "camera sees the person and that the silhouettes are not empty", file=sys.stderr)
        return 3
    if stopped:
        print(f"jaxtrack track: error: tracked {len(poses)} frames and stopped: {stopped}", file=sys.stderr)
        return 4
    return 0


def _track_video(stream, first, model, header, validation, spec, args, name, on_chunk):
    """``track --video``: the tracker prepared on the videos' first segment (``first``), then run
    on over the rest, read and tracked a segment of ``--chunk-frames`` frames at a time, so that
    one segment's silhouettes are held at a time (``tracking.track_stream``)."""
    import jax

    from .likelihood import get_likelihood
    from .tracking import PIXEL_SAMPLE_TAG, prepare_tracking, segment_observations, track_stream

    prepared = prepare_tracking(first, model, header, args.method, validation, spec, seed=args.seed, name=name)
    reads_silhouettes = "silhouettes" in get_likelihood(spec.likelihood).observes
    sample_key = jax.random.fold_in(jax.random.key(args.seed), PIXEL_SAMPLE_TAG)

    def further():
        k = 0
        while (segment := stream.read(args.chunk_frames or stream.wanted)) is not None:
            k += 1
            if not reads_silhouettes:
                segment = segment.replace(silhouettes=None)
            yield segment_observations(prepared.scene, segment, spec.likelihood, spec.likelihood_options,
                                       key=jax.random.fold_in(sample_key, k), name=name)

    return track_stream(prepared, further(), on_chunk=on_chunk)


def _estimate_sequence(sequence, poses, joints):
    """The test sequence with the estimates as its pose and joints (the HumanEva skeleton's
    names where the file has none)."""
    import numpy as np

    from .body import humaneva_skeleton

    skeleton = humaneva_skeleton()
    named = {} if sequence.joint_names is not None else {
        "joint_names": np.asarray(skeleton.joint_names), "parents": np.asarray(skeleton.parents),
        "pose_layout": np.asarray(skeleton.pose_layout)}
    return sequence.replace(pose=poses, joints3d=joints, **named)


_SCALE = 100.0


MAX_SEED = 2**32 - 1
MAX_IMAGE_SIDE = 4096  # pixels: a 4096x4096 scene already holds 16 M pixels a view and frame


def _seed(text: str) -> int:
    """A PRNG seed: a whole number from 0 to ``MAX_SEED`` (refused by argparse otherwise)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"a seed is a whole number from 0 to {MAX_SEED}, got {text}")
    return value


def _at_least(low: int, high: int | None = None):
    """An argparse type: a whole number from ``low`` (to ``high``)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"expected a whole number from {low}" + (f" to {high}" if high else " up")
                                             + f", got {text}")
        return value

    return parse


def _finite_float(text: str) -> float:
    """An argparse type: a finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text}")
    return value


def _fraction(text: str) -> float:
    """An argparse type: a number from 0 to 1."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 1, got {text!r}") from None
    if not 0.0 <= value <= 1.0:  # NaN fails both comparisons
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 1, got {text}")
    return value


def _decay_factor(text: str) -> float:
    """An argparse type: a factor per frame, above 0 and at most 1."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 < value <= 1.0:  # NaN fails both comparisons
        raise argparse.ArgumentTypeError(f"expected a number above 0 and at most 1, got {text}")
    return value


def _resolution(text: str) -> tuple[int, int]:
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 80x60, got {text!r}") from None
    return width, height


def _residual_help(whose: str) -> str:
    from .tracking import available_trackers, get_tracker

    owners = [n for n in available_trackers() if get_tracker(n).residual is not None]
    defaults = ", ".join(f"{n} {r.residual:g}" + (f" fading by {r.residual_decay:g} a frame" if r.residual and r.residual_decay < 1 else "")
                         for n, r in ((n, get_tracker(n)) for n in owners))
    return (f"give {whose} whose pose is decoded from a latent point ({', '.join(owners)}) an off-manifold pose residual "
            f"that walks with SCALE times the pose random walk's steps (0: none) (default: each tracker's own: {defaults})")


def _velocity_defaults() -> str:
    from .tracking import available_trackers, get_tracker

    return ", ".join(n for n in available_trackers() if get_tracker(n).velocity) + " on, the others off"


def _manifold_defaults() -> str:
    from .tracking import available_trackers, get_tracker

    recipes = [get_tracker(n) for n in available_trackers()]
    return ", ".join(f"{r.name} {r.manifold}" for r in recipes if r.needs_manifold)


def _methods_help() -> str:
    from .tracking import available_trackers, get_tracker

    return "; ".join(f"{name}: {get_tracker(name).description}" for name in available_trackers())


def _body_arguments(parser, whose: str) -> None:
    parser.add_argument("--body", choices=("auto", "joints", "default", "calibrate"),
                        help=f"{whose}'s body: auto (default): the file's skeleton, else the one inverse kinematics fits to its "
                             "joints3d, else a training or validation file's of the same subject, else calibrated from the first "
                             "frames' silhouettes; joints: fitted to the joints even over the file's skeleton; default: the "
                             "default body; calibrate: limb lengths and radii always fitted to the first frames' silhouettes")
    parser.add_argument("--calibrate-body", action="store_true", help="the same as --body calibrate")
    parser.add_argument("--height", type=float, metavar="M",
                        help="the subject's standing height in metres: the body calibration's prior (the reference proportions "
                             "scaled to it)")
    parser.add_argument("--body-prior", choices=("default", "proportions", "motion"), default="default",
                        help="what centres a body calibration's prior: default (the default): the default body's proportions; "
                             "proportions: those of the motion model's subjects (the validation and training takes); motion: "
                             "their proportions and clavicle posture, for a person who is the motion model's subject "
                             "(docs/body.md)")


def load_plugins(argv) -> None:
    """Import every ``--plugin MODULE`` (a dotted module name or a .py file) named in ``argv``,
    before the parser is built, so that the trackers it registers are known."""
    import importlib
    import importlib.util

    argv = list(argv)
    plugins = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--plugin"]
    plugins += [a.split("=", 1)[1] for a in argv if a.startswith("--plugin=")]
    for plugin in plugins:
        if plugin.endswith(".py"):
            if not os.path.isfile(plugin):
                raise FileNotFoundError(f"--plugin {plugin}: no such file")
            spec = importlib.util.spec_from_file_location(os.path.splitext(os.path.basename(plugin))[0], plugin)
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
        else:
            importlib.import_module(plugin)


def _likelihood_arguments(parser) -> None:
    from .likelihood import DEFAULT_LIKELIHOOD, available_likelihoods, get_likelihood

    parser.add_argument("--likelihood", choices=available_likelihoods(),
                        help="a registered likelihood: " + "; ".join(f"{n}: {get_likelihood(n).description}"
                                                                     for n in available_likelihoods())
                             + f" (default: {DEFAULT_LIKELIHOOD}; track --video with --keypoints: silhouette+keypoints, or "
                               "keypoints alone where the silhouettes miss the person the keypoints place)")
    parser.add_argument("--likelihood-option", action="append", metavar="KEY=VALUE",
                        help="an option of the likelihood (e.g. edge_width=1.5 for silhouette)")


def _likelihood_options(args) -> dict:
    from .likelihood import DEFAULT_LIKELIHOOD, get_likelihood

    recipe = get_likelihood(args.likelihood or DEFAULT_LIKELIHOOD)
    return _options(args.likelihood_option, recipe.options, f"likelihood {recipe.name!r}")


def _experiment_arguments(experiment) -> None:
    """The trackers, runs, manifold fit and seed of ``experiment`` and ``protocol``."""
    from .manifold import DEFAULT_OPTIMISER, OPTIMISERS, manifold_kinds
    from .tracking import PAPER_TRACKERS, START_CHOICES, available_trackers

    experiment.add_argument("--methods", nargs="+", default=list(PAPER_TRACKERS), choices=available_trackers(),
                            help=f"registered trackers (default: {' '.join(PAPER_TRACKERS)}). {_methods_help()}")
    experiment.add_argument("--plugin", action="append", default=[],
                            help="a module (dotted name or .py file) to import first; it may register trackers")
    experiment.add_argument("--runs", type=_at_least(1), default=5, help="runs per method (default: %(default)s)")
    experiment.add_argument("--batch-runs", action="store_true",
                            help="track each method's runs in one compiled call (vmapped over the runs' keys)")
    experiment.add_argument("--latent-dim", type=int,
                            help="latent dimension of every manifold (default: each tracker's own, MRPF 2, GPAPF and LatentPF 3; "
                                 "else 2 for bc-gplvm and gpdm, 3 for gle, tle, le)")
    experiment.add_argument("--fit-steps", type=_at_least(1), default=300, help="L-BFGS iterations of the manifold (default: %(default)s)")
    experiment.add_argument("--fit-optimiser", choices=OPTIMISERS, default=DEFAULT_OPTIMISER,
                            help="the manifold fit's L-BFGS: one evaluation per loop iteration (lbfgs, the default: compiles in "
                                 "about half the time) or optax's with its zoom line search (optax: the docs' tracking tables "
                                 "measured before 2026-11-26)")
    experiment.add_argument("--seed", type=_seed, default=0)
    experiment.add_argument("--start", choices=START_CHOICES, default="truth",
                            help="truth: every tracker starts from each test take's frame-0 ground truth (the paper's "
                                 "protocol); auto: from a pose found in the first frame's images by an annealed search over "
                                 "the first manifold the trackers run on (a BC-GPLVM fitted for it where none does), the "
                                 "same start for every tracker; the ground truth then only scores (default: %(default)s)")
    experiment.add_argument("--manifold", choices=manifold_kinds(trackable=True),
                            help="the manifold of every manifold tracker of its family (GP: "
                                 f"{', '.join(manifold_kinds(family='gp', trackable=True))}; Laplacian Eigenmaps: "
                                 f"{', '.join(manifold_kinds(family='spectral', trackable=True))}; the other family keeps its "
                                 f"own) (default: each tracker's own: {_manifold_defaults()})")


def build_parser() -> argparse.ArgumentParser:
    from .manifold import DEFAULT_OPTIMISER, OPTIMISERS, get_manifold_kind, manifold_kinds
    from .tracking import available_trackers

    parser = argparse.ArgumentParser(
        prog="jaxtrack", description="Articulated human motion tracking with particle filters and pose manifolds, in JAX."
    )
    parser.add_argument("--debug", action="store_true",
                        help="on an error, show the Python traceback instead of the one-line message")
    parser.add_argument("--no-compile-cache", action="store_true",
                        help="do not keep compiled trackers between calls (default: kept in $JAXTRACK_CACHE_DIR, else "
                             "$XDG_CACHE_HOME/jaxtrack/xla or ~/.cache/jaxtrack/xla; JAXTRACK_CACHE_DIR=off turns it off too)")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="run the pipeline end to end on the embedded synthetic default")
    demo.add_argument("--out", default="jaxtrack_demo", help="output folder (default: %(default)s)")
    demo.add_argument("--seed", type=_seed, default=0, help="PRNG seed (default: %(default)s)")
    demo.add_argument("--frames", type=_at_least(2), help="test frames per sequence (default: 40; 60 with --show-likelihood)")
    demo.add_argument("--budget", type=int, help="likelihood evaluations per frame (default: 300; 500 with --show-likelihood)")
    demo.add_argument("--runs", type=_at_least(1), default=2, help="runs per method (default: %(default)s)")
    demo.add_argument("--ground-prior", action=argparse.BooleanOptionalAction, default=True,
                      help="the trackers' likelihood times the ground plane's prior (--no-ground-prior: the silhouettes alone) "
                           "(default: on)")
    demo.add_argument("--show-likelihood", action="store_true",
                      help="instead: score true against perturbed poses and refine poses by gradient descent")
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
    convert.add_argument("--seed", type=_seed, default=0, help="PRNG seed for the IK restarts (default: %(default)s)")
    convert.add_argument("--level-floor", action="store_true",
                         help="rotate the motion so that the floor under its stance foot is level (a capture whose "
                              "vertical is not the floor's normal: docs/floor.md, 'A tilted capture')")
    convert.set_defaults(run=_convert)

    scene = sub.add_parser("scene", help="render a sequence's motion into synthetic multi-view silhouettes (a test sequence)")
    scene.add_argument("source", help="a sequence file with 'pose' (e.g. from 'jaxtrack convert')")
    scene.add_argument("out", nargs="?", help="output sequence file (.npz) with cameras and silhouettes (not with --video)")
    scene.add_argument("--start", type=_at_least(0), default=0, help="first frame to keep (default: %(default)s)")
    scene.add_argument("--frames", type=_at_least(1), help="frames to keep (default: to the end)")
    scene.add_argument("--width", type=_at_least(8, MAX_IMAGE_SIDE), default=80, help="image width in pixels (default: %(default)s)")
    scene.add_argument("--height", type=_at_least(8, MAX_IMAGE_SIDE), default=60, help="image height in pixels (default: %(default)s)")
    scene.add_argument("--views", type=_at_least(1, 64), default=4, help="cameras around the capture area (default: %(default)s)")
    scene.add_argument("--clean", action="store_true", help="no background-subtraction noise")
    scene.add_argument("--no-centre", action="store_true", help="keep the recorded floor position (default: centre the path)")
    scene.add_argument("--seed", type=_seed, default=0, help="PRNG seed of the silhouette noise (default: %(default)s)")
    scene.add_argument("--keypoints", action="store_true",
                       help="also write synthetic 2-D keypoint detections (keypoints2d): the true joints projected, with noise")
    scene.add_argument("--keypoint-noise", type=float, default=5.0, metavar="PX",
                       help="their Gaussian pixel noise (default: %(default)s)")
    scene.add_argument("--keypoint-dropped", type=float, default=0.1, metavar="P",
                       help="the probability that a joint is missing (default: %(default)s)")
    scene.add_argument("--keypoint-swapped", type=float, default=0.0, metavar="P",
                       help="the probability that a view's frame has left and right exchanged (default: %(default)s)")
    scene.add_argument("--rgb", action="store_true",
                       help="film the scene in colour: the solid body (not the tracker's capsules) over a real photograph, "
                            "shaded, with cast shadows, a lighting change and sensor noise (needs --video)")
    scene.add_argument("--video", metavar="OUTDIR",
                       help="with --rgb: write one video per camera, background videos, calibration.json, keypoints.npz "
                            "(--keypoint-* noise) and truth.npz into this folder")
    scene.add_argument("--background-frames", type=int, default=30,
                       help="with --video: frames of the empty scene per camera, for background subtraction (default: %(default)s)")
    scene.set_defaults(run=_scene)

    from .io import KEYPOINT_FORMATS, KEYPOINT_LAYOUTS
    from .tracking import START_CHOICES

    keypoints = sub.add_parser("keypoints", help="add a 2-D pose detector's keypoints (OpenPose, COCO JSON) to a sequence file")
    keypoints.add_argument("sequence", help="a sequence file with cameras")
    keypoints.add_argument("out", help="output sequence file (.npz): the same with keypoints2d")
    keypoints.add_argument("sources", nargs="+",
                           help="per camera, in the file's camera order: an OpenPose output folder (one *_keypoints.json per "
                                "frame) or a COCO keypoint JSON; or one keypoint .npz of every camera (--format npz)")
    keypoints.add_argument("--format", choices=KEYPOINT_FORMATS,
                           help="what the sources are (default: told from them: a folder is OpenPose, a .json COCO, an .npz "
                                "jaxtrack's keypoint file)")
    keypoints.add_argument("--layout", choices=tuple(KEYPOINT_LAYOUTS),
                           help="the detector's keypoint layout (default: told from the points per person, and BODY_25 from "
                                "BODY_25B from where points 0-4 lie)")
    keypoints.add_argument("--calibration", nargs="+", metavar="FILE",
                           help="the cameras, replacing the file's: one JSON or TOML (aniposelib, Pose2Sim, FreeMoCap) file, "
                                "or one OpenCV FileStorage YAML/XML per camera (docs/keypoints.md)")
    keypoints.add_argument("--units", choices=("m", "mm"), help="the calibration's length unit (default: told from the cameras)")
    keypoints.add_argument("--up", help="the calibration world's up axis, e.g. z, y, -y (default: told from the cameras)")
    keypoints.set_defaults(run=_keypoints)

    fit = sub.add_parser("fit", help="fit a pose manifold to one or more sequence files with 'pose'")
    fit.add_argument("motion", nargs="+", help="sequence files (.npz) with pose vectors")
    fit.add_argument("--plugin", action="append", default=[],
                     help="a module (dotted name or .py file) to import first; it may register manifold kinds")
    fit.add_argument("--model", choices=[*manifold_kinds(), "vlmm", "spm-gplvm"], default="bc-gplvm",
                     help="a registered manifold kind: " + "; ".join(f"{k}: {get_manifold_kind(k).description}"
                                                                    for k in manifold_kinds())
                     + "; vlmm: a bc-gplvm (--vlmm-manifold; 3-D unless --latent-dim) with paper 004's motion prototypes and VLMM "
                       "fitted on it and stored in the same file; spm-gplvm: paper 003's active-set GPLVM of the motion's "
                       "3-D joints seen from the view sphere as scaled-prismatic-model poses, for track2d (options "
                       "active=200, every=3, iterations=3) (default: %(default)s)")
    fit.add_argument("--manifold-option", action="append", metavar="KEY=VALUE",
                     help="an option of the manifold kind's maker (e.g. num_inducing=100 for sparse-gplvm)")
    fit.add_argument("--inducing", type=_at_least(1), help="inducing points of sparse-gplvm and sparse-bc-gplvm (default: 150, at "
                                                                   "most one per frame)")
    fit.add_argument("--vlmm-manifold", choices=("bc-gplvm", "sparse-bc-gplvm"), default="bc-gplvm",
                     help="the manifold of --model vlmm: 004 fits a sparse-bc-gplvm (default: %(default)s, as jaxtrack "
                          "experiment's vlmmpf)")
    fit.add_argument("--seed", type=_seed, default=0, help="PRNG seed for the MLP back-constraint's weights (default: %(default)s)")
    fit.add_argument("--latent-dim", type=int, help="latent dimension (default: the kind's own: 2 for the GP models, 3 for gle, tle, le)")
    fit.add_argument("--steps", type=_at_least(1), default=300,
                     help="L-BFGS iterations at most (default: %(default)s, as jaxtrack experiment's --fit-steps)")
    fit.add_argument("--optimiser", choices=OPTIMISERS, default=DEFAULT_OPTIMISER,
                     help="the GP models' L-BFGS (default: %(default)s, as jaxtrack experiment's --fit-optimiser)")
    fit.add_argument("--out", required=True, help="output model file (e.g. model.eqx)")
    fit.set_defaults(run=_fit)

    experiment = sub.add_parser("experiment", help="compare trackers the way paper 000 does (table, curves, animations)")
    experiment.add_argument("--train", nargs="+", required=True, help="training sequence files (pose or joints3d)")
    experiment.add_argument("--validation", nargs="+", required=True,
                            help="validation sequence file(s): the trackers' dynamics are fitted on them (000 sec. 5.2)")
    experiment.add_argument("--test", nargs="+", required=True, help="test sequence files with silhouettes, cameras and ground truth")
    _experiment_arguments(experiment)
    experiment.add_argument("--frames", type=_at_least(1), help="track only the first FRAMES frames of each test sequence (paper: 200)")
    _spec_arguments(experiment, "every tracker", "each test sequence")
    experiment.add_argument("--no-animation", action="store_true", help="skip the overlay GIFs")
    experiment.add_argument("--out", default="jaxtrack_experiment", help="output folder (default: %(default)s)")
    experiment.set_defaults(run=_experiment)

    protocol = sub.add_parser("protocol", help="trackers on people the manifold has never seen: a leave-one-subject-out "
                              "protocol end to end, with its within-subject rows (table)")
    from .experiment import FOLD_MODES, PROTOCOLS, RENDERERS

    protocol.add_argument("name", choices=list(PROTOCOLS),
                          help="; ".join(f"{n}: {p.description}" for n, p in PROTOCOLS.items()))
    protocol.add_argument("--data", default=os.path.join("..", "shared", "data"),
                          help="the shared motion-capture folder (cmu35/, multi_subject/) (default: %(default)s)")
    protocol.add_argument("--modes", nargs="+", choices=FOLD_MODES, default=list(FOLD_MODES),
                          help="cross: the test subject left out of training; within: trained on its own other takes "
                               "(default: both)")
    protocol.add_argument("--subjects", nargs="+", help="test subjects (default: each in turn)")
    protocol.add_argument("--without", nargs="+", metavar="SUBJECT",
                          help="drop these subjects from the whole protocol: its cross folds on the others are where a "
                               "setting for them is chosen without their motion (nested validation)")
    protocol.add_argument("--centre-subjects", action="store_true",
                          help="take each training subject's posture out of its takes (its mean joint angles replaced by "
                               "the training takes' pooled mean), so the manifold learns the gait and not the people "
                               "(docs/subjects.md, \"A person's own posture\")")
    protocol.add_argument("--level-floor", action=argparse.BooleanOptionalAction, default=True,
                          help="level every take onto the floor under its stance foot when converting it: CMU 07's "
                               "capture rises 1.1 degrees along its walks, the trackers' floor is level (docs/floor.md, "
                               "'A tilted capture'; default: on)")
    protocol.add_argument("--views", type=_at_least(1, 64), default=3, help="cameras (default: %(default)s)")
    protocol.add_argument("--azimuth", type=_finite_float, nargs="+", default=[45.0], metavar="DEG",
                          help="the first camera's direction from the capture area's centre, degrees from the x axis, the "
                               "others following at equal angles; or one direction per camera (default: 45)")
    protocol.add_argument("--image-size", type=_image_size, default=(80, 60), metavar="WxH",
                          help="the test views' size in pixels (default: 80x60)")
    protocol.add_argument("--renderer", choices=RENDERERS, default="solid",
                          help="the body that draws the test silhouettes: solid (ellipsoids with feet and hands) or capsules "
                               "(the subject's skeleton in other radii); never the tracker's (default: %(default)s)")
    _experiment_arguments(protocol)
    _spec_arguments(protocol, "every tracker", "each test take")
    protocol.add_argument("--out", default="jaxtrack_protocol", help="output folder (default: %(default)s)")
    protocol.set_defaults(run=_protocol)

    track = sub.add_parser("track", help="track one test sequence with a fitted manifold and write the estimates")
    track.add_argument("test", nargs="?",
                       help="test sequence file with silhouettes (or keypoints) and cameras; its ground truth, if any, is the "
                            "start (--start) and scores the result (or give --video)")
    track.add_argument("--video", nargs="+", metavar="VIDEO",
                       help="instead of a test file: one video file or image folder per camera, in the calibration's order; "
                            "silhouettes by background subtraction, the start found automatically")
    track.add_argument("--background", nargs="+", metavar="VIDEO",
                       help="with --video: one video or folder of the empty scene per camera (default: the median of frames "
                            "spread over the videos themselves)")
    track.add_argument("--calibration", nargs="+", metavar="FILE",
                       help="with --video: the cameras (documented JSON, OpenCV YAML/XML, aniposelib/Pose2Sim TOML)")
    track.add_argument("--units", choices=("m", "mm"), help="the calibration's length unit (default: told from the cameras)")
    track.add_argument("--up", help="the calibration world's up axis, e.g. z, y, -y (default: told from the cameras)")
    track.add_argument("--keypoints", nargs="+", metavar="SOURCE",
                       help="with --video: a detector's 2-D keypoints, one .npz of every camera or one OpenPose folder / COCO "
                            "JSON per camera; read by the keypoint likelihoods and the automatic start")
    track.add_argument("--keypoint-format", choices=KEYPOINT_FORMATS,
                       help="(default: told from the sources: a folder is OpenPose, a .json COCO, an .npz jaxtrack's file)")
    track.add_argument("--keypoint-layout", choices=tuple(KEYPOINT_LAYOUTS),
                       help="the detector's layout (default: told from the points per person, and BODY_25 from BODY_25B "
                            "from where points 0-4 lie)")
    track.add_argument("--frames", type=_at_least(1), help="with --video: track at most this many frames")
    track.add_argument("--person", type=_at_least(0), default=0,
                       help="with per-camera keypoint files (OpenPose, COCO) holding several people: which of the people "
                            "found at the first frame to follow, as listed (default: %(default)s, the one most cameras see)")
    track.add_argument("--fps", type=float, help="with --video of image folders: their frame rate")
    track.add_argument("--start", choices=START_CHOICES,
                       help="truth: frame 0's ground truth; auto: found from the first frame's images by an annealed search "
                            "over the model's latent space (default: truth when the test file has it, else auto)")
    track.add_argument("--overlay", metavar="MP4", help="with --video: also write the estimate drawn over the videos")
    track.add_argument("--model",
                       help="a model file from 'jaxtrack fit': a GP manifold (gpdm, bc-gplvm, ...) for mrpf, mrpf-alg1, gpapf "
                            "and latentpf (on a GPDM the latent draw is its dynamics, on a BC-GPLVM 000 eq. 27's); a gle, tle "
                            "or le for glegbpf; sir and apf need none")
    track.add_argument("--validation",
                       help="validation sequence file: the tracker's dynamics are fitted on it (000 sec. 5.2); default: the "
                            "model file's own training motion, or with no model file the embedded walk at the test's frame "
                            "rate (docs/trackers.md)")
    track.add_argument("--method", choices=available_trackers(), default="mrpf", help=_methods_help())
    track.add_argument("--plugin", action="append", default=[], help="a module to import first; it may register trackers")
    track.add_argument("--seed", type=_seed, default=0)
    _spec_arguments(track, "the tracker", "the test sequence")
    track.add_argument("--max-degenerate", type=_fraction, default=0.0,
                       help="the largest fraction of frames on which every particle may score -inf/NaN (tracking blind) "
                            "before the command exits with status 3; the estimates are written either way (default: %(default)s)")
    track.add_argument("--chunk-frames", type=_at_least(0), default=100,
                       help="track this many frames at a time and save the estimates so far to OUT.partial.npz after each "
                            "chunk, so an interruption loses one chunk at most (a test file: the same result; --video: the "
                            "videos are read a chunk at a time too, in the memory of one chunk; 0: one pass); Ctrl-C "
                            "stops once the chunk being tracked is saved, a second Ctrl-C at once "
                            "(default: %(default)s)")
    track.add_argument("--out", required=True, help="output sequence file with the estimated pose and joints3d")
    track.set_defaults(run=_track)

    track2d = sub.add_parser("track2d", help="track a person's upper body in one monocular video (paper 003), from the "
                                              "first frame's markers")
    track2d.add_argument("--video", required=True, help="a video file or image folder")
    track2d.add_argument("--markers", required=True,
                         help='JSON {"markers": {"head": [x, y], ...}}: the first frame\'s markers in pixels, named '
                              "pelvis, thorax, head, lshoulder, lelbow, lwrist, rshoulder, relbow, rwrist")
    track2d.add_argument("--model", required=True, help="a model file from 'jaxtrack fit --model spm-gplvm'")
    track2d.add_argument("--method", default="latentpf2d", choices=("latentpf2d", "condensation2d", "mht2d"),
                         help="latentpf2d: 003's Condensation in the latent space (200 particles); condensation2d: "
                              "Condensation on a shoulder-anchored arm chain with an AR(2) model (1000 particles); mht2d: "
                              "multiple-hypothesis tracking on that chain (10 modes) (default: %(default)s)")
    track2d.add_argument("--background", help="a video file or image folder of the empty scene from the same camera: the "
                                               "trackers then score each frame's silhouette too (background subtraction)")
    track2d.add_argument("--option", action="append", metavar="KEY=VALUE",
                         help="a tracker option, e.g. start=fitted, estimate=marker-mean, silhouette_weight=3000, particles=500")
    track2d.add_argument("--frames", type=_at_least(2), help="track the first FRAMES frames (default: all)")
    track2d.add_argument("--seed", type=_seed, default=0)
    track2d.add_argument("--chunk-frames", type=_at_least(1), default=64,
                         help="frames read and tracked at a time; the tracks so far are written after each (default: %(default)s)")
    track2d.add_argument("--fps", type=float, default=30.0, help="the overlay video's frame rate (default: %(default)s)")
    track2d.add_argument("--no-overlay", action="store_true", help="skip the overlay video (OUT_overlay.mp4)")
    track2d.add_argument("--out", required=True, help="output .npz: markers2d (T, 9, 2) pixels and marker_names")
    track2d.set_defaults(run=_track2d)

    plot = sub.add_parser("plot-latent", help="draw a fitted model's latent space over its predictive variance")
    plot.add_argument("model", help="a model file written by 'jaxtrack fit'")
    plot.add_argument("--out", help="output PNG (default: MODEL_latent.png)")
    plot.set_defaults(run=_plot_latent)
    return parser


def _spec_arguments(parser, whose: str, sequences: str) -> None:
    """The flags of a ``tracking.TrackingSpec`` that ``experiment`` and ``track`` share (read
    back by ``_spec_fields``)."""
    from .tracking import GRADIENT_COST

    parser.add_argument("--budget", type=int, default=500, help="likelihood evaluations per frame (default: %(default)s)")
    parser.add_argument("--layers", type=int, default=5, help="annealing layers of APF and GPAPF (default: %(default)s)")
    _likelihood_arguments(parser)
    parser.add_argument("--likelihood-scale", type=float, default=_SCALE, help="ln p = -scale * cost (default: %(default)s)")
    parser.add_argument("--calibrate-shape", action="store_true",
                        help=f"fit the capsule radii to {sequences}'s first frame before tracking")
    parser.add_argument("--ground-prior", action=argparse.BooleanOptionalAction, default=True,
                        help="keep the feet out of the floor (world z = 0): the likelihood times a prior on the ankles' height, "
                             "their clearance fitted on the validation motion (--no-ground-prior: the silhouettes alone) "
                             "(default: on)")
    _body_arguments(parser, sequences)
    parser.add_argument("--refine-body", action=argparse.BooleanOptionalAction, default=None,
                        help="where the body is calibrated from the images, track once, calibrate it again on tracked frames "
                             "spread over the sequence (12 at 4 views of 160x120, up to 40 for smaller images; the knees and "
                             "elbows bent), then track with the refined body "
                             "(default: where the start is given, not where it is found automatically, as from --video, whose "
                             "tracks it made worse; --no-refine-body: the first frames' calibration alone)")
    parser.add_argument("--fit-radii", action=argparse.BooleanOptionalAction, default=None,
                        help="fit the capsule radii to the silhouettes of 12 frames spread over each test sequence at their "
                             "ground-truth poses, the skeleton kept (default: where the skeleton is fitted to the file's joints "
                             "and the file gives no radii; --no-fit-radii: the default radii there)")
    parser.add_argument("--resolution", type=_resolution, metavar="WxH",
                        help="track at this image size: the test silhouettes are block-averaged and the cameras rescaled "
                             "(e.g. 80x60 for 320x240 data); with --video the frames are averaged down to it as they are "
                             "decoded, a whole factor of their size (default there: the largest at which the person is "
                             "still 120 px tall)")
    parser.add_argument("--pixel-samples", type=int, metavar="N",
                        help="score the silhouettes on N stratified sample pixels per view and frame (outline band, "
                             "interior, near and far background) instead of every pixel: a cost independent of the image "
                             "size; 0: every pixel (default: by the image size tracked at: every pixel up to 160x120, 2048 "
                             "up to 320x240, 4096 above; the choice is printed)")
    parser.add_argument("--refine-steps", type=int, default=0,
                        help="gradient-refined (MALA) moves per particle per frame, paid for out of the budget at "
                             f"{GRADIENT_COST:g} evaluations a gradient (default: %(default)s, none)")
    parser.add_argument("--velocity", action=argparse.BooleanOptionalAction,
                        help=f"give {whose}'s dynamics (--no-velocity: none) a Kalman-tracked velocity of the root (and "
                             "of the pose or latent point where the dynamics support it) fitted on the validation motion "
                             f"(default: each tracker's own: {_velocity_defaults()})")
    parser.add_argument("--residual", type=float, metavar="SCALE", help=_residual_help(whose))
    parser.add_argument("--residual-decay", type=_decay_factor, metavar="D",
                        help="the residual's factor per frame, r_t = D r_(t-1) + noise: 1 a random walk, below 1 it fades "
                             "back to the manifold (default: each tracker's own with its own residual, 1 with --residual)")
    parser.add_argument("--gait-rate", type=float, default=0.0, metavar="SPREAD",
                        help=f"give {whose} on a manifold a per-particle gait rate, its log drawn with this spread: each "
                             "particle steps its dynamics 0, 1 or 2 times a frame at its own cadence (default: 0, none; "
                             "tried across people and not kept: docs/subjects.md)")


def _spec_fields(args) -> dict:
    """The ``TrackingSpec`` fields of the flags ``_spec_arguments`` adds (``--height`` checked
    here, so its message names the flag)."""
    from .likelihood import DEFAULT_LIKELIHOOD

    if args.height is not None:
        from .body import check_height

        check_height(args.height, "--height")
    return {
        "budget": args.budget, "layers": args.layers, "likelihood": args.likelihood or DEFAULT_LIKELIHOOD,
        "likelihood_options": _likelihood_options(args),
        "likelihood_scale": args.likelihood_scale, "calibrate_shape": args.calibrate_shape, "ground_prior": args.ground_prior,
        "body": _body_choice(args), "height": args.height, "body_prior": args.body_prior, "refine_body": args.refine_body,
        "fit_radii": args.fit_radii,
        "resolution": args.resolution,
        "pixel_samples": "auto" if args.pixel_samples is None else args.pixel_samples, "refine_steps": args.refine_steps,
        "velocity": args.velocity, "residual": args.residual, "residual_decay": args.residual_decay,
        "gait_rate": args.gait_rate,
    }


def compilation_cache_folder() -> str | None:
    """Where the command line keeps XLA's compiled programs between calls, or None (off):
    ``$JAXTRACK_CACHE_DIR`` (``off`` or empty: none), else ``$XDG_CACHE_HOME/jaxtrack/xla``, else
    ``~/.cache/jaxtrack/xla``."""
    folder = os.environ.get("JAXTRACK_CACHE_DIR")
    if folder is not None:
        return None if folder.strip().lower() in ("", "off", "0", "none") else folder
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "jaxtrack", "xla")


def enable_compilation_cache(folder: str | None) -> None:
    """Keep every compiled program in ``folder`` (JAX's persistent compilation cache), so a
    second call of a command with the same shapes loads its trackers instead of compiling them
    again. The small programs too, not only the slow ones: what that saves is measured in
    docs/testing.md, "Cold start"."""
    if folder is None:
        return
    import jax

    jax.config.update("jax_compilation_cache_dir", folder)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


def _report(command: str, err: BaseException) -> int:
    """Print one line for ``err`` and return the exit status: 2 for bad input (jaxtrack's own
    error families, ``ValueError``, a missing or unreadable file), 1 for anything else (a bug:
    the line says how to see the traceback), 130 for Ctrl-C."""
    from .errors import JaxtrackError

    if isinstance(err, KeyboardInterrupt):
        print(f"jaxtrack {command}: interrupted", file=sys.stderr)
        return 130
    if isinstance(err, (JaxtrackError, ValueError, OSError)):
        print(f"jaxtrack {command}: error: {err}", file=sys.stderr)
        return 2
    message = str(err).strip().splitlines()[0] if str(err).strip() else ""
    print(f"jaxtrack {command}: internal error: {type(err).__name__}: {message} "
          "(a bug in jaxtrack or a plugin; run again with --debug for the traceback)", file=sys.stderr)
    return 1


def main(argv=None) -> int:
    """The ``jaxtrack`` command. Every error ends in one line on stderr and a non-zero status,
    never a traceback, unless ``--debug`` comes before the command."""
    argv = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in argv[: next((i for i, a in enumerate(argv) if not a.startswith("-")), len(argv))]
    try:
        load_plugins(argv)
    except Exception as err:
        if debug:
            raise
        print(f"jaxtrack: error: cannot load plugin: {type(err).__name__}: {err}", file=sys.stderr)
        return 2
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        enable_compilation_cache(None if args.no_compile_cache else compilation_cache_folder())
        return args.run(args)
    except (Exception, KeyboardInterrupt) as err:
        if args.debug:
            raise
        return _report(args.command, err)


if __name__ == "__main__":
    sys.exit(main())

"""The video path: the RGB renderer, videos written and read back, background subtraction on
them, triangulation, the automatic start, and ``sequence_from_video``'s handling of bad input."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.body import forward_kinematics
from jaxtrack.camera import default_rig, project_points
from jaxtrack.data import PhotoSettings, SolidBody, generate_motion, render_rgb, render_solid_silhouettes
from jaxtrack.image import fit_background, subtract_background
from jaxtrack.io import VideoFileError, VideoWriter, save_calibration
from jaxtrack.tracking import prepare_test, root_guess, sequence_from_video, triangulate

from helpers import interrupt_the_second_chunk, small_scene

QUIET = PhotoSettings(sensor_noise=0.0, lighting_change=0.0, shadow_strength=0.0)


@pytest.fixture(scope="module")
def filmed():
    """A 6-frame walk filmed by 2 cameras at 64x48, with the default photo settings."""
    motion = generate_motion("walk", "S1", num_frames=6, fps=30.0, key=jax.random.key(3))
    rig = default_rig(64, 48, num_views=2)
    solid = SolidBody(motion.body.skeleton)
    pictures, masks = render_rgb(jax.random.key(0), solid, rig, motion.pose, fps=30.0, chunk=2)
    return motion, rig, solid, pictures, masks


@pytest.mark.xdist_group("colour_film")  # one worker compiles the renderer (--dist loadgroup)
def test_rgb_masks_are_the_solid_body_silhouettes_and_the_empty_scene_is_the_photo(filmed):
    motion, rig, solid, pictures, masks = filmed
    assert pictures.shape == (2, 6, 48, 64, 3) and pictures.dtype == np.uint8 and masks.shape == (2, 6, 48, 64)
    reference = render_solid_silhouettes(solid, rig, motion.pose, samples=2).swapaxes(0, 1)
    assert np.mean(reference == masks) > 0.999 and masks.any(axis=(2, 3)).all()
    backgrounds = np.stack([np.full((48, 64, 3), 100 + 50 * c, np.uint8) for c in range(2)])
    empty, none = render_rgb(jax.random.key(0), solid, rig, motion.pose[:2], settings=QUIET, backgrounds=backgrounds,
                             with_body=False, chunk=2)
    assert not none.any()
    np.testing.assert_array_equal(empty, np.broadcast_to(backgrounds[:, None], empty.shape))
    # The body is drawn in its clothes' colours: far from the flat background inside the mask.
    posed, hit = render_rgb(jax.random.key(0), solid, rig, motion.pose[:2], settings=QUIET, backgrounds=backgrounds, chunk=2)
    inside = np.abs(posed.astype(int) - backgrounds[:, None].astype(int)).sum(-1)[hit]
    assert np.median(inside) > 60


@pytest.mark.xdist_group("colour_film")  # one worker compiles the renderer (--dist loadgroup)
def test_rgb_shadows_and_lighting_change_act_as_stated(filmed):
    motion, rig, solid, *_ = filmed
    grey = np.full((2, 48, 64, 3), 200, np.uint8)
    plain, _ = render_rgb(jax.random.key(0), solid, rig, motion.pose[:2], settings=QUIET, backgrounds=grey, chunk=2)
    shaded, _ = render_rgb(jax.random.key(0), solid, rig, motion.pose[:2], backgrounds=grey,
                           settings=PhotoSettings(sensor_noise=0.0, lighting_change=0.0, shadow_strength=0.5), chunk=2)
    floor = (plain == 200).all(-1)  # pixels without any of the body
    darker = (shaded < 198).any(-1) & floor
    assert darker.any()  # the body's shadow on the floor
    assert np.all(shaded[darker] >= 99) and np.all(shaded[floor & ~darker] == 200)  # at most halved, else untouched
    lit, _ = render_rgb(jax.random.key(0), solid, rig, motion.pose[:2], backgrounds=grey, first_frame=15, fps=30.0,
                        settings=PhotoSettings(sensor_noise=0.0, lighting_change=0.1, lighting_period=4.0, shadow_strength=0.0),
                        with_body=False, chunk=2)
    phase = 2 * np.pi * np.arange(2) / 2
    expected = np.round(200 * (1 + 0.1 * np.sin(2 * np.pi * 15 / (4.0 * 30.0) + phase)))
    np.testing.assert_allclose(lit[:, 0, 10, 10, 0], expected, atol=1)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_background_subtraction_finds_the_rendered_person():
    motion = generate_motion("walk", "S1", num_frames=4, fps=30.0, key=jax.random.key(3))
    rig = default_rig(160, 120, num_views=2)
    solid = SolidBody(motion.body.skeleton)
    pictures, masks = render_rgb(jax.random.key(0), solid, rig, motion.pose[::2], fps=30.0, chunk=2)
    empty, _ = render_rgb(jax.random.key(1), solid, rig, motion.pose[:2], fps=30.0, with_body=False, chunk=2)
    model = fit_background(np.moveaxis(empty, 1, 0))
    found = subtract_background(model, np.moveaxis(pictures, 1, 0))
    mask = np.asarray(found.mask).swapaxes(0, 1)
    iou = (mask & masks).sum(axis=(2, 3)) / (mask | masks).sum(axis=(2, 3))
    # A person 60 pixels tall: the errors are in the band of mixed pixels along the outline
    # (docs/video.md: IoU 0.84 at 320x240 from H.264 video, 0.94 away from a 2-pixel band).
    assert iou.min() > 0.75, iou
    assert np.asarray(found.shadow).any()  # the cast shadow is seen, and not taken for the person


def test_triangulation_and_the_root_guess_recover_the_truth():
    motion, rig, scene = small_scene()
    joints = np.asarray(scene.joints3d[0])
    uv, _, _ = project_points(rig, jnp.asarray(joints))
    pixels = np.asarray(uv).swapaxes(0, 1)  # (C, J, 2)
    points, seen = triangulate(rig, pixels, np.ones(pixels.shape[:2]))
    assert seen.all()
    np.testing.assert_allclose(points, joints, atol=1e-6)
    one = np.ones(pixels.shape[:2])
    one[1:, 3] = 0  # joint 3 seen by one camera only
    assert not triangulate(rig, pixels, one)[1][3]
    keypoints = np.concatenate([pixels, np.ones(pixels.shape[:2] + (1,))], axis=-1)
    xy, heading, how = root_guess(rig, motion.body.skeleton, keypoints=keypoints)
    pose = np.asarray(scene.pose[0])
    assert how == "keypoints"
    np.testing.assert_allclose(xy, pose[:2], atol=1e-6)
    assert abs(np.angle(np.exp(1j * (heading - pose[3])))) < 0.05
    xy, heading, how = root_guess(rig, motion.body.skeleton, silhouettes=scene.silhouettes[:, 0])
    # noisy 40x30 views (clutter blobs, foot shadows), where a pixel spans 0.15 m at the body
    assert how == "silhouette centroids" and heading is None and np.linalg.norm(xy - pose[:2]) < 0.2
    with pytest.raises(ValueError, match="fewer than two cameras"):
        root_guess(rig, motion.body.skeleton, silhouettes=np.zeros_like(scene.silhouettes[:, 0]))


def test_start_search_settings_are_checked():
    from jaxtrack.tracking import StartSearch

    assert StartSearch().height_spread == 0.0
    for bad in (-0.01, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="height_spread"):
            StartSearch(height_spread=bad)
    with pytest.raises(ValueError, match="particles"):
        StartSearch(particles=0)


def test_the_automatic_start_holds_the_root_at_the_motion_s_height_on_the_person_s_legs():
    """``root_height_legs``: where the body is the person's own (the file's skeleton), the root
    is held at the motion's height times their legs over the motion's; on a guessed body (the
    default) at the motion's height as given."""
    from jaxtrack.manifold import make_gpdm
    from jaxtrack.tracking import StartSearch, leg_length

    motion, _, scene = small_scene(num_frames=6, width=40, height=30, noisy=False)
    model = make_gpdm([np.asarray(motion.pose)[:, 6:]], 2)
    tall = scene.replace(skeleton_offsets=1.1 * np.asarray(scene.body().skeleton.offsets), joints3d=None)
    search = StartSearch(particles=8, layers=1)
    common = {"key": jax.random.key(0), "start": "auto", "start_model": model, "root_height": 0.9, "start_search": search}
    own = prepare_test(tall, "tall", root_height_legs=0.8, **common)
    assert own.body_source == "file" and leg_length(own.body) == pytest.approx(1.1 * leg_length(scene.body()), rel=1e-5)
    root_z = list(own.body.skeleton.pose_layout).index("root_z")
    assert float(own.initial_pose[root_z]) == pytest.approx(0.9 * leg_length(own.body) / 0.8, abs=1e-5)
    guessed = prepare_test(tall, "guessed", body="default", root_height_legs=0.8, **common)
    assert float(guessed.initial_pose[root_z]) == pytest.approx(0.9, abs=1e-6)
    unscaled = prepare_test(tall, "unscaled", **common)  # no legs given: the height as given
    assert float(unscaled.initial_pose[root_z]) == pytest.approx(0.9, abs=1e-6)


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_the_automatic_start_lands_near_the_truth_without_reading_it():
    from jaxtrack.manifold import make_gpdm

    motion, _, scene = small_scene(num_frames=4, width=80, height=60, noisy=False)
    model = make_gpdm([np.asarray(motion.pose)[:, 6:]], 2)
    height = float(np.mean(np.asarray(motion.pose)[:, 2]))
    blind = scene.replace(joints3d=None, pose=None, pose_layout=None)
    found = prepare_test(blind, "blind", key=jax.random.key(0), body="default", start="auto", start_model=model,
                         root_height=height)
    assert found.truth_joints is None and np.isnan(found.start_error_mm)
    start = np.asarray(forward_kinematics(found.body.skeleton, found.initial_pose), np.float64)
    error = 1000 * np.mean(np.linalg.norm(start - np.asarray(scene.joints3d[0]), axis=-1))
    assert error < 60, error
    # the search holds the root's height at the one given (StartSearch.height_spread = 0)
    root_z = list(found.body.skeleton.pose_layout).index("root_z")
    assert float(found.initial_pose[root_z]) == pytest.approx(height, abs=1e-6)
    scored = prepare_test(scene, "scored", key=jax.random.key(0), body="default", start="auto", start_model=model, root_height=height)
    assert scored.start_error_mm == pytest.approx(error, abs=1e-3)
    # 004's blobs fit their evidence from a start: the search reads the silhouettes' likelihood, so it finds the same pose
    said = []
    blobs = prepare_test(blind, "blobs", key=jax.random.key(0), body="default", start="auto", start_model=model, root_height=height,
                         likelihood="blobs", say=said.append)
    np.testing.assert_array_equal(np.asarray(blobs.initial_pose), np.asarray(found.initial_pose))
    assert any("searched with the silhouette likelihood" in line for line in said)
    with pytest.raises(ValueError, match="start_model and root_height"):
        prepare_test(scene, "x", key=jax.random.key(0), start="auto")
    with pytest.raises(ValueError, match="needs ground truth"):
        prepare_test(blind, "blind", key=jax.random.key(0))


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (ffmpeg writes and reads 8 videos)
@pytest.mark.xdist_group("colour_film")
def test_videos_read_back_into_a_sequence_and_bad_input_is_named(filmed, tmp_path):
    motion, rig, solid, pictures, masks = filmed
    empty, _ = render_rgb(jax.random.key(1), solid, rig, motion.pose[:4], fps=30.0, with_body=False, chunk=2)
    names = [str(n) for n in rig.names]
    videos = [tmp_path / f"{n}.mp4" for n in names]
    backgrounds = [tmp_path / f"bg_{n}.mp4" for n in names]
    with VideoWriter(videos, 30.0) as writer:
        writer.write(pictures[:, :3])
        writer.write(pictures[:, 3:])
    with VideoWriter(backgrounds, 30.0) as writer:
        writer.write(empty)
    save_calibration(tmp_path / "rig.json", rig)
    read = sequence_from_video(videos, rig, background=backgrounds)
    assert read.stopped is None and read.total_frames == 6 and read.sequence.fps == pytest.approx(30.0)
    assert read.sequence.silhouettes.shape == (2, 6, 48, 64)
    overlap = (read.sequence.silhouettes > 0) & masks
    # H.264 (chroma at half resolution) around a person 20 pixels tall: the plumbing is tested here
    assert overlap.sum() / ((read.sequence.silhouettes > 0) | masks).sum() > 0.5
    with pytest.raises(ValueError, match="give one video per camera"):
        sequence_from_video(videos[:1], rig)
    small = default_rig(80, 60, num_views=2)
    with pytest.raises(VideoFileError, match="calibration is for 80x60"):
        sequence_from_video(videos, small)
    # A camera that sees nobody from frame 4 on: the frames before are kept, the reason given.
    blank = pictures.copy()
    blank[1, 4:] = np.asarray(empty[1, :2])
    cut = [tmp_path / f"cut_{n}.mp4" for n in names]
    with VideoWriter(cut, 30.0) as writer:
        writer.write(blank)
    read = sequence_from_video(cut, rig, background=backgrounds)
    assert read.sequence.num_frames == 4 and "camera 'C2' sees nobody at frame 4" in read.stopped
    with pytest.raises(ValueError, match="even width and height"), VideoWriter([tmp_path / "odd.mp4"], 30.0) as writer:
        writer.write(np.zeros((1, 1, 5, 5, 3), np.uint8))


def _png_folders(root, pictures, names):
    """One folder of PNG frames per camera (lossless, unlike H.264)."""
    import imageio.v3 as iio

    folders = []
    for name, frames in zip(names, pictures):
        folder = root / name
        folder.mkdir(parents=True)
        for t, frame in enumerate(frames):
            iio.imwrite(folder / f"{t:04d}.png", frame)
        folders.append(folder)
    return folders


@pytest.mark.xdist_group("colour_film")
def test_a_video_an_encoder_cropped_reads_as_the_whole_on_the_pixels_they_share(filmed, tmp_path):
    """Camera C2's frames 8 px narrower than its calibration (an encoder's crop to a multiple of
    8): read with a warning naming the file and both sizes, padded blank at the right, and its
    silhouettes are the uncropped video's on the pixels they share. A difference no encoder
    makes is refused, saying what to check."""
    motion, rig, solid, pictures, _ = filmed
    names = [str(n) for n in rig.names]
    empty, _ = render_rgb(jax.random.key(1), solid, rig, motion.pose[:4], fps=30.0, with_body=False, chunk=2)
    whole = _png_folders(tmp_path / "whole", pictures, names)
    whole_empty = _png_folders(tmp_path / "whole_empty", empty, names)
    cropped = _png_folders(tmp_path / "cropped", [pictures[0], pictures[1][:, :, :56]], names)  # C2: 64 -> 56 px wide
    cropped_empty = _png_folders(tmp_path / "cropped_empty", [empty[0], empty[1][:, :, :56]], names)
    said = []
    expected = sequence_from_video(whole, rig, fps=30.0, background=whole_empty).sequence.silhouettes
    read = sequence_from_video(cropped, rig, fps=30.0, background=cropped_empty, say=said.append).sequence.silhouettes
    warning = [s for s in said if s.startswith("warning:")]
    assert len(warning) == 2 and "background" in warning[0]
    assert "C2" in warning[1] and "56x48" in warning[1] and "64x48" in warning[1]
    assert "8 px cropped at the right, read as blank" in warning[1]
    assert read.shape == expected.shape == (2, 6, 48, 64)
    np.testing.assert_array_equal(read[0], expected[0])
    np.testing.assert_array_equal(read[1, :, :, :56], expected[1, :, :, :56])
    assert not read[1, :, :, 56:].any()  # the blank pixels are background
    assert expected[1].any()
    resized = [pictures[0], pictures[1][:, ::2, ::2]]  # 32x24: a resized video, not an encoder's crop
    with pytest.raises(VideoFileError, match=r"frames of 32x24, but its calibration is for 64x48 .*calibration's camera order"):
        sequence_from_video(_png_folders(tmp_path / "resized", resized, names), rig, fps=30.0)


def _filmed_walk(tmp_path, motion_frames: int, frames: int, size, views: int):
    """A walk's sequence file and its film (``jaxtrack scene --rgb --video``, 4 background
    frames): ``(walk.npz, film folder)``."""
    from jaxtrack.cli import main
    from jaxtrack.data import motion_sequence
    from jaxtrack.io import save_sequence

    motion = generate_motion("walk", "S1", num_frames=motion_frames, fps=30.0, key=jax.random.key(0))
    walk = tmp_path / "walk.npz"
    save_sequence(walk, motion_sequence(motion))
    film = tmp_path / "film"
    assert main(["scene", str(walk), "--rgb", "--video", str(film), "--frames", str(frames), "--width", str(size[0]),
                 "--height", str(size[1]), "--views", str(views), "--background-frames", "4"]) == 0
    return walk, film


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache
def test_film_then_track_from_video_without_ground_truth(tmp_path, capsys, monkeypatch):
    """``scene --rgb --video`` writes what a user of real cameras has; ``track --video`` reads
    it back with no ground truth (automatic start), writes the estimates and an overlay video,
    and exits 4 naming the frame where a camera stops seeing the person, keeping the poses;
    chunked and interrupted with no keypoints, it keeps the first chunk's estimates."""
    from jaxtrack.cli import main
    from jaxtrack.io import load_sequence

    walk, film = _filmed_walk(tmp_path, 12, 8, (96, 72), 3)
    assert "calibration.json, keypoints.npz" in capsys.readouterr().out
    names = ["C1", "C2", "C3"]
    assert all((film / f"{n}.mp4").exists() and (film / "background" / f"{n}.mp4").exists() for n in names)
    truth = load_sequence(film / "truth.npz")
    assert truth.silhouettes.shape == (3, 8, 72, 96) and truth.joints3d.shape == (8, 15, 3)
    model = tmp_path / "m.eqx"
    assert main(["fit", str(walk), "--out", str(model), "--steps", "5"]) == 0
    videos = [str(film / f"{n}.mp4") for n in names]
    args = ["track", "--video", *videos, "--background", *[str(film / "background" / f"{n}.mp4") for n in names],
            "--calibration", str(film / "calibration.json"), "--keypoints", str(film / "keypoints.npz"),
            "--likelihood", "silhouette+keypoints", "--model", str(model), "--validation", str(walk), "--method", "sir",
            "--budget", "64", "--body", "default"]
    assert main([*args, "--out", str(tmp_path / "est"), "--overlay", str(tmp_path / "est.mp4")]) == 0
    out = capsys.readouterr().out
    assert "automatic start: the root placed by the keypoints" in out and "wrote" in out
    estimate = load_sequence(tmp_path / "est.npz")
    assert estimate.joints3d.shape == (8, 15, 3) and estimate.silhouettes is None
    error = 1000 * np.mean(np.linalg.norm(estimate.joints3d - truth.joints3d, axis=-1))
    assert error < 150, error  # tracked, roughly: 64 particles, a 5-step manifold
    from jaxtrack.io import MultiViewVideo

    def frames_of(path):
        with MultiViewVideo([path]) as video:
            return np.concatenate([block for _, block in video.chunks(8)], axis=1)  # (1, T, H, W, 3)

    overlay = frames_of(tmp_path / "est.mp4")
    assert overlay.shape == (1, 8, 72, 3 * 96, 3)
    # COCO files per camera with a bystander, more confident, in C1 and C2 (40 px to the right and
    # 30 px down: a second person): associated across the cameras, the walker is followed.
    import json

    from jaxtrack.body import HUMANEVA_JOINTS

    detections = np.asarray(np.load(film / "keypoints.npz")["keypoints"], np.float64)  # (3, 8, 15, 3)
    coco = ["head"] * 5 + ["lshoulder", "rshoulder", "lelbow", "relbow", "lwrist", "rwrist", "lhip", "rhip", "lknee", "rknee",
                           "lankle", "rankle"]
    order = [HUMANEVA_JOINTS.index(n) for n in coco]
    files = []
    for c, name in enumerate(names):
        results = []
        for t in range(8):
            person = detections[c, t][order]
            if c < 2:
                other = person + np.where(person[:, 2:] > 0, [40.0, 30.0, 0.0], 0.0)
                results.append({"image_id": t, "keypoints": other.ravel().tolist(), "score": 1.0})
            results.append({"image_id": t, "keypoints": person.ravel().tolist(), "score": 0.8})
        files.append(tmp_path / f"{name}.json")
        files[-1].write_text(json.dumps(results))
    keyed = [*args]
    keyed[keyed.index("--keypoints") + 1] = str(files[0])
    keyed[keyed.index("--keypoints") + 2:keyed.index("--keypoints") + 2] = [str(f) for f in files[1:]]
    assert main([*keyed, "--out", str(tmp_path / "coco")]) == 0
    out = capsys.readouterr().out
    assert "person 0 (followed): seen by C1, C2, C3" in out and "followed through 8 of 8 frames" in out
    followed = load_sequence(tmp_path / "coco.npz").keypoints2d[:, :, 2:]  # the joints COCO marks (not pelvis, thorax)
    seen = followed[..., 2] > 0
    assert seen.mean() > 0.8
    np.testing.assert_allclose(followed[..., :2][seen], detections[:, :, 2:, :2][seen], atol=1e-3)
    # Camera C2 sees nobody from frame 5: frames 0-4 tracked and written, exit status 4.
    with VideoWriter([tmp_path / "C2_cut.mp4"], 30.0) as writer:
        frames = frames_of(videos[1])
        frames[:, 5:] = frames_of(film / "background" / "C2.mp4")[:, :3]
        writer.write(frames)
    cut = [videos[0], str(tmp_path / "C2_cut.mp4"), videos[2]]
    args[2:5] = cut
    assert main([*args, "--out", str(tmp_path / "cut")]) == 4
    assert "camera 'C2' sees nobody at frame 5" in capsys.readouterr().err
    assert load_sequence(tmp_path / "cut.npz").num_frames == 5
    # Chunked, from the videos alone (no keypoints: nothing per frame is kept but the estimates),
    # interrupted in the second chunk: the first chunk's partial file is a valid sequence.
    alone = [a for a in args if a != "silhouette+keypoints"]
    alone[2:5] = videos  # the whole films
    alone[alone.index("--keypoints"):alone.index("--keypoints") + 2] = []
    alone[alone.index("--likelihood") + 1:alone.index("--likelihood") + 1] = ["silhouette"]
    assert main([*alone, "--chunk-frames", "3", "--out", str(tmp_path / "chunked")]) == 0
    assert "3/8 frames tracked" in capsys.readouterr().out and load_sequence(tmp_path / "chunked.npz").num_frames == 8
    interrupt_the_second_chunk(monkeypatch)
    assert main([*alone, "--chunk-frames", "3", "--out", str(tmp_path / "stopped")]) == 130
    kept = load_sequence(tmp_path / "stopped.partial.npz")
    assert kept.num_frames == 3 and kept.joints3d.shape == (3, 15, 3) and kept.has_cameras
    monkeypatch.undo()
    # Bad input before any work: no calibration, a calibration for other cameras' sizes.
    assert main(["track", "--video", *videos, "--model", str(model), "--validation", str(walk), "--out", str(tmp_path / "x")]) == 2
    assert "--video needs the cameras" in capsys.readouterr().err


def _still_person_scene(tmp_path, free_frames: int):
    """Two cameras of 64x48 grey with sensor noise, 12 frames; a dark 'person' (rows 10-39,
    columns 24-33) stands still in every frame but the first ``free_frames``, where it stands
    at columns 4-13. Its keypoints (C, T, 15, 3) span its box: no empty-scene video."""
    rng = np.random.default_rng(0)
    frames = np.clip(120 + rng.normal(0, 2, (2, 12, 48, 64, 3)), 0, 255).astype(np.uint8)
    keypoints = np.zeros((2, 12, 15, 3), np.float32)
    for t in range(12):
        left = 4 if t < free_frames else 24
        frames[:, t, 10:40, left:left + 10] = 30
        keypoints[:, t, :, 0] = np.linspace(left + 1, left + 8, 15)
        keypoints[:, t, :, 1] = np.linspace(12, 37, 15)
        keypoints[:, t, :, 2] = 0.9
    return _png_folders(tmp_path, frames, ["C1", "C2"]), keypoints


def test_the_background_leaves_out_the_person_the_keypoints_place_and_a_still_person_is_flagged(tmp_path):
    """No empty-scene video and a person who stands still: the median of the video holds them.
    Each pixel's median over the frames whose keypoints leave it free recovers the background
    where a few frames show it, and the silhouettes fill the keypoints' box; where no frame
    shows it, the silhouettes miss the person and the cameras are flagged as untrusted."""
    from jaxtrack.tracking import MIN_COVERAGE, silhouette_coverage

    rig = default_rig(64, 48, num_views=2)
    folders, keypoints = _still_person_scene(tmp_path / "moved", free_frames=4)
    read = sequence_from_video(folders, rig, fps=30.0, keypoints=keypoints)
    assert read.untrusted_cameras() == [] and np.all(read.camera_coverage() > 0.9)
    person = read.sequence.silhouettes[:, 6:, 10:40, 24:34]
    assert person.mean() > 0.9 and read.sequence.silhouettes[:, 6:, :, 40:].sum() == 0
    # the median of every frame holds the still person: its silhouettes miss them
    import imageio.v3 as iio

    frames = np.stack([np.stack([iio.imread(p) for p in sorted(f.iterdir())]) for f in folders], axis=1)  # (T, C, H, W, 3)
    plain = fit_background(frames)
    masks = np.asarray(subtract_background(plain, frames).mask)
    assert np.nanmedian(silhouette_coverage(masks, keypoints.swapaxes(0, 1), 1)) < MIN_COVERAGE
    still, keypoints = _still_person_scene(tmp_path / "still", free_frames=0)
    read = sequence_from_video(still, rig, fps=30.0, keypoints=keypoints, through_empty=True)
    assert read.untrusted_cameras() == ["C1", "C2"] and np.all(read.camera_coverage() < MIN_COVERAGE)


def test_a_video_read_in_segments_is_the_video_read_at_once(tmp_path):
    """``VideoStream.read`` a few frames at a time (segments that end inside a decoded chunk)
    gives the silhouettes and keypoints of one read, frame for frame, then None."""
    from jaxtrack.tracking import open_video

    rig = default_rig(64, 48, num_views=2)
    folders, keypoints = _still_person_scene(tmp_path, free_frames=8)
    whole = sequence_from_video(folders, rig, fps=30.0, keypoints=keypoints).sequence
    with open_video(folders, rig, fps=30.0, keypoints=keypoints, chunk=4) as stream:
        segments = [stream.read(5), stream.read(5), stream.read(5)]
        assert stream.read(5) is None and stream.frames_read == 12 and stream.stopped is None
    assert [s.num_frames for s in segments] == [5, 5, 2]
    np.testing.assert_array_equal(np.concatenate([s.silhouettes for s in segments], axis=1), whole.silhouettes)
    np.testing.assert_array_equal(np.concatenate([s.keypoints2d for s in segments], axis=1), whole.keypoints2d)
    np.testing.assert_array_equal(segments[1].camera_K, whole.camera_K)  # at the tracking resolution, as the whole


def test_keypoints_shorter_than_the_videos_or_seeing_nobody_are_said_and_tracked_through(tmp_path):
    """Keypoints of 9 frames for 12 frames of video: the last 3 read as missing (confidence 0),
    with a warning; a frame where no camera's keypoints see anyone is counted and said; the
    silhouettes of every frame are kept."""
    rig = default_rig(64, 48, num_views=2)
    folders, keypoints = _still_person_scene(tmp_path, free_frames=8)
    short = keypoints[:, :9].copy()
    short[:, 5, :, 2] = 0.0  # nobody in frame 5
    said = []
    read = sequence_from_video(folders, rig, fps=30.0, keypoints=short, say=said.append)
    assert read.sequence.num_frames == 12 and read.stopped is None
    kept = read.source.keypoints2d
    np.testing.assert_array_equal(kept[:, :9], short)
    assert kept.shape == (2, 12, 15, 3) and not kept[:, 9:, :, 2].any()
    assert any("the keypoints hold 9 frames, the videos 12: frames 9-11 have no keypoints" in line for line in said)
    assert any("see the person in 1 of 9 frames (from frame 5)" in line for line in said)


@pytest.mark.xdist_group("colour_film")
def test_frames_averaged_down_as_they_are_decoded(filmed, tmp_path):
    """``reduce``: image folders averaged in numpy, video files by ffmpeg's area scaler (in RGB),
    both the mean of each block of the whole frame (a folder exactly, a video within a level),
    an encoder's crop filled blank before the average; ``sequence_from_video`` at a resolution
    holds the cameras and keypoints rescaled, and gives them back at the videos' size."""
    from jaxtrack.io import MultiViewVideo, fit_frames, reduce_frames

    motion, rig, solid, pictures, _ = filmed
    names = [str(n) for n in rig.names]
    folders = _png_folders(tmp_path / "png", [pictures[0], pictures[1][:, :, :56]], names)  # C2 cropped by 8 px
    videos = [tmp_path / f"{n}.mp4" for n in names]
    with VideoWriter(videos, 30.0) as writer:
        writer.write(pictures)
    empty, _ = render_rgb(jax.random.key(1), solid, rig, motion.pose[:4], fps=30.0, with_body=False, chunk=2)
    backgrounds = _png_folders(tmp_path / "empty", empty, names)
    whole = np.stack([pictures[0], fit_frames(pictures[1][:, :, :56], 64, 48)])
    with MultiViewVideo(folders, frame_sizes=[(64, 48)] * 2, reduce=2) as video:
        assert video.sizes == ((32, 24),) * 2 and video.frame_sizes == ((64, 48),) * 2
        np.testing.assert_array_equal(np.concatenate([b for _, b in video.chunks(4)], axis=1), reduce_frames(whole, 2))
    with MultiViewVideo(videos, reduce=4) as small, MultiViewVideo(videos) as full:
        averaged = np.concatenate([b for _, b in small.chunks(4)], axis=1)
        expected = reduce_frames(np.concatenate([b for _, b in full.chunks(4)], axis=1), 4)
    assert averaged.shape == (2, 6, 12, 16, 3) and np.abs(averaged.astype(int) - expected).max() <= 1
    with pytest.raises(ValueError, match="cannot be reduced 3 times"):
        MultiViewVideo(videos, reduce=3)
    keypoints = np.zeros((2, 6, 15, 3), np.float32)
    keypoints[..., 0], keypoints[..., 1], keypoints[..., 2] = 31.5, 23.5, 1.0
    read = sequence_from_video(folders, rig, fps=30.0, keypoints=keypoints, resolution=(32, 24), background=backgrounds)
    assert read.reduce == 2 and read.sequence.silhouettes.shape == (2, 6, 24, 32)
    np.testing.assert_allclose(read.sequence.camera_K, np.asarray(rig.resized(32, 24).K), rtol=1e-6)
    np.testing.assert_allclose(read.sequence.keypoints2d[..., :2], np.broadcast_to([15.5, 11.5], (2, 6, 15, 2)))  # (x + 0.5) / 2 - 0.5
    source = read.source
    np.testing.assert_allclose(source.camera_K, np.asarray(rig.K), rtol=1e-6)
    np.testing.assert_array_equal(source.keypoints2d, keypoints)
    assert source.silhouettes is None and tuple(source.image_size[0]) == (64, 48)
    with pytest.raises(ValueError, match=r"cannot resample 64x48 images to 48x24: the target must divide the size \(e\.g\. 32x24"):
        sequence_from_video(folders, rig, fps=30.0, resolution=(48, 24))
    with pytest.raises(ValueError, match=r"the width would be averaged over 2 pixels and the height over 4; keep the aspect"):
        sequence_from_video(folders, rig, fps=30.0, resolution=(32, 12))


def test_the_tracking_resolution_is_chosen_from_the_person_size():
    """The preview: the smallest whole reduction with the longer side at 640 px or under; the
    tracking resolution: the largest multiple of it that keeps the person 120 px tall."""
    from jaxtrack.tracking import choose_reduction, common_reductions, preview_reduction

    portrait = [(1088, 1920)] * 4
    assert common_reductions(portrait) == [1, 2, 4, 8, 16, 32, 64]
    assert preview_reduction(portrait) == 4 and preview_reduction([(320, 240)]) == 1
    assert choose_reduction(portrait, 4, 373.0) == 4  # 93 px at the preview: kept
    assert choose_reduction(portrait, 4, 1500.0) == 8  # 187 px at 8, 94 at 16
    assert choose_reduction(portrait, 4, 4000.0) == 32
    assert choose_reduction([(1920, 1080)], 2, 900.0) == 6  # 150 px; 8 would leave 112


def test_the_person_height_that_chooses_the_resolution_is_measured_on_the_videos(tmp_path):
    """``resolution="auto"`` reads the person's height off the keypoints (their extent over 0.9),
    else off the silhouettes of the videos' frames, also when the background model comes from an
    empty-scene video (whose frames show nobody); a person under 120 px keeps the videos' size."""
    rig = default_rig(64, 48, num_views=2)
    folders, keypoints = _still_person_scene(tmp_path / "walk", free_frames=4)
    rng = np.random.default_rng(3)
    empty = np.clip(120 + rng.normal(0, 2, (2, 4, 48, 64, 3)), 0, 255).astype(np.uint8)
    backgrounds = _png_folders(tmp_path / "empty", empty, ["C1", "C2"])
    said = []
    read = sequence_from_video(folders, rig, fps=30.0, background=backgrounds, resolution="auto", say=said.append)
    assert read.reduce == 1 and any("the person is about 30 px tall (silhouettes)" in s for s in said), said
    said = []
    sequence_from_video(folders, rig, fps=30.0, keypoints=keypoints, resolution="auto", say=said.append)
    assert any("the person is about 28 px tall (keypoints)" in s for s in said), said  # rows 12-37: 25 px / 0.9


@pytest.mark.slow  # a 320x240 film looped to 150 and 1200 frames, tracked twice in subprocesses: about 2 minutes on 2 cores
def test_a_long_video_is_tracked_in_the_memory_of_one_segment(tmp_path):
    """``track --video`` reads and tracks a segment of ``--chunk-frames`` frames at a time: the
    peak resident memory of 1200 frames is that of 150 (the silhouettes and pixel samples of
    1200 frames of two 320x240 cameras alone would hold over 250 MB more)."""
    import subprocess
    import sys

    from jaxtrack.cli import main
    from jaxtrack.io import MultiViewVideo

    walk, film = _filmed_walk(tmp_path, 30, 30, (320, 240), 2)
    assert main(["fit", str(walk), "--out", str(tmp_path / "m.eqx"), "--steps", "5"]) == 0
    names = ["C1", "C2"]
    with MultiViewVideo([film / f"{n}.mp4" for n in names]) as video:
        clip = np.concatenate([block for _, block in video.chunks(30)], axis=1)  # (2, 30, 240, 320, 3)
    peaks = {}
    for frames in (150, 1200):
        looped = [tmp_path / f"{n}_{frames}.mp4" for n in names]
        with VideoWriter(looped, 30.0) as writer:
            for piece in range(frames // 30):  # there and back: no jump where the loop closes
                writer.write(clip if piece % 2 == 0 else clip[:, ::-1])
        argv = ["track", "--video", *map(str, looped), "--background", *[str(film / "background" / f"{n}.mp4") for n in names],
                "--calibration", str(film / "calibration.json"), "--model", str(tmp_path / "m.eqx"), "--method", "sir",
                "--budget", "32", "--body", "default", "--chunk-frames", "50", "--out", str(tmp_path / f"est_{frames}")]
        code = (f"import resource, sys; from jaxtrack.cli import main; rc = main({argv!r}); "
                "print('PEAK', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(rc)")
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1500)
        assert done.returncode == 0, done.stderr[-2000:]
        peaks[frames] = int(done.stdout.rsplit("PEAK", 1)[1]) / 1024  # MB
    from jaxtrack.io import load_sequence

    assert load_sequence(tmp_path / "est_1200.npz").num_frames == 1200
    assert peaks[1200] - peaks[150] < 100, peaks  # one pass holds over 250 MB more

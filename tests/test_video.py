"""Multi-view video input: image folders and video files per camera, read in chunks and
synchronised by frame index; unequal lengths, missing sources and corrupt frames refused with the
file and the frame; frames sampled over a video for its background."""

import warnings

import imageio
import imageio.v3 as iio
import numpy as np
import pytest
from scipy import ndimage

from jaxtrack.io import MultiViewVideo, VideoFileError, encoder_size_difference, fit_frames, sample_frames_evenly


def _frames(count, seed, height=48, width=64):
    rng = np.random.default_rng(seed)
    smooth = ndimage.gaussian_filter(rng.random((count, height, width, 3)), (0, 4, 4, 0))
    return np.round(255 * (smooth - smooth.min()) / np.ptp(smooth)).astype(np.uint8)


def _folder(path, frames):
    path.mkdir()
    for t, frame in enumerate(frames):
        iio.imwrite(path / f"frame_{t:04d}.png", frame)
    return path


def test_image_folders_are_read_in_synchronised_chunks(tmp_path):
    views = [_frames(10, seed) for seed in range(3)]
    folders = [_folder(tmp_path / f"cam{c}", v) for c, v in enumerate(views)]
    with MultiViewVideo(folders) as video:
        assert video.num_frames == 10 and video.sizes == ((64, 48),) * 3 and video.names == ("C1", "C2", "C3")
        chunks = list(video.chunks(4))
    assert [first for first, _ in chunks] == [0, 4, 8] and chunks[-1][1].shape == (3, 2, 48, 64, 3)
    np.testing.assert_array_equal(np.concatenate([c for _, c in chunks], axis=1), np.stack(views))
    sampled = sample_frames_evenly(folders, count=4)
    np.testing.assert_array_equal(sampled, np.stack(views)[:, [0, 3, 6, 9]].swapaxes(0, 1))


# imageio-ffmpeg leaves its ffmpeg process's pipes to the garbage collector
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_video_file_decodes_close_to_its_frames(tmp_path):
    frames = _frames(12, 7)
    path = tmp_path / "cam.mp4"
    with warnings.catch_warnings():  # ffmpeg runs as a subprocess: JAX warns of the fork
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        writer = imageio.get_writer(path, format="FFMPEG", fps=30, codec="libx264", quality=9, macro_block_size=16)
        for frame in frames:
            writer.append_data(frame)
        writer.close()
    folder = _folder(tmp_path / "cam2", frames)
    with MultiViewVideo([path, folder], names=["video", "pictures"]) as video:
        assert video.num_frames == 12 and video.sizes == ((64, 48), (64, 48))
        decoded = np.concatenate([c for _, c in video.chunks(5)], axis=1)
    assert decoded.shape == (2, 12, 48, 64, 3)
    assert np.abs(decoded[0].astype(int) - frames).mean() < 4.0  # lossy, but the same pictures


# imageio-ffmpeg leaves its ffmpeg process's pipes to the garbage collector
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_bad_video_input_names_the_file_and_the_frame(tmp_path):
    a = _folder(tmp_path / "a", _frames(5, 0))
    b = _folder(tmp_path / "b", _frames(4, 1))
    with pytest.raises(VideoFileError, match=r"different numbers of frames: .*a 5, .*b 4"):
        MultiViewVideo([a, b])
    with pytest.raises(FileNotFoundError, match="no video or image folder"):
        MultiViewVideo([a, tmp_path / "nowhere.mp4"])
    c = _folder(tmp_path / "c", _frames(5, 2))
    (c / "frame_0003.png").write_bytes(b"\x89PNG not really")
    got = []
    with MultiViewVideo([a, c]) as video, pytest.raises(VideoFileError, match=r"frame_0003\.png: frame 3 cannot be decoded"):
        for first, _frames_read in video.chunks(1):
            got.append(first)
    assert got == [0, 1, 2]  # what was read before the bad frame was handed out
    (tmp_path / "junk.mp4").write_bytes(b"not a video at all")
    with pytest.raises(VideoFileError, match=r"junk\.mp4: not a readable video"):
        MultiViewVideo([tmp_path / "junk.mp4"])


def test_an_encoder_s_crop_or_pad_is_undone_at_the_right_and_bottom_edges(tmp_path):
    frames = _frames(3, 5)  # 64x48
    np.testing.assert_array_equal(fit_frames(frames, 64, 48), frames)
    padded = fit_frames(frames[:, :40, :56], 64, 48)  # cropped 8 px at the right, 8 at the bottom
    assert padded.shape == (3, 48, 64, 3) and not padded[:, 40:].any() and not padded[:, :, 56:].any()
    np.testing.assert_array_equal(padded[:, :40, :56], frames[:, :40, :56])
    np.testing.assert_array_equal(fit_frames(frames, 56, 40), frames[:, :40, :56])  # padded: cut off
    assert encoder_size_difference("a.mp4", "C1", (64, 48), (64, 48)) is None
    line = encoder_size_difference("a.mp4", "C1", (1080, 1920), (1088, 1920))
    assert line.startswith("a.mp4: camera 'C1'") and "1080x1920" in line and "1088x1920" in line
    assert "8 px cropped at the right, read as blank" in line
    assert "8 px padded at the bottom, cut off" in encoder_size_difference("a.mp4", "C1", (1088, 1088), (1088, 1080))
    for found, wanted in [((1072, 1920), (1088, 1920)), ((1084, 1920), (1088, 1920)), ((1920, 1088), (1088, 1920))]:
        with pytest.raises(VideoFileError, match="not an encoder's crop or pad"):  # 16 px; not a multiple of 8; rotated
            encoder_size_difference("a.mp4", "C1", found, wanted)
    # MultiViewVideo: a folder 8 px narrower than its frame size comes out at that size, said
    wide, narrow = _folder(tmp_path / "wide", frames), _folder(tmp_path / "narrow", frames[:, :, :56])
    with MultiViewVideo([wide, narrow], frame_sizes=[(64, 48), (64, 48)]) as video:
        assert video.source_sizes == ((64, 48), (56, 48)) and video.sizes == ((64, 48), (64, 48))
        assert len(video.adjusted) == 1 and "narrow" in video.adjusted[0]
        _, block = next(video.chunks(3))
    np.testing.assert_array_equal(block[1], fit_frames(frames[:, :, :56], 64, 48))
    np.testing.assert_array_equal(block[0], frames)

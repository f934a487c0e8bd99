"""Several people's detections associated across the cameras by their triangulation."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.camera import default_rig
from jaxtrack.data import DetectorNoise, detect_keypoints, generate_motion
from jaxtrack.tracking import associate_people, describe_people, find_people


def _people(frames=12):
    """A rig of 4 cameras at 640x480, the tracked walker's and a bystander's (T, 15, 3) joints,
    and each one's detections in every camera (C, T, 15, 3)."""
    rig = default_rig(640, 480, dtype=jnp.float64)
    walker = generate_motion("walk", "S1", num_frames=frames, fps=30.0, key=jax.random.key(0)).joints3d
    bystander = np.asarray(generate_motion("walk", "S2", num_frames=frames, fps=30.0, key=jax.random.key(1)).joints3d)
    bystander = bystander + np.array([0.0, -1.5, 0.0]) - bystander[:1, :1] * np.array([1, 1, 0])
    noise = DetectorNoise(noise_px=2.0, dropped=0.0)
    return (rig, np.asarray(walker), bystander, detect_keypoints(jax.random.key(2), walker, rig, noise),
            detect_keypoints(jax.random.key(3), bystander, rig, DetectorNoise(noise_px=2.0, dropped=0.0, confidence=1.0)))


def test_the_consistent_person_is_followed_where_a_bystander_is_more_confident_in_one_view():
    rig, walker, _, walker_2d, bystander_2d = _people()
    T = walker_2d.shape[1]
    # Camera 0 sees the bystander, more confident, first; cameras 1 and 2 see both; camera 3 the walker only.
    people = [[np.stack([bystander_2d[0, t], walker_2d[0, t]]) for t in range(T)],
              [np.stack([walker_2d[1, t], bystander_2d[1, t]]) for t in range(T)],
              [np.stack([bystander_2d[2, t], walker_2d[2, t]]) for t in range(T)],
              [walker_2d[3, t][None] for t in range(T)]]
    found = find_people(rig, [p[0] for p in people])
    assert [p.detections for p in found] == [(1, 0, 1, 0), (0, 1, 0, None)]  # the walker in 4 cameras, the bystander in 3
    np.testing.assert_allclose(found[0].joints, walker[0], atol=0.03)  # triangulated within 3 cm (2 px noise)
    association = associate_people(rig, people, fps=30.0)
    np.testing.assert_array_equal(association.keypoints, walker_2d)  # every camera, every frame: the walker's detection
    assert association.missing == 0 and association.found_again == ()
    assert describe_people(association, rig.names)[0].startswith("person 0 (followed): seen by C1, C2, C3, C4")
    other = associate_people(rig, people, fps=30.0, person=1)  # the user's choice: the bystander
    np.testing.assert_array_equal(other.keypoints[:3], bystander_2d[:3])
    assert not other.keypoints[3, :, :, 2].any()
    with pytest.raises(ValueError, match="person 2 asked for, but 2 people were found at frame 0"):
        associate_people(rig, people, fps=30.0, person=2)


def test_a_person_missing_from_every_view_is_found_again_and_a_far_one_is_not_taken():
    rig, walker, _, walker_2d, bystander_2d = _people()
    T = walker_2d.shape[1]
    gone = range(4, 7)  # the walker leaves every view for 3 frames; the bystander, 1.5 m away, stays
    # Back 1 m from where it left: within 3 m/s over the 4 frames at 10 Hz, plus 0.3 m.
    back = detect_keypoints(jax.random.key(2), walker + np.array([0.0, 1.0, 0.0]), rig, DetectorNoise(noise_px=2.0, dropped=0.0))
    people = [[np.stack([bystander_2d[c, t]] + ([] if t in gone else [(back if t > 6 else walker_2d)[c, t]])) for t in range(T)]
              for c in range(4)]
    association = associate_people(rig, people, fps=10.0)
    assert association.missing == 3 and association.found_again == (7,)
    assert not association.keypoints[:, 4:7, :, 2].any()  # the bystander is not taken meanwhile
    np.testing.assert_array_equal(association.keypoints[:, 7:], back[:, 7:])
    np.testing.assert_array_equal(association.keypoints[:, :4], walker_2d[:, :4])
    # At 30 Hz the same jump is beyond reach (0.7 m): the person stays missing rather than jump.
    assert associate_people(rig, people, fps=30.0).missing == T - 4


def test_nobody_seen_by_two_cameras_is_an_error():
    rig, _, _, walker_2d, _ = _people(4)
    alone = [[walker_2d[0, t][None] for t in range(4)]] + [[np.zeros((0, 15, 3))] * 4 for _ in range(3)]
    with pytest.raises(ValueError, match=r"no person is seen consistently by two cameras.*cameras' order"):
        associate_people(rig, alone, fps=30.0)

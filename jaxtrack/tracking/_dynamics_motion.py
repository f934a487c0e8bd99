"""The motion a tracker's dynamics are fitted on, when no validation file is given.

000 sec. 5.2 fits the dynamics' noise scales (and here the velocity, the ground prior's
clearance and the standing height of the automatic start) on validation motion. A user with
a recording has none, so ``track`` falls back, in this order, on:

1. the model file's own training motion: ``jaxtrack fit`` stores it in the file
   (``motion_record``: the training takes' poses, skeletons and frame rate);
2. for the trackers that need no manifold (SIR, APF) run with no model file, the embedded walk
   (``DEFAULT_MOTION``: the procedural walk of ``jaxtrack demo``) generated at the test's frame
   rate. Its frame-to-frame steps are the pose random walk's scales.

Fitting the noise scales on the manifold's own training motion rather than held-out motion
can only make them smaller (the training poses lie on the manifold): give ``--validation``
where held-out motion of the kind being tracked exists.
"""

from __future__ import annotations

import jax
import numpy as np

from ..io import Sequence

MOTION_KEY = "motion"  # the model header's ``extra`` entry that holds the training motion
POSE_DECIMALS = 6  # radians and metres: 1 micro-unit, well under any filter's noise
JOINT_DECIMALS = 4  # metres: 0.1 mm
DEFAULT_MOTION = ("walk", "S1", 240)  # the embedded motion: gait, synthetic subject, frames
_DEFAULT_MOTION_TAG = 90210  # folded into the run's key for the embedded walk's variability


def motion_record(sequences, names) -> dict:
    """The training takes as a JSON-serialisable record for a model file's ``extra``: each
    take's name, frame rate, subject, (T, D) poses and layout, and its skeleton (offsets, else
    its (T, J, 3) joints to fit one on, rounded to 0.1 mm)."""
    takes = []
    for sequence, name in zip(sequences, names):
        if sequence.pose is None:
            raise ValueError(f"{name}: a training take needs 'pose' to be stored with the model")
        take = {"name": str(name), "fps": float(sequence.fps),
                "pose": np.round(np.asarray(sequence.pose, np.float64), POSE_DECIMALS).tolist(),
                "pose_layout": [str(n) for n in sequence.pose_layout]}
        if sequence.subject is not None:
            take["subject"] = str(sequence.subject)
        if sequence.skeleton_offsets is not None:
            take["skeleton_offsets"] = np.asarray(sequence.skeleton_offsets, np.float64).tolist()
        elif sequence.joints3d is not None:
            take["joints3d"] = np.round(np.asarray(sequence.joints3d, np.float64), JOINT_DECIMALS).tolist()
        for key in ("joint_names", "parents"):
            value = getattr(sequence, key)
            if value is not None:
                take[key] = np.asarray(value).tolist()
        takes.append(take)
    return {"takes": takes}


def motion_from_record(record: dict, where: str) -> list[Sequence]:
    """The training takes of a model file's ``motion_record``, as sequences."""
    try:
        takes = record["takes"]
        return [Sequence.create(fps=take["fps"], subject=take.get("subject"), pose=np.asarray(take["pose"], np.float64),
                                pose_layout=np.asarray(take["pose_layout"]),
                                **{key: np.asarray(take[key]) for key in ("skeleton_offsets", "joints3d", "joint_names", "parents")
                                   if key in take})
                for take in takes]
    except (KeyError, TypeError, ValueError) as error:
        raise ValueError(f"{where}: its stored training motion is unreadable ({error}); give --validation") from None


def default_motion(fps: float, key) -> Sequence:
    """The embedded walk (``DEFAULT_MOTION``) at ``fps``, as a motion sequence."""
    from ..data import generate_motion, motion_sequence

    gait, subject, frames = DEFAULT_MOTION
    return motion_sequence(generate_motion(gait, subject, num_frames=frames, fps=float(fps),
                                           key=jax.random.fold_in(key, _DEFAULT_MOTION_TAG)))


def stored_motion(header: dict, where: str) -> dict:
    """The training motion record a model file's header stores (``motion_record``).

    Raises:
        ValueError: a model file fitted before jaxtrack stored it, naming ``where``.
    """
    stored = (header.get("extra") or {}).get(MOTION_KEY)
    if stored is None:
        raise ValueError(f"{where} does not store its training motion (fitted by an older jaxtrack): give --validation "
                         "(a motion file the dynamics are fitted on), or refit it with 'jaxtrack fit'")
    return stored


def dynamics_motion(validation, header: dict | None, *, fps: float, key, model_name: str = "the model file") -> tuple[list[Sequence], str]:
    """The motion the dynamics are fitted on, and where it came from (for the report).

    Args:
        validation: a validation ``Sequence``, a list of them, or None.
        header: the model file's header (None: no model file).
        fps: the test's frame rate (the embedded walk is generated at it).
        key: PRNG key (the embedded walk's stride variability).

    Raises:
        ValueError: a model file that stores no training motion, with no validation given.
    """
    if validation is not None:
        sequences = [validation] if isinstance(validation, Sequence) else list(validation)
        if not sequences:
            raise ValueError("validation is an empty list: give one validation sequence or more, or None")
        return sequences, "the validation motion"
    if header is None:
        gait, subject, frames = DEFAULT_MOTION
        return [default_motion(fps, key)], (f"the embedded {gait} ({subject}, {frames} frames at {fps:g} Hz: no model file "
                                            "and no validation motion)")
    sequences = motion_from_record(stored_motion(header, model_name), model_name)
    frames = sum(len(s.pose) for s in sequences)
    return sequences, f"the model's own training motion ({len(sequences)} take{'s' if len(sequences) > 1 else ''}, {frames} frames)"

"""The command line's error handling beside the bad-input corpus (tests/bad_inputs/, where every
malformed file is one case): ``--debug`` shows the traceback, and an error that is not bad input
(a bug, here in a plugin) says so in one line."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from jaxtrack.cli import main
from jaxtrack.io import save_sequence

from helpers import small_scene

sys.path.insert(0, str(Path(__file__).resolve().parent / "bad_inputs"))

from corpus import CASES


@pytest.mark.slow
def test_debug_shows_the_traceback_and_a_bug_is_named_as_one(tmp_path, capsys):
    argv = next(c for c in CASES if c.name == "ASF bone length 0").build(tmp_path)
    with pytest.raises(ValueError, match="length must be positive"):
        main(["--debug", *argv])
    plugin = tmp_path / "broken.py"
    plugin.write_text(
        "from jaxtrack.tracking import TrackerRecipe, register_tracker\n"
        "def fit(key, motion):\n"
        "    raise KeyError('a bug in the plugin')\n"
        "register_tracker(TrackerRecipe('broken', 'Broken', 'fails', fit=fit, build=lambda *a: None), replace=True)\n"
    )
    scene = tmp_path / "scene.npz"
    save_sequence(scene, small_scene(num_frames=4)[-1])
    model = tmp_path / "m.eqx"
    assert main(["fit", str(scene), "--out", str(model), "--steps", "1"]) == 0
    capsys.readouterr()
    argv = ["track", str(scene), "--plugin", str(plugin), "--method", "broken", "--model", str(model), "--validation", str(scene),
            "--out", str(tmp_path / "est")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "internal error: KeyError" in err and "--debug" in err and "Traceback" not in err
    with pytest.raises(KeyError, match="a bug in the plugin"):
        main(["--debug", *argv])

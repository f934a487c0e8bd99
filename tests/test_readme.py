"""The README's quick example must keep working."""

import os
import re

import numpy as np
import pytest


@pytest.mark.slow  # 13 s or more on 2 cores with an empty compilation cache (docs/testing.md)
def test_quick_example_runs():
    path = os.path.join(os.path.dirname(__file__), "..", "README.md")
    with open(path, encoding="utf-8") as handle:
        text = handle.read()
    code = re.search(r"## Quick example\n\n(?:<!--.*?-->\n)?```python\n(.*?)```", text, re.S).group(1)
    assert len(code.splitlines()) <= 20
    namespace = {}
    # running the README's own example is the point of this test
    exec(compile(code, "README quick example", "exec"), namespace)  # noqa: S102
    assert namespace["info"].estimate.shape == (40, 32)
    error = float(namespace["error"])
    # SIR with a random walk fitted on another walk drifts here (95-120 mm over keys 3-8): this
    # checks that the example runs and follows the person, not the tracker's accuracy.
    assert np.isfinite(error) and error < 200, error

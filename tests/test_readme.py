"""The README's quick example must keep working."""

import os
import re

import numpy as np


def test_quick_example_runs():
    path = os.path.join(os.path.dirname(__file__), "..", "README.md")
    with open(path, encoding="utf-8") as handle:
        text = handle.read()
    code = re.search(r"## Quick example\n\n```python\n(.*?)```", text, re.S).group(1)
    assert len(code.splitlines()) <= 20
    namespace = {}
    exec(compile(code, "README quick example", "exec"), namespace)
    loglik = np.asarray(namespace["loglik"])
    assert loglik.shape == (500,) and np.all(np.isfinite(loglik)) and np.all(loglik <= 0)

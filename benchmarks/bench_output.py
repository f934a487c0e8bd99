"""What every benchmark does with its figures besides printing them: ``--json PATH``."""

from __future__ import annotations

import json
import time


def write_json(rows, path: str | None) -> None:
    """Write ``rows`` (JSON-serialisable) to ``path`` with indent 1; nothing when ``path`` is None.
    Called after each row by the long benchmarks, so an interrupted run keeps what it measured."""
    if path:
        with open(path, "w") as handle:
            json.dump(rows, handle, indent=1)


def pin_threads(threads: int) -> None:
    """Pin XLA's CPU thread pool to ``threads`` cores (before JAX is imported; an ``XLA_FLAGS``
    already set wins), so that timings on a shared machine use the cores they were given."""
    import os

    os.environ.setdefault("XLA_FLAGS", f"--xla_cpu_multi_thread_eigen=true intra_op_parallelism_threads={threads}")


def add_output_arguments(parser, plot: str | None = None) -> None:
    """The options every benchmark shares: ``--threads`` (for ``pin_threads``), ``--json PATH``
    and, when ``plot`` describes a figure, ``--plot PNG``."""
    parser.add_argument("--threads", type=int, default=2, help="CPU threads for XLA (pin them to the cores you have)")
    parser.add_argument("--json", metavar="PATH", help="also write the rows to this JSON file")
    if plot is not None:
        parser.add_argument("--plot", metavar="PNG", help=plot)


def median_seconds(fn, repeats: int) -> float:
    """The median wall time of ``repeats`` calls of ``fn`` (which must block until done)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return sorted(times)[len(times) // 2]

"""Settings of the HumanEva-style experiment (defaults: paper 000 sec. 6.1): a
``tracking.TrackingSpec`` (how every tracker tracks) plus the experiment's own settings (which
trackers, how many runs, how many frames, the seed)."""

from __future__ import annotations

import dataclasses

from ..errors import ConfigurationError
from ..tracking import PAPER_TRACKERS, TrackingSpec, get_tracker


@dataclasses.dataclass(frozen=True)
class ExperimentConfig(TrackingSpec):
    """Every field of ``tracking.TrackingSpec`` (the budget, the manifold and its fit, the
    likelihood, the body, the ground prior, velocity and residual; validated there), and:

    Attributes:
        methods: registered tracker names (``jaxtrack.tracking.available_trackers()``).
        runs: runs per tracker, each with its own key.
        batch_runs: track a tracker's runs on a test sequence in one compiled call (``jax.vmap``
            over the runs' keys; ``tracking.track_runs``): the same runs up to float rounding,
            fewer dispatches; frames/s is then the batch's frames over its time, compile included.
        frames: track only the first ``frames`` frames of each test sequence (None: all).
        seed: base PRNG seed; the tracker named ``m`` runs with keys folded from
            ``fold_in(key(seed), tracking.tracker_stream(m))`` (a hash of its name).

    ``config.spec`` is the ``TrackingSpec`` alone.
    """

    methods: tuple[str, ...] = PAPER_TRACKERS
    runs: int = 5
    batch_runs: bool = False
    frames: int | None = None
    seed: int = 0

    def __post_init__(self):
        super().__post_init__()
        if not self.methods:
            raise ConfigurationError("the experiment needs at least one tracker in methods")
        if len(set(self.methods)) != len(self.methods):
            raise ConfigurationError(f"methods lists a tracker twice: {list(self.methods)}")
        if isinstance(self.runs, bool) or not isinstance(self.runs, int) or self.runs < 1:
            raise ConfigurationError(f"runs must be a positive integer, got {self.runs!r}")
        if self.frames is not None and (isinstance(self.frames, bool) or not isinstance(self.frames, int) or self.frames < 1):
            raise ConfigurationError(f"frames must be a positive integer or None, got {self.frames!r}")
        for method in self.methods:  # unknown names: ValueError listing the registered ones
            self.check_method(method)

    @property
    def needs_manifold(self) -> bool:
        return any(get_tracker(m).needs_manifold for m in self.methods)

    @property
    def manifold_specs(self) -> tuple[tuple[str, int], ...]:
        """The ``(kind, latent_dim)`` manifolds the experiment fits, in the order of the methods."""
        return tuple(dict.fromkeys(s for s in map(self.manifold_spec_of, self.methods) if s is not None))

    @property
    def manifold_kinds(self) -> tuple[str, ...]:
        """The manifold kinds the experiment fits, in the order of the methods."""
        return tuple(dict.fromkeys(kind for kind, _ in self.manifold_specs))

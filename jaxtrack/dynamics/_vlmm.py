"""Variable-length Markov model over motion-prototype labels (004 sec. 5.2; Ron, Singer and
Tishby 1996; Galata, Johnson and Hogg 2001).

Learning (host side, counting): every context ``s`` (the last ``|s| <= max_memory`` labels,
oldest first) seen at least ``min_count`` times gets its next-label distribution ``P(.|s)``; the
full suffix tree is pruned bottom-up, a context ``s = a s'`` surviving when it, or a longer
context below it, predicts differently enough from its suffix ``s'``:
``P(s) KL(P(.|s) || P(.|s')) >= threshold`` (the weighted KL criterion). Predictions are
smoothed, ``gamma(s, k) = (1 - K g) P(k|s) + g``.

Prediction (inside jit): the pruned tree compiled to a probabilistic finite-state automaton
``(Q, K, tau, gamma, s)`` whose states are the tree's contexts closed under prefixes (so that the
longest suffix of ``history + k`` among them is ``tau(state, k)``: constant cost per frame,
tables as arrays and the state as an integer). State 0 is the empty context.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._custom_types import Array, Float, Int, PRNGKeyArray


@dataclasses.dataclass(frozen=True)
class SuffixTree:
    """A pruned prediction suffix tree.

    Attributes:
        num_symbols: K, the alphabet's size (labels 0..K-1).
        contexts: {context tuple (oldest first): (K,) smoothed next-label probabilities}; holds
            the empty context and every suffix of each context.
        max_memory: the longest context allowed.
    """

    num_symbols: int
    contexts: dict
    max_memory: int

    def longest_suffix(self, history) -> tuple:
        """The longest suffix of ``history`` (oldest first) that is a context of the tree."""
        history = tuple(int(h) for h in history)
        for length in range(min(len(history), self.max_memory), 0, -1):
            if history[-length:] in self.contexts:
                return history[-length:]
        return ()

    def predict(self, history) -> np.ndarray:
        """``gamma(history, .)``: (K,) probabilities of the next label."""
        return self.contexts[self.longest_suffix(history)]

    @property
    def depth(self) -> int:
        """The longest context kept (the memory the data asked for)."""
        return max(len(c) for c in self.contexts)


class VLMM(eqx.Module):
    """The automaton of a ``SuffixTree``.

    Attributes:
        transition: (Q, K) int, ``tau(q, k)``: the state after label k.
        output: (Q, K) ``gamma(q, .)``: the next label's probabilities in state q.
        initial: (Q,) ``s``: how often each state was occupied in the training sequences (where a
            lost tracker restarts, 004 sec. 6.1).
        contexts: the context of each state (oldest first), for reading; state 0 is ``()``.
    """

    transition: Int[Array, "q k"]
    output: Float[Array, "q k"]
    initial: Float[Array, " q"]
    contexts: tuple = eqx.field(static=True)

    @property
    def num_states(self) -> int:
        return self.transition.shape[0]

    @property
    def num_symbols(self) -> int:
        return self.transition.shape[1]

    def step(self, state: Int[Array, ...], label: Int[Array, ...]) -> Int[Array, ...]:
        """``tau(state, label)``, elementwise."""
        return self.transition[state, label]

    def sample(self, key: PRNGKeyArray, state: Int[Array, " n"]) -> Int[Array, " n"]:
        """One next label per state, drawn from ``gamma(state, .)``."""
        return jax.random.categorical(key, jnp.log(self.output[state]), axis=-1)

    def run(self, labels) -> Int[Array, " t"]:
        """The states after each label of a sequence, from the empty context."""
        def one(state, label):
            state = self.transition[state, label]
            return state, state

        return jax.lax.scan(one, jnp.zeros((), self.transition.dtype), jnp.asarray(labels, self.transition.dtype))[1]


def check_label_sequences(sequences, num_symbols: int | None = None) -> tuple[list, int]:
    """Validated label sequences (lists of ints) and the alphabet size."""
    if isinstance(sequences, np.ndarray) and sequences.ndim == 1:
        sequences = [sequences]
    out = []
    for i, seq in enumerate(sequences):
        arr = np.asarray(seq)
        if arr.ndim != 1 or not (np.issubdtype(arr.dtype, np.integer) or arr.size == 0):
            raise ValueError(f"label sequence {i} must be a 1-D array of integers, got shape {arr.shape} {arr.dtype}")
        if arr.size and arr.min() < 0:
            raise ValueError(f"label sequence {i} has a negative label")
        out.append(arr.astype(np.int64))
    if not out or sum(len(s) for s in out) < 2:
        raise ValueError("the VLMM needs at least two labels in its training sequences")
    top = max(int(s.max()) for s in out if s.size) + 1
    if num_symbols is None:
        num_symbols = top
    elif top > num_symbols:
        raise ValueError(f"labels run up to {top - 1} but num_symbols is {num_symbols}")
    return out, int(num_symbols)


def fit_suffix_tree(sequences, num_symbols: int | None = None, *, max_memory: int = 5, min_count: int = 2,
                    threshold: float = 1e-3, smoothing: float = 1e-3) -> SuffixTree:
    """Learn the pruned prediction suffix tree of label sequences (module docstring).

    Args:
        sequences: label sequences (each a 1-D int array), e.g. the training motion's prototype
            per frame.
        num_symbols: K (default: the largest label + 1).
        max_memory: N, the longest context (004 uses 5).
        min_count: a context must be followed by a label at least this often to be considered.
        threshold: the weighted KL criterion's epsilon (nats).
        smoothing: g, the probability floor of every label.

    Raises:
        ValueError: bad labels, a ``max_memory`` under 1, or a smoothing that leaves no
            probability (``K g >= 1``).
    """
    sequences, K = check_label_sequences(sequences, num_symbols)
    if isinstance(max_memory, bool) or not isinstance(max_memory, int) or max_memory < 1:
        raise ValueError(f"max_memory must be a positive integer, got {max_memory!r}")
    if not 0 <= smoothing < 1.0 / K:
        raise ValueError(f"smoothing must be in [0, 1/K) = [0, {1.0 / K:.3g}), got {smoothing}")
    counts: dict = {}
    for seq in sequences:
        for t in range(len(seq) - 1):  # the label at t+1 after each context ending at t
            nxt = int(seq[t + 1])
            for length in range(0, min(max_memory, t + 1) + 1):
                context = tuple(int(v) for v in seq[t + 1 - length:t + 1])
                counts.setdefault(context, np.zeros(K))[nxt] += 1
    if () not in counts:
        raise ValueError("the VLMM needs a sequence of two or more labels")
    total = counts[()].sum()
    kept = {c: n for c, n in counts.items() if n.sum() >= min_count or c == ()}
    prob = {c: n / n.sum() for c, n in kept.items()}

    def gain(context):
        p, q = prob[context], prob[context[1:]]
        kl = float(np.sum(np.where(p > 0, p * (np.log(np.maximum(p, 1e-300)) - np.log(np.maximum(q, 1e-12))), 0.0)))
        return kept[context].sum() / total * kl

    # Bottom-up: a context stays if it passes the criterion or a longer one below it stays.
    survivors = {()}
    for length in range(max_memory, 0, -1):
        for context in [c for c in kept if len(c) == length]:
            if context in survivors or gain(context) >= threshold:
                survivors.add(context)
                for cut in range(1, length):  # every suffix of a kept context is kept
                    survivors.add(context[cut:])
    smoothed = {c: (1.0 - K * smoothing) * prob[c] + smoothing for c in survivors}
    return SuffixTree(num_symbols=K, contexts=smoothed, max_memory=max_memory)


def compile_automaton(tree: SuffixTree, sequences=None) -> VLMM:
    """The PFSA of a suffix tree: states are its contexts closed under prefixes; ``tau(q, k)``
    the longest suffix of ``q + (k,)`` among them; ``gamma(q, .)`` the tree's prediction after
    ``q``. ``initial`` counts the states the ``sequences`` pass through (uniform over the
    states if None)."""
    states = set(tree.contexts)
    frontier = list(states)
    while frontier:  # close under prefixes (dropping the newest label), and their suffixes
        context = frontier.pop()
        for cut in range(len(context)):
            for candidate in (context[:len(context) - 1 - cut], context[cut + 1:]):
                if candidate not in states:
                    states.add(candidate)
                    frontier.append(candidate)
    ordered = sorted(states, key=lambda c: (len(c), c))
    index = {c: i for i, c in enumerate(ordered)}
    K = tree.num_symbols
    transition = np.zeros((len(ordered), K), np.int32)
    output = np.zeros((len(ordered), K))
    for context, i in index.items():
        output[i] = tree.predict(context)
        for k in range(K):
            extended = context + (k,)
            for cut in range(len(extended) + 1):
                if extended[cut:] in index:
                    transition[i, k] = index[extended[cut:]]
                    break
    visits = np.ones(len(ordered))
    if sequences is not None:
        visits = np.zeros(len(ordered))
        for seq in check_label_sequences(sequences, K)[0]:
            state = 0
            for label in seq:
                state = transition[state, int(label)]
                visits[state] += 1
    return VLMM(transition=jnp.asarray(transition), output=jnp.asarray(output), initial=jnp.asarray(visits / visits.sum()),
                contexts=tuple(ordered))


def fit_vlmm(sequences, num_symbols: int | None = None, **options) -> tuple[VLMM, SuffixTree]:
    """``fit_suffix_tree`` then ``compile_automaton`` (``options`` go to the first)."""
    tree = fit_suffix_tree(sequences, num_symbols, **options)
    return compile_automaton(tree, sequences), tree

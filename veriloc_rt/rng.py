"""Named random streams derived from the one config seed.

Each consumer asks for its own stream by name (``"topology"``, ``"trajectory"``, ...), so adding
a new consumer never shifts the numbers another one draws.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any

import numpy as np


def _name_key(name: str) -> int:
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


def stream(seed: int, name: str, *index: int) -> np.random.Generator:
    """Independent generator for ``(seed, name, *index)``; same arguments, same numbers."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), _name_key(name), *map(int, index)]))


class KeptDraw:
    """The last values computed from generators, each kept under a key and the generator's state
    on entry: a call with an equal key from a generator in that state gets the value back, with
    the generator moved past its draws, as if computed again.

    :param size: values kept (the oldest is dropped)
    """

    def __init__(self, size: int = 1):
        self.size = int(size)
        self._entries: list[tuple] = []   # (key, state on entry, value, state after)

    def __call__(self, key: Any, rng: np.random.Generator, compute: Callable[[], Any]):
        """``compute()`` (which draws from ``rng``), or the value kept by an earlier call with an
        equal key and the same ``rng`` state, with ``rng`` moved past its draws."""
        state = rng.bit_generator.state
        for e in self._entries:
            if e[0] == key and e[1] == state:
                rng.bit_generator.state = e[3]
                return e[2]
        value = compute()
        self._entries = [(key, state, value, rng.bit_generator.state)] + self._entries[:self.size - 1]
        return value

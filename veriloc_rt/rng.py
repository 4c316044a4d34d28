"""Named random streams derived from the one config seed.

Each consumer asks for its own stream by name (``"topology"``, ``"trajectory"``, ...), so adding
a new consumer never shifts the numbers another one draws.
"""

from __future__ import annotations

import hashlib

import numpy as np


def _name_key(name: str) -> int:
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


def stream(seed: int, name: str, *index: int) -> np.random.Generator:
    """Independent generator for ``(seed, name, *index)``; same arguments, same numbers."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), _name_key(name), *map(int, index)]))

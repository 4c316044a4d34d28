"""Independent oracles of TS 38.211 sequences for the NR tests."""

from __future__ import annotations


def gold_reference(c_init: int, length: int) -> list[int]:
    """TS 38.211 5.2.1 written out literally, one bit at a time (independent of the vectorised code)."""
    nc = 1600
    x1 = [1] + [0] * 30
    x2 = [(c_init >> i) & 1 for i in range(31)]
    for n in range(nc + length):
        x1.append((x1[n + 3] + x1[n]) % 2)
        x2.append((x2[n + 3] + x2[n + 2] + x2[n + 1] + x2[n]) % 2)
    return [(x1[n + nc] + x2[n + nc]) % 2 for n in range(length)]

"""The chain's statistically exact shortcuts and the switch back to the reference path.

A shortcut changes the random numbers a chain draws but not the distribution of anything the
receiver reads, so a run's outcome shares, error distributions and detector statistics are the
same distributions (``benchmarks/equivalence.py`` tests them against the reference path and
states its power; the reports are in ``docs/performance.md``). The shortcuts, by name:

* ``noise``: the UE's thermal noise drawn only on the REs its receiver reads (the PRS replicas'
  REs, every RE of the symbols the noise estimate reads and of the slots whose tags are checked),
  frequency domain (:class:`~veriloc_rt.phy.chain.downlink.DownlinkChannel`).

The environment variable ``VERILOC_RT_REFERENCE`` selects the reference path of the shortcuts it
names (comma separated; ``all``: every one), read when a chain is built: the same config and
seed then give the reference path's files, as before the shortcut.
"""

from __future__ import annotations

import os

__all__ = ["ENV", "SHORTCUTS", "reference"]

#: the environment variable naming the shortcuts to leave out
ENV = "VERILOC_RT_REFERENCE"
#: the shortcuts (module docstring)
SHORTCUTS = ("noise",)


def reference(name: str) -> bool:
    """Whether the shortcut ``name`` is left out (``VERILOC_RT_REFERENCE`` names it or ``all``)."""
    if name not in SHORTCUTS:
        raise ValueError(f"Argument `name` must be one of {SHORTCUTS}, not {name!r}")
    named = {p.strip() for p in os.environ.get(ENV, "").split(",") if p.strip()}
    return name in named or "all" in named

"""veriloc-rt: 5G NR OTDOA positioning security on ray-traced urban canyons and 38.901 UMa.

The public API is re-exported here lazily, so that ``import veriloc_rt`` stays light and Sionna
(with its LLVM back end) is only loaded by the functions that trace rays.
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "Config": "veriloc_rt.config",
    "load_config": "veriloc_rt.config",
    "load_preset": "veriloc_rt.config.presets",
    "preset_names": "veriloc_rt.config.presets",
    "DEFAULT_PRESET": "veriloc_rt.config.presets",
    "InputError": "veriloc_rt.errors",
    "CIR": "veriloc_rt.propagation.cir",
    "urban_canyon": "veriloc_rt.world.scene.canyon",
    "trace": "veriloc_rt.propagation.raytrace",
    "run": "veriloc_rt.sim.engine",
    "Results": "veriloc_rt.sim.engine",
    "gold_sequence": "veriloc_rt.phy.nr.prs",
    "prs_c_init": "veriloc_rt.phy.nr.prs",
    "prs_sequence": "veriloc_rt.phy.nr.prs",
    "uma_pathloss_db": "veriloc_rt.propagation.uma",
    "load_run": "veriloc_rt.report.tables",
    "RunTables": "veriloc_rt.report.tables",
    "export_parquet": "veriloc_rt.report.tables",
    "export_mat": "veriloc_rt.report.tables",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'veriloc_rt' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)


def __dir__() -> list[str]:
    """The module's own names and the lazy exports (``dir(veriloc_rt)``, tab completion)."""
    return sorted(set(globals()) | set(__all__))

"""The run folder: ``run.json`` (config, seed, status, versions, timing), resume checks, keys.

A run (:mod:`~veriloc_rt.sim.engine`) and a Monte Carlo run (:mod:`~veriloc_rt.sim.montecarlo`)
write the same ``run.json`` through :func:`write_run_json`, and a resumed one checks it with
:func:`check_resume`: the results on disk must come from the same resolved config.
"""

from __future__ import annotations

import json
import platform
from importlib import metadata
from pathlib import Path

from ..config import Config, config_to_dict
from ..errors import InputError
from ..phy.security.keys import load_keys, simulated_keys
from ..rng import stream

__all__ = ["package_version", "package_versions", "run_keys", "same_config", "check_resume",
           "write_run_json"]

#: distributions whose versions ``run.json`` records
VERSIONED = ("veriloc-rt", "sionna-rt", "mitsuba", "drjit", "numpy", "scipy", "trimesh",
             "cryptography", "ldpc")


def package_version(name: str) -> str | None:
    """Installed version of a distribution (None when it is not installed)."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def package_versions(*extra: str) -> dict:
    """``{"python": version, distribution: version or None}`` of :data:`VERSIONED` and ``extra``."""
    return {"python": platform.python_version()} | {n: package_version(n) for n in VERSIONED + extra}


def run_keys(cfg: Config, num_bs: int) -> dict:
    """Key material of every BS: the config's key files, else simulated keys from the seed."""
    if cfg.security.keys_dir:
        return load_keys(cfg.security.keys_dir, range(num_bs))
    return simulated_keys(range(num_bs), stream(cfg.seed, "keys"), aes_bits=cfg.security.aes_key_bits)


def _saved_config(path: Path) -> dict:
    """The ``config`` of a ``run.json``; raises OSError, ValueError or KeyError."""
    return json.loads(path.read_text())["config"]


def same_config(path: Path, cfg: Config) -> bool:
    """Whether the ``run.json`` at ``path`` exists and was written for ``cfg``."""
    try:
        return _saved_config(path) == json.loads(json.dumps(config_to_dict(cfg)))
    except (OSError, ValueError, KeyError):
        return False


def check_resume(out: Path, cfg: Config) -> None:
    """Raise :class:`InputError` (``--resume: ...``) unless ``out`` holds a run of ``cfg``."""
    info = out / "run.json"
    if not info.exists():
        raise InputError("--resume", f"no run.json in {out}: nothing to resume (run without --resume)")
    try:
        _saved_config(info)
    except (ValueError, KeyError):
        raise InputError("--resume", f"{info} is not a veriloc-rt run.json") from None
    if not same_config(info, cfg):
        raise InputError("--resume", f"the results in {out} were produced by a different config "
                         "(or --points/--seed); resume with the same ones or use a new --out")


def write_run_json(out: Path, cfg: Config, status: str, timing: dict, fields: dict | None = None,
                   versions: tuple[str, ...] = ()) -> None:
    """Write ``out/run.json`` atomically (a temporary file renamed over it).

    :param status: ``running`` or ``complete``
    :param fields: further top-level entries (the scene XML, the realisations)
    :param versions: distributions recorded besides :data:`VERSIONED`
    """
    info = {"config": config_to_dict(cfg), "seed": cfg.seed, "status": status, **(fields or {}),
            "versions": package_versions(*versions), "timing_s": timing}
    tmp = out / "run.json.tmp"
    tmp.write_text(json.dumps(info, indent=2))
    tmp.replace(out / "run.json")

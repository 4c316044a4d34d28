"""The run folder: ``run.json`` (config, seed, status, versions, timing), its lock, the checks
before a run writes into it, resume checks, keys.

A run (:mod:`~veriloc_rt.sim.engine`) and a Monte Carlo run (:mod:`~veriloc_rt.sim.montecarlo`)
hold the folder's lock (:func:`locked`) for as long as they write into it, and check it first:
a resumed run with :func:`check_resume` (the results on disk must come from the same resolved
config), a new one with :func:`check_fresh` (the folder is empty or holds a run of the same
config, unless ``force``). Both write the same ``run.json`` through :func:`write_run_json`.
Every file is written atomically (:mod:`veriloc_rt.fileio`), so a run that fails or is killed
leaves each file either as it was or complete.
"""

from __future__ import annotations

import json
import logging
import os
import platform
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Iterator

from ..config import Config, config_to_dict
from ..config.run import SCENARIOS
from ..errors import InputError
from ..fileio import TMP_MARK, atomic_write_text
from ..phy.security.keys import load_keys, simulated_keys
from ..rng import stream

log = logging.getLogger(__name__)

__all__ = ["package_version", "package_versions", "run_keys", "same_config", "check_resume",
           "check_fresh", "clear_run_files", "locked", "write_run_json", "LOCK_FILE",
           "OWNER_FILE", "CHAIN_FILE", "RUN_FILES"]

#: the lock of a run folder (held by the run writing into it; left in place after a run)
LOCK_FILE = ".veriloc-run.lock"
#: the process id and host of the run holding the lock (removed when it ends)
OWNER_FILE = ".veriloc-run.owner"
#: the chain results a resumed run reuses (:mod:`~veriloc_rt.sim.chain_store`)
CHAIN_FILE = "chains.bin"
#: files a run writes into its folder besides ``scene/`` (a new run replaces them all)
RUN_FILES = ("run.json", "metrics.json", "propagation_summary.json", CHAIN_FILE, "outcomes.png",
             "detection_rates.png", "scene_top_view.png", "montecarlo.csv",
             "montecarlo_detection_rates.png", "roc.csv", "roc.png",
             *(f"{s}_{kind}" for s in SCENARIOS
               for kind in ("results.csv", "timeseries.png", "map.png")))

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


def _ignored(name: str) -> bool:
    """Files a folder may hold and still count as empty: the lock, temporary files."""
    return name in (LOCK_FILE, OWNER_FILE) or TMP_MARK in name


def check_fresh(out: Path, cfg: Config, force: bool = False) -> None:
    """Raise :class:`InputError` (``--out DIR: ...``) unless a new run of ``cfg`` may write into
    ``out``: it does not exist, is empty, or holds a run of the same config (which the new run
    replaces; ``--resume`` would continue it instead); anything else only with ``force``.
    """
    if force or not out.exists():
        return
    if not out.is_dir():
        raise InputError(f"--out {out}", "not a folder")
    if not any(not _ignored(p.name) for p in out.iterdir()):
        return
    info = out / "run.json"
    if not info.exists():
        raise InputError(f"--out {out}", "not empty and holds no veriloc-rt run: use an empty "
                         "or new folder, or --force to write into it anyway")
    if not same_config(info, cfg):
        raise InputError(f"--out {out}", "holds a run of another config (or --points/--seed): "
                         "use a new --out, the same config with --resume to continue it, or "
                         "--force to replace it")
    try:
        status = json.loads(info.read_text()).get("status")
    except (OSError, ValueError):
        status = None
    if status != "complete":
        log.warning("%s holds an unfinished run of this config: starting it over (--resume "
                    "would keep its finished points)", out)


def clear_run_files(out: Path) -> None:
    """Remove the files of an earlier run (:data:`RUN_FILES`) from ``out``, so that a new
    run's folder holds nothing of the old one (a realisation's folder clears itself when it
    runs). Other files and folders stay."""
    for name in RUN_FILES:
        (out / name).unlink(missing_ok=True)


def _owner(out: Path) -> str:
    try:
        return (out / OWNER_FILE).read_text().strip() or "unknown"
    except (OSError, UnicodeDecodeError):
        return "unknown"


@contextmanager
def locked(out: Path) -> Iterator[Path]:
    """Hold the lock of the run folder ``out`` (created if missing) while the block runs.

    :raises InputError: ``--out DIR: locked by another run (pid N on HOST)`` when another run
        holds it, or ``--out DIR: ...`` when the folder cannot be created or written
    """
    from filelock import FileLock, Timeout

    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError(f"--out {out}", "not a folder") from None
    except OSError as exc:
        raise InputError(f"--out {out}", f"cannot create it ({exc.strerror or exc})") from None
    lock = FileLock(out / LOCK_FILE, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise InputError(f"--out {out}", f"locked by another run ({_owner(out)})") from None
    except OSError as exc:
        raise InputError(f"--out {out}", f"cannot write into it ({exc.strerror or exc})") from None
    try:
        atomic_write_text(out / OWNER_FILE, f"pid {os.getpid()} on {platform.node()}\n")
        yield out
    finally:
        (out / OWNER_FILE).unlink(missing_ok=True)
        lock.release()


def write_run_json(out: Path, cfg: Config, status: str, timing: dict, fields: dict | None = None,
                   versions: tuple[str, ...] = ()) -> None:
    """Write ``out/run.json`` atomically (a temporary file renamed over it).

    :param status: ``running`` or ``complete``
    :param fields: further top-level entries (the scene XML, the realisations)
    :param versions: distributions recorded besides :data:`VERSIONED`
    """
    info = {"config": config_to_dict(cfg), "seed": cfg.seed, "status": status, **(fields or {}),
            "versions": package_versions(*versions), "timing_s": timing}
    atomic_write_text(out / "run.json", json.dumps(info, indent=2))

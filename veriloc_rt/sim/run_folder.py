"""The run folder: ``run.json`` (config, seed, status, versions, timing), its lock, the checks
before a run writes into it, resume checks, keys.

A run (:mod:`~veriloc_rt.sim.engine`) and a Monte Carlo run (:mod:`~veriloc_rt.sim.montecarlo`)
hold the folder's lock (:func:`locked`) for as long as they write into it, and check it first:
a resumed run with :func:`check_resume` (the results on disk must come from the same resolved
config), a new one with :func:`check_fresh` (the folder is empty or holds an unfinished run of
the same config with no finished point, unless ``force``: finished results are never replaced
without it). Both first refuse files that are not regular ones where the run reads or writes
(:func:`check_run_files`: a FIFO would block it for ever). Both write the same ``run.json``
through :func:`write_run_json`; a run that ends unfinished records ``stopped``
(:func:`mark_stopped`), and one killed outright leaves ``running`` and its owner file, whose
process :func:`run_is_alive` finds gone.
Every file is written atomically (:mod:`veriloc_rt.fileio`), so a run that fails or is killed
leaves each file either as it was or complete.
"""

from __future__ import annotations

import errno
import json
import logging
import os
import platform
import stat
from contextlib import contextmanager
from importlib import metadata
from pathlib import Path
from typing import Iterator

from ..config import Config, config_to_dict
from ..attacks.threats import scenario_names
from ..errors import InputError, short_repr
from ..fileio import TMP_MARK, atomic_write_text, json_text
from ..inputs import decode_text, read_bytes
from ..phy.security.keys import load_keys, simulated_keys
from ..rng import stream

log = logging.getLogger(__name__)

__all__ = ["package_version", "package_versions", "run_keys", "same_config", "check_resume",
           "check_fresh", "check_run_files", "clear_run_files", "locked", "write_run_json",
           "mark_stopped", "read_run_json", "owner_status", "run_is_alive", "finished_points", "LOCK_FILE", "OWNER_FILE",
           "CHAIN_FILE", "RUN_FILES", "run_files", "MAX_RUN_JSON_BYTES"]

#: the lock of a run folder (held by the run writing into it; left in place after a run)
LOCK_FILE = ".veriloc-run.lock"
#: the process id and host of the run holding the lock (removed when it ends)
OWNER_FILE = ".veriloc-run.owner"
#: the chain results a resumed run reuses (:mod:`~veriloc_rt.sim.chain_store`)
CHAIN_FILE = "chains.bin"
#: files a run writes into its folder besides ``scene/`` (a new run replaces them all)
def run_files() -> tuple[str, ...]:
    """The files a run writes into its folder besides ``scene/``, for every scenario
    registered now (``'none'`` and each threat of the threat registry, plug-ins included)."""
    return ("run.json", "metrics.json", "propagation_summary.json", CHAIN_FILE, "outcomes.png",
            "detection_rates.png", "scene_top_view.png", "montecarlo.csv",
            "montecarlo_detection_rates.png", "roc.csv", "roc.png",
            *(f"cir_{links}.npz" for links in ("bs_to_ue", "bs_to_adversary",
                                               "adversary_to_ue")),
            *(f"{s}_{kind}" for s in scenario_names()
              for kind in ("results.csv", "links.csv", "timeseries.png", "map.png")))


#: :func:`run_files` of the built-in scenarios
RUN_FILES = run_files()

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


#: largest ``run.json`` read, bytes (a Monte Carlo's lists every realisation: ~100 bytes each)
MAX_RUN_JSON_BYTES = 64 << 20
#: largest results CSV a resumed run reads back, bytes (~400 bytes a point)
MAX_RESULTS_BYTES = 1 << 40

#: what a file that is not a regular one is, by its ``stat`` type
_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


def _not_regular(path: Path) -> str | None:
    """None when ``path`` is missing (a dangling symbolic link included) or a regular file
    (followed through symbolic links); else what is wrong with it, for a message."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "is a symbolic link loop, not a regular file"
        return f"cannot be checked ({exc.strerror})"
    if stat.S_ISREG(st.st_mode):
        return None
    kind = next((name for test, name in _KINDS if test(st.st_mode)), "a special file")
    return f"is {kind}, not a regular file"


def _check_regular(out: Path, names, role: str) -> None:
    for name in names:
        problem = _not_regular(out / name)
        if problem is not None:
            raise InputError(str(out / name), f"{problem} ({role}): remove it, or use another "
                             "--out")


def check_run_files(out: Path) -> None:
    """Raise :class:`InputError` (``<file>: ...``) if a file a run reads or writes in ``out``
    (:data:`RUN_FILES`, the lock and owner files) exists and is not a regular file: reading a
    FIFO waits for a writer for ever, a device may never end, a folder cannot be replaced.
    Checked before anything in ``out`` is read, for a new and a resumed run."""
    _check_regular(out, run_files(), "a run reads and replaces it")
    _check_regular(out, (LOCK_FILE, OWNER_FILE), "a run's lock")
    scene = out / "scene"
    if scene.exists() and not scene.is_dir():
        raise InputError(str(scene), "is not a folder (a run writes its scene there): remove "
                         "it, or use another --out")


def read_run_json(path: Path) -> dict:
    """The content of a ``run.json`` (a JSON object with a ``config``).

    :raises InputError: ``<path>: ...`` when it is missing, not a regular file, not UTF-8,
        not JSON or not a run's
    """
    data = read_bytes(path, str(path), "run file", MAX_RUN_JSON_BYTES)
    text = decode_text(data, str(path), "run file")
    try:
        info = json.loads(text)
    except ValueError as exc:
        raise InputError(str(path), f"not valid JSON ({exc}): not a veriloc-rt run.json, or "
                         "a damaged one") from None
    if not isinstance(info, dict) or not isinstance(info.get("config"), dict):
        raise InputError(str(path), "holds no run config: not a veriloc-rt run.json")
    return info


def _saved_config(path: Path) -> dict:
    """The ``config`` of a ``run.json`` (:func:`read_run_json`)."""
    return read_run_json(path)["config"]


def _same(saved: dict, cfg: Config) -> bool:
    return saved == json.loads(json_text(config_to_dict(cfg)))


def same_config(path: Path, cfg: Config) -> bool:
    """Whether the ``run.json`` at ``path`` exists and was written for ``cfg``."""
    try:
        return _same(_saved_config(path), cfg)
    except InputError:
        return False


def check_resume(out: Path, cfg: Config) -> None:
    """Raise :class:`InputError` unless ``out`` holds a run of ``cfg``: ``--resume: ...``
    (nothing to resume, another config) or ``<file>: ...`` (a damaged ``run.json``, a file
    that is not a regular one)."""
    info = out / "run.json"
    if out.is_dir():
        check_run_files(out)
    if not os.path.lexists(info):
        raise InputError("--resume", f"no run.json in {out}: nothing to resume (run without --resume)")
    if not _same(_saved_config(info), cfg):
        raise InputError("--resume", f"the results in {out} were produced by a different config "
                         "(or --points/--seed); resume with the same ones or use a new --out")


def _ignored(name: str) -> bool:
    """Files a folder may hold and still count as empty: the lock, temporary files."""
    return name in (LOCK_FILE, OWNER_FILE) or TMP_MARK in name


def finished_points(out: Path) -> int:
    """Points in the results CSVs of ``out`` and of its realisation folders (complete lines
    after the header; the files are regular ones, :func:`check_run_files`)."""
    total = 0
    for path in [*out.glob("*_results.csv"), *out.glob("realisation_*/*_results.csv")]:
        try:
            if not path.is_file():
                continue
            with open(path, "rb") as fh:
                lines = sum(chunk.count(b"\n") for chunk in iter(lambda: fh.read(1 << 20), b""))
            total += max(0, lines - 1)
        except OSError:
            continue
    return total


def check_fresh(out: Path, cfg: Config, force: bool = False) -> None:
    """Raise :class:`InputError` (``--out DIR: ...``) unless a new run of ``cfg`` may write into
    ``out``: it does not exist, is empty, or holds an unfinished run of the same config that
    finished no point yet (which the new run starts over); anything else only with ``force``:
    finished results (a complete run, or the points of an unfinished one, which ``--resume``
    continues) are never replaced without it. Files that are not regular ones
    (:func:`check_run_files`) are refused even with ``force``.
    """
    if not out.exists():
        return
    if not out.is_dir():
        raise InputError(f"--out {out}", "not a folder")
    check_run_files(out)
    held = [p.name for p in out.iterdir() if not _ignored(p.name)]
    info = out / "run.json"
    # a run stopped while it built its scene (before run.json exists) leaves scene/ alone
    if force or not held or (held == ["scene"] and not os.path.lexists(info)):
        return
    if not os.path.lexists(info):
        raise InputError(f"--out {out}", "not empty and holds no veriloc-rt run: use an empty "
                         "or new folder, or --force to write into it anyway")
    try:
        saved = read_run_json(info)
    except InputError as exc:
        raise InputError(exc.field, f"{exc.problem}; use a new --out, or --force to replace "
                         "the run there") from None
    if not _same(saved["config"], cfg):
        raise InputError(f"--out {out}", "holds a run of another config (or --points/--seed): "
                         "use a new --out, the same config with --resume to continue it, or "
                         "--force to replace it")
    if saved.get("status") == "complete":
        raise InputError(f"--out {out}", "holds a complete run of this config: its results "
                         "are kept; use a new --out, or --force to replace them")
    done = finished_points(out)
    if done:
        raise InputError(f"--out {out}", f"holds an unfinished run of this config with {done} "
                         "finished points: add --resume to continue it, or --force to start "
                         "it over")
    log.info("%s holds an unfinished run of this config with no finished point: starting it "
             "over", out)


def clear_run_files(out: Path) -> None:
    """Remove the files of an earlier run (:data:`RUN_FILES`) from ``out``, so that a new
    run's folder holds nothing of the old one (a realisation's folder clears itself when it
    runs). Other files and folders stay."""
    for name in run_files():
        (out / name).unlink(missing_ok=True)


def _pid_ended(pid: int) -> bool:
    """Whether process ``pid`` of this host has ended (gone, or a zombie not yet reaped)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except OSError:      # EPERM: it exists, another user's
        return False
    try:   # the state is the field after the command's closing parenthesis (proc(5))
        with open(f"/proc/{pid}/stat", "rb") as fh:
            return fh.read().rpartition(b")")[2].split()[0] in (b"Z", b"X")
    except (OSError, IndexError):
        return False


def owner_status(out: Path) -> tuple[str, bool | None]:
    """Who holds the run folder ``out``, from its owner file: (description, alive), alive
    True/False for a process of this host, None when unknown (another host, no or an
    unreadable owner file)."""
    path = out / OWNER_FILE
    if not os.path.lexists(path):
        return f"no {OWNER_FILE} names it", None
    try:
        text = decode_text(read_bytes(path, str(path), "owner file", 4096), str(path),
                           "owner file").strip()
    except InputError as exc:
        return f"its {OWNER_FILE} cannot be read: {exc.problem}", None
    parts = text.split()
    if len(parts) == 4 and parts[0] == "pid" and parts[1].isdigit() and parts[2] == "on":
        pid, host = int(parts[1]), parts[3]
        if host == platform.node():
            if _pid_ended(pid):
                return f"pid {pid} on {host}, which has ended", False
            return f"pid {pid} on {host}", True
        return f"pid {pid} on {host}", None
    return f"its {OWNER_FILE} says {short_repr(text)}", None


def run_is_alive(out: Path) -> bool:
    """Whether a run holds ``out`` now: its owner file exists and does not name a process of
    this host that has ended (a run killed with SIGKILL leaves its owner file behind)."""
    if not os.path.lexists(out / OWNER_FILE):
        return False
    return owner_status(out)[1] is not False


def mark_stopped(out: Path) -> None:
    """Set the status of ``out/run.json`` from ``running`` to ``stopped`` (a run that ended
    unfinished: ``--resume`` continues it). Best effort: a run that stops because the disk is
    full cannot write it, and its status stays ``running``; the live view then reads the
    owner file (:func:`run_is_alive`)."""
    path = out / "run.json"
    if not os.path.lexists(path):    # stopped before it began: nothing to record
        return
    try:
        info = read_run_json(path)
        if info.get("status") == "running":
            info["status"] = "stopped"
            atomic_write_text(path, json_text(info))
    except (InputError, OSError) as exc:   # the run's own error is the message
        log.info("%s: could not record the status 'stopped' (%s)", path, exc)


def _lock_holder(out: Path) -> str:
    """The ``(...)`` of the "locked by another run" message: what the owner file says."""
    text, alive = owner_status(out)
    hint = f"`fuser {out / LOCK_FILE}` lists the processes holding it"
    if alive is False:
        return f"{text}; a process it started still holds the lock: {hint}"
    if text.startswith("no ") or text.startswith("its "):
        return f"{text}; {hint}"
    return text


@contextmanager
def locked(out: Path) -> Iterator[Path]:
    """Hold the lock of the run folder ``out`` (created if missing) while the block runs.

    :raises InputError: ``--out DIR: locked by another run (pid N on HOST)`` when another run
        holds it (what its owner file says), ``--out DIR: ...`` when the folder cannot be
        created or written, ``<file>: ...`` when the lock or owner file is not a regular file
    """
    from filelock import FileLock, Timeout

    try:
        out.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise InputError(f"--out {out}", "not a folder") from None
    except OSError as exc:
        raise InputError(f"--out {out}", f"cannot create it ({exc.strerror or exc})") from None
    _check_regular(out, (LOCK_FILE, OWNER_FILE), "a run's lock")
    lock = FileLock(out / LOCK_FILE, timeout=0)
    try:
        lock.acquire()
    except Timeout:
        raise InputError(f"--out {out}", f"locked by another run ({_lock_holder(out)})") from None
    except OSError as exc:
        raise InputError(f"--out {out}", f"cannot write into it ({exc.strerror or exc})") from None
    try:
        atomic_write_text(out / OWNER_FILE, f"pid {os.getpid()} on {platform.node()}\n")
        yield out
    finally:
        (out / OWNER_FILE).unlink(missing_ok=True)
        lock.release()


def _relative(out: Path, value):
    """A path inside ``out`` as text relative to ``out`` (the folder can be moved); any other
    value as it is."""
    if isinstance(value, (str, Path)) and os.path.isabs(value):
        try:
            return Path(value).relative_to(out).as_posix()
        except ValueError:
            return str(value)
    return value


def git_revision() -> str | None:
    """The commit of the package's source checkout (``git rev-parse HEAD``, with ``-dirty``
    appended when tracked files differ from it), or None when the package is not at the top of
    a git work tree (an installed copy) or git is missing."""
    import subprocess

    here = Path(__file__).resolve().parents[2]   # the folder holding veriloc_rt/
    try:
        top, rev = subprocess.run(["git", "-C", str(here), "rev-parse", "--show-toplevel",
                                   "HEAD"], capture_output=True, text=True, timeout=10,
                                  check=True).stdout.split()
        if Path(top).resolve() != here:  # an installed copy inside some other repository
            return None
        dirty = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               timeout=10, check=True).stdout.strip()
    except (OSError, ValueError, subprocess.SubprocessError):
        return None
    return f"{rev}-dirty" if dirty else rev or None


def write_run_json(out: Path, cfg: Config, status: str, timing: dict, fields: dict | None = None,
                   versions: tuple[str, ...] = ()) -> None:
    """Write ``out/run.json`` atomically (a temporary file renamed over it).

    :param status: ``running``, ``stopped`` (:func:`mark_stopped`) or ``complete``
    :param fields: further top-level entries (the scene XML, the realisations); a path inside
        ``out`` is written relative to ``out``
    :param versions: distributions recorded besides :data:`VERSIONED`
    """
    info = {"config": config_to_dict(cfg), "seed": cfg.seed, "status": status,
            **{k: _relative(out, v) for k, v in (fields or {}).items()},
            "versions": package_versions(*versions), "git_revision": git_revision(),
            "timing_s": timing}
    atomic_write_text(out / "run.json", json_text(info))

"""Find libLLVM >= 19 for Dr.Jit's CPU back end and select the Mitsuba variant.

Sionna RT 2.2 (Dr.Jit 1.5) on the CPU needs libLLVM 19 or newer: LLVM 14 is refused and 15-16
abort with ``LLVM ERROR: Cannot select ... fmaximum``. :func:`import_sionna` must run before
anything imports ``mitsuba`` or ``sionna``; it honours ``DRJIT_LIBLLVM_PATH`` and otherwise
searches the usual library folders.
"""

from __future__ import annotations

import glob
import logging
import os
import re
import sys
from types import ModuleType

log = logging.getLogger(__name__)

#: Mitsuba variant Sionna RT uses on the CPU
VARIANT = "llvm_ad_mono_polarized"

MIN_LLVM_MAJOR = 19

#: Folders searched for libLLVM when ``DRJIT_LIBLLVM_PATH`` is not set
SEARCH_DIRS = (
    "/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib",
    "/usr/local/lib", "/usr/lib/llvm-*/lib", "/opt/homebrew/opt/llvm/lib", "/usr/local/opt/llvm/lib",
)

INSTALL_HINT = ("install libLLVM 19 or newer (Debian/Ubuntu: 'apt-get install libllvm19'), "
                "or point DRJIT_LIBLLVM_PATH at libLLVM-19.so")


class BackendError(RuntimeError):
    """No usable LLVM for Dr.Jit, or Sionna RT could not be loaded."""


def llvm_major(path: str) -> int | None:
    """LLVM major version from a library file name (``libLLVM-19.so``, ``libLLVM.so.19.1``)."""
    name = os.path.basename(path)
    m = re.match(r"libLLVM[-.]?(\d+)", name) or re.match(r"libLLVM\.so\.(\d+)", name) \
        or re.match(r"libLLVM\.(\d+)\.dylib", name)
    return int(m.group(1)) if m else None


def find_libllvm(search_dirs: tuple[str, ...] = SEARCH_DIRS) -> str | None:
    """Newest libLLVM with major version >= 19 in ``search_dirs`` (None if there is none)."""
    found: list[tuple[int, str]] = []
    for pattern in search_dirs:
        for folder in sorted(glob.glob(pattern)):
            for lib in glob.glob(os.path.join(folder, "libLLVM*.so*")) + \
                    glob.glob(os.path.join(folder, "libLLVM*.dylib")):
                major = llvm_major(lib)
                if major is not None and major >= MIN_LLVM_MAJOR and os.path.isfile(lib):
                    found.append((major, lib))
    if not found:
        return None
    found.sort(key=lambda t: (t[0], -len(t[1])))
    return found[-1][1]


def configure_llvm() -> str:
    """Set ``DRJIT_LIBLLVM_PATH`` to a usable libLLVM and return it.

    :raises BackendError: when no libLLVM >= 19 is found, naming the package to install
    """
    given = os.environ.get("DRJIT_LIBLLVM_PATH")
    if given:
        if not os.path.isfile(given):
            raise BackendError(f"DRJIT_LIBLLVM_PATH={given} does not exist; {INSTALL_HINT}")
        major = llvm_major(given)
        if major is not None and major < MIN_LLVM_MAJOR:
            raise BackendError(f"DRJIT_LIBLLVM_PATH={given} is LLVM {major}; Dr.Jit 1.5 needs "
                               f">= {MIN_LLVM_MAJOR}: {INSTALL_HINT}")
        return given
    lib = find_libllvm()
    if lib is None:
        raise BackendError(f"no libLLVM >= {MIN_LLVM_MAJOR} found for Sionna RT's CPU back end: "
                           f"{INSTALL_HINT}")
    os.environ["DRJIT_LIBLLVM_PATH"] = lib
    log.debug("using %s for Dr.Jit", lib)
    return lib


def import_sionna() -> ModuleType:
    """Configure LLVM, select :data:`VARIANT` and return the ``sionna.rt`` module."""
    if "sionna.rt" in sys.modules and "mitsuba" in sys.modules:
        return sys.modules["sionna.rt"]
    configure_llvm()
    try:
        import mitsuba as mi
        mi.set_variant(VARIANT)
        import sionna.rt as rt
    except ImportError as exc:
        raise BackendError(f"cannot import Sionna RT ({exc}); run scripts/setup.sh") from exc
    except (RuntimeError, AttributeError) as exc:
        raise BackendError(f"Mitsuba variant {VARIANT} is unavailable ({exc}); "
                           f"{INSTALL_HINT}") from exc
    return rt

#!/usr/bin/env bash
# Idempotent set-up of veriloc-rt on Debian/Ubuntu: system libLLVM 19 (Dr.Jit's CPU back end for
# Sionna RT; LLVM 14-16 do not work) and a virtual environment .venv with the package and its test
# extras. Safe to run again: it only installs what is missing or changed.
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3.12 python3.13 python3; do
    if command -v "$cand" >/dev/null 2>&1; then PY="$cand"; break; fi
  done
fi
[ -n "$PY" ] || { echo "setup: no python3 found; install Python >= 3.11" >&2; exit 1; }
"$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' \
  || { echo "setup: $PY is $("$PY" -V 2>&1); veriloc-rt needs Python >= 3.11" >&2; exit 1; }

have_llvm() {
  # the package finds libLLVM >= 19 by itself; this only decides whether to install it
  local f
  for f in /usr/lib/*/libLLVM-{19,2[0-9]}.so* /usr/lib/*/libLLVM.so.{19,2[0-9]}* \
           /usr/lib/llvm-{19,2[0-9]}/lib/libLLVM*.so*; do
    [ -e "$f" ] && return 0
  done
  [ -n "${DRJIT_LIBLLVM_PATH:-}" ] && [ -e "$DRJIT_LIBLLVM_PATH" ]
}
apt_pkgs=()
if ! have_llvm; then
  apt_pkgs+=(libllvm19)
fi
if [ ! -x .venv/bin/python ] && ! "$PY" -c 'import ensurepip, venv' >/dev/null 2>&1; then
  apt_pkgs+=("python3-venv")
fi
if [ ${#apt_pkgs[@]} -gt 0 ]; then
  echo "setup: installing system packages: ${apt_pkgs[*]}"
  $SUDO apt-get update -qq
  $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${apt_pkgs[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $PY"
  "$PY" -m venv .venv
fi

# reinstall only when the package metadata changed (editable install: code changes need nothing)
stamp=".venv/.veriloc-rt-setup"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ]; then
  echo "setup: installing veriloc-rt and its dependencies into .venv"
  .venv/bin/python -m pip install --quiet --disable-pip-version-check -e ".[test]" 2> >(grep -v "^WARNING: Location" >&2)
  echo "$want" > "$stamp"
fi
# the package's bytecode, once: an environment with PYTHONDONTWRITEBYTECODE would otherwise
# compile every module at every start of the command (about 0.13 s each time)
.venv/bin/python -m compileall -q veriloc_rt >/dev/null
.venv/bin/python -c 'from veriloc_rt.backend import configure_llvm; configure_llvm()' \
  || { echo "setup: libLLVM >= 19 not usable; see the message above" >&2; exit 1; }
echo "setup: ready (.venv/bin/veriloc-rt)"

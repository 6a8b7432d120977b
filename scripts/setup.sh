#!/usr/bin/env bash
# Set up pilerl in ./.venv on a fresh machine that has Python >= 3.11 and the package
# registries. Idempotent: a second run only checks what is there.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
pip_install() {
  # drop pip's noise about package-index locations this machine does not have
  .venv/bin/python -m pip install --quiet --disable-pip-version-check "$@" 2>&1 \
    | sed '/is ignored: it is neither a file nor a directory/d'
}
# torch first and pinned: 2.13.0 resolves to the local CPU wheel; an unpinned torch would
# pull several GB of CUDA packages.
pip_install torch==2.13.0
pip_install -e ".[dev]"

# Offscreen rendering (MUJOCO_GL=egl) needs an EGL library; install Mesa's if it is missing.
LDCONFIG=$(command -v ldconfig || echo /sbin/ldconfig)  # /sbin may not be on PATH
if ! "$LDCONFIG" -p 2>/dev/null | grep -q 'libEGL.so.1'; then
  if command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq libegl1 libgl1 libgles2 libegl-mesa0 \
      libgl1-mesa-dri >/dev/null
  else
    echo "setup: no libEGL found; install your distribution's EGL/Mesa packages" \
         "for rendering (simulation and tests without rendering still work)" >&2
  fi
fi
echo "setup: ok ($(.venv/bin/python -c 'import torch, torchrl, mujoco, gymnasium; print(
  f"torch {torch.__version__}, torchrl {torchrl.__version__}, mujoco {mujoco.__version__},"
  f" gymnasium {gymnasium.__version__}")'))"

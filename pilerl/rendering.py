"""Offscreen rendering that works in a plain shell: the MuJoCo GL backend, chosen early.

MuJoCo picks its OpenGL backend once, when ``mujoco`` is first imported, from the
``MUJOCO_GL`` variable; with none set it picks GLFW, which needs a display. Importing
TorchRL's envs already imports MuJoCo, so setting the variable later is too late. pilerl
therefore decides the backend at the top of ``import pilerl`` (and of the pile-loader
plugin), before anything else is imported:

- a backend the user chose (``MUJOCO_GL`` set) is kept;
- with a display (``DISPLAY`` or ``WAYLAND_DISPLAY``), MuJoCo's own default is kept;
- headless, the first of EGL and OSMesa whose library the machine has is chosen
  (no GPU needed: Mesa's EGL renders in software).

If MuJoCo was imported before pilerl with a backend that cannot work headless (GLFW with
no display), :func:`choose_backend` points MuJoCo's renderer at the headless backend's
context class (``mujoco.rendering.classic.gl_context.GLContext``, which the renderer
reads each time it is made), so that the import order does not matter.

Whether this machine can render at all is checked before any work, by
:func:`rendering_available`, which renders one tiny frame in a child process (a failed
OpenGL start can abort a process, so the recipe itself never tries first). Recipes turn
their ``videos`` setting into a decision with :func:`resolve_videos`: ``auto`` renders when
possible and warns once otherwise; ``true`` refuses before any work if it cannot.

This module imports nothing heavy: it must run before MuJoCo is imported.
"""

from __future__ import annotations

import ctypes.util
import functools
import logging
import os
import subprocess
import sys

log = logging.getLogger(__name__)

HEADLESS_BACKENDS = {"egl": "EGL", "osmesa": "OSMesa"}  # MUJOCO_GL value -> library name
PROBE_TIMEOUT_S = 120.0  # a software GL start on a busy 2-core machine takes a few seconds
_PROBE = (
    "import mujoco\n"
    'model = mujoco.MjModel.from_xml_string(\'<mujoco><worldbody><geom size="1"/>'
    "</worldbody></mujoco>')\n"
    "renderer = mujoco.Renderer(model, height=8, width=8)\n"
    "renderer.update_scene(mujoco.MjData(model))\n"
    "assert renderer.render().shape == (8, 8, 3)\n"
    "renderer.close()\n"
)


class RenderingUnavailable(RuntimeError):
    """Videos were asked for explicitly, but this machine cannot render offscreen."""


def has_display() -> bool:
    """Whether a window system is reachable (X11 or Wayland)."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def headless_backend() -> str | None:
    """The first headless backend whose library this machine has (``egl``, ``osmesa``)."""
    for backend, library in HEADLESS_BACKENDS.items():
        if ctypes.util.find_library(library):
            return backend
    return None


def choose_backend() -> str | None:
    """Set ``MUJOCO_GL`` for this process (and its children) unless the user chose one.

    Returns the backend in force (``None``: MuJoCo's default with a display, or no
    backend at all on a headless machine without EGL and OSMesa).
    """
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    if has_display():
        return None
    backend = headless_backend()
    if backend is None:
        return None
    os.environ["MUJOCO_GL"] = backend
    if "mujoco" in sys.modules:
        _switch_imported_mujoco(backend)
    return backend


def _switch_imported_mujoco(backend: str) -> None:
    """Point an already-imported MuJoCo's renderer at ``backend``'s GL context class."""
    if "OpenGL" in sys.modules and os.environ.get("PYOPENGL_PLATFORM") not in (None, backend):
        log.warning(
            "MuJoCo and PyOpenGL were imported before pilerl with another GL platform; "
            "rendering may fail: import pilerl first or set MUJOCO_GL=%s",
            backend,
        )
        return
    from mujoco.rendering.classic import gl_context

    if backend == "egl":
        from mujoco.egl import GLContext
    else:
        from mujoco.osmesa import GLContext
    gl_context.GLContext = GLContext


@functools.cache
def rendering_available() -> tuple[bool, str]:
    """Whether an offscreen frame can be rendered here, and why not.

    Renders an 8x8 frame in a child process with this process's backend; the answer is
    cached for the process.
    """
    backend = os.environ.get("MUJOCO_GL")
    if not backend and not has_display():
        return False, (
            "no display and neither EGL nor OSMesa found (install your distribution's "
            "libegl1 / Mesa packages, or set MUJOCO_GL)"
        )
    try:
        probe = subprocess.run(
            [sys.executable, "-c", _PROBE],
            capture_output=True,
            text=True,
            timeout=PROBE_TIMEOUT_S,
            env={**os.environ, "OMP_NUM_THREADS": "1"},
        )
    except subprocess.TimeoutExpired:
        return False, f"a test frame took over {PROBE_TIMEOUT_S:.0f} s (MUJOCO_GL={backend})"
    if probe.returncode != 0:
        lines = (probe.stderr or probe.stdout).strip().splitlines()
        reason = lines[-1] if lines else f"exit code {probe.returncode}"
        return False, f"a test frame failed with MUJOCO_GL={backend or 'default'}: {reason}"
    return True, f"MUJOCO_GL={backend or 'default'}"


def resolve_videos(videos: bool | str, *, where: str = "videos", renders: bool = True) -> bool:
    """Turn a ``videos`` setting (``true``, ``false`` or ``auto``) into a decision, now.

    ``auto`` renders when this machine can, else logs one warning and goes on without
    videos; ``true`` raises :class:`RenderingUnavailable` before any work if it cannot.
    ``renders``: whether the simulator renders at all (its plugin's ``renders``); if not,
    ``auto`` means no videos and ``true`` is refused.
    """
    choice = str(videos).strip().lower()  # Hydra hands a str field "True" for true
    if choice == "false":
        return False
    if choice not in ("true", "auto"):
        raise ValueError(f"{where}: must be true, false or auto, got {videos!r}")
    if not renders:
        if choice == "true":
            raise ValueError(f"{where}=true, but this simulator does not render: set it false")
        log.info("%s: the simulator does not render: no videos", where)
        return False
    available, reason = rendering_available()
    if available:
        return True
    if choice == "auto":
        log.warning("%s: this machine cannot render offscreen (%s): no videos", where, reason)
        return False
    raise RenderingUnavailable(
        f"{where}=true, but this machine cannot render offscreen: {reason}. "
        f"Set {where}=false (or auto) to run without videos."
    )

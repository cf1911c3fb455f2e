"""Offscreen rendering of the MuJoCo scene (EGL by default, OSMesa as fallback) and MP4 videos.

MuJoCo 3.x reads ``MUJOCO_GL`` once, when ``import mujoco`` imports its GL module
(``mujoco.rendering.classic.gl_context``); unset, it binds GLFW, which needs a display. Nothing
is chosen at import of this package: :func:`select_gl` chooses when something first renders
(:class:`OffscreenCamera` calls it) — the user's ``MUJOCO_GL`` if set, else EGL if its library
is installed, else OSMesa — and, when MuJoCo was imported without a choice, rebinds MuJoCo's GL
module to it. Commands that render call :func:`configure_gl` first, which also probes the
backend in a subprocess and falls back to OSMesa.
On software GL, shadows and reflections cost several times the rest of a frame: they are off
unless asked for.
"""

from __future__ import annotations

import ctypes.util
import errno
import importlib
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import imageio.v2 as imageio
import numpy as np

from cpp_mujoco.util.io import _umask, atomic_path
from cpp_mujoco.util.signals import deferred

GL_BACKENDS = ("egl", "osmesa")
_GL_MODULE = "mujoco.rendering.classic.gl_context"  # where MuJoCo 3.x binds its GLContext
_PROBE = (
    "import mujoco;"
    'm = mujoco.MjModel.from_xml_string(\'<mujoco><worldbody><geom size="1 1 .1" type="plane"/>'
    "</worldbody></mujoco>');"
    "r = mujoco.Renderer(m, 8, 8); d = mujoco.MjData(m); r.update_scene(d); r.render()"
)


class RenderingError(RuntimeError):
    """No offscreen GL backend works, or the one MuJoCo loaded is not the one asked for."""


def default_gl_backend() -> str:
    """EGL if its library is installed, else OSMesa, else none (physics runs without GL).
    Runs ``ldconfig`` (``find_library``): call it only when something renders."""
    if ctypes.util.find_library("EGL"):
        return "egl"
    if ctypes.util.find_library("OSMesa"):
        return "osmesa"
    return "disabled"


def gl_works(backend: str, timeout: float = 60.0) -> bool:
    """Whether MuJoCo can render offscreen with ``backend`` (tried in a fresh process)."""
    env = {**os.environ, "MUJOCO_GL": backend}
    env.pop("PYOPENGL_PLATFORM", None)
    try:
        result = subprocess.run(
            [sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return False
    return result.returncode == 0


def loaded_gl_backend() -> str | None:
    """The backend MuJoCo's renderer is bound to ("egl", "osmesa", "glfw", …); None when MuJoCo
    is not imported yet or bound none (``MUJOCO_GL=disabled``)."""
    if "mujoco" not in sys.modules:
        return None
    context = getattr(sys.modules.get(_GL_MODULE), "GLContext", None)
    return context.__module__.rsplit(".", 1)[-1] if context is not None else None


def select_gl(backend: str | None = None) -> str:
    """Make MuJoCo render offscreen with ``backend``; return the backend it renders with.

    ``backend`` defaults to ``MUJOCO_GL``, else :func:`default_gl_backend`. Before MuJoCo is
    imported this only sets ``MUJOCO_GL``. After, a MuJoCo imported with ``MUJOCO_GL`` unset (so
    bound to GLFW) has its GL module re-imported under the choice; one imported with a choice
    keeps it, and asking for another is a :class:`RenderingError` (one process, one GL).
    """
    wanted = (backend or os.environ.get("MUJOCO_GL") or default_gl_backend()).lower().strip()
    if wanted in ("disabled", "disable", "off"):
        raise RenderingError(
            "no offscreen GL library found (libEGL, libOSMesa); install them with "
            "scripts/setup.sh as root, or set MUJOCO_GL"
        )
    if "mujoco" in sys.modules and loaded_gl_backend() == wanted:
        return wanted
    gl = sys.modules.get(_GL_MODULE)
    read = getattr(gl, "_MUJOCO_GL", "")  # what MuJoCo's GL module read at its import
    if read:
        raise RenderingError(
            f"MuJoCo was already imported with MUJOCO_GL={read!r}; set MUJOCO_GL={wanted} before "
            "importing cpp_mujoco's physics or mujoco"
        )
    os.environ["MUJOCO_GL"] = wanted
    if "OpenGL" not in sys.modules:
        os.environ.pop("PYOPENGL_PLATFORM", None)  # MuJoCo's GL module sets the one it needs
    if "mujoco" not in sys.modules:
        return wanted  # MuJoCo reads the choice when it is imported
    try:
        gl = importlib.reload(gl) if gl is not None else importlib.import_module(_GL_MODULE)
        renderer = importlib.import_module("mujoco.rendering.classic.renderer")
    except (ImportError, OSError, RuntimeError) as e:
        raise RenderingError(f"cannot load MuJoCo's {wanted} GL backend: {e}") from e
    mujoco = sys.modules["mujoco"]
    mujoco.GLContext, mujoco.Renderer = gl.GLContext, renderer.Renderer
    return wanted


def configure_gl(backend: str | None = None) -> str:
    """Choose a working offscreen backend before anything renders; return its name.

    ``backend`` forces one (``egl`` or ``osmesa``); otherwise the first that works (probed in a
    subprocess) is taken — unless MuJoCo already renders offscreen with one.
    """
    if backend is not None and backend not in GL_BACKENDS:
        raise RenderingError(
            f"unknown GL backend {backend!r}; choose from {', '.join(GL_BACKENDS)}"
        )
    loaded = loaded_gl_backend()
    if loaded in GL_BACKENDS and backend in (None, loaded):
        return loaded
    candidates = [backend] if backend else list(GL_BACKENDS)
    for name in candidates:
        if gl_works(name):
            return select_gl(name)
    raise RenderingError(
        f"no offscreen GL backend works here (tried {', '.join(candidates)}); install the system "
        "libraries with scripts/setup.sh as root (libegl1, libosmesa6)"
    )


DEFAULT_MAX_GEOM = 10_000  # mujoco.Renderer's own default scene size
LIGHT_SCALE = 0.6  # diffuse and specular light kept: tiles show their colours, not white


class OffscreenCamera:
    """Renders one camera of a model: a named MJCF camera, or a chase camera tracking a body.

    ``decorate(scene, data)`` is called with the ``MjvScene`` and the ``MjData`` after each
    ``update_scene`` and before the render, to add what the model does not hold — the map's
    tiles and no-fly volumes (:class:`~cpp_mujoco.physics.view.scenery.Scenery`), the coverage,
    trail
    and airframe (:class:`~cpp_mujoco.physics.view.chase.MissionDecor`). Its ``geom_count``, if it
    has
    one, is added to the scene's room for geoms. The model's lights are dimmed by
    ``light_scale`` in the scene (the model is untouched): at full strength the headlight and the
    sun saturate every light tile to white, and a seen cell could not be drawn lighter.
    """

    def __init__(
        self,
        model,
        camera: str | None = None,
        track_body: str | None = None,
        width: int = 320,
        height: int = 240,
        shadows: bool = False,
        reflections: bool = False,
        distance: float = 12.0,
        elevation: float = -30.0,
        azimuth: float = 135.0,
        decorate: Callable[[Any, Any], None] | None = None,
        light_scale: float = LIGHT_SCALE,
    ):
        import mujoco  # GL: this module chooses the backend, importable before MuJoCo

        select_gl()  # the first render chooses the GL backend (see the module docstring)
        max_geom = DEFAULT_MAX_GEOM + int(getattr(decorate, "geom_count", 0))
        try:
            self.renderer = mujoco.Renderer(model, height, width, max_geom=max_geom)
        except Exception as e:  # the GL libraries report failures in many shapes
            raise RenderingError(
                f"cannot create an offscreen {width}x{height} context with "
                f"MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}: {e}"
            ) from e
        self.scene_option = mujoco.MjvOption()
        flags = self.renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW] = shadows
        flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = reflections
        if camera is not None:
            self.camera: object = camera
        else:
            cam = mujoco.MjvCamera()
            cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
            cam.trackbodyid = model.body(track_body).id if track_body else 0
            cam.distance, cam.elevation, cam.azimuth = distance, elevation, azimuth
            self.camera = cam
        self._flags = (shadows, reflections)
        self.width, self.height = width, height
        self.decorate = decorate
        self.light_scale = light_scale

    def render(self, data) -> np.ndarray:
        """(H, W, 3) uint8 frame of the current state."""
        import mujoco  # GL: this module chooses the backend, importable before MuJoCo

        self.renderer.update_scene(data, camera=self.camera, scene_option=self.scene_option)
        scene = self.renderer.scene
        if self.light_scale != 1.0:  # update_scene remade the lights: scale them afresh
            for light in scene.lights[: scene.nlight]:
                light.diffuse = np.asarray(light.diffuse) * self.light_scale
                light.specular = np.asarray(light.specular) * self.light_scale
        if self.decorate is not None:
            self.decorate(scene, data)
        flags = scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW], flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = (
            self._flags
        )
        return self.renderer.render()

    def close(self) -> None:
        try:
            self.renderer.close()
        except Exception:  # noqa: BLE001 - GL teardown errors at exit carry no information
            pass


class _Abandoned(BaseException):
    """Thrown into :func:`~cpp_mujoco.util.io.atomic_path` to drop its temporary file quietly."""


def _one_line_error(exc: BaseException, folder: Path) -> BaseException:
    """imageio-ffmpeg reports a failed pipe as a multi-line ``IOError`` (the ffmpeg command and
    an empty stderr); make it one line, and name a full disk before the temporary file is removed
    (which frees the space again)."""
    if not isinstance(exc, OSError) or exc.errno is not None:
        return exc
    try:
        if os.statvfs(folder).f_bavail == 0:
            return OSError(errno.ENOSPC, "No space left on device")
    except OSError:
        pass
    lines = str(exc).strip().splitlines()
    return OSError(f"ffmpeg stopped ({lines[0] if lines else type(exc).__name__})")


def _has_index(path: Path) -> bool:
    """Whether an MP4 has its ``moov`` box (the index ffmpeg writes last): a file cut by a full
    disk or a size limit lacks it and does not play."""
    try:
        with open(path, "rb") as f:
            return b"moov" in f.read()
    except OSError:
        return False


class VideoWriter:
    """MP4 (H.264) through imageio-ffmpeg, written to a temporary file beside ``path``.

    :meth:`close` finalises the video and renames it to ``path``. ``close(partial=True)`` — what
    an interrupted mission does — finalises it as ``<stem>.partial.mp4`` instead: playable, but
    never mistaken for a complete video. A failure (a full disk, ffmpeg gone) removes the
    temporary file and raises :class:`~cpp_mujoco.util.io.WriteError` with one line. A previous
    file at
    ``path`` stays untouched until a new video replaces it.
    """

    def __init__(self, path: str | os.PathLike, fps: float = 20.0):
        self.path = Path(path)
        self.partial_path = self.path.with_name(f"{self.path.stem}.partial{self.path.suffix}")
        self.frames = 0
        self._closed = False
        self._writer = None
        self._target = atomic_path(self.path)
        self._tmp = self._target.__enter__()  # WriteError for a folder or an unwritable place
        try:
            self._writer = imageio.get_writer(
                str(self._tmp), format="FFMPEG", fps=fps, codec="libx264", quality=7,
                macro_block_size=8, ffmpeg_log_level="quiet",
            )  # fmt: skip
        except Exception as exc:  # noqa: BLE001 - reported as a WriteError by _fail
            self._fail(exc)

    def _fail(self, exc: BaseException):
        """Drop the temporary file and raise the failure as a one-line WriteError."""
        self._closed = True
        error = _one_line_error(exc, self.path.parent)
        if self._writer is not None:
            try:
                self._writer.close()
            except Exception:  # noqa: BLE001, S110 - ffmpeg is already gone; the error says why
                pass
        self._target.__exit__(type(error), error, None)  # raises WriteError for OSError
        raise error

    def write(self, frame: np.ndarray) -> None:
        if self._closed:
            raise ValueError(f"video {self.path} is already closed")
        try:
            with deferred():  # an interrupt mid-frame would make imageio kill ffmpeg
                self._writer.append_data(frame)
        except Exception as exc:  # noqa: BLE001 - reported as a WriteError by _fail
            self._fail(exc)
        self.frames += 1

    def close(self, partial: bool = False) -> Path | None:
        """Finalise; return the file written (``partial_path`` if ``partial``), or None when
        no frame was written (no file then, an empty video would only mislead)."""
        if self._closed:
            return None
        self._closed = True
        try:
            self._writer.close()  # ffmpeg writes the index; without it the file does not play
        except Exception as exc:  # noqa: BLE001 - reported as a WriteError by _fail
            self._fail(exc)
        if self.frames and not _has_index(self._tmp):  # imageio ignores ffmpeg's exit status
            self._fail(RuntimeError("ffmpeg could not finalise the video (no index written)"))
        if self.frames == 0 or partial:
            if self.frames:
                try:
                    os.replace(self._tmp, self.partial_path)
                    os.chmod(self.partial_path, 0o666 & ~_umask())
                except OSError as exc:
                    self._fail(exc)
            self._target.__exit__(_Abandoned, _Abandoned(), None)
            return self.partial_path if self.frames else None
        self._target.__exit__(None, None, None)  # fsync, rename over path
        return self.path

"""Offscreen rendering of the MuJoCo scene (EGL by default, OSMesa as fallback) and MP4 videos.

MuJoCo fixes its GL backend when it is first imported, from ``MUJOCO_GL``. The package sets a
default at import (:func:`default_gl_backend`); commands that render call :func:`configure_gl`
before anything imports MuJoCo, which probes EGL in a subprocess and falls back to OSMesa.
On software GL, shadows and reflections cost several times the rest of a frame: they are off
unless asked for.
"""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

GL_BACKENDS = ("egl", "osmesa")
_PROBE = (
    "import mujoco;"
    'm = mujoco.MjModel.from_xml_string(\'<mujoco><worldbody><geom size="1 1 .1" type="plane"/>'
    "</worldbody></mujoco>');"
    "r = mujoco.Renderer(m, 8, 8); d = mujoco.MjData(m); r.update_scene(d); r.render()"
)


class RenderingError(RuntimeError):
    """No offscreen GL backend works, or the one MuJoCo loaded is not the one asked for."""


def default_gl_backend() -> str:
    """EGL if its library is installed, else OSMesa, else none (physics runs without GL)."""
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


def configure_gl(backend: str | None = None) -> str:
    """Make sure MuJoCo will load a working offscreen backend; return its name.

    ``backend`` forces one (``egl`` or ``osmesa``); otherwise the first that works is taken.
    Must run before MuJoCo is imported in this process, or agree with what it loaded.
    """
    if backend is not None and backend not in GL_BACKENDS:
        raise RenderingError(
            f"unknown GL backend {backend!r}; choose from {', '.join(GL_BACKENDS)}"
        )
    loaded = "mujoco" in sys.modules
    if loaded:
        current = os.environ.get("MUJOCO_GL", "")
        if backend is not None and backend != current:
            raise RenderingError(
                f"MuJoCo was already imported with MUJOCO_GL={current!r}; set MUJOCO_GL={backend} "
                "before importing cpp_mujoco's physics or mujoco"
            )
        if current not in GL_BACKENDS:
            raise RenderingError(f"MuJoCo was imported with MUJOCO_GL={current!r}: no offscreen GL")
        return current
    candidates = [backend] if backend else list(GL_BACKENDS)
    for name in candidates:
        if gl_works(name):
            os.environ["MUJOCO_GL"] = name
            os.environ.pop("PYOPENGL_PLATFORM", None)
            return name
    raise RenderingError(
        f"no offscreen GL backend works here (tried {', '.join(candidates)}); install the system "
        "libraries with scripts/setup.sh as root (libegl1, libosmesa6)"
    )


class OffscreenCamera:
    """Renders one camera of a model: a named MJCF camera, or a chase camera tracking a body."""

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
    ):
        import mujoco

        try:
            self.renderer = mujoco.Renderer(model, height, width)
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

    def render(self, data) -> np.ndarray:
        """(H, W, 3) uint8 frame of the current state."""
        import mujoco

        self.renderer.update_scene(data, camera=self.camera, scene_option=self.scene_option)
        flags = self.renderer.scene.flags
        flags[mujoco.mjtRndFlag.mjRND_SHADOW], flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = (
            self._flags
        )
        return self.renderer.render()

    def close(self) -> None:
        try:
            self.renderer.close()
        except Exception:  # noqa: BLE001 - GL teardown errors at exit carry no information
            pass


class VideoWriter:
    """MP4 (H.264) through imageio-ffmpeg; closing on error or interrupt finalises the file."""

    def __init__(self, path: str | os.PathLike, fps: float = 20.0):
        import imageio.v2 as imageio

        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._writer = imageio.get_writer(
                str(self.path), fps=fps, codec="libx264", quality=7, macro_block_size=8
            )
        except OSError as e:
            raise OSError(f"cannot write video {self.path}: {e}") from e
        self.frames = 0

    def write(self, frame: np.ndarray) -> None:
        self._writer.append_data(frame)
        self.frames += 1

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

"""Fixtures shared by several test modules."""

import os

import pytest

if os.environ.get("PYTEST_XDIST_WORKER"):  # two test workers share the cores: one thread each
    for _name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")


@pytest.fixture
def one_thread():
    """Tiny nets: torch's thread pool on a shared 2-core box costs more than it saves."""
    import torch  # noqa: F401 - one_torch_thread acts on an imported torch

    from cpp_mujoco.protocol.physics_tasks import one_torch_thread

    with one_torch_thread():
        yield


@pytest.fixture(scope="module")
def gl():
    """The backend the first render will choose (``select_gl``); skip where none works."""
    from cpp_mujoco.physics.view.rendering import GL_BACKENDS, default_gl_backend, gl_works

    backend = os.environ.get("MUJOCO_GL") or default_gl_backend()
    if backend not in GL_BACKENDS or not gl_works(backend):
        pytest.skip(f"no offscreen GL here (MUJOCO_GL={backend!r})")
    return backend

"""Fixtures shared by several test modules."""

import pytest


@pytest.fixture
def one_thread():
    """Tiny nets: torch's thread pool on a shared 2-core box costs more than it saves."""
    import torch  # noqa: F401 - one_torch_thread acts on an imported torch

    from cpp_mujoco.physics.protocol import one_torch_thread

    with one_torch_thread():
        yield

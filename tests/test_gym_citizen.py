"""The envs as gymnasium expects them: strict actions, rendering, RecordVideo, vector seeding."""

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cpp_mujoco  # noqa: F401 - registers the envs
from cpp_mujoco.grid.vector_env import GridVectorEnv
from cpp_mujoco.maps import GridMap

SMALL = GridMap.from_ascii(["LTT", "TNT", "TTL"], name="small")
BAD_ACTIONS = [2.5, 2.0, np.float64(1.0), np.array(2.0), "1", True, np.array([2]), 5, -1, None]
GOOD_ACTIONS = [2, np.int64(2), np.uint8(2), np.array(2), np.array(2, dtype=np.int32)]


@pytest.fixture(scope="module")
def physics():
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL)
    yield env
    env.close()


# ----------------------------------------------------------------------------- actions
@pytest.mark.parametrize("action", BAD_ACTIONS, ids=repr)
def test_both_envs_reject_the_same_non_integer_actions(physics, action):
    grid = gym.make("cpp_mujoco/Grid-v0", map=SMALL)
    for env in (grid, physics):
        env.reset(seed=0, options={"start": (0, 0), "budget": 5})
        with pytest.raises(ValueError, match="action must be an integer in 0..4"):
            env.step(action)
        _, _, _, _, info = env.step(1)  # the bad action changed nothing
        assert info["budget"] == 4 and info["position"] == (0, 1)


@pytest.mark.parametrize("action", GOOD_ACTIONS, ids=repr)
def test_integer_actions_of_any_integer_type_are_taken(action):
    env = gym.make("cpp_mujoco/Grid-v0", map=SMALL)
    env.reset(seed=0, options={"start": (0, 0), "budget": 5})
    *_, info = env.step(action)  # south
    assert info["position"] == (1, 0) and info["budget"] == 4


def test_physics_env_takes_numpy_integer_actions(physics):
    physics.reset(seed=0, options={"start": (0, 0), "budget": 5})
    *_, info = physics.step(np.array(1))  # east, as a 0-d array (what SB3's predict returns)
    assert info["position"] == (0, 1) and not info["rejected"]


def test_vector_env_rejects_float_actions():
    envs = GridVectorEnv(num_envs=2, map=SMALL)
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="actions must be 2 integers"):
        envs.step(np.array([1.5, 2.0]))


# ----------------------------------------------------------------------------- rendering
def test_physics_render_mode_is_checked_and_lazy():
    from cpp_mujoco.physics.envs.single import MuJoCoEnv

    with pytest.raises(ValueError, match="render_mode"):
        MuJoCoEnv(map=SMALL, render_mode="depth")
    with pytest.raises(ValueError, match="render_size"):
        MuJoCoEnv(map=SMALL, render_mode="rgb_array", render_size=(0, 64))
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL)
    env.reset(seed=0)
    assert env.render() is None and env.unwrapped._camera is None


def test_physics_rgb_array_shows_the_chase_camera(gl):
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, render_mode="rgb_array")
    assert env.metadata["render_modes"] == ["rgb_array"] and env.metadata["render_fps"] > 0
    assert env.unwrapped._camera is None  # no GL until the first render
    env.reset(seed=0, options={"start": (0, 0), "budget": 5})
    before = env.render()
    assert before.shape == (384, 512, 3) and before.dtype == np.uint8
    assert before.std() > 10  # not a blank frame
    env.step(1)  # east: the tracked UAV moved, so the ground under it did
    assert np.abs(env.render().astype(int) - before).mean() > 1
    env.close()
    assert env.unwrapped._camera is None


def test_record_video_records_a_physics_episode(gl, tmp_path):
    import imageio.v2 as imageio
    from gymnasium.wrappers import RecordVideo

    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, render_mode="rgb_array")
    env = RecordVideo(
        env, str(tmp_path / "videos"), episode_trigger=lambda _: True, disable_logger=True
    )
    env.reset(seed=0, options={"start": (0, 0), "budget": 5})
    for action in (1, 3, 4):  # east, west, land
        *_, terminated, _, info = env.step(action)
    assert terminated and info["landed"]
    env.close()
    (video,) = (tmp_path / "videos").glob("*.mp4")
    assert video.stat().st_size > 0
    frames = imageio.mimread(video)
    assert len(frames) == 4 and frames[0].shape == (384, 512, 3)


def test_check_env_with_rendering(gl):
    env = gym.make("cpp_mujoco/MuJoCo-v0", map=SMALL, render_mode="rgb_array")
    check_env(env.unwrapped)
    env.close()


def test_vector_env_renders_one_map_image_per_env():
    envs = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=3, map=SMALL, render_mode="rgb_array")
    assert envs.render_mode == "rgb_array"
    envs.reset(seed=[0, 1, 2])
    frames = envs.render()
    assert len(frames) == 3 and all(f.shape == (48, 48, 3) for f in frames)
    assert gym.make_vec("cpp_mujoco/Grid-v0", num_envs=2, map=SMALL).render() is None
    with pytest.raises(ValueError, match="render_mode"):
        GridVectorEnv(num_envs=2, map=SMALL, render_mode="human")


# ----------------------------------------------------------------------------- import side effects
def _python(code: str) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter with no GL backend chosen; warnings are errors."""
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    return subprocess.run(
        [sys.executable, "-W", "error", "-c", code], env=env, capture_output=True, text=True
    )


def test_importing_the_package_and_using_the_grid_sets_nothing():
    result = _python(
        "import ctypes.util, os, sys\n"
        "def no_ldconfig(name): raise AssertionError(f'find_library({name!r}) at import')\n"
        "ctypes.util.find_library = no_ldconfig\n"
        "import cpp_mujoco, gymnasium as g\n"
        "import cpp_mujoco.physics.config, cpp_mujoco.physics.geometry\n"
        "e = g.make('cpp_mujoco/Grid-v0'); e.reset(seed=0); e.step(1)\n"
        "assert 'MUJOCO_GL' not in os.environ, os.environ['MUJOCO_GL']\n"
        "assert 'mujoco' not in sys.modules and 'dm_control' not in sys.modules\n"
    )
    assert result.returncode == 0, result.stderr[-2000:]


def test_the_first_render_chooses_the_gl_backend(gl):
    result = _python(
        "import os, gymnasium as g, cpp_mujoco\n"
        "from cpp_mujoco.maps import GridMap\n"
        "from cpp_mujoco.physics.view.rendering import default_gl_backend, loaded_gl_backend\n"
        "small = GridMap.from_ascii(['LTT', 'TNT', 'TTL'], name='small')\n"
        "env = g.make('cpp_mujoco/MuJoCo-v0', map=small, render_mode='rgb_array')\n"
        "env.reset(seed=0)\n"
        "assert 'MUJOCO_GL' not in os.environ  # building and flying chose nothing\n"
        "frame = env.render()\n"
        "assert frame.shape == (384, 512, 3) and frame.std() > 10, frame.std()\n"
        "chosen = os.environ['MUJOCO_GL']\n"
        "assert chosen == default_gl_backend() == loaded_gl_backend(), chosen\n"
        "env.close()\n"
        "print(chosen)\n"
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.strip() == gl


# ----------------------------------------------------------------------------- vector seeding
@pytest.mark.parametrize("seed", [[5, 17, 3, 99], 7], ids=["list", "int"])
def test_native_vector_env_equals_sync_vector_env_of_single_envs(seed):
    kwargs = dict(map=SMALL, min_budget=2, max_budget=6, render_mode="rgb_array")
    native = gym.make_vec("cpp_mujoco/Grid-v0", num_envs=4, **kwargs)
    sync = gym.vector.SyncVectorEnv(
        [lambda: gym.make("cpp_mujoco/Grid-v0", **kwargs) for _ in range(4)]
    )
    a, _ = native.reset(seed=seed)
    b, _ = sync.reset(seed=seed)
    rng = np.random.default_rng(0)
    resets = 0
    for _ in range(40):  # short budgets: many NEXT_STEP autoresets, each a fresh draw per env
        for key in a:
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        actions = rng.integers(5, size=4)
        a, ra, ta, _, ia = native.step(actions)
        b, rb, tb, _, ib = sync.step(actions)
        np.testing.assert_allclose(ra, rb)
        np.testing.assert_array_equal(ta, tb)
        np.testing.assert_array_equal(ia["budget"], ib["budget"])
        resets += int(ta.sum())
    assert resets > 8
    for fa, fb in zip(native.render(), sync.render(), strict=True):
        np.testing.assert_array_equal(fa, fb)


def test_seed_list_is_validated_and_reproducible():
    envs = GridVectorEnv(num_envs=3, map="A")
    _, first = envs.reset(seed=[1, 2, 3])
    _, again = envs.reset(seed=[1, 2, 3])
    np.testing.assert_array_equal(first["position"], again["position"])
    np.testing.assert_array_equal(first["budget"], again["budget"])
    assert envs.np_random_seed == (1, 2, 3)
    _, partial = envs.reset(seed=[1, None, 3])  # None keeps env 1's generator going
    assert envs.np_random_seed == (1, 2, 3)
    np.testing.assert_array_equal(partial["budget"][[0, 2]], first["budget"][[0, 2]])
    with pytest.raises(ValueError, match="3 entries; num_envs is 4|num_envs is 3"):
        envs.reset(seed=[1, 2])
    with pytest.raises(ValueError, match=r"seed\[1\]"):
        envs.reset(seed=[1, -2, 3])
    with pytest.raises(ValueError, match="seed must be"):
        envs.reset(seed="0")

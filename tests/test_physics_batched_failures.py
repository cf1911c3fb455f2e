"""The batched physics env's failures are the single env's, bit for bit: MuJoCo's resets of a
diverging drone, a flip, a drone driven into the ground mid-move, the cut-off landing — and each
drone's MuJoCo state (the solver's warmstart included, which ``mujoco.batch`` keeps per drone)
stays the single env's after every step."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np

import cpp_mujoco  # noqa: F401  (registers the envs)
from cpp_mujoco.grid.actions import EAST, LAND, NORTH, SOUTH, WEST
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.envs.vector import MuJoCoVectorEnv
from cpp_mujoco.physics.power.battery import CUTOFF

OPEN = GridMap.from_ascii(["TTTTT", "TTTTT", "TTLTT", "TTTTT", "TTTTT"], name="open")
KEYS = ("position", "budget", "landed", "crashed", "energy_used_j", "flight_time_s",
        "nfz_violations", "max_track_error_m", "state_of_charge", "crash_reason")  # fmt: skip


def _fly(kwargs: dict, perturb, actions: list[int], n: int = 3, budget: int = 10, at: int = 0):
    """``n`` drones of a batched env and ``n`` single envs from (2, 2); ``perturb(i, qpos,
    qvel)`` edits each drone's state before action ``at`` (views of its state row in its
    flight: a single env's is a batch of one). Every info key must agree exactly after every
    step, and so must the full MuJoCo state (qpos, qvel, act, warmstart). Returns each crash
    reason."""
    venv = MuJoCoVectorEnv(num_envs=n, map=OPEN, **kwargs)
    singles = [gym.make("cpp_mujoco/MuJoCo-v0", map=OPEN, **kwargs).unwrapped for _ in range(n)]
    start = {"start": np.array([[2, 2]] * n), "budget": np.full(n, budget)}
    venv.reset(seed=list(range(n)), options=start)
    f = venv.flight
    q, v = f.cols[0], f.cols[1]
    S = mujoco.mjtState  # a batch row begins with these components, in this order
    compared = S.mjSTATE_TIME | S.mjSTATE_PHYSICS | S.mjSTATE_WARMSTART
    size = mujoco.mj_stateSize(f.model, compared)
    full = np.empty(size)
    for i, env in enumerate(singles):
        env.reset(seed=i, options={"start": (2, 2), "budget": budget})
    done = [False] * n
    reasons: list[str | None] = [None] * n
    for step, action in enumerate(actions):
        if step == at:
            for i, env in enumerate(singles):  # a single env's drone is its batch's row 0
                perturb(i, env.flight.state[0, q], env.flight.state[0, v])
                perturb(i, f.state[i, q], f.state[i, v])
        *_, info = venv.step(np.full(n, action))
        for i, env in enumerate(singles):
            if done[i]:
                continue
            *_, term, _, si = env.step(action)
            for key in KEYS:
                assert np.array_equal(si[key], info[key][i]), f"step {step} env {i}: {key}"
            mujoco.mj_getState(env.model, env.data, full, compared)
            np.testing.assert_array_equal(full, f.state[i, :size], err_msg=f"step {step} env {i}")
            done[i] = bool(term)
            reasons[i] = si["crash_reason"]
        if all(done):
            break
    assert all(done)
    venv.close()
    return reasons


def test_divergence_resets_and_a_flip_end_as_in_the_single_env():
    """After one action: drone 0 so fast that its drag makes a bad acceleration (MuJoCo resets
    it and counts the divergence), drone 1 with a velocity MuJoCo resets without that count
    (the motors cut, then the reset pose is on the ground), drone 2 upside down, drone 3 driven
    into the ground mid-move (contacts and the solver's warmstart in a move; it flies on),
    drone 4 untouched, flying on while the others end."""

    def perturb(i, qpos, qvel):
        if i == 0:
            qvel[0] = 1e6
        elif i == 1:
            qvel[0] = 1e12
        elif i == 2:
            qpos[3:7] = (0.0, 1.0, 0.0, 0.0)
        elif i == 3:
            qvel[2] = -40.0

    with np.errstate(all="ignore"):
        reasons = _fly({}, perturb, [EAST, EAST, WEST, WEST, LAND], n=5, at=1)
    assert reasons[0] == "numerical divergence (NaN or unstable acceleration)"
    assert reasons[1].startswith("battery")  # the motors cut at that speed, then the reset
    assert reasons[2] == "flipped over"
    assert reasons[3] is None and reasons[4] is None  # landed


def test_cut_off_landing_touches_down_as_in_the_single_env():
    """The battery failsafe lands each drone where it is: touchdown and settle on the skids."""
    reasons = _fly({"battery_cutoff_v": 3.95}, lambda i, qpos, qvel: None, [NORTH, SOUTH] * 6)
    assert reasons == [CUTOFF] * 3

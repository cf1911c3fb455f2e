"""How fast the physics envs run compared with MuJoCo alone, and the protocol over workers.

``env`` physics steps/s are measured while the env flies a mission (random actions, a fresh
episode whenever one ends); ``raw`` is a Python loop of single ``mj_step`` calls on the same
model in the same process. overhead ratio = env / raw (1.0 would mean the controller, camera,
energy and wind cost nothing); real-time factor = simulated seconds per wall-clock second.
"""

from __future__ import annotations

import time

import gymnasium as gym
import mujoco
import numpy as np
from mujoco.batch import Batch

from cpp_mujoco.agent import load_agent
from cpp_mujoco.maps import GridMap
from cpp_mujoco.physics.airborne import air_model
from cpp_mujoco.physics.calibration import calibration
from cpp_mujoco.physics.envs.mixed_wind import MixedWindVectorEnv
from cpp_mujoco.physics.envs.single import MuJoCoEnv
from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets


def benchmark_physics(seconds: float = 5.0, map: str = "A", seed: int = 0) -> dict:  # noqa: A002
    """Measure for about ``seconds`` of wall time (split between the two runs)."""
    env = MuJoCoEnv(map=map)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed, options={"budget": 75})
    model, data = env.model, env.data
    budget = seconds / 2

    sim_time, actions, episodes = 0.0, 0, 1
    start = time.perf_counter()
    while time.perf_counter() - start < budget:
        t0 = data.time
        *_, terminated, _, _ = env.step(int(rng.integers(5)))
        sim_time += data.time - t0
        actions += 1
        if terminated:
            env.reset(seed=int(rng.integers(1 << 31)), options={"budget": 75})
            episodes += 1
    env_wall = time.perf_counter() - start
    env_steps = sim_time / model.opt.timestep

    env.reset(seed=seed, options={"budget": 75})  # hovering at cruise altitude
    data.ctrl[:] = data.act[:]
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < budget:
        for _ in range(1000):
            mujoco.mj_step(model, data)
        n += 1000
    raw_wall = time.perf_counter() - start

    env_rate, raw_rate = env_steps / env_wall, n / raw_wall
    return {
        "timestep_s": float(model.opt.timestep),
        "control_rate_hz": env.config.control_rate,
        "camera_rate_hz": env.config.camera_rate,
        "env_steps_per_s": env_rate,
        "raw_steps_per_s": raw_rate,
        "overhead_ratio": env_rate / raw_rate,
        "real_time_factor": env_rate * model.opt.timestep,
        "raw_real_time_factor": raw_rate * model.opt.timestep,
        "actions_per_s": actions / env_wall,
        "episodes": episodes,
        "sim_seconds": sim_time,
    }


def benchmark_batched(
    seconds: float = 4.0,
    num_envs: int = 64,
    map: str = "A",
    seed: int = 0,  # noqa: A002
) -> dict:
    """Actions/s and physics steps/s of one ``MuJoCo-v0`` against the batched env of
    ``num_envs`` drones (1 and 2 stepping threads), and raw ``mj_step`` of the same model, side
    by side in one process; random moves with 2 % landings, budget 75, new episodes as they end.
    Each rate is the best of two rounds (the machine is shared: the best is the least disturbed).
    The batched env steps airborne drones on a model
    without contacts (:mod:`~cpp_mujoco.physics.airborne`): ``batched_full_model_*`` flies it
    with every step on the full model, and ``*_physics_ratio_vs_air`` divides by raw
    ``mj_step`` of that contact-free model instead (the ratios the 0.8 target cannot flatter)."""
    rng = np.random.default_rng(seed)
    single = MuJoCoEnv(map=map)
    timestep = single.model.opt.timestep

    def actions(n):
        return np.where(rng.random(n) < 0.02, 4, rng.integers(0, 4, size=n))

    def run_single() -> tuple[float, float]:
        single.reset(seed=seed, options={"budget": 75})
        acts, sim, start = 0, 0.0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            t0 = single.data.time
            *_, terminated, _, _ = single.step(int(actions(1)[0]))
            sim += single.data.time - t0
            acts += 1
            if terminated:
                single.reset(options={"budget": 75})
        wall = time.perf_counter() - start
        return acts / wall, sim / timestep / wall

    def run_batched(threads: int, air: bool = True) -> tuple:
        env = gym.make_vec("cpp_mujoco/MuJoCo-v0", num_envs=num_envs, map=map, threads=threads)
        if not air:
            env.flight.air = None
        env.reset(seed=seed, options={"budget": np.full(num_envs, 75)})
        clock = env.flight.state[:, 0]  # each drone's simulated time
        acts, sim, start = 0, 0.0, time.perf_counter()
        while time.perf_counter() - start < seconds:
            t0 = clock.copy()
            env.step(actions(num_envs))
            flown = clock - t0
            sim += flown[flown > 0].sum()  # a drone reset this step starts from 0
            acts += num_envs
        wall = time.perf_counter() - start
        env.close()
        return acts / wall, sim / timestep / wall

    def run_raw(air: bool = False) -> float:
        single.reset(seed=seed, options={"budget": 75})
        model, data = air_model(single.model) if air else single.model, single.data
        data.ctrl[:] = data.act[:]
        n, start = 0, time.perf_counter()
        while time.perf_counter() - start < seconds / 2:
            for _ in range(1000):
                mujoco.mj_step(model, data)
            n += 1000
        return n / (time.perf_counter() - start)

    kinds = [("single", run_single), ("batched_1", lambda: run_batched(1)),
             ("batched_2", lambda: run_batched(2)), ("raw", run_raw),
             ("batched_full_model", lambda: run_batched(1, air=False)),
             ("raw_air", lambda: run_raw(air=True))]  # fmt: skip
    best: dict[str, tuple] = {}
    for _ in range(2):  # interleaved rounds: a disturbance hits every kind alike
        for name, fn in kinds:
            value = fn()
            key = value if isinstance(value, tuple) else (value,)
            if name not in best or key[0] > best[name][0]:
                best[name] = key
    (sa, ss), (b1a, b1s), (b2a, b2s), (raw,) = (
        best["single"],
        best["batched_1"],
        best["batched_2"],
        best["raw"],
    )
    return {
        "num_envs": num_envs,
        "single_actions_per_s": sa,
        "batched_actions_per_s": b1a,
        "batched_2_threads_actions_per_s": b2a,
        "batched_vs_single": b1a / sa,
        "batched_2_threads_vs_single": b2a / sa,
        "raw_mj_step_per_s": raw,
        "single_physics_ratio": ss / raw,
        "batched_physics_ratio": b1s / raw,
        "batched_2_threads_physics_ratio": b2s / raw,
        "raw_air_mj_step_per_s": best["raw_air"][0],
        "batched_physics_ratio_vs_air": b1s / best["raw_air"][0],
        "batched_full_model_actions_per_s": best["batched_full_model"][0],
        "batched_full_model_physics_ratio": best["batched_full_model"][1] / raw,
        "air_steps_speedup": b1a / best["batched_full_model"][0],
    }


def batch_stepping_rate(
    drones: int = 192,
    seconds: float = 2.0,
    map: str = "A",  # noqa: A002
    air: bool = True,
) -> float:
    """``mj_step``/s of MuJoCo alone as the batched env steps it: ``drones`` hovering drones,
    5 steps per ``Batch.step`` call (a control tick's), no Python between calls but the loop;
    at cruise altitude, so on the contact-free model (``air``; False: the full model)."""
    env = MuJoCoEnv(map=map)
    env.reset(seed=0, options={"budget": 75})
    env.data.ctrl[:] = env.data.act
    kind = mujoco.mjtState.mjSTATE_INTEGRATION
    row = np.empty(mujoco.mj_stateSize(env.model, kind))
    mujoco.mj_getState(env.model, env.data, row, kind)
    sims = Batch(air_model(env.model) if air else env.model, drones, nthread=1, persistent=True)
    sims.state[:] = row
    sims.forward()
    calls, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        sims.step(None, 5)
        calls += 1
    return calls * drones * 5 / (time.perf_counter() - start)


def benchmark_protocol(map: str = "A", step: int = 1, ray_step: int = 1) -> dict:  # noqa: A002
    """Wall time of the MuJoCo protocol of the bundled agent on ``map`` (budgets every ``step``)
    over 2 local worker processes, and on Ray with 1 and 2 CPUs (budgets every ``ray_step``; each
    runtime started before the clock starts). The Ray runs must agree episode by episode.
    ``stepping_floor_s``: the protocol's physics steps at :func:`batch_stepping_rate` on both
    cores — MuJoCo's own share of the wall time, which no Python around it can remove."""
    policy = load_agent(map)
    start = time.perf_counter()
    local = evaluate(policy, map, backend="mujoco", budgets=protocol_budgets(step=step), workers=2)
    wall = time.perf_counter() - start
    steps = float(local.physics["flight_time_s"].sum()) / MuJoCoEnv(map=map).model.opt.timestep
    floor = steps / batch_stepping_rate() / 2  # MuJoCo alone, on both cores
    out = {
        f"protocol_{map}_episodes": int(local.budgets.size),
        f"protocol_{map}_local_2_workers_s": wall,
        f"protocol_{map}_physics_steps": steps,
        f"protocol_{map}_stepping_floor_s": floor,
        f"protocol_{map}_stepping_share": floor / wall,
    }
    try:
        import ray  # optional: the ray extra
    except ImportError:
        return out
    budgets = protocol_budgets(step=ray_step)
    results = {}
    for cpus in (1, 2):
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
        try:
            start = time.perf_counter()
            results[cpus] = evaluate(
                policy, map, backend="mujoco", budgets=budgets, workers=cpus, engine="ray"
            )
            out[f"ray_{cpus}_cpu_s"] = time.perf_counter() - start
        finally:
            ray.shutdown()
    energy = [r.physics["energy_used_j"] for r in results.values()]
    if not np.array_equal(*energy):
        raise RuntimeError("Ray with 1 and 2 CPUs flew different episodes")
    out.update(
        ray_episodes=int(results[1].budgets.size),
        ray_scaling=out["ray_1_cpu_s"] / out["ray_2_cpu_s"],
    )
    return out


def flight_figures(wind_speed: float = 8.0) -> dict:
    """The physical figures quoted in ``docs/physics.md``: calibration, a one-cell step response,
    landing energy and the headwind energy ratios (default configuration)."""
    open_map = GridMap.from_ascii(["TTTTT", "TTTTT", "TTLTT", "TTTTT", "TTTTT"], name="open")

    def fly(actions, trace=False, **kwargs):
        env = MuJoCoEnv(map=open_map, **kwargs)
        env.reset(seed=0, options={"start": (2, 2), "budget": 10})
        env.flight.trace = [] if trace else None
        for a in actions:
            *_, info = env.step(a)
        return env, info

    env, info = fly((1,), trace=True)  # one cell east
    tr = np.array(env.flight.trace)
    goal = env.flight.waypoint(13)
    speed = np.linalg.norm(np.diff(tr[:, 1:4], axis=0), axis=1) / env.flight.dt
    unit = env.unit_energy
    _, land = fly((4,))
    head = {w: fly((0,), wind_speed=w)[1]["energy_used_j"] for w in (0.0, wind_speed)}
    loop = {w: fly((0, 0, 2, 2), wind_speed=w)[1]["energy_used_j"] for w in (0.0, wind_speed)}
    return {
        "calibration": calibration(env.config),
        "step_time_s": info["flight_time_s"],
        "step_final_error_m": info["tracking_error_m"],
        "step_overshoot_m": float(tr[:, 1].max() - goal[0]),
        "step_max_altitude_error_m": float(np.abs(tr[:, 3] - goal[2]).max()),
        "step_peak_speed_m_s": float(speed.max()),
        "land_energy_units": land["energy_used_j"] / unit,
        "land_time_s": land["flight_time_s"],
        f"headwind_{wind_speed:g}_move_ratio": head[wind_speed] / head[0.0],
        f"headwind_{wind_speed:g}_out_and_back_ratio": loop[wind_speed] / loop[0.0],
    }


def benchmark_mixed(seconds: float = 15.0, num_envs: int = 64, map: str = "B") -> dict:  # noqa: A002
    """Actions/s of the fine-tuning env (:class:`MixedWindVectorEnv`: calm air and 9 m/s
    moderate from N/E/S/W) with the four directions in one batch, against the same weathers
    kept in five batches (a condition key that changes nothing keeps them apart); interleaved,
    best of two rounds."""
    calm, rest = num_envs // 5, num_envs - num_envs // 5
    shares = [rest // 4 + (k < rest % 4) for k in range(4)]
    wind = {"wind_speed": 9.0, "turbulence": "moderate"}

    def conditions(apart: bool) -> list:
        winds = [
            ({**wind, "wind_direction": 90.0 * k, **({"gust_seed": 0} if apart and k % 2 else {})},
             n)
            for k, n in enumerate(shares)
        ]  # fmt: skip
        return [({}, calm), *winds]

    rng = np.random.default_rng(0)
    best = {"merged": 0.0, "apart": 0.0}
    for _ in range(2):
        for name in best:
            env = MixedWindVectorEnv(conditions(name == "apart"), map, autoreset_mode="SameStep")
            env.reset(seed=0)
            acts, start = 0, time.perf_counter()
            while time.perf_counter() - start < seconds:
                env.step(np.where(rng.random(num_envs) < 0.02, 4, rng.integers(0, 4, num_envs)))
                acts += num_envs
            best[name] = max(best[name], acts / (time.perf_counter() - start))
            env.close()
    return {
        "mixed_num_envs": num_envs,
        "mixed_merged_actions_per_s": best["merged"],
        "mixed_apart_actions_per_s": best["apart"],
        "mixed_speedup": best["merged"] / best["apart"],
    }


def run() -> dict:
    """The ``physics`` section as ``cpp-mujoco benchmark`` runs it (≈ 10 min on 2 cores: the
    full protocol on map A is part of it)."""
    return {**benchmark_physics(seconds=5.0), **benchmark_batched(), **benchmark_protocol()}


if __name__ == "__main__":
    import argparse
    import json

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("seconds", nargs="?", type=float, default=5.0)
    parser.add_argument("--figures", action="store_true", help="physical figures instead")
    parser.add_argument("--batched", type=int, metavar="N", help="single vs N batched drones")
    parser.add_argument("--protocol", type=int, metavar="STEP", help="protocol wall times")
    parser.add_argument("--mixed", type=int, metavar="N", help="fine-tuning env, N drones")
    args = parser.parse_args()
    if args.figures:
        result = flight_figures()
    elif args.batched:
        result = benchmark_batched(args.seconds, args.batched)
    elif args.mixed:
        result = benchmark_mixed(args.seconds, args.mixed)
    elif args.protocol:
        result = benchmark_protocol(step=args.protocol)
    else:
        result = benchmark_physics(args.seconds)
    print(json.dumps(result, indent=1))

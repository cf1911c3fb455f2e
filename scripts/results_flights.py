"""Flies the result families whose files scripts/results_docs.py renders, and writes the files.

    python scripts/results_flights.py planners                    # results/planners_abc.json
    python scripts/results_flights.py transfer --budget-step 1    # results/transfer_abc.json
    python scripts/results_flights.py transfer --budget-step 1 --wind-agents
                                                      # results/transfer_abc_wind.json
    python scripts/results_flights.py map-set --map-set heldout32-v1   # results/map_set_*.json
    python scripts/results_flights.py map-set --map-set city32-v1 --agent general-city
    python scripts/results_flights.py map-set --map-set city50-v1 --no-agent
    python scripts/results_flights.py network-alone --map-set heldout16-v1
                                                      # results/network_alone_*.json
    python scripts/results_flights.py network-alone --map-set city32-v1 --agent general-city
    python scripts/results_flights.py symmetric-q --map-set scatter16-v1
                                                      # results/symmetric_q_*.json
    python scripts/results_flights.py value-beam --map-set scatter16-v1 --workers 2
                                                      # results/value_beam_*.json
    python scripts/results_flights.py value-beam --map-set city50-v1 --agent general-city \
        --budget-step 10                              # results/value_beam_city50-v1_step10.json
    python scripts/results_flights.py energy                      # results/action_energy.json
    python scripts/results_flights.py wind-agents                 # results/wind_agents_grid.json
    python scripts/results_flights.py calibration                 # results/calibration.json

then ``python scripts/results_docs.py`` rewrites the pages from them. ``--budget-step N`` flies a
map-set family at every N-th budget only (the largest included), for a set whose whole protocol
costs more than a sitting: its files end in ``_stepN`` and its rows are named a sample of the
protocol wherever shown; flown with the planners at the same step (``map-set --budget-step N``),
they are compared on the same episodes. A map-set flight stopped part-way leaves its rows in
results/partial/ and the same command resumes it there. Each file records the command that flew
it; every result in it names its map (and digest), policy, backend and conditions.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
PARTIAL = RESULTS / "partial"  # the rows of flights stopped part-way, to resume
COMMAND = "python scripts/results_flights.py"


def write(name: str, data: dict) -> None:
    from cpp_mujoco.util.io import atomic_write_text, json_default

    atomic_write_text(RESULTS / name, json.dumps(data, indent=1, default=json_default))
    print(f"wrote results/{name}")


def transfer(workers: int, budget_step: int, wind_agents: bool = False) -> None:
    """The bundled per-map agents on A, B and C (the wind-robust ones with ``wind_agents``), on
    the grid and flown unchanged in calm MuJoCo air over the same episodes:
    results/transfer_abc.json (results/transfer_abc_wind.json)."""
    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets

    budgets = protocol_budgets(step=budget_step)
    rows = []
    suffix = "-wind" if wind_agents else ""
    for name in ("A", "B", "C"):
        agent = load_agent(name + suffix)
        for backend in ("grid", "mujoco"):
            kwargs = {"workers": workers} if backend == "mujoco" else {}
            result = evaluate(agent, name, backend=backend, budgets=budgets, **kwargs)
            rows.append(result.summary())
            print(f"{name} {backend}: {result.landing_ratio:.2%} / {result.coverage_ratio:.2%}")
    command = f"{COMMAND} transfer --budget-step {budget_step}"
    command += " --wind-agents" if wind_agents else ""
    write(f"transfer_abc{suffix.replace('-', '_')}.json", {"command": command, "results": rows})


def set_file(family: str, name: str, budget_step: int = 1) -> str:
    """A map-set family's result file: ``<family>_<set>.json``, ``…_step<N>.json`` where only
    every N-th budget is flown."""
    return f"{family}_{name}" + ("" if budget_step == 1 else f"_step{budget_step}") + ".json"


def map_set(name: str, agent: str | None = "general", workers: int = 1, step: int = 1) -> None:
    """``cpp-mujoco evaluate --map-set NAME`` for the planners and a general agent (none: a set
    it does not fit, e.g. obstacles it cannot see) on the grid (every map, the whole protocol):
    results/map_set_<NAME>.json."""
    args = ["--planner", "safe-greedy", "beam-search", *(["--agent", agent] if agent else [])]
    _evaluate_set(name, args, set_file("map_set", name, step), workers, step)


def network_alone(name: str, agent: str, workers: int = 1, step: int = 1) -> None:
    """The general agent's network with the return rule only (no revisit or finish mask) on a
    map set, the whole protocol on the grid: results/network_alone_<NAME>.json."""
    args = ["--agent", agent, "--rule", "return-mask"]
    _evaluate_set(name, args, set_file("network_alone", name, step), workers, step)


def symmetric_q(name: str, agent: str, workers: int = 1, step: int = 1) -> None:
    """The general agent with its rules and the symmetric-Q rule added on a map set, the whole
    protocol on the grid: results/symmetric_q_<NAME>.json."""
    args = ["--agent", agent, "--rule", "+symmetric-q"]
    _evaluate_set(name, args, set_file("symmetric_q", name, step), workers, step)


def value_beam(name: str, agent: str, workers: int = 1, step: int = 1) -> None:
    """The general agent with its rules flown through the beam search its Q-values rank
    (``--value-beam``, 32 paths) on a map set, the whole protocol on the grid:
    results/value_beam_<NAME>.json."""
    args = ["--agent", agent, "--value-beam"]
    _evaluate_set(name, args, set_file("value_beam", name, step), workers, step)


def _evaluate_set(name: str, args: list[str], result: str, workers: int, step: int = 1) -> None:
    """``evaluate --map-set`` into runs/flights/<result>/, the result copied to results/. The
    rows are kept in results/partial/<result>.rows.json as they land: a flight stopped part-way
    (a long one spans several sittings) resumes from it, committed or not."""
    import shutil

    from cpp_mujoco.cli.main import main as cli
    from cpp_mujoco.review.results import file_part

    stem = Path(result).stem
    out, checkpoint = ROOT / "runs" / "flights" / stem, PARTIAL / f"{stem}.rows.json"
    args = [*args, "--workers", str(workers), "--checkpoint", str(checkpoint)]
    args += [] if step == 1 else ["--budget-step", str(step)]
    code = cli(["evaluate", "--map-set", name, *args, "--out", str(out)])
    if code:
        raise SystemExit(code)
    shutil.copyfile(out / f"grid_{file_part(name)}.json", RESULTS / result)
    print(f"wrote results/{result}")


def planners() -> None:
    """The reference planners on A, B and C, the whole protocol on the grid:
    results/planners_abc.json."""
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.protocol.evaluate import evaluate

    rows = [
        evaluate(make_planner(p), name).summary()
        for name in ("A", "B", "C")
        for p in ("random", "safe-greedy", "beam-search")
    ]
    write("planners_abc.json", {"command": f"{COMMAND} planners", "results": rows})


def energy(repeats: int) -> None:
    """Each kind of action's battery energy on an open map, steady and in moderate turbulence,
    calm and 3..12 m/s from N/E/S/W: results/action_energy.json."""
    from dataclasses import asdict

    from cpp_mujoco.physics.action_energy import _OPEN, KINDS, action_energy_table
    from cpp_mujoco.physics.calibration import unit_energy
    from cpp_mujoco.physics.config import PhysicsConfig

    config = PhysicsConfig()
    steady = action_energy_table(config)
    gusty = action_energy_table(config, turbulence="moderate", repeats=repeats)
    rows = [
        {"map": _OPEN.label, "map_digest": _OPEN.digest, "backend": "mujoco",
         "policy": "from the middle cell out and back along each axis, a hover, a landing",
         "wind_speed": a.wind_speed, "wind_direction": a.wind_direction,
         "steady": asdict(a), "gusty": asdict(b),
         "conditions": {"physics_config": asdict(config), "gust_histories": repeats}}
        for a, b in zip(steady, gusty, strict=True)
    ]  # fmt: skip
    write("action_energy.json", {
        "command": f"{COMMAND} energy --repeats {repeats}", "kinds": list(KINDS),
        "unit_energy_j": unit_energy(config), "turbulence": "moderate", "repeats": repeats,
        "rows": rows,
    })  # fmt: skip


def calibration_units() -> None:
    """One calm move's battery energy (the budget unit before its margin) for each power model,
    the rotors alone and drawn from the pack: results/calibration.json."""
    from dataclasses import asdict, replace

    from cpp_mujoco.maps import load_map
    from cpp_mujoco.physics.calibration import calibration
    from cpp_mujoco.physics.config import POWER_MODELS, PhysicsConfig

    open_map = load_map("A")  # the rows name a map; the calibration flies its own 3x3 patch
    rows = []
    for model in POWER_MODELS:
        for resistance in (0.0, PhysicsConfig().battery_cell_resistance):
            config = replace(PhysicsConfig(), power_model=model, battery_cell_resistance=resistance)
            rows.append({
                **open_map.identity(), "policy": "the calibration moves (physics/calibration.py)",
                "backend": "mujoco", "power_model": model, "cell_resistance_ohm": resistance,
                **{k: v for k, v in calibration(config).items() if k != "key"},
                "conditions": {"physics_config": asdict(config)},
            })  # fmt: skip
    write("calibration.json", {"command": f"{COMMAND} calibration", "results": rows})


def wind_agents() -> None:
    """The paper agents and the wind-robust agents on the grid, calm and in the grid's 9 m/s wind
    (every episode 9 m/s from N/E/S/W, moderate gust costs), beside the safe greedy wind planner
    (every 5th budget): results/wind_agents_grid.json."""
    from dataclasses import replace

    from cpp_mujoco.agent import load_agent
    from cpp_mujoco.grid.wind import GridWind
    from cpp_mujoco.map_sets.size_classes import size_config
    from cpp_mujoco.planners import make_planner
    from cpp_mujoco.protocol.evaluate import evaluate, protocol_budgets

    calm = size_config(16)
    windy = replace(calm, wind=GridWind(min_speed=9.0, max_speed=9.0, calm_fraction=0.0))
    rows = []
    for name in ("A", "B", "C"):
        for policy in (load_agent(name), load_agent(f"{name}-wind")):
            rows += [evaluate(policy, name, config=c).summary() for c in (calm, windy)]
        planner = make_planner("safe-greedy-wind")
        budgets = protocol_budgets(windy, step=5)
        rows.append(evaluate(planner, name, config=windy, budgets=budgets).summary())
        print(f"{name}: " + ", ".join(f"{r['landing_ratio']:.2%} / {r['coverage_ratio']:.2%}"
                                      for r in rows[-5:]))  # fmt: skip
    write("wind_agents_grid.json", {"command": f"{COMMAND} wind-agents", "results": rows})


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "family",
        choices=[
            "planners", "transfer", "map-set", "network-alone", "symmetric-q", "value-beam",
            "energy", "wind-agents", "calibration",
        ],
    )  # fmt: skip
    p.add_argument("--map-set", default="heldout16-v1", help="map-set: which set")
    p.add_argument(
        "--agent", default="general",
        help="map-set, network-alone, symmetric-q, value-beam: the general agent flown "
        "(general-city on the city sets)",
    )  # fmt: skip
    p.add_argument("--no-agent", action="store_true", help="map-set: the planners only")
    p.add_argument(
        "--workers", type=int, default=2,
        help="transfer: MuJoCo worker processes; map-set, network-alone, symmetric-q, "
        "value-beam: processes flying the set's maps side by side",
    )  # fmt: skip
    p.add_argument(
        "--budget-step", type=int, default=None,
        help="transfer: every n-th budget (default 10); map-set, network-alone, symmetric-q, "
        "value-beam: every n-th budget of the set's size class, a sample of the protocol "
        "(default 1: every budget)",
    )  # fmt: skip
    p.add_argument("--wind-agents", action="store_true", help="transfer: the wind-robust agents")
    p.add_argument("--repeats", type=int, default=5, help="energy: gust histories per row")
    args = p.parse_args(argv)
    if args.budget_step is not None and args.budget_step < 1:
        p.error(f"--budget-step must be a positive integer, got {args.budget_step}")
    step = args.budget_step or 1
    if args.family == "planners":
        planners()
    elif args.family == "transfer":
        transfer(args.workers, args.budget_step or 10, args.wind_agents)
    elif args.family == "map-set":
        map_set(args.map_set, None if args.no_agent else args.agent, args.workers, step)
    elif args.family == "network-alone":
        network_alone(args.map_set, args.agent, args.workers, step)
    elif args.family == "symmetric-q":
        symmetric_q(args.map_set, args.agent, args.workers, step)
    elif args.family == "value-beam":
        value_beam(args.map_set, args.agent, args.workers, step)
    elif args.family == "wind-agents":
        wind_agents()
    elif args.family == "calibration":
        calibration_units()
    else:
        energy(args.repeats)
    print("now: python scripts/results_docs.py (the pages from the files)")
    return 0


if __name__ == "__main__":
    sys.exit(main())

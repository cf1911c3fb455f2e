"""The options and checks every subcommand shares: numbers with bounds, output folders and files,
progress bars, the weather, the workers, the exact planner's solver, an agent file.

Each ``add_*(parser)`` adds its options; each check raises ``ValueError`` or
``argparse.ArgumentTypeError`` with one line saying what to give instead. Nothing numerical is
imported here, so building the parser stays fast.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

# the reference planners (cpp_mujoco.planners.PLANNERS, named here for the parser; a test keeps
# them equal); evaluate flies the first three when no policy is named — the wind planners price
# moves with the observed wind and are asked for by name
PLANNER_NAMES = (
    "random", "safe-greedy", "beam-search", "safe-greedy-wind", "beam-search-wind", "optimal",
)  # fmt: skip

DEFAULT_PLANNERS = PLANNER_NAMES[:3]
# Dryden turbulence levels (MIL-F-8785C), the same as physics.air.turbulence.LEVELS; named
# here so that building the parser imports no numerical module (a test keeps them equal)
TURBULENCE_LEVELS = ("none", "light", "moderate", "severe")
# the agents' rules (cpp_mujoco.agent.rules.RULES, named here with one line each so that building
# the parser imports no torch; a test keeps them equal), in the order an agent applies them
RULES = {
    "return-mask": "only the actions after which the way home is still paid",
    "revisit-mask": "no move back into a fruitless cell flown through since the coverage grew",
    "finish-mask": "no landing while an unseen target can still be reached and left for home",
    "progress-mask": "while one is in reach, only moves one step nearer a cell showing a target",
    "symmetric-q": "the argmax of the Q-values averaged over the map's rotations and mirrors",
    "symmetric-q-unseen": "symmetric-q but on the maps the agent learned in their own orientation",
}
TRAIN_HELP = "train the DDQN agent on a map"
TRAIN_GENERAL_HELP = "train one DDQN agent for any map on generated maps"
# the exact planner's solvers (cpp_mujoco.planners.optimal_solver.SOLVERS, named here so that
# building the parser imports no planner; a test keeps them equal), the default first
SOLVERS = ("highs", "cp-sat")
DEFAULT_CACHE = "results/optimum"  # the committed cache of the bundled maps' protocol


def int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be >= {low}, got {value}")
        return value

    parse.__name__ = f"integer >= {low}"
    return parse


def out_dir(path: str) -> Path:
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OSError(f"cannot create output folder {out}: {e.strerror}") from e
    return out


def progress_wanted(args) -> bool:
    """Bars only for a person watching: stderr is a terminal and --no-progress is not given."""
    return not getattr(args, "no_progress", False) and sys.stderr.isatty()


def check_output_file(option: str, path: str | None, suffix: str) -> None:
    """An output file option pointing at a folder fails now, not after the mission flew."""
    if path and Path(path).is_dir():
        example = Path(path) / f"out{suffix}"
        raise ValueError(f"{option} {path} is a folder; give a file name such as {example}")


def check_agent_file(spec: str) -> None:
    path = Path(spec)
    if path.is_dir():
        hint = next(
            (f" such as {p}" for p in (path / "best.pt", path / "agent.pt") if p.is_file()), ""
        )
        raise ValueError(f"--agent {spec} is a folder; give a checkpoint file{hint}")


def add_budget_step_option(p, default: int = 1, help: str | None = None) -> None:
    """``--budget-step``: every n-th budget of each map's size class, the largest kept."""
    p.add_argument(
        "--budget-step", type=int_at_least(1), default=default,
        help=help or "every n-th budget of each map's size class (16x16: 25..75, 32x32: "
        "50..150, 50x50: 150..250), the largest always included (default: %(default)s, all)",
    )  # fmt: skip


def parse_start(text: str | None, example: str = "12,2") -> tuple[int, int] | None:
    """``--start ROW,COL`` as a cell (None when not given)."""
    if text is None:
        return None
    try:
        row, col = (int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--start must be ROW,COL (e.g. {example}), got {text!r}") from None
    return row, col


def add_fov_side_option(p) -> None:
    """``--fov-side``: the camera's square, for the episodes and the planners alike."""
    p.add_argument(
        "--fov-side", type=int_at_least(1), default=3, metavar="N",
        help="the camera sees the NxN cells around the UAV (3: the paper; 5: its city-map "
        "successors, where obstacles hide cells) (default: %(default)s)",
    )  # fmt: skip


def add_cell_pixels_option(p) -> None:
    p.add_argument(
        "--cell-pixels", type=int_at_least(1), metavar="N",
        help="a PNG map's pixels per cell side (default: one; an image obviously drawn at "
        "several is refused, naming N)",
    )  # fmt: skip


def add_any_map_option(p) -> None:
    p.add_argument(
        "--any-map", action="store_true",
        help="fly an agent on a map it was not trained on (refused otherwise; results say so)",
    )  # fmt: skip


def add_progress_option(p) -> None:
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bars (they are shown only when stderr is a terminal)",
    )


def add_wind_options(p) -> None:
    p.add_argument(
        "--wind-speed", type=float, default=0.0, help="mujoco: steady wind, m/s (default: 0)"
    )
    p.add_argument(
        "--wind-direction",
        type=float,
        default=0.0,
        help="mujoco: where the wind blows from, degrees clockwise from north (default: 0)",
    )
    p.add_argument(
        "--gust-std", type=float, default=0.0, help="mujoco: gust strength, m/s (default: 0)"
    )
    p.add_argument(
        "--turbulence", default="none", choices=TURBULENCE_LEVELS,
        help="mujoco: Dryden turbulence (MIL-F-8785C) on top of the wind; docs/turbulence.md "
        "(default: %(default)s)",
    )  # fmt: skip


_WEATHER_DEFAULTS = {
    "wind_speed": 0.0,
    "wind_direction": 0.0,
    "gust_std": 0.0,
    "turbulence": "none",
}


def weather_options(args) -> dict:
    """The weather options as ``MuJoCo-v0`` keyword arguments (so results record them); on the
    grid, where there is no weather, a weather option is an error rather than silently ignored."""
    weather = {k: getattr(args, k) for k in _WEATHER_DEFAULTS}
    if args.backend != "mujoco":
        given = [k for k, v in weather.items() if v != _WEATHER_DEFAULTS[k]]
        if given:
            flags = ", ".join("--" + k.replace("_", "-") for k in given)
            raise ValueError(f"{flags}: weather needs --backend mujoco (the grid has none)")
        return {}
    return weather


def add_workers_option(p) -> None:
    p.add_argument(
        "--workers", type=int_at_least(1), default=None,
        help="worker processes: in MuJoCo the episodes' (default: all cores); for a map set on "
        "the grid its maps', flown side by side (there one, this process, unless given)",
    )  # fmt: skip


def positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, got {text}")
    return value


def add_solver_options(p) -> None:
    p.add_argument(
        "--time-limit", type=positive_seconds, default=60.0, metavar="S",
        help="the exact planner's solver time per episode; a mission not proven by then is "
        "kept and labelled so (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--solver-workers", type=int_at_least(1), default=1,
        help="the solver's threads per episode (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--solver", choices=SOLVERS, default=SOLVERS[0],
        help="the exact planner's solver: HiGHS (branch and cut) or OR-Tools CP-SAT "
        "(default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--memory", type=int, choices=(1, 2), default=1,
        help="cells of memory in the exact planner's model: 2 tightens its bound at every "
        "branch-and-cut node for about four times the variables, for episodes 1 leaves open "
        "(default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--jobs", type=int_at_least(1), default=1,
        help="episodes solved at once, one process each (default: %(default)s)",
    )  # fmt: skip
    p.add_argument(
        "--optimum", metavar="DIR",
        help="the solved episodes' cache, one JSON file per map digest: read, and written by "
        f"what is solved (default: the committed one, {DEFAULT_CACHE} of the checkout or the "
        "installed package's copy)",
    )  # fmt: skip


def add_agent_options(p) -> None:
    """How the agents act: ``--rule`` (their rules) and ``--value-beam`` (search)."""
    rules = "; ".join(f"{name}: {what}" for name, what in RULES.items())
    changes = [f"{sign}{name}" for name in RULES for sign in ("+", "no-")]
    p.add_argument(
        "--rule", action="append", choices=[*RULES, *changes, "none"], metavar="RULE",
        help=f"the rules the agents fly with, repeatable: NAME (exactly these), +NAME or no-NAME "
        f"(the file's own with NAME added or taken away), 'none' (no rule) — {rules} "
        f"(default: each file's own)",
    )  # fmt: skip
    p.add_argument(
        "--value-beam", type=int_at_least(1), nargs="?", const=32, metavar="WIDTH",
        help="fly each agent through a beam search of WIDTH paths per episode (default 32) "
        "that its Q-values rank, its own mission the fallback; results name it "
        "NAME+value-beam (cpp_mujoco.agent.value_beam)",
    )  # fmt: skip


def check_rules(args) -> None:
    """``--rule`` only with ``--agent``; ``none`` alone; names and changes not mixed."""
    if getattr(args, "value_beam", None) and not getattr(args, "agent", None):
        raise ValueError("--value-beam searches with the agents' values; give --agent too")
    rules = getattr(args, "rule", None)
    if not rules:
        return
    if not getattr(args, "agent", None):
        raise ValueError("--rule sets the rules of the agents flown; give --agent too")
    if "none" in rules and len(rules) > 1:
        raise ValueError("--rule none flies the agents without any rule; give it alone")
    changes = [r for r in rules if r.startswith(("+", "no-"))]
    if changes and len(changes) != len(rules):
        raise ValueError("--rule takes rule names (exactly these) or +NAME/no-NAME, not both")


def rules_for(own: list[str], rules: list[str] | None) -> list[str]:
    """The rules an agent whose file names ``own`` flies with under ``--rule rules``."""
    if not rules:
        return list(own)
    if rules == ["none"]:
        return []
    if not rules[0].startswith(("+", "no-")):
        return [name for name in RULES if name in rules]
    added = {r[1:] for r in rules if r.startswith("+")}
    taken = {r.removeprefix("no-") for r in rules if r.startswith("no-")}
    return [name for name in RULES if (name in own or name in added) and name not in taken]

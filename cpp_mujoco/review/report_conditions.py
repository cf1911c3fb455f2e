"""Conditions as one readable line: backend, budgets, episodes, weather, guard, seed.

Why: the tables' and results' JSON carry every condition (the whole physics config), which is
right for reproducing a number and unreadable beside it. The report shows this line beside each
result and keeps the full JSON one click away. Plain Python only: the report imports no
numerics.
"""

from __future__ import annotations

from typing import Any

from cpp_mujoco.util.tables import BACKEND_NAMES, backend_name

_POINTS = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def merge(shared: dict, own: dict) -> dict:
    """``own`` over ``shared``, nested dicts key by key (a table row's full conditions)."""
    out = dict(shared)
    for key, value in own.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = merge(out[key], value)
        else:
            out[key] = value
    return out


def compass(degrees: float) -> str:
    """Where the wind blows from: ``N``, ``E``…; other angles in degrees."""
    degrees = float(degrees) % 360
    index, rest = divmod(degrees, 45)
    return _POINTS[int(index)] if rest == 0 else f"{degrees:g}°"


def budgets_summary(budgets: Any) -> str:
    """``budgets 25..75 step 1``, ``budgets 25, 41, 75``, or what part is known."""
    if not isinstance(budgets, dict):
        return f"budgets {budgets}" if budgets is not None else ""
    if budgets.get("values"):
        return "budgets " + ", ".join(str(v) for v in budgets["values"])
    low, high, step = budgets.get("min"), budgets.get("max"), budgets.get("step")
    text = f"budgets {low}..{high}" if low is not None and high is not None else "budgets"
    if step:
        text += f" step {step}"
    return "" if text == "budgets" else text


def weather_summary(conditions: dict) -> str:
    """The weather of a result as the tables' weather cells show it (``9 m/s N/E/S/W + moderate
    turbulence``, ``calm``; a gust seed other than 0 is named), from its
    ``physics_config``, ``env_kwargs`` or flat keys, and the directions of its parts."""
    env = {
        **{k: v for k, v in conditions.items() if not isinstance(v, dict | list)},
        **(conditions.get("env_kwargs") or {}),
        **(conditions.get("physics_config") or {}),
    }
    directions = []
    for part in conditions.get("parts") or ():
        part_env = {**(part.get("env_kwargs") or {}), **(part.get("physics_config") or {})}
        if "wind_direction" in part_env:
            directions.append(compass(part_env["wind_direction"]))
    if not directions and "wind_direction" in env:
        directions = [compass(env["wind_direction"])]
    speed = env.get("wind_speed")
    if speed is None and "backend" not in conditions and not directions:
        return ""
    text = "calm" if not speed else f"{float(speed):g} m/s"
    if speed and directions:
        each = "each of " if conditions.get("directions") == "each" else ""
        text += f" {each}" + "/".join(dict.fromkeys(directions))
    turbulence = env.get("turbulence")
    if turbulence and turbulence != "none":
        text += f" + {turbulence} turbulence"
    if env.get("gust_std"):
        text += f" + gusts σ {float(env['gust_std']):g}"
    if env.get("gust_seed"):  # other gust histories of the same episodes: not the reported ones
        text += f", gust seed {int(env['gust_seed'])}"
    return text


def _by_backend(conditions: dict) -> bool:
    """Conditions keyed by backend: a grid vs MuJoCo row's."""
    return bool(conditions) and all(
        k in BACKEND_NAMES and isinstance(v, dict) for k, v in conditions.items()
    )


def summary_parts(conditions: dict, with_backend: bool = True) -> list[str]:
    """What decided a result's numbers, item by item (backend, budgets, episodes, weather,
    return guard, seed)."""
    parts = []
    if conditions.get("backend") and with_backend:
        parts.append(backend_name(conditions["backend"]))
    parts.append(budgets_summary(conditions.get("budgets")))
    if conditions.get("budget") is not None:
        parts.append(f"budget {conditions['budget']}")
    if conditions.get("episodes") is not None:
        parts.append(f"{conditions['episodes']} episodes")
    parts.append(weather_summary(conditions))
    env = {**(conditions.get("env_kwargs") or {}), **(conditions.get("physics_config") or {})}
    if env.get("return_guard") or conditions.get("return_guard"):
        parts.append("return guard on")
    if conditions.get("seed") is not None:
        parts.append(f"seed {conditions['seed']}")
    return [p for p in parts if p]


def conditions_summary(
    conditions: dict, leave_out: dict | None = None, with_backend: bool = True
) -> str:
    """:func:`summary_parts` as one line, less the items ``leave_out``'s summary has too (a
    table row beside the line of what all rows share); conditions keyed by backend give one
    ``grid: …; MuJoCo: …`` part per backend."""
    leave_out = leave_out or {}
    if _by_backend(conditions):
        texts = []
        for key, value in conditions.items():
            other = leave_out.get(key) if _by_backend(leave_out) else None
            text = conditions_summary(
                {"backend": key, **value},
                {"backend": key, **other} if other else None,
                with_backend=False,
            )
            if text:
                texts.append(f"{backend_name(key)}: {text}")
        return "; ".join(texts)
    known = set(summary_parts(leave_out)) if leave_out else set()
    return ", ".join(p for p in summary_parts(conditions, with_backend) if p not in known)

"""The rotor power model's power-vs-airspeed curve in trimmed level flight (still air).

    python scripts/power_curve.py                 # 0–15 m/s in 0.5 m/s steps
    python scripts/power_curve.py --out DIR --max-speed 20

Writes out/power/power_curve.json (every point with its parts and the trim, the airframe and
model parameters) and out/power/power_curve.png (total and parts, and the momentum model for
comparison). docs/power.md discusses it against published measurements.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

from matplotlib.figure import Figure

from cpp_mujoco.physics.calibration import _airframe
from cpp_mujoco.physics.power.rotor import ForwardFlightPower, PowerModel, level_flight_power
from cpp_mujoco.util.io import atomic_path, atomic_write_text, json_default

PARTS = (("induced_w", "induced"), ("profile_w", "profile"), ("drag_w", "drag (parasite)"),
         ("avionics_w", "avionics"))  # fmt: skip


def curve(max_speed: float = 15.0, step: float = 0.5, air_density: float = 1.225) -> dict:
    """The curve and its summary figures as one JSON-ready dict."""
    params = _airframe()
    model = ForwardFlightPower(params, air_density)
    momentum = PowerModel(params, air_density)
    n = int(round(max_speed / step))
    points = [level_flight_power(model, params, air_density, i * step) for i in range(n + 1)]
    for p in points:  # the airspeed-blind model at the same trim thrust
        p["momentum_power_w"] = momentum.power([p["thrust_per_rotor_n"]] * 4)
    hover = points[0]["power_w"]
    best = min(points, key=lambda p: p["power_w"])
    above = [p for p in points if p["airspeed_m_s"] > best["airspeed_m_s"]]
    crossing = next((p["airspeed_m_s"] for p in above if p["power_w"] >= hover), None)
    # best range: the airspeed that minimises energy per metre (power / speed)
    moving = [p for p in points if p["airspeed_m_s"] > 0]
    best_range = min(moving, key=lambda p: p["power_w"] / p["airspeed_m_s"])
    return {
        "conditions": "trimmed level flight in still air, ISA sea level; power drawn by rotors "
        "and avionics (the battery's internal loss is not included)",
        "airframe": {
            "mass_kg": params.mass,
            "drag_area_m2": params.drag_area,
            "rotor_radius_m": params.rotor_radius,
            "power_efficiency": params.power_efficiency,
            "avionics_w": params.avionics_power,
        },  # fmt: skip
        "rotor_aero": asdict(model.aero),
        "motor_esc_efficiency": model.motor_efficiency,
        "air_density_kg_m3": air_density,
        "summary": {
            "hover_power_w": hover,
            "min_power_w": best["power_w"],
            "min_power_speed_m_s": best["airspeed_m_s"],
            "min_over_hover": best["power_w"] / hover,
            "back_to_hover_power_at_m_s": crossing,
            "best_range_speed_m_s": best_range["airspeed_m_s"],
            "power_at_max_speed_over_hover": points[-1]["power_w"] / hover,
        },
        "points": points,
    }


def figure(data: dict, path: Path) -> None:
    points = data["points"]
    v = [p["airspeed_m_s"] for p in points]
    fig = Figure(figsize=(7, 4.2))
    ax = fig.add_subplot()
    ax.plot(v, [p["power_w"] for p in points], "k-", lw=2, label="forward-flight model")
    ax.plot(v, [p["momentum_power_w"] for p in points], "k:", label="hover momentum model")
    for key, label in PARTS:
        ax.plot(v, [p[key] for p in points], lw=1, label=label)
    s = data["summary"]
    ax.axhline(s["hover_power_w"], color="0.7", lw=0.8)
    ax.plot([s["min_power_speed_m_s"]], [s["min_power_w"]], "ko")
    ax.set_xlabel("airspeed, m/s (trimmed level flight)")
    ax.set_ylabel("battery power, W")
    best, ratio, where = s["min_power_w"], s["min_over_hover"], s["min_power_speed_m_s"]
    ax.set_title(f"450-size quadrotor: minimum {best:.0f} W ({ratio:.2f}× hover) at {where:g} m/s")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/power", help="output folder")
    parser.add_argument("--max-speed", type=float, default=15.0, help="m/s")
    parser.add_argument("--step", type=float, default=0.5, help="m/s")
    args = parser.parse_args(argv)
    if not (args.max_speed > 0 and 0 < args.step <= args.max_speed):
        parser.error("need --max-speed > 0 and 0 < --step <= --max-speed")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    data = curve(args.max_speed, args.step)
    atomic_write_text(out / "power_curve.json", json.dumps(data, indent=1, default=json_default))
    figure(data, out / "power_curve.png")
    s = data["summary"]
    print("airspeed m/s   power W   /hover   induced  profile  drag")
    for p in data["points"]:
        if p["airspeed_m_s"] % 1 == 0:
            ratio = p["power_w"] / s["hover_power_w"]
            print(f"{p['airspeed_m_s']:8.1f} {p['power_w']:10.1f} {ratio:8.3f}"
                  f" {p['induced_w']:8.1f} {p['profile_w']:8.1f} {p['drag_w']:6.1f}")  # fmt: skip
    print(json.dumps(s, indent=1))
    print(f"wrote {out / 'power_curve.json'} and {out / 'power_curve.png'}")


if __name__ == "__main__":
    main()

"""The scaling page's table from ``cpp-mujoco benchmark``'s report, beside the targets each
measure is held to (``scripts/results_docs.py`` puts it between its markers)."""

from __future__ import annotations

# (label, how to read it from the report, format, the target it is held to)
_BENCH_ROWS = (
    (
        "single grid env (`gym.make`, random actions)",
        ("grid", "single_env_steps_per_s"),
        "{:,.0f} steps/s",
        "≥ 30,000",
    ),
    (
        "batched grid env, 1024 envs",
        ("grid", "batched_env_steps_per_s_1024_envs"),
        "{:,.0f} env-steps/s",
        "≥ 1,000,000",
    ),
    (
        "full protocol, safe greedy, map A",
        ("grid", "protocol_safe_greedy_s"),
        "{:.1f} s",
        "seconds",
    ),
    ("full protocol, beam search, map A", ("grid", "protocol_beam_search_s"), "{:.1f} s", ""),
    (
        "physics env steps/s ÷ raw `mj_step` (one env)",
        ("physics", "overhead_ratio"),
        "{:.2f}",
        "≥ 0.5",
    ),
    ("physics real-time factor, one env", ("physics", "real_time_factor"), "{:,.0f}×", "≥ 300×"),
    (
        "batched physics env ({num_envs} drones) vs single env, grid actions/s in one process",
        ("physics", "batched_vs_single"),
        "{:.2f}×",
        "≥ 2×",
    ),
    (
        "batched physics steps/s ÷ raw `mj_step` of the arena model",
        ("physics", "batched_physics_ratio"),
        "{:.2f}",
        "≥ 0.8",
    ),
    (
        "the same ÷ raw `mj_step` of the contact-free copy",
        ("physics", "batched_physics_ratio_vs_air"),
        "{:.2f}",
        "",
    ),
    (
        "full MuJoCo protocol, map A, 2 worker processes",
        ("physics", "protocol_A_local_2_workers_s"),
        "{:.1f} s",
        "≤ 2 min",
    ),
    (
        "its MuJoCo stepping alone (the floor)",
        ("physics", "protocol_A_stepping_floor_s"),
        "{:.1f} s",
        "",
    ),
    ("Ray, 1 → 2 CPUs, the same protocol", ("physics", "ray_scaling"), "{:.2f}×", "≥ 1.7×"),
    ("DDQN training loop", ("training", "updates_per_s"), "{:.1f} updates/s", ""),
    ("DDQN update (the paper's network, batch 128)", ("training", "update_ms"), "{:.1f} ms", ""),
    (
        "onboard camera 320×240, offscreen GL",
        ("review", "onboard_render_320x240_fps"),
        "{:.0f} frames/s",
        "≥ 100",
    ),
    (
        "Rerun recording added to a mission with video",
        ("review", "rerun_overhead_ratio"),
        "{:+.0%} wall time",
        "≤ 25 %",
    ),
)


_DECISION_POLICIES = (
    ("general", "general agent with its rules", "≤ 20 ms"),
    ("general_network_alone", "general agent, network + return rule", "≤ 20 ms"),
    (
        "general_value_beam",
        "the bundled general policy, searching with its values (value beam)",
        "",
    ),
    ("general_city", "city agent with its rules (on city32-v1)", "≤ 20 ms"),
    ("safe_greedy", "safe greedy planner", ""),
    ("beam_search", "beam search planner", ""),
)
_BENCH_ROWS += tuple(
    (f"one UAV's decision, {label}, {size}×{size}: mean per action", ("decision", key),
     "{:.1f} ms", target)
    for size in (16, 32)
    for name, label, target in _DECISION_POLICIES
    for key in [f"{name}_{size}x{size}_ms_mean"]
) + tuple(
    (f"{label}'s first decision (its whole plan), {size}×{size}",
     ("decision", f"{name}_{size}x{size}_ms_max"), "{:.0f} ms", "")
    for name, label in (("beam_search", "beam search"), ("general_value_beam", "the value beam"))
    for size in (16, 32)
)  # fmt: skip


def benchmark_table(data: dict, source: str) -> str:
    """``cpp-mujoco benchmark``'s report as the scaling page's table, with the targets each
    measure is held to and the machine's load while it ran (a loaded machine: lower bounds)."""
    lines = ["| measure | value | target |", "|---|---|---|"]
    for label, (section, key), fmt, target in _BENCH_ROWS:
        if key in data.get(section, {}):
            label = label.format(num_envs=data.get("physics", {}).get("num_envs", "N"))
            lines.append(f"| {label} | {fmt.format(data[section][key])} | {target} |")
    m = data["machine"]
    lines += [
        "",
        f"{m['cpus']} CPUs, load average {m['load_average_1m_before']:.1f} before and "
        f"{m['load_average_1m_after']:.1f} after (its own processes included; other jobs make "
        f"the rates lower bounds); Python {m['python']}. From `{source}`, measured by "
        f"`{data['command']}`.",
    ]
    return "\n".join(lines)

"""Energy, the forward-flight power ratio and the battery per drone, compiled (numba), on the
state of :class:`~cpp_mujoco.physics.power.state.BatchedEnergy` and
:class:`~cpp_mujoco.physics.power.state.BatchedBattery`: :func:`power`, the last kernel of a
compiled tick (:mod:`~cpp_mujoco.physics.compiled_tick`), after
:func:`~cpp_mujoco.physics.control.kernels.control` has written the drones' commands.

Each expression in its scalar twin's order (:mod:`~cpp_mujoco.physics.power.rotor`,
:mod:`~cpp_mujoco.physics.power.battery`), no fastmath. Every
constant comes in an argument, none from another module's globals: numba would freeze those
into its cache, which only notices changes to this file.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def _ocv(s, k):  # k: compiled_tick.OCV
    return -k[0] * math.exp(-k[1] * s) + k[2] + s * (k[3] + s * (k[4] + s * k[5]))


@njit(cache=True)
def _ocv_integral(s, k):
    """``batched_power._ocv_integral`` (the scalar's order)."""
    e = math.exp(-k[1] * s) - 1.0
    return s * (k[2] + s * (k[7] + s * (k[8] + s * k[5] / 4))) + e * k[6]


@njit(cache=True)
def _ratio(thrust, v_par, v_perp, f):
    """:meth:`ForwardFlightPower.ratio`; ``f``: inv_2rho_a, vrs, ct_rho_a, kappa, fm, k_mu,
    p0, steps."""
    vh2 = thrust * f[0]
    vh = math.sqrt(vh2)
    vp = max(v_perp, -f[1] * vh)
    v = -0.5 * vp + math.sqrt(0.25 * vp * vp + vh2)
    if v_par != 0.0:
        vpar2, vh4 = v_par * v_par, vh2 * vh2
        if vh2 < v * v_par:
            v = vh2 / v_par
        for _ in range(int(f[7])):
            s = v + vp
            q = s * s + vpar2
            v -= (v * v * q - vh4) / (2.0 * v * (q + v * s))
    mu2 = v_par * v_par * f[2] / thrust
    r = (f[3] * v + f[4] * vp) / vh + f[6] * (1.0 + f[5] * mu2)
    return r if r > 0.0 else 0.0


@njit(cache=True)
def _current(v, res, power):  # pack_current, −1.0 where the pack cannot
    if power <= 0.0:
        return 0.0
    disc = v * v - 4.0 * res * power
    if disc < 0.0:
        return -1.0
    return 2.0 * power / (v + math.sqrt(disc))


@njit(cache=True)
def _draw(d, power, dt, cells, res, cutoff, k, charge_c, soc, current, drawn_j, load_j,
          loss_j, below_cutoff, f_soc):  # fmt: skip
    """:meth:`Battery.draw` of pack ``d``: (chemical J, whether the pack could carry
    ``power``). ``k``: ``compiled_tick.OCV``; ``f_soc``: F(soc) per pack, kept as the numpy
    twin keeps it."""
    q, s0, f0 = charge_c[d], soc[d], f_soc[d]
    finite = not math.isinf(q)
    v = cells * _ocv(s0, k)
    cur = _current(v, res, power)
    if cur < 0.0:
        return math.nan, False
    s1, f1 = s0, f0
    for _ in range(3):  # the OCV averaged over the tick's charge, to rounding
        if not finite or cur == 0.0:
            break
        s1 = s0 - cur * dt / q
        f1 = _ocv_integral(s1, k)
        v = cells * (f0 - f1) / (s0 - s1)
        cur = _current(v, res, power)
        if cur < 0.0:
            return math.nan, False
    if finite and cur > 0.0:
        s1 = s0 - cur * dt / q
        f1 = _ocv_integral(s1, k)
        v = cells * (f0 - f1) / (s0 - s1)
    loss = cur * cur * res * dt
    chem = v * cur * dt
    soc[d] = max(s1, 0.0)
    f_soc[d] = f1 if s1 >= 0.0 else _ocv_integral(soc[d], k)
    current[d] = cur
    below_cutoff[d] = v - cur * res < cells * cutoff
    drawn_j[d] += chem
    load_j[d] += power * dt if power > 0.0 else 0.0
    loss_j[d] += loss
    return chem, True


@njit(cache=True)
def _energy(act, f, air0, air1, air2, c, decay, ff):
    """:class:`IntervalEnergy` (J of the tick) from the rotor states and commands;
    ``ff[8]`` says whether the forward-flight ratio applies."""
    coef, idle, edt, mean_decay = c[26], c[27], c[28], c[29]
    forward = ff[8] != 0.0
    v_par = math.hypot(air0, air1) if forward else 0.0
    total = 0.0
    for k in range(4):
        u = f[k]
        dd = act[k] - u
        rotor = 0.0
        for w in decay:
            t = u + dd * w
            rotor += t * math.sqrt(t)
        if forward:
            t = u + dd * mean_decay
            if t > 0.0:
                rotor *= _ratio(t, v_par, air2, ff)
        total += rotor
    return (total * coef + idle) * edt


@njit(cache=True)
def power(go, st, cols, c, air, motors_on, t, energy_used, capacity, decay, ff, charge_c, soc,
          current, drawn_j, load_j, loss_j, below_cutoff, f_soc, flags):  # fmt: skip
    """The energy and battery of :meth:`BatchedFlight._control` for drones ``go`` (their ctrl
    written, ``air`` row k the k-th's air in the body frame): the energy drawn, or the motors
    cut. ``flags`` per drone: 1 the pack could not carry the load, 2 the failsafe may land it;
    returns how many are flagged. ``c``: ``compiled_tick.control_constants``."""
    a0, u0, dt, cells, res, cutoff, ocv = cols[2], cols[3], c[5], c[30], c[31], c[32], c[40:49]
    flagged = 0
    for k in range(go.size):
        d = go[k]
        flags[k] = 0
        if not motors_on[d]:
            continue
        act, f = st[d, a0 : a0 + 4], st[d, u0 : u0 + 4]
        joules = _energy(act, f, air[k, 0], air[k, 1], air[k, 2], c, decay, ff)
        chem, ok = _draw(d, joules / dt, dt, cells, res, cutoff, ocv, charge_c, soc, current,
                         drawn_j, load_j, loss_j, below_cutoff, f_soc)  # fmt: skip
        if math.isnan(chem):  # the pack cannot carry the load: the motors stop, a fall begins
            motors_on[d] = False
            current[d] = 0.0
            f[:] = 0.0
            t[d] = 0.0  # the fall gets its own time limit
            flags[k] = 0 if ok else 1
        else:
            energy_used[d] += chem
            if below_cutoff[d] or energy_used[d] >= capacity[d]:
                flags[k] = 2
        flagged += flags[k] != 0
    return flagged

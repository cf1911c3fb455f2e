"""Energy, the forward-flight power ratio and the battery per drone, compiled (numba): the one
implementation of the rules of :mod:`~cpp_mujoco.physics.power.rotor` and
:mod:`~cpp_mujoco.physics.power.battery`, which hold their constants and state. :func:`power` is
the last kernel of a tick (:mod:`~cpp_mujoco.physics.tick`), after
:func:`~cpp_mujoco.physics.tick_kernels.control` has written the drones' commands.

No fastmath. Every constant comes in an argument, none from another module's globals: numba
would freeze those into its cache, which only notices changes to this file.
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def ocv(s, k):
    """Open-circuit voltage of one cell at state of charge ``s`` (V); ``k``:
    :data:`~cpp_mujoco.physics.power.battery.OCV`."""
    return -k[0] * math.exp(-k[1] * s) + k[2] + s * (k[3] + s * (k[4] + s * k[5]))


@njit(cache=True)
def ocv_integral(s, k):
    """∫₀^s V_oc (V per unit SOC): a cell's energy per coulomb of capacity, in closed form."""
    e = math.exp(-k[1] * s) - 1.0
    return s * (k[2] + s * (k[7] + s * (k[8] + s * k[5] / 4))) + e * k[6]


@njit(cache=True)
def induced(vh2, v_par, vp, f):
    """Glauert's induced velocity (m/s) of one rotor from v_h², V∥ and the clamped V⊥: start
    above the root, at the axial solution of v(v + V⊥) = v_h² (exact at V∥ = 0) or v_h²/V∥,
    whichever is smaller; g(v) = v²((v + V⊥)² + V∥²) − v_h⁴ then descends to it (Newton)."""
    v = -0.5 * vp + math.sqrt(0.25 * vp * vp + vh2)
    if v_par != 0.0:
        vpar2, vh4 = v_par * v_par, vh2 * vh2
        if vh2 < v * v_par:
            v = vh2 / v_par
        for _ in range(int(f[7])):
            s = v + vp
            q = s * s + vpar2
            v -= (v * v * q - vh4) / (2.0 * v * (q + v * s))
    return v


@njit(cache=True)
def ratio(thrust, v_par, v_perp, f):
    """One rotor's mechanical power in moving air over its still-air power at the same thrust
    (:class:`~cpp_mujoco.physics.power.rotor.ForwardFlightPower`); ``f``: its
    :meth:`~cpp_mujoco.physics.power.rotor.ForwardFlightPower.constants`."""
    vh2 = thrust * f[0]
    vh = math.sqrt(vh2)
    vp = max(v_perp, -f[1] * vh)
    v = induced(vh2, v_par, vp, f)
    mu2 = v_par * v_par * f[2] / thrust
    # P = T(κ v_i + V⊥) + P0(1 + Kμ²), over T·v_h/FM; never below zero (no regeneration)
    r = (f[3] * v + f[4] * vp) / vh + f[6] * (1.0 + f[5] * mu2)
    return r if r > 0.0 else 0.0


@njit(cache=True)
def current_of(v, res, power):
    """Current (A) at which a source of ``v`` behind ``res`` delivers ``power`` W: the
    smaller root of V·I − I²R = P, written cancellation-free; −1.0 where it cannot (V² < 4RP)."""
    if power <= 0.0:
        return 0.0
    disc = v * v - 4.0 * res * power
    if disc < 0.0:
        return -1.0
    return 2.0 * power / (v + math.sqrt(disc))


@njit(cache=True)
def _draw(d, power, dt, cells, res, cutoff, k, charge_c, soc, current, drawn_j, load_j,
          loss_j, below_cutoff, f_soc):  # fmt: skip
    """Carry ``power`` W for ``dt`` s from pack ``d``: (chemical J removed, whether the pack
    could carry it). The OCV is averaged over the tick's charge (exact ∫V_oc dq); a few
    fixed-point passes converge to rounding, as a tick moves the SOC by well under 1e-3.
    ``chem`` = load + I²R loss to rounding. ``k``: the OCV curve; ``f_soc``: F(soc) per pack."""
    q, s0, f0 = charge_c[d], soc[d], f_soc[d]
    finite = not math.isinf(q)
    v = cells * ocv(s0, k)
    cur = current_of(v, res, power)
    if cur < 0.0:
        return math.nan, False
    s1, f1 = s0, f0
    for _ in range(3):  # the OCV averaged over the tick's charge, to rounding
        if not finite or cur == 0.0:
            break
        s1 = s0 - cur * dt / q
        f1 = ocv_integral(s1, k)
        v = cells * (f0 - f1) / (s0 - s1)
        cur = current_of(v, res, power)
        if cur < 0.0:
            return math.nan, False
    if finite and cur > 0.0:
        s1 = s0 - cur * dt / q
        f1 = ocv_integral(s1, k)
        v = cells * (f0 - f1) / (s0 - s1)
    loss = cur * cur * res * dt
    chem = v * cur * dt
    soc[d] = max(s1, 0.0)
    f_soc[d] = f1 if s1 >= 0.0 else ocv_integral(soc[d], k)
    current[d] = cur
    below_cutoff[d] = v - cur * res < cells * cutoff
    drawn_j[d] += chem
    load_j[d] += power * dt if power > 0.0 else 0.0
    loss_j[d] += loss
    return chem, True


@njit(cache=True)
def _energy(act, f, air0, air1, air2, c, decay, ff):
    """J of one tick (:class:`~cpp_mujoco.physics.power.rotor.IntervalEnergy`) from the rotor
    states and commands; ``ff[8]`` says whether the forward-flight ratio applies."""
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
                rotor *= ratio(t, v_par, air2, ff)
        total += rotor
    return (total * coef + idle) * edt


@njit(cache=True)
def power(go, st, cols, c, air, motors_on, t, energy_used, capacity, decay, ff, charge_c, soc,
          current, drawn_j, load_j, loss_j, below_cutoff, f_soc, flags):  # fmt: skip
    """The energy and battery of a tick for drones ``go`` (their ctrl
    written, ``air`` row k the k-th's air in the body frame): the energy drawn, or the motors
    cut. ``flags`` per drone: 1 the pack could not carry the load, 2 the failsafe may land it;
    returns how many are flagged. ``c``:
    :func:`~cpp_mujoco.physics.kernel_constants.control_constants`."""
    a0, u0, dt, cells, res, cutoff, curve = cols[2], cols[3], c[5], c[30], c[31], c[32], c[40:49]
    flagged = 0
    for k in range(go.size):
        d = go[k]
        flags[k] = 0
        if not motors_on[d]:
            continue
        act, f = st[d, a0 : a0 + 4], st[d, u0 : u0 + 4]
        joules = _energy(act, f, air[k, 0], air[k, 1], air[k, 2], c, decay, ff)
        chem, ok = _draw(d, joules / dt, dt, cells, res, cutoff, curve, charge_c, soc, current,
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

"""Oracle for `cncsim bode` (tests/bode.rs): the linear model of one servo axis built with
python-control from the scenario, drive file and URDF alone, independently of cncsim's code.

Usage: bode_oracle.py SCENARIO.toml AXIS LOOP FREQUENCIES_JSON [TWO_MASS_JSON]

FREQUENCIES_JSON is a JSON list of frequencies (Hz). The transmission is compliant when the
drive file gives transmission_stiffness_n_per_m (and transmission_damping_n_s_per_m; rotary:
_nm_per_rad, _nm_s_per_rad), else rigid; TWO_MASS_JSON ({"stiffness": k, "damping": c}, at the
joint) overrides it. Prints JSON: the response's magnitude (dB) and phase (degrees)
at the frequencies, the open loop's, and python-control's margins of the open loop.

The model (SI, joint side; k = motor rad per joint unit, J and C on the motor side):
  m_d = J k^2, c_d = C k^2; m_c = mass of every link below the joint; c_c = the joint's damping
  armature   L di/dt = K_a u - R i - K_b' k v_d      (K_b' = K_b in voltage mode, 0 in current)
  force      F = k K_m i                             (ideal torque: F = k u)
  rigid      (m_d + m_c) a = F - (c_d + c_c) v
  two-mass   m_d a_d = F - c_d v_d - k_t (x_d - x_c) - c_t (v_d - v_c)
             m_c a_c = k_t (x_d - x_c) + c_t (v_d - v_c) - c_c v_c
The loop samples at the servo period T and holds the command (zero-order hold): the plant is
discretised with control.c2d(..., 'zoh'); P = x_fb/u, P_m = x_d/u.
PID ([controller] type = "pid"): C(z) = Kp + Ki T z/(z-1) + Kd (z-1)/(T z).
  position  x_fb/r = P (C + FF)/(1 + C P), FF = ff0 + ff1 jw - ff2 w^2; open loop L = C P.
Cascade (type = "cascade", the velocity loop on the motor encoder):
  C_v = F (Kpv + Kiv T z/(z-1)), F the command filters (second-order Butterworth low-pass,
  notch (s^2 + 2 d z w s + w^2)/(s^2 + 2 z w s + w^2), z = width/(2 f)), each the Tustin image
  prewarped at its frequency; V = a/(1 - (1-a) z^-1) (1 - z^-1)/T the velocity estimate,
  a = 1 - exp(-2 pi f_v T); C_p = Kpp + Kip T z/(z-1).
  velocity  v_m/v_cmd = jw P_m C_v/(1 + C_v V P_m); open loop L = C_v V P_m.
  position  x_fb/r = P R/(1 + L), R = C_v (C_p + kvff jw) + F kaff (m_d + m_c) g (jw)^2,
            g = R/(K_m K_a k) (ideal torque: 1/k); open loop L = C_v C_p P + C_v V P_m.
plant loop: P (magnitude in dB re 1 mm per command unit), open loop as for position.
Margins of the open loop by control.margin.
"""

import json
import math
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import control
import numpy as np


def load(scenario_path, axis):
    scenario_path = Path(scenario_path)
    s = tomllib.loads(scenario_path.read_text())
    urdf = (scenario_path.parent / s["machine"]).resolve()
    drives = tomllib.loads(urdf.with_suffix(".drives.toml").read_text())
    d = drives["axes"][axis]
    tr = d["transmission"]
    if tr["kind"] == "belt":
        k = tr["gear_ratio"] / tr["pulley_radius_m"]
    elif tr["kind"] == "screw":
        k = tr.get("gear_ratio", 1.0) * 2 * math.pi / tr["lead_m"]
    else:
        k = tr["ratio"]
    j = d["rotor_inertia_kg_m2"] + d.get("transmission_inertia_kg_m2", 0.0)
    c = d["viscous_damping_nm_s_per_rad"]
    # Moved mass: every link below the axis's joint.
    root = ET.parse(urdf).getroot()
    joints = {jn.get("name"): jn for jn in root.findall("joint")}
    children = {}
    for jn in root.findall("joint"):
        children.setdefault(jn.find("parent").get("link"), []).append(jn)
    masses = {
        ln.get("name"): float(ln.find("inertial/mass").get("value"))
        for ln in root.findall("link")
        if ln.find("inertial/mass") is not None
    }
    joint = joints[d["joint"]]
    dyn = joint.find("dynamics")
    joint_damping = float(dyn.get("damping", 0.0)) if dyn is not None else 0.0
    stack, moved = [joint.find("child").get("link")], 0.0
    while stack:
        link = stack.pop()
        moved += masses.get(link, 0.0)
        stack += [jn.find("child").get("link") for jn in children.get(link, [])]
    # A compliant transmission (drive file keys, linear or rotary); absent: rigid.
    stiffness = d.get("transmission_stiffness_n_per_m", d.get("transmission_stiffness_nm_per_rad"))
    damping = d.get("transmission_damping_n_s_per_m", d.get("transmission_damping_nm_s_per_rad", 0.0))
    # The scenario's [mechanics]: compliance = false makes every drive train rigid;
    # [mechanics.transmission.<axis>] gives an axis's stiffness and damping instead.
    mech = s.get("mechanics", {})
    own = mech.get("transmission", {}).get(axis)
    if own is not None:
        stiffness = own.get("stiffness_n_per_m", own.get("stiffness_nm_per_rad"))
        damping = own.get("damping_n_s_per_m", own.get("damping_nm_s_per_rad", 0.0))
    if mech.get("compliance", True) is False:
        stiffness = None
    motor = d["motor"]
    mode = s.get("actuator", {}).get("amplifier_mode", d.get("amplifier_mode", "voltage"))
    return {
        "k": k,
        "md": j * k * k,
        "cd": c * k * k,
        "mc": moved,
        "cc": joint_damping,
        "km": motor["torque_constant_nm_per_a"],
        "kb": motor["back_emf_v_s_per_rad"] if mode == "voltage" else 0.0,
        "r": motor["resistance_ohm"],
        "l": motor["inductance_h"],
        "ka": d["amplifier_gain"],
        "ideal": s.get("actuator", {}).get("model") == "ideal-torque",
        "feedback": s.get("feedback", {}).get("position", d.get("feedback", "motor")),
        "period": s["timing"]["servo_period_ms"] * 1e-3,
        "two_mass": None if stiffness is None else {"stiffness": stiffness, "damping": damping},
    }


def plant(m, two_mass):
    """Continuous state space u -> [x_d, x_c]."""
    k = m["k"]
    if two_mass is None:
        mass, damp = m["md"] + m["mc"], m["cd"] + m["cc"]
        a = [[0, 1], [0, -damp / mass]]
        b = [[0], [k / mass]]
        c = [[1, 0], [1, 0]]
        force_row, velocity_col = 1, 1
        mech_mass = mass
    else:
        kt, ct = two_mass["stiffness"], two_mass["damping"]
        md, mc, cd, cc = m["md"], m["mc"], m["cd"], m["cc"]
        a = [
            [0, 1, 0, 0],
            [-kt / md, -(cd + ct) / md, kt / md, ct / md],
            [0, 0, 0, 1],
            [kt / mc, ct / mc, -kt / mc, -(cc + ct) / mc],
        ]
        b = [[0], [k / md], [0], [0]]
        c = [[1, 0, 0, 0], [0, 0, 1, 0]]
        force_row, velocity_col = 1, 1
        mech_mass = md
    a, b, c = np.array(a, float), np.array(b, float), np.array(c, float)
    if not m["ideal"]:
        n = a.shape[0]
        a2 = np.zeros((n + 1, n + 1))
        a2[:n, :n] = a
        a2[force_row, n] = k * m["km"] / mech_mass
        a2[n, velocity_col] = -m["kb"] * k / m["l"]
        a2[n, n] = -m["r"] / m["l"]
        b2 = np.zeros((n + 1, 1))
        b2[n, 0] = m["ka"] / m["l"]
        c2 = np.zeros((2, n + 1))
        c2[:, :n] = c
        a, b, c = a2, b2, c2
    return control.ss(a, b, c, np.zeros((2, 1)))


def filters(g, t):
    """The cascade's command filters F(z) (1 without)."""
    f = control.tf([1], [1], t)
    if g.get("torque_lowpass_hz") is not None:
        w = 2 * math.pi * g["torque_lowpass_hz"]
        lp = control.tf([w * w], [1, math.sqrt(2) * w, w * w])
        f = f * control.c2d(lp, t, "bilinear", prewarp_frequency=w)
    if g.get("notch_hz") is not None:
        w = 2 * math.pi * g["notch_hz"]
        zeta = g["notch_width_hz"] / (2 * g["notch_hz"])
        d = g.get("notch_depth", 0.0)
        notch = control.tf([1, 2 * d * zeta * w, w * w], [1, 2 * zeta * w, w * w])
        f = f * control.c2d(notch, t, "bilinear", prewarp_frequency=w)
    return f


def laws(m, s, axis, t, w):
    """The controller as u = R(w) r - B_fb x_fb - B_m x_m: (R at w, B_fb tf, B_m tf, the
    velocity loop's C_v and V), from the scenario's [controller]."""
    c = s["controller"]
    z = control.tf([1, 0], [1], t)
    jw = 1j * w
    if c["type"] == "pid":
        g = c["axes"][axis]
        pid = g["kp"] + g.get("ki", 0.0) * t * z / (z - 1) + g.get("kd", 0.0) * (z - 1) / (t * z)
        ff = g.get("ff0", 0.0) + g.get("ff1", 0.0) * jw - g.get("ff2", 0.0) * w * w
        zs = np.exp(1j * w * t)
        return np.asarray(pid(zs), complex) + ff, pid, 0 * z, None, None
    g = c["cascade"][axis]
    fc = c.get("velocity_filter_hz", 0.0)
    a = 1 - math.exp(-2 * math.pi * fc * t) if fc > 0 else 1.0
    f = filters(g, t)
    cv = f * (g["velocity_kp"] + g.get("velocity_ki", 0.0) * t * z / (z - 1))
    estimate = a / (1 - (1 - a) / z) * (1 - 1 / z) / t
    cp = g["position_kp"] + g.get("position_ki", 0.0) * t * z / (z - 1)
    per_force = 1 / m["k"] if m["ideal"] else m["r"] / (m["km"] * m["ka"] * m["k"])
    zs = np.exp(1j * w * t)
    cv_f, cp_f, f_f = (np.asarray(x(zs), complex) for x in (cv, cp, f))
    r = cv_f * (cp_f + g.get("velocity_ff", 0.0) * jw) + f_f * g.get(
        "acceleration_ff", 0.0
    ) * (m["md"] + m["mc"]) * per_force * jw * jw
    return r, cv * cp, cv * estimate, cv, estimate


def main():
    scenario, axis, loop, freqs = sys.argv[1:5]
    s = tomllib.loads(Path(scenario).read_text())
    m = load(scenario, axis)
    two_mass = json.loads(sys.argv[5]) if len(sys.argv) > 5 else m["two_mass"]
    t = m["period"]
    freqs = np.array(json.loads(freqs), float)
    w = 2 * math.pi * freqs
    sysd = control.c2d(plant(m, two_mass), t, "zoh")
    out_row = 1 if m["feedback"] == "carriage" else 0
    tfs = control.ss2tf(sysd)
    p, pm_tf = tfs[out_row, 0], tfs[0, 0]
    r, b_fb, b_m, cv, estimate = laws(m, s, axis, t, w)
    if loop == "velocity":
        if cv is None:
            raise SystemExit("loop velocity: the scenario's controller is not a cascade")
        open_loop = control.minreal(b_m * pm_tf, verbose=False)
    else:
        open_loop = control.minreal(b_fb * p + b_m * pm_tf, verbose=False)
    zs = np.exp(1j * w * t)
    p_f = np.asarray(p(zs), complex)
    pm_f = np.asarray(pm_tf(zs), complex)
    # The open loop pointwise from its parts (the minimal realisation is for the margins).
    b_fb_f = np.asarray(b_fb(zs), complex) if loop != "velocity" else 0
    l_f = b_fb_f * p_f + np.asarray(b_m(zs), complex) * pm_f
    if loop == "plant":
        h = p_f * 1e3  # mm per command unit
    elif loop == "position":
        h = p_f * r / (1 + l_f)
    else:
        h = 1j * w * pm_f * np.asarray(cv(zs), complex) / (1 + l_f)
    # Resonances and antiresonances: peaks and dips of |P| (plant) or |L| on a dense grid.
    dense = np.geomspace(freqs.min(), freqs.max(), 200000)
    zd = np.exp(1j * 2 * math.pi * dense * t)
    feature = np.asarray(p(zd), complex) if loop == "plant" else np.asarray(open_loop(zd), complex)
    mag = 20 * np.log10(np.abs(feature))
    peaks = [float(dense[i]) for i in range(1, len(mag) - 1) if mag[i] > mag[i - 1] and mag[i] >= mag[i + 1]]
    dips = [float(dense[i]) for i in range(1, len(mag) - 1) if mag[i] < mag[i - 1] and mag[i] <= mag[i + 1]]
    gm, pm, wcg, wcp = control.margin(open_loop)
    result = {
        "magnitude_db": (20 * np.log10(np.abs(h))).tolist(),
        "phase_deg": np.degrees(np.angle(h)).tolist(),
        "open_loop_magnitude_db": (20 * np.log10(np.abs(l_f))).tolist(),
        "open_loop_phase_deg": np.degrees(np.angle(l_f)).tolist(),
        "gain_margin_db": None if not np.isfinite(gm) else 20 * math.log10(gm),
        "phase_margin_deg": None if not np.isfinite(pm) else float(pm),
        "phase_crossover_hz": None if not np.isfinite(wcg) else float(wcg) / (2 * math.pi),
        "gain_crossover_hz": None if not np.isfinite(wcp) else float(wcp) / (2 * math.pi),
        "mass_kg": m["md"] + m["mc"],
        "resonances_hz": peaks,
        "antiresonances_hz": dips,
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()

"""Anchor: MuJoCo step cost of cncsim's calibrated XYZ table, backlash and guide contacts included.

The model is built to match the cncsim machine, so that the physics step costs of the two can be
compared on the same model. Sources are models/xyz_table.urdf, xyz_table.drives.toml
and scenarios/paper_circle_05mms.toml. Units are SI and z points up.

Model (MJCF generated below). cncsim builds the same structure in Rapier (src/model/mod.rs):
  X and Y axes. Each is a drive-side body (motor + gearbox + belt pulley) on a slide. Its
        inertia is the armature J*k^2 = 3.89e-5 * (100/0.025)^2 = 622.4 kg, with damping
        C*k^2 = 107.91 N s/m, and its own mass is 1e-9 kg (MuJoCo refuses a massless moving body;
        in cncsim it is massless). The carriage hangs on the drive body by two slides:
        'slack', along the axis, with rigid limits +-b/2 (b = 0.32 mm X, 0.45 mm Y: the
        backlash), and 'lift', vertical and free. The carriage therefore rests on its guide:
        a runner pad (box 40 x 40 x 5 mm) under the carriage lies on a rail (box spanning the
        travel) of the parent link. An explicit box-box <pair> with condim 3 and Coulomb
        mu = 0.01 carries the weight, and the friction mu*N acts there.
  masses: X carriage 8 kg, Y carriage 3.5 kg, Z column 15 kg (fixed on Y), Z slide 0.5 kg,
        with the URDF's COMs and inertias. X's guide carries 27 kg (264.9 N), Y's 19 kg (186.4 N).
  Z     ball screw of lead 5 mm: one slide, armature (5.51e-5 + 4.48e-5) * (2 pi/0.005)^2
        = 157.76 kg, damping 31.95 N s/m. No guide and no backlash, as in cncsim.
  contacts: cncsim makes the guide contacts 1 kHz and critically damped (static sag
        g/w^2 ~ 0.25 um), on one ball runner per guide (this model keeps a pad). In MuJoCo
        1 kHz is solref = (0.16 ms, 1); at 0.25 ms that is below MuJoCo's safe limit
        2*timestep, and with refsafe disabled the carriages bounce on the rails (the contacts
        flicker), so solref = (0.5 ms = 2*timestep, 1) = 318 Hz is used.
        The contact margin is 0: gravity closes the exact touch in the first step.
        The cone is elliptic with impratio 1000. MuJoCo's default pyramidal cone makes the sliding
        carriages hop: the runner loses its 4 contacts for one step every 3-4 ms, and the normal
        force swings from 0 to 3.4x the weight. Its soft friction also creeps 12.7 um in 1 s under
        a push of 90 % of breakaway at mu 0.1 (cncsim: 1.7 nm); elliptic/impratio 1000: 6.6 nm.
        The default cone is timed as its own variant.
  backlash limits: rigid in cncsim. MuJoCo's limits are soft; with the default
        solreflimit (20 ms) the gap grows by 44 um under the friction load, so here
        solreflimit = (2*timestep, 1). The frictionloss variants get the same solreffriction.
  drives: current-mode amplifier + DC motor. The amplifier cancels the back-EMF, so
        L di/dt + R i = K_a u and F = k K_m i. This is a MuJoCo 'general' actuator with
        dyntype filterexact (tau = L/R: 2.09 ms X/Y, 1.5 ms Z) and gain k K_m K_a / R
        (800 N/V X/Y, 402 N/V Z); ctrl is the PID output in volts, clamped to the output limit.
        cncsim's supply clamp |K_a u + K_b w| <= 24 V is not modelled; the script checks that it
        never binds. cncsim applies the step's mean current, MuJoCo the current at the start of the
        step.
  solver: MuJoCo defaults apart from the cone (Euler, Newton, 100 iterations, tol 1e-8); dt 0.25 ms.

Controller, as in paper_circle_05mms: a positional PID per axis at T = 8 ms on the carriage
position (linear scale). The error is in m and the output in V: X kp 13.57, ki 22.79, kd 2.02;
Y 13.57, 22.93, 2.008 (both limited to 6 V); Z 8.876, 17.31, 1.138 (3.125 V). It integrates
conditionally, like cncsim's (no integration while the output is saturated and the error
pushes further). Setpoints come from cncsim's seed interpolator: hold (130, 100, 0) mm for 10 s,
then a circle r = 30 mm about (100, 100) mm, ccw, by equal chords V*T = 0.04 mm. The last sample
lands exactly on the start point. That is 5964 ticks = 190,848 physics steps = 47.71 s.

Variants (c):
  backlash+contacts      the model above
  same, pyramidal cone   the same with MuJoCo's default cone (impratio 1): the step cost of defaults
  rigid+contacts         backlash removed: the carriage is on the drive slide (plus its lift slide)
  backlash+frictionloss  contacts removed: no lift slide, and the friction mu*N is the
                         frictionloss of a fixed tendon drive+slack (the carriage's travel), so it
                         acts on the carriage's velocity, as a guide would
  rigid+frictionloss     both removed: frictionloss mu*N on the single slide
  rigid, no friction     cncsim's "rigid joints" benchmark variant

Measures, per variant, median of 3 (runs interleaved across variants):
  (a)  us per mj_step in the closed loop: Python PID every servo tick, then
       mj_step(m, d, nstep=T/dt). T = 8 ms (the scenario), and also T = 1 ms (32 and 4 steps
       per call);
  (b)  us per mj_step replaying the ctrl recorded in (a) at 8 ms. One assignment and one
       mj_step(nstep=32) per tick give the identical trajectory without the PID;
  (b') us per mj_step of one mj_step(m, d, nstep=190848) call with constant ctrl: X and Y
       slide at 5 mm/s, with the ctrl set to damping + mu*N (no Python at all);
  (b'') the same single call for cncsim's benchmark case: constant forces [1, -1, 5] N from
       rest at (0.1, 0.1, 0) m. X and Y are held by static friction, and Z creeps up.
Sanity (d), on the backlash+contacts model: the guide normal forces against the weight; the
sliding friction against mu*N; creep under a push at 90 % of breakaway (without backlash, as in
cncsim's test); lost motion on cncsim's triangle-move test (mu 0.1, as in its
tests/friction_backlash.rs) and at the circle's reversals; the max following errors per variant.
There is also a run with cncsim's calibrated stiction (mu_s 0.02, Stribeck v_s 1 mm/s). It sets
the pair friction from Python before every step, so it is not timed, and it gives following
errors comparable with cncsim's 0.592 / 0.928 mm.

Run: python tools/mujoco/xyz_table_anchor.py  (needs `pip install mujoco==4.0.0 numpy`; about
4 min on a quiet machine), or tools/physics_vs_mujoco.sh, which also times cncsim's physics step
and prints the ratios. The output also goes to out/mujoco_xyz_table.txt. Before the timing runs
the script waits (sleep 120 s, up to 20 min) while the 1-minute load average is above 1.5;
QUICK=1 makes one timing run without waiting.
"""
import math
import os
import tempfile
import platform
import sys
import time

import mujoco
import numpy as np

# ---------------------------------------------------------------- machine data (cncsim files)
G = 9.81
DT = 0.25e-3
K_BELT = 100.0 / 0.025                 # motor rad per m: gear 100, pulley r 25 mm
K_SCREW = 2 * math.pi / 0.005          # motor rad per m: lead 5 mm
ARM = {"x": 3.89e-5 * K_BELT**2, "y": 3.89e-5 * K_BELT**2,
       "z": (5.51e-5 + 4.48e-5) * K_SCREW**2}
DAMP = {"x": 6.7446e-6 * K_BELT**2, "y": 6.7446e-6 * K_BELT**2, "z": 2.0234e-5 * K_SCREW**2}
KRAT = {"x": K_BELT, "y": K_BELT, "z": K_SCREW}
KM = {"x": 0.055, "y": 0.055, "z": 0.0833}
KB = {"x": 5.54e-2, "y": 5.54e-2, "z": 0.0833}
RES = {"x": 1.1, "y": 1.1, "z": 2.0}
IND = {"x": 2.3e-3, "y": 2.3e-3, "z": 3.0e-3}
KA = {"x": 4.0, "y": 4.0, "z": 7.68}
SUPPLY = 24.0
GAIN = {a: KRAT[a] * KM[a] * KA[a] / RES[a] for a in "xyz"}      # N per V, steady state
TAU = {a: IND[a] / RES[a] for a in "xyz"}                          # electrical time constant
BACKLASH = {"x": 0.32e-3, "y": 0.45e-3}
MU = 0.01
CARRIED = {"x": 8 + 3.5 + 15 + 0.5, "y": 3.5 + 15 + 0.5}           # kg on each guide
PID = {"x": (13.57, 22.79, 2.02, 6.0), "y": (13.57, 22.93, 2.008, 6.0),
       "z": (8.876, 17.31, 1.138, 3.125)}
CONTACT_TC = 2 * DT                    # 500 Hz (0.32 ms) is below MuJoCo's 2*dt floor
STIFF_TC = 2 * DT                      # backlash limits and frictionloss: as stiff as allowed
IMPRATIO = 1000                        # elliptic cone: friction 1000x harder than the normal

# ---------------------------------------------------------------- program (paper_circle_05mms)
CX, CY, R = 0.100, 0.100, 0.030
V = 0.005
SETTLE = 10.0
RUNS = 1 if os.environ.get("QUICK") else 3

VARIANTS = [
    ("backlash+contacts", dict(backlash=True, friction="contact")),
    ("same, pyramidal cone", dict(backlash=True, friction="contact", cone="pyramidal", impratio=1)),
    ("rigid+contacts", dict(backlash=False, friction="contact")),
    ("backlash+frictionloss", dict(backlash=True, friction="frictionloss")),
    ("rigid+frictionloss", dict(backlash=False, friction="frictionloss")),
    ("rigid, no friction", dict(backlash=False, friction="none")),
]


class Tee:
    def __init__(self, path):
        self.f = open(path, "w")

    def write(self, s):
        sys.__stdout__.write(s)
        self.f.write(s)

    def flush(self):
        sys.__stdout__.flush()
        self.f.flush()


def mjcf(backlash=True, friction="contact", mu=MU, contact_tc=CONTACT_TC, refsafe=True,
         cone="elliptic", impratio=IMPRATIO):
    contact = friction == "contact"
    tiny = '<inertial pos="0 0 0" mass="1e-9" diaginertia="1e-12 1e-12 1e-12"/>'

    def drive_joint(a, axis):
        fl = ""
        if friction == "frictionloss" and not backlash:
            fl = f' frictionloss="{mu * CARRIED[a] * G:.6f}" solreffriction="{STIFF_TC} 1"'
        return (f'<joint name="{a}_drive" type="slide" axis="{axis}" armature="{ARM[a]:.6f}" '
                f'damping="{DAMP[a]:.6f}"{fl}/>')

    def carriage_joints(a, axis):
        s = ""
        if backlash:
            b = BACKLASH[a]
            s += (f'<joint name="{a}_slack" type="slide" axis="{axis}" range="{-b / 2} {b / 2}" '
                  f'solreflimit="{STIFF_TC} 1"/>')
        if contact:
            s += f'<joint name="{a}_lift" type="slide" axis="0 0 1"/>'
        return s

    def axis_block(a, axis, pos, inertial, geoms, children):
        if backlash:
            return (f'<body name="{a}_drive" pos="{pos}">{drive_joint(a, axis)}{tiny}'
                    f'<body name="{a}_carriage">{carriage_joints(a, axis)}{inertial}{geoms}'
                    f'{children}</body></body>')
        return (f'<body name="{a}_carriage" pos="{pos}">{drive_joint(a, axis)}'
                f'{carriage_joints(a, axis)}{inertial}{geoms}{children}</body>')

    # Runner: 40 x 40 x 5 mm pad whose bottom face is at the joint origin; rail: top face at the
    # joint origin, spanning the travel [-0.02, 0.32] m plus the runner's half length.
    runner = '<geom name="{a}_runner" type="box" size="0.02 0.02 0.0025" pos="0 0 0.0025" mass="0"/>'
    x_rail = '<geom name="x_rail" type="box" size="0.19 0.02 0.0025" pos="0.15 0 0.0475"/>'
    y_rail = ('<geom name="y_rail" type="box" size="0.02 0.19 0.0025" pos="0 0.15 0.0375" '
              'mass="0"/>')
    z = (f'<body name="z_column"><inertial pos="0 0 0.17" mass="15" '
         f'diaginertia="0.0924994 0.0924994 0.0159999"/>'
         f'<body name="z_slide" pos="0.06 0 0.20"><joint name="z" type="slide" axis="0 0 1" '
         f'armature="{ARM["z"]:.6f}" damping="{DAMP["z"]:.6f}"/>'
         f'<inertial pos="0 0 0" mass="0.5" diaginertia="0.0010042 0.0010042 0.00013333"/>'
         f'</body></body>')
    yb = axis_block("y", "0 1 0", "0 0 0.04",
                    '<inertial pos="0 0 0.02" mass="3.5" diaginertia="0.0079333 0.0079333 0.0149333"/>',
                    runner.format(a="y") if contact else "", z)
    xb = axis_block("x", "1 0 0", "0 0 0.05",
                    '<inertial pos="0 0.15 0.015" mass="8" diaginertia="0.16727 0.01767 0.18373"/>',
                    (runner.format(a="x") + y_rail) if contact else "", yb)
    pairs = tendons = ""
    if contact:
        fr = (f'friction="{mu} {mu} 0.005 0.0001 0.0001" condim="3" '
              f'solref="{contact_tc:.6e} 1" margin="0"')
        pairs = (f'<contact><pair name="x_guide" geom1="x_rail" geom2="x_runner" {fr}/>'
                 f'<pair name="y_guide" geom1="y_rail" geom2="y_runner" {fr}/></contact>')
    if friction == "frictionloss" and backlash:
        tendons = "<tendon>" + "".join(
            f'<fixed name="{a}_travel" frictionloss="{mu * CARRIED[a] * G:.6f}" '
            f'solreffriction="{STIFF_TC} 1">'
            f'<joint joint="{a}_drive" coef="1"/><joint joint="{a}_slack" coef="1"/></fixed>'
            for a in "xy") + "</tendon>"
    acts = "".join(
        f'<general name="m{a}" joint="{"z" if a == "z" else a + "_drive"}" dyntype="filterexact" '
        f'dynprm="{TAU[a]:.8g}" gainprm="{GAIN[a]:.8g}" ctrlrange="{-PID[a][3]} {PID[a][3]}"/>'
        for a in "xyz")
    flag = "" if refsafe else '<flag refsafe="disable"/>'
    return f"""<mujoco model="xyz_table_backlash">
  <compiler autolimits="true"/>
  <option timestep="{DT}" gravity="0 0 {-G}" cone="{cone}" impratio="{impratio}">{flag}</option>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>{x_rail if contact else ""}{xb}</worldbody>
  {pairs}{tendons}
  <actuator>{acts}</actuator>
</mujoco>"""


class Table:
    """Model, data and the addresses the loop needs."""

    def __init__(self, **kw):
        self.backlash = kw.get("backlash", True)
        self.friction_kind = kw.get("friction", "contact")
        self.contact = self.friction_kind == "contact"
        self.m = mujoco.MjModel.from_xml_string(mjcf(**kw))
        self.d = mujoco.MjData(self.m)
        m = self.m
        jq = lambda n: int(m.jnt_qposadr[m.joint(n).id])
        jv = lambda n: int(m.jnt_dofadr[m.joint(n).id])
        self.q_drive = [jq("x_drive"), jq("y_drive"), jq("z")]
        self.v_drive = [jv("x_drive"), jv("y_drive"), jv("z")]
        self.q_slack = [jq("x_slack"), jq("y_slack")] if self.backlash else None
        self.v_slack = [jv("x_slack"), jv("y_slack")] if self.backlash else None
        self.v_lift = [jv("x_lift"), jv("y_lift")] if self.contact else None
        self.pairs = [m.pair("x_guide").id, m.pair("y_guide").id] if self.contact else None

    def reset(self, q0, v0=(0.0, 0.0, 0.0), slack=0.0, force=None):
        m, d = self.m, self.d
        mujoco.mj_resetData(m, d)
        for i in range(3):
            d.qpos[self.q_drive[i]] = q0[i]
            d.qvel[self.v_drive[i]] = v0[i]
        if self.backlash:
            for i in range(2):
                d.qpos[self.q_slack[i]] = slack[i] if np.ndim(slack) else slack
        if force is not None:            # constant forces from t = 0: ctrl and current preset
            u = [force[i] / GAIN[a] for i, a in enumerate("xyz")]
            d.ctrl[:] = u
            d.act[:] = u
        mujoco.mj_forward(m, d)

    def carriage(self):
        q = self.d.qpos
        if self.backlash:
            return (q[self.q_drive[0]] + q[self.q_slack[0]], q[self.q_drive[1]] + q[self.q_slack[1]],
                    q[self.q_drive[2]])
        return q[self.q_drive[0]], q[self.q_drive[1]], q[self.q_drive[2]]

    def carriage_velocity(self):
        v = self.d.qvel
        if self.backlash:
            return (v[self.v_drive[0]] + v[self.v_slack[0]], v[self.v_drive[1]] + v[self.v_slack[1]])
        return v[self.v_drive[0]], v[self.v_drive[1]]


def setpoints(ts):
    """cncsim's seed interpolator: settle hold, then the circle by equal chords V*T."""
    p0 = (CX + R, CY, 0.0)
    chord = V * ts
    theta = math.acos((2 * R * R - chord * chord) / (2 * R * R))
    steps = 2 * math.pi / theta
    count = math.ceil(steps)
    sp = [p0] * round(SETTLE / ts) + [p0]
    for k in range(1, count + 1):
        if k < steps:
            a = theta * k
            sp.append((CX + R * math.cos(a), CY + R * math.sin(a), 0.0))
        else:
            sp.append(p0)
    return sp, round(SETTLE / ts)


def closed_loop(t, sp, ts, stiction=None, trace=False):
    """The scenario with the Python PID. Returns (wall s, steps, errors, ctrl per tick, trace)."""
    m, d = t.m, t.d
    nsub = round(ts / DT)
    t.reset(sp[0])
    kp = [PID[a][0] for a in "xyz"]
    ki = [PID[a][1] for a in "xyz"]
    kd = [PID[a][2] for a in "xyz"]
    lim = [PID[a][3] for a in "xyz"]
    integ = [0.0, 0.0, 0.0]
    prev = [0.0, 0.0, 0.0]
    u = [0.0, 0.0, 0.0]
    n = len(sp)
    errs = [None] * n
    ctrl_log = np.zeros((n, 3))
    ctrl = d.ctrl
    qpos = d.qpos
    step = mujoco.mj_step
    qd, qs = t.q_drive, t.q_slack
    rec = [] if trace else None
    t0 = time.perf_counter()
    for k in range(n):
        if qs is not None:
            q = (qpos[qd[0]] + qpos[qs[0]], qpos[qd[1]] + qpos[qs[1]], qpos[qd[2]])
        else:
            q = (qpos[qd[0]], qpos[qd[1]], qpos[qd[2]])
        s = sp[k]
        e = (s[0] - q[0], s[1] - q[1], s[2] - q[2])
        for i in range(3):
            ei = e[i]
            integral = integ[i] + ts * ei
            un = kp[i] * ei + ki[i] * integral + kd[i] * (ei - prev[i]) / ts
            ui = -lim[i] if un < -lim[i] else (lim[i] if un > lim[i] else un)
            if not (ui != un and (ei > 0) == (un > 0)):
                integ[i] = integral
            prev[i] = ei
            u[i] = ui
        ctrl[:] = u
        ctrl_log[k] = u
        errs[k] = e
        if stiction is None and rec is None:
            step(m, d, nsub)
        else:
            for _ in range(nsub):
                if stiction is not None:
                    stiction(t)
                step(m, d)
                if rec is not None:
                    rec.append(record_state(t))
    wall = time.perf_counter() - t0
    return wall, n * nsub, np.array(errs), ctrl_log, rec


def record_state(t):
    d = t.d
    q = d.qpos
    c = t.carriage()
    row = [q[t.q_drive[0]], q[t.q_drive[1]], c[0], c[1], c[2]]
    if t.contact:
        row += [d.qfrc_constraint[t.v_lift[0]], d.qfrc_constraint[t.v_lift[1]]]
    else:
        row += [math.nan, math.nan]
    v = d.qvel
    row += [v[t.v_drive[0]], v[t.v_drive[1]], float(d.solver_niter[0]), float(d.nefc), float(d.ncon)]
    return row


def replay(t, sp0, ctrl_log, ts):
    m, d = t.m, t.d
    nsub = round(ts / DT)
    t.reset(sp0)
    ctrl = d.ctrl
    step = mujoco.mj_step
    t0 = time.perf_counter()
    for u in ctrl_log:
        ctrl[:] = u
        step(m, d, nsub)
    return time.perf_counter() - t0, len(ctrl_log) * nsub


def sliding_forces(t, speed):
    """Drive forces that hold X and Y at `speed` (damping + mu*N) and Z against gravity."""
    f = []
    for a in "xy":
        fr = MU * CARRIED[a] * G if t.contact or t.friction_kind == "frictionloss" else 0.0
        f.append(DAMP[a] * speed + fr)
    f.append(0.5 * G)
    return f


def single_call(t, nsteps, kind):
    m, d = t.m, t.d
    if kind == "slide":
        f = sliding_forces(t, V)
        slack = [-BACKLASH["x"] / 2, -BACKLASH["y"] / 2]    # drive leads by b/2 when pushing
        t.reset((0.0, 0.0, 0.0), v0=(V, V, 0.0), slack=slack, force=f)
        if t.backlash:
            for i in range(2):
                d.qvel[t.v_slack[i]] = 0.0
    else:  # cncsim's benchmark case
        t.reset((0.1, 0.1, 0.0), force=[1.0, -1.0, 5.0])
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nsteps)
    wall = time.perf_counter() - t0
    return wall, t.carriage(), t.carriage_velocity()


def wait_for_quiet(limit=1.5, nap=120, max_wait=1200):
    waited = 0
    while os.getloadavg()[0] > limit and waited < max_wait:
        print(f"  load average {os.getloadavg()[0]:.2f} > {limit}: sleeping {nap} s "
              f"(waited {waited} s)", flush=True)
        time.sleep(nap)
        waited += nap
    return waited


def fmt_load():
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + " (1, 5, 15 min)"


def contact_forces(t, pair):
    """Normal and friction force (world vector) summed over the contacts of one pair."""
    m, d = t.m, t.d
    gid = (m.pair_geom1[pair], m.pair_geom2[pair])
    n, fw, cnt = 0.0, np.zeros(3), 0
    f6 = np.zeros(6)
    for i in range(d.ncon):
        c = d.contact[i]
        if (c.geom1, c.geom2) in (gid, gid[::-1]):
            mujoco.mj_contactForce(m, d, i, f6)
            frame = c.frame.reshape(3, 3)      # rows: normal, tangent 1, tangent 2
            n += f6[0]
            fw += f6[1] * frame[1] + f6[2] * frame[2]
            cnt += 1
    return n, fw, cnt


def main():
    # QUICK=1: one timing run, no waiting for a quiet machine, output in the temporary folder
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = (os.path.join(tempfile.gettempdir(), "mujoco_xyz_table_quick.txt") if os.environ.get("QUICK") else
           os.path.join(repo, "out", "mujoco_xyz_table.txt"))
    os.makedirs(os.path.dirname(out), exist_ok=True)
    sys.stdout = Tee(out)
    print(f"mujoco {mujoco.__version__}, numpy {np.__version__}, python {platform.python_version()}, "
          f"{platform.machine()}, cores={os.cpu_count()}")
    print(f"dt {DT * 1e3} ms, servo 8 ms (and 1 ms), circle r {R * 1e3:.0f} mm at {V * 1e3:.0f} mm/s "
          f"about ({CX * 1e3:.0f}, {CY * 1e3:.0f}) mm after a {SETTLE:.0f} s hold; mu {MU}, "
          f"backlash X {BACKLASH['x'] * 1e3} mm, Y {BACKLASH['y'] * 1e3} mm")
    print("armature [kg]: " + ", ".join(f"{a} {ARM[a]:.2f}" for a in "xyz")
          + "; damping [N s/m]: " + ", ".join(f"{a} {DAMP[a]:.3f}" for a in "xyz"))
    print("drive gain [N/V]: " + ", ".join(f"{a} {GAIN[a]:.2f}" for a in "xyz")
          + "; current lag L/R [ms]: " + ", ".join(f"{a} {TAU[a] * 1e3:.3f}" for a in "xyz"))
    print(f"guide contacts: box-box pairs, condim 3, solref ({CONTACT_TC * 1e3:.2f} ms, 1) = "
          f"{1 / (2 * math.pi * CONTACT_TC):.0f} Hz, elliptic cone, impratio {IMPRATIO}; backlash "
          f"limits and frictionloss: solref ({STIFF_TC * 1e3:.2f} ms, 1)\n")

    sp8, settle8 = setpoints(8e-3)
    sp1, settle1 = setpoints(1e-3)
    tables = {name: Table(**kw) for name, kw in VARIANTS}

    # ---------------------------------------------------------------- timing
    print("timing: " + fmt_load())
    waited = 0 if os.environ.get("QUICK") else wait_for_quiet()
    load_before = os.getloadavg()
    print(f"timing starts after {waited} s of waiting; {fmt_load()}", flush=True)
    res = {name: {k: [] for k in ("a8", "a1", "b", "bs", "bc")} for name, _ in VARIANTS}
    ctrl_logs, errs8, identical = {}, {}, {}
    for rep in range(RUNS):
        for name, _ in VARIANTS:
            t = tables[name]
            wall, n, err, ulog, _ = closed_loop(t, sp8, 8e-3)
            res[name]["a8"].append(wall / n)
            ctrl_logs[name], errs8[name] = ulog, err
            final = t.d.qpos.copy()
            wall, n1, _, _, _ = closed_loop(t, sp1, 1e-3)
            res[name]["a1"].append(wall / n1)
            wall, n = replay(t, sp8[0], ulog, 8e-3)
            res[name]["b"].append(wall / n)
            identical[name] = bool(np.array_equal(final, t.d.qpos))
            wall, _, _ = single_call(t, n, "slide")
            res[name]["bs"].append(wall / n)
            wall, _, _ = single_call(t, n, "bench")
            res[name]["bc"].append(wall / n)
        print(f"  run {rep + 1}/{RUNS} done; {fmt_load()}", flush=True)
    load_after = os.getloadavg()
    nsteps = len(sp8) * 32
    print(f"\n{nsteps} physics steps per run ({nsteps * DT:.2f} s simulated); "
          f"load average before timing {load_before[0]:.2f}, after {load_after[0]:.2f}")
    print("(a) closed loop, Python PID, mj_step(nstep=T/dt) per tick; (b) replay of (a)'s ctrl, "
          "mj_step(nstep=32) per 8 ms;\n(b') one mj_step(nstep=N) call, constant ctrl, X and Y "
          "sliding at 5 mm/s; (b'') one call, cncsim bench case: forces [1,-1,5] N from rest.")
    print("us per physics step, median of 3 [min-max]; RTF = simulated s / wall s of the median\n")
    hdr = (f"{'variant':<22} {'nv':>2} {'(a) T=8ms':>20} {'(a) T=1ms':>20} {'(b) replay':>20} "
           f"{'(b) const slide':>20} {'(b) cncsim case':>20}")
    print(hdr)
    for name, _ in VARIANTS:
        cells = []
        for key in ("a8", "a1", "b", "bs", "bc"):
            v = np.array(res[name][key]) * 1e6
            med = float(np.median(v))
            cells.append(f"{med:5.2f} [{v.min():.2f}-{v.max():.2f}] {DT * 1e6 / med:4.0f}x")
        print(f"{name:<22} {tables[name].m.nv:>2} " + " ".join(f"{c:>20}" for c in cells))
    print("replay ends in the closed loop's final state bit for bit: "
          + ", ".join(f"{k}: {v}" for k, v in identical.items()))

    # ---------------------------------------------------------------- sanity (d)
    print("\n(d) sanity, backlash+contacts model")
    t = tables["backlash+contacts"]
    _, _, err, ulog, rec = closed_loop(t, sp8, 8e-3, trace=True)
    rec = np.array(rec)
    prog = slice(settle8 * 32, None)          # physics steps of the program phase
    nx, ny = rec[prog, 5], rec[prog, 6]
    wx, wy = CARRIED["x"] * G, CARRIED["y"] * G
    print(f"  guide normal force over the circle: X mean {nx.mean():.3f} N (min {nx.min():.3f}, "
          f"max {nx.max():.3f}) vs weight {wx:.3f} N ({(nx.mean() / wx - 1) * 100:+.4f} %); "
          f"Y mean {ny.mean():.3f} N (min {ny.min():.3f}, max {ny.max():.3f}) vs {wy:.3f} N "
          f"({(ny.mean() / wy - 1) * 100:+.4f} %)")
    print(f"  solver: mean {rec[:, 9].mean():.2f} Newton iterations per step (max {rec[:, 9].max():.0f}), "
          f"mean {rec[:, 10].mean():.1f} constraint rows, {rec[:, 11].mean():.2f} contacts")
    _, _, _, _, rp = closed_loop(tables["same, pyramidal cone"], sp8, 8e-3, trace=True)
    rp = np.array(rp)[prog]
    print(f"  same with the pyramidal cone: X {rp[:, 5].min():.1f}..{rp[:, 5].max():.1f} N, "
          f"Y {rp[:, 6].min():.1f}..{rp[:, 6].max():.1f} N; a guide without contact in "
          f"{int(((rp[:, 5] == 0) | (rp[:, 6] == 0)).sum())} of {len(rp)} steps; "
          f"{rp[:, 9].mean():.2f} iterations, {rp[:, 10].mean():.1f} rows, {rp[:, 11].mean():.2f} contacts")
    # voltage check: current mode V = K_a u + K_b w must stay within the supply
    vmax = 0.0
    for i, a in enumerate("xyz"):
        w = np.abs(rec[:, 7 + i]) * KRAT[a] if i < 2 else 0.0
        u = np.repeat(np.abs(ulog[:, i]), 32)
        vmax = max(vmax, float(np.max(KA[a] * u + KB[a] * w)))
    print(f"  largest armature voltage |K_a u| + K_b |w| = {vmax:.3f} V (supply {SUPPLY} V: the "
          f"clamp never binds); max |u| = " + ", ".join(f"{np.abs(ulog[:, i]).max():.4f}" for i in range(3)) + " V")
    # reversals: slack swing and lost motion
    steps_per_rev = len(sp8) - settle8 - 1
    for ax, i, phase in (("X", 0, math.pi), ("Y", 1, math.pi / 2), ("Y", 1, 1.5 * math.pi)):
        k_rev = (settle8 + round(phase / (2 * math.pi) * steps_per_rev)) * 32
        w0, w1 = k_rev - 1200 * 32 // 8, k_rev + 1200 * 32 // 8   # +-1.2 s of physics steps
        drv, car = rec[w0:w1, i], rec[w0:w1, 2 + i]
        sign = 1.0 if phase == math.pi / 2 else -1.0    # Y max at pi/2, X min at pi, Y min at 3pi/2
        turn = int(np.argmax(sign * drv))
        ctop = car[turn]
        moved = next(j for j in range(turn, len(car)) if sign * (ctop - car[j]) > 0.5e-6)
        lost = abs(drv[turn] - drv[moved])
        still = np.abs(car[turn:moved] - ctop).max()
        slack = car - drv
        b = BACKLASH[ax.lower()]
        print(f"  circle reversal {ax} at {math.degrees(phase):.0f} deg: lost motion {lost * 1e6:.1f} um "
              f"(b {b * 1e6:.0f} um), carriage still within {still * 1e6:.2f} um for "
              f"{(moved - turn) * DT:.3f} s; slack swing {(slack.max() - slack.min()) * 1e6:.1f} um")

    # triangle test of cncsim tests/friction_backlash.rs (mu 0.1, b 0.32 mm, motor feedback)
    tri = Table(backlash=True, friction="contact", mu=0.1)
    tri.reset((0.1, 0.1, 0.0))
    m, d = tri.m, tri.d
    hold = 0.5 * G
    vz = tri.v_drive[2]
    d.qfrc_applied[vz] = hold
    mujoco.mj_step(m, d, round(0.1 / DT))
    amp, spd = 1e-3, 2e-3
    half = amp / spd
    path, tt = [], 0.0
    while tt < 2 * half + 0.2:
        target = 0.1 + (spd * tt if tt < half else max(amp - spd * (tt - half), 0.0))
        xd, vd = d.qpos[tri.q_drive[0]], d.qvel[tri.v_drive[0]]
        d.qfrc_applied[tri.v_drive[0]] = 2.0e6 * (target - xd) - 4.0e4 * vd
        mujoco.mj_step(m, d)
        path.append((d.qpos[tri.q_drive[0]], tri.carriage()[0]))
        tt += DT
    path = np.array(path)
    turn = int(np.argmax(path[:, 0]))
    dtop, ctop = path[turn]
    moved = next(j for j in range(turn, len(path)) if ctop - path[j, 1] > 0.5e-6)
    lost = dtop - path[moved, 0]
    still = np.abs(path[turn:moved, 1] - ctop).max()
    print(f"  triangle move (cncsim's test: mu 0.1, 2 mm/s, 1 mm): drive leads by "
          f"{(dtop - ctop) * 1e6:.2f} um (b/2 = 160), lost motion {lost * 1e6:.2f} um (cncsim 320.8), "
          f"carriage still within {still * 1e6:.3f} um (cncsim 0.5); trails by "
          f"{(path[-1, 1] - path[-1, 0]) * 1e6:.2f} um at the end")

    # sliding friction and creep
    for mu in (0.1, MU):
        line = []
        for cone, imp in (("elliptic", IMPRATIO), ("pyramidal", 1)):
            # creep, as cncsim's no_creep_below_breakaway (no backlash): settle 0.2 s holding Z,
            # then push the drive at 90 % of mu*N for 1 s
            tr = Table(backlash=False, friction="contact", mu=mu, cone=cone, impratio=imp)
            cr = []
            for i, a in enumerate("xy"):
                tr.reset((0.1, 0.1, 0.0))
                tr.d.qfrc_applied[tr.v_drive[2]] = hold
                mujoco.mj_step(tr.m, tr.d, round(0.2 / DT))
                c0 = tr.carriage()[i]
                tr.d.qfrc_applied[tr.v_drive[i]] = 0.9 * mu * CARRIED[a] * G
                mujoco.mj_step(tr.m, tr.d, round(1.0 / DT))
                cr.append(abs(tr.carriage()[i] - c0))
            line.append(f"{cone} X {cr[0] * 1e9:.1f}, Y {cr[1] * 1e9:.1f} nm")
        tb = Table(backlash=True, friction="contact", mu=mu)
        # sliding: steady 5 mm/s with ctrl = damping + mu*N; ratio friction/normal on the pair
        f = [DAMP["x"] * V + mu * CARRIED["x"] * G, DAMP["y"] * V + mu * CARRIED["y"] * G, hold]
        tb.reset((0.0, 0.0, 0.0), v0=(V, V, 0.0),
                 slack=[-BACKLASH["x"] / 2, -BACKLASH["y"] / 2], force=f)
        mujoco.mj_step(tb.m, tb.d, round(1.0 / DT))
        fn, ft, off = np.zeros((2, 4000)), np.zeros((2, 4000)), [0, 0]
        for k in range(4000):                      # second second: per-step contact forces
            mujoco.mj_step(tb.m, tb.d)
            for i in range(2):
                n, fw, cnt = contact_forces(tb, tb.pairs[i])
                fn[i, k], ft[i, k] = n, abs(fw[i])
                off[i] += cnt == 0
        vel = tb.carriage_velocity()
        ratios = [f"{'XY'[i]} mean F_t / mean N = {ft[i].mean() / fn[i].mean():.6f} "
                  f"(N {fn[i].min():.1f}..{fn[i].max():.1f}, no contact in {off[i]}/4000 steps)"
                  for i in range(2)]
        print(f"  mu {mu}: creep in 1 s under a push of 90 % of mu*N (no backlash): "
              + "; ".join(line) + " (cncsim at mu 0.1: 1.7 nm)")
        print(f"  mu {mu}: sliding for 2 s with ctrl = c*v + mu*N (backlash model): "
              f"v = {vel[0] * 1e3:.4f}, {vel[1] * 1e3:.4f} mm/s (started at 5); " + "; ".join(ratios))

    # following errors per variant (8 ms run) and with stiction
    print("\n  max |following error| over the circle [mm] (X, Y, Z), 8 ms servo:")
    for name, _ in VARIANTS:
        e = np.abs(errs8[name][settle8:]) * 1e3
        print(f"    {name:<22} {e[:, 0].max():.3f}, {e[:, 1].max():.3f}, {e[:, 2].max():.4f}")

    def stribeck(tab, mu_k=0.01, mu_s=0.02, vs=1e-3):
        v = tab.carriage_velocity()
        for i, p in enumerate(tab.pairs):
            mu = mu_k + (mu_s - mu_k) * math.exp(-(v[i] / vs) ** 2)
            tab.m.pair_friction[p, 0] = mu
            tab.m.pair_friction[p, 1] = mu
    ts = Table(backlash=True, friction="contact")
    _, _, e, _, _ = closed_loop(ts, sp8, 8e-3, stiction=stribeck)
    e = np.abs(e[settle8:]) * 1e3
    print(f"    {'same, cncsim stiction':<22} {e[:, 0].max():.3f}, {e[:, 1].max():.3f}, "
          f"{e[:, 2].max():.4f}   (mu_s 0.02, v_s 1 mm/s, set every step from Python; "
          f"cncsim paper_circle_05mms: 0.592, 0.928, <0.02)")
    print(f"\n{fmt_load()}")


if __name__ == "__main__":
    main()

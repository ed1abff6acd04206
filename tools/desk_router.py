#!/usr/bin/env python3
"""Writes models/desk_router/: a small desktop router described the way a CAD exporter
(SolidWorks' sw_urdf_exporter) writes a machine, with meshes generated here.

cncsim's own example machine, not a real one: a fixed bridge on two uprights, the bed moving
under it (Y), a carriage on the bridge (X), a ram on the carriage (Z) with a spindle and a
6 mm tool, a counterweight on a chain over a pulley beside the ram (a <mimic> of Z moving the
other way), a tool-length probe on the carriage and a toggle clamp on the bed that no axis
drives, and a 120 mm block of stock on the bed.

As an exporter writes it: one ROS-style package (package.xml, urdf/, meshes/) whose URDF names
its meshes `package://desk_router/meshes/<Link>.STL`; every link has one binary STL in its own
frame, an <inertial> at its centre of mass with the full tensor in the link's frame, the same
mesh as visual and collision; every joint frame is turned (rpy by quarter turns, printed to
15 digits as the exporter prints them) and the axes point along -z or any other local axis.

Everything is laid out below in world coordinates at the home pose (all joints at zero, metres,
z up); each link's solids are moved into the link's frame through the joint chain. Masses and
inertias come from the solids (uniform density per solid, overlaps ignored).

Run: python3 tools/desk_router.py [OUT] (OUT defaults to models/desk_router/; tests/your_machine.rs
checks that the committed files are what this writes).
"""

import math
import os
import struct
import sys

NAME = "desk_router"
OUT = (sys.argv[1] if len(sys.argv) > 1
       else os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "models", NAME))
HALF_PI = math.pi / 2

ALU, STEEL, CAST_IRON, POM = 2700.0, 7850.0, 7200.0, 1410.0


# ---- small linear algebra (3×3 as row tuples) ---------------------------------------------------
def matmul(a, b):
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3))


def transpose(a):
    return tuple(tuple(a[j][i] for j in range(3)) for i in range(3))


def apply(a, v):
    return tuple(sum(a[i][k] * v[k] for k in range(3)) for i in range(3))


def sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def rpy_matrix(r, p, y):
    # URDF: R = Rz(y)·Ry(p)·Rx(r), quarter turns snapped so the frames stay exactly orthogonal.
    def snap(v):
        return float(round(v)) if abs(v - round(v)) < 1e-12 else v

    cr, sr, cp, sp, cy, sy = (snap(f(t)) for t in (r, p, y) for f in (math.cos, math.sin))
    rx = ((1, 0, 0), (0, cr, -sr), (0, sr, cr))
    ry = ((cp, 0, sp), (0, 1, 0), (-sp, 0, cp))
    rz = ((cy, -sy, 0), (sy, cy, 0), (0, 0, 1))
    return matmul(rz, matmul(ry, rx))


IDENTITY = rpy_matrix(0, 0, 0)


# ---- the machine ---------------------------------------------------------------------------------
# Solids in world coordinates at home: ("box", centre, size, density) or
# ("cyl", centre of the base, axis "x"/"y"/"z" (+ direction), radius, length, density).
LINKS = {
    "base_link": {
        "colour": "0.29804 0.29804 0.32157 1",
        "solids": [
            ("box", (0, 0, 0.02), (0.50, 0.62, 0.04), CAST_IRON),  # base plate
            ("box", (-0.12, 0, 0.05), (0.02, 0.58, 0.02), STEEL),  # Y rails
            ("box", (0.12, 0, 0.05), (0.02, 0.58, 0.02), STEEL),
            ("box", (-0.23, 0.08, 0.20), (0.04, 0.08, 0.32), ALU),  # uprights
            ("box", (0.23, 0.08, 0.20), (0.04, 0.08, 0.32), ALU),
            ("box", (0, 0.08, 0.33), (0.42, 0.06, 0.06), ALU),  # bridge
        ],
    },
    "Bed": {
        "colour": "0.64706 0.67843 0.70196 1",
        "solids": [
            ("box", (0, 0, 0.075), (0.36, 0.36, 0.03), ALU),  # table
            ("box", (-0.12, 0, 0.0625), (0.06, 0.34, 0.005), STEEL),  # guide blocks
            ("box", (0.12, 0, 0.0625), (0.06, 0.34, 0.005), STEEL),
        ],
    },
    "Stock": {
        "colour": "0.84706 0.78431 0.58824 1",
        "solids": [("box", (0, 0, 0.105), (0.12, 0.12, 0.03), ALU)],
    },
    "ClampLever": {
        "colour": "0.8 0.2 0.15 1",
        "solids": [
            ("box", (0.0875, 0, 0.1), (0.015, 0.03, 0.02), STEEL),  # foot
            ("box", (0.0875, 0, 0.125), (0.01, 0.01, 0.03), STEEL),  # handle
        ],
    },
    "XCarriage": {
        "colour": "0.79216 0.81961 0.93333 1",
        "solids": [("box", (0, 0.04, 0.33), (0.10, 0.02, 0.10), ALU)],
    },
    "ZRam": {
        "colour": "0.89804 0.91765 0.92941 1",
        "solids": [
            ("box", (0, 0, 0.30), (0.05, 0.04, 0.16), ALU),  # ram
            ("cyl", (0, 0, 0.22), "-z", 0.02, 0.05, STEEL),  # spindle nose
            ("cyl", (0, 0, 0.17), "-z", 0.003, 0.03, STEEL),  # 6 mm tool, tip at z = 0.14
        ],
    },
    "Counterweight": {
        "colour": "0.2 0.2 0.22 1",
        "solids": [("box", (0.07, 0.0175, 0.30), (0.03, 0.025, 0.15), STEEL)],
    },
    "Probe": {
        "colour": "0.15 0.45 0.8 1",
        "solids": [
            ("cyl", (-0.045, 0.0, 0.31), "-z", 0.008, 0.05, POM),  # body
            ("cyl", (-0.045, 0.0, 0.26), "-z", 0.002, 0.015, STEEL),  # stylus
        ],
    },
}

# Joints: name, type, parent, child, origin of the child frame in world coordinates at home,
# the joint's rpy relative to the parent's frame (quarter turns, as the exporter writes them),
# the joint's direction in world coordinates, limits, and a <mimic>.
JOINTS = [
    dict(name="BedJoint", type="prismatic", parent="base_link", child="Bed",
         origin=(0, 0, 0.06), rpy=(HALF_PI, 0, 0), direction=(0, 1, 0),
         limit=(-0.12, 0.12, 400, 0.3)),
    dict(name="StockJoint", type="fixed", parent="Bed", child="Stock",
         origin=(0, 0, 0.09), rpy=(0, 0, 0)),
    dict(name="ClampJoint", type="revolute", parent="Bed", child="ClampLever",
         origin=(0.0875, 0, 0.095), rpy=(0, 0, -HALF_PI), direction=(0, -1, 0),
         limit=(0, 1.2, 5, 2)),
    dict(name="XJoint", type="prismatic", parent="base_link", child="XCarriage",
         origin=(0, 0.03, 0.33), rpy=(0, HALF_PI, 0), direction=(1, 0, 0),
         limit=(-0.15, 0.15, 200, 0.3)),
    dict(name="ZJoint", type="prismatic", parent="XCarriage", child="ZRam",
         origin=(0, 0, 0.30), rpy=(HALF_PI, 0, HALF_PI), direction=(0, 0, 1),
         limit=(-0.05, 0, 200, 0.2)),
    dict(name="CounterweightJoint", type="prismatic", parent="XCarriage", child="Counterweight",
         origin=(0.07, 0.0175, 0.30), rpy=(HALF_PI, 0, HALF_PI), direction=(0, 0, 1),
         limit=(0, 0.05, 0, 0.2), mimic=("ZJoint", -1)),
    dict(name="ProbeJoint", type="prismatic", parent="XCarriage", child="Probe",
         origin=(-0.045, 0.0, 0.31), rpy=(-HALF_PI, 0, 0), direction=(0, 0, -1),
         limit=(0, 0.03, 20, 0.1)),
]

# The link frames' orientations in the world at home, composed down the chain.
ROTATION = {"base_link": IDENTITY}
ORIGIN = {"base_link": (0.0, 0.0, 0.0)}
for joint in JOINTS:
    ROTATION[joint["child"]] = matmul(ROTATION[joint["parent"]], rpy_matrix(*joint["rpy"]))
    ORIGIN[joint["child"]] = joint["origin"]


def to_link(link, point):
    return apply(transpose(ROTATION[link]), sub(point, ORIGIN[link]))


# ---- solids: triangles and mass properties ------------------------------------------------------
def box_triangles(centre, size):
    hx, hy, hz = (s / 2 for s in size)
    c = [(centre[0] + sx * hx, centre[1] + sy * hy, centre[2] + sz * hz)
         for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    # corners indexed by (sx, sy, sz) bits: 0 = (-,-,-) … 7 = (+,+,+); faces counter-clockwise
    # seen from outside.
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, cc, d in quads:
        tris.append((c[a], c[b], c[cc]))
        tris.append((c[a], c[cc], c[d]))
    return tris


def axis_frame(axis):
    sign = -1.0 if axis.startswith("-") else 1.0
    k = "xyz".index(axis[-1])
    w = [0.0, 0.0, 0.0]
    w[k] = sign
    u = [0.0, 0.0, 0.0]
    u[(k + 1) % 3] = 1.0
    v = [0.0, 0.0, 0.0]
    v[(k + 2) % 3] = sign
    return tuple(u), tuple(v), tuple(w)


def cylinder_triangles(base, axis, radius, length, segments=32):
    u, v, w = axis_frame(axis)

    def at(angle, h):
        ca, sa = math.cos(angle), math.sin(angle)
        return tuple(base[i] + radius * (ca * u[i] + sa * v[i]) + h * w[i] for i in range(3))

    bottom, top = base, tuple(base[i] + length * w[i] for i in range(3))
    tris = []
    for s in range(segments):
        a0, a1 = 2 * math.pi * s / segments, 2 * math.pi * (s + 1) / segments
        p0, p1, q0, q1 = at(a0, 0), at(a1, 0), at(a0, length), at(a1, length)
        tris += [(p0, p1, q1), (p0, q1, q0), (bottom, p1, p0), (top, q0, q1)]
    return tris


def solid_triangles(solid):
    if solid[0] == "box":
        return box_triangles(solid[1], solid[2])
    return cylinder_triangles(solid[1], solid[2], solid[3], solid[4])


def solid_mass_properties(solid):
    """Mass, centre and inertia about the centre (world axes) of one solid."""
    if solid[0] == "box":
        _, centre, (a, b, c), rho = solid
        m = rho * a * b * c
        diag = (m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12)
        return m, centre, tuple(tuple(diag[i] if i == j else 0.0 for j in range(3)) for i in range(3))
    _, base, axis, r, h, rho = solid
    m = rho * math.pi * r * r * h
    _, _, w = axis_frame(axis)
    centre = tuple(base[i] + h / 2 * w[i] for i in range(3))
    along, across = m * r * r / 2, m * (3 * r * r + h * h) / 12
    k = "xyz".index(axis[-1])
    diag = tuple(along if i == k else across for i in range(3))
    return m, centre, tuple(tuple(diag[i] if i == j else 0.0 for j in range(3)) for i in range(3))


def link_mass_properties(link):
    parts = [solid_mass_properties(s) for s in LINKS[link]["solids"]]
    mass = sum(p[0] for p in parts)
    com = tuple(sum(p[0] * p[1][i] for p in parts) / mass for i in range(3))
    inertia = [[0.0] * 3 for _ in range(3)]
    for m, c, ic in parts:
        d = sub(c, com)
        dd = sum(x * x for x in d)
        for i in range(3):
            for j in range(3):
                inertia[i][j] += ic[i][j] + m * ((dd if i == j else 0.0) - d[i] * d[j])
    # Into the link's frame: I_link = Rᵀ·I_world·R.
    rot = ROTATION[link]
    inertia = matmul(transpose(rot), matmul(tuple(map(tuple, inertia)), rot))
    return mass, to_link(link, com), inertia


# ---- writers --------------------------------------------------------------------------------------
def write_stl(path, link):
    tris = []
    for solid in LINKS[link]["solids"]:
        tris += [tuple(to_link(link, p) for p in t) for t in solid_triangles(solid)]
    with open(path, "wb") as f:
        header = f"{NAME} {link}: generated by tools/desk_router.py".encode()
        f.write(header.ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for a, b, c in tris:
            e1, e2 = sub(b, a), sub(c, a)
            n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                 e1[0] * e2[1] - e1[1] * e2[0])
            norm = math.sqrt(sum(x * x for x in n)) or 1.0
            f.write(struct.pack("<3f", *(x / norm for x in n)))
            for p in (a, b, c):
                f.write(struct.pack("<3f", *p))
            f.write(struct.pack("<H", 0))


def num(x):
    # As the exporter prints numbers: up to 15 significant digits, no trailing zeros.
    if abs(x) < 1e-15:
        return "0"
    return f"{x:.15g}"


def nums(v):
    return " ".join(num(x) for x in v)


def link_xml(link):
    mass, com, inertia = link_mass_properties(link)
    mesh = f"package://{NAME}/meshes/{link}.STL"
    i = inertia
    return f"""  <link
    name="{link}">
    <inertial>
      <origin
        xyz="{nums(com)}"
        rpy="0 0 0" />
      <mass
        value="{num(round(mass, 6))}" />
      <inertia
        ixx="{num(round(i[0][0], 9))}"
        ixy="{num(round(i[0][1], 9))}"
        ixz="{num(round(i[0][2], 9))}"
        iyy="{num(round(i[1][1], 9))}"
        iyz="{num(round(i[1][2], 9))}"
        izz="{num(round(i[2][2], 9))}" />
    </inertial>
    <visual>
      <origin
        xyz="0 0 0"
        rpy="0 0 0" />
      <geometry>
        <mesh
          filename="{mesh}" />
      </geometry>
      <material
        name="">
        <color
          rgba="{LINKS[link]['colour']}" />
      </material>
    </visual>
    <collision>
      <origin
        xyz="0 0 0"
        rpy="0 0 0" />
      <geometry>
        <mesh
          filename="{mesh}" />
      </geometry>
    </collision>
  </link>
"""


def joint_xml(joint):
    parent, child = joint["parent"], joint["child"]
    xyz = to_link(parent, joint["origin"])
    text = f"""  <joint
    name="{joint['name']}"
    type="{joint['type']}">
    <origin
      xyz="{nums(round(x, 12) for x in xyz)}"
      rpy="{nums(joint['rpy'])}" />
    <parent
      link="{parent}" />
    <child
      link="{child}" />
"""
    if "direction" in joint:
        axis = apply(transpose(ROTATION[child]), joint["direction"])
        lower, upper, effort, velocity = joint["limit"]
        text += f"""    <axis
      xyz="{nums(round(a) for a in axis)}" />
    <limit
      lower="{num(lower)}"
      upper="{num(upper)}"
      effort="{num(effort)}"
      velocity="{num(velocity)}" />
"""
    if "mimic" in joint:
        leader, multiplier = joint["mimic"]
        text += f"""    <mimic
      joint="{leader}"
      multiplier="{num(multiplier)}"
      offset="0" />
"""
    return text + "  </joint>\n"


def main():
    os.makedirs(os.path.join(OUT, "urdf"), exist_ok=True)
    os.makedirs(os.path.join(OUT, "meshes"), exist_ok=True)
    for link in LINKS:
        write_stl(os.path.join(OUT, "meshes", f"{link}.STL"), link)
    order = ["base_link"] + [j["child"] for j in JOINTS]
    by_child = {j["child"]: j for j in JOINTS}
    body = ""
    for link in order:
        body += link_xml(link)
        if link in by_child:
            body += joint_xml(by_child[link])
    urdf = f"""<?xml version="1.0" encoding="utf-8"?>
<!-- cncsim's example machine in the shape a CAD exporter writes one: written by
     tools/desk_router.py (edit that, not this file). -->
<robot
  name="{NAME}">
{body}</robot>
"""
    with open(os.path.join(OUT, "urdf", f"{NAME}.urdf"), "w") as f:
        f.write(urdf)
    with open(os.path.join(OUT, "package.xml"), "w") as f:
        f.write(f"""<?xml version="1.0"?>
<package format="2">
  <name>{NAME}</name>
  <version>1.0.0</version>
  <description>cncsim's example desktop router, in the shape a CAD exporter writes a machine
    (urdf/, meshes/ behind package:// paths). Written by tools/desk_router.py.</description>
  <maintainer email="cncsim@example.invalid">cncsim</maintainer>
  <license>MIT OR Apache-2.0</license>
  <buildtool_depend>catkin</buildtool_depend>
  <exec_depend>urdf</exec_depend>
</package>
""")


if __name__ == "__main__":
    main()

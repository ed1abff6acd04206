#!/usr/bin/env python3
"""Writes the planner's test programs (tests/fixtures/plan/*.ngc): programs with the character
of CAM output that the trajectory planner must pass without needless stops.

  spiral_tangent_arcs.ngc  a spiral of 5° G2 arcs, each tangent to the one before, the radius
                           shrinking 1.5 % per arc (60 mm to 10 mm), coordinates to 0.1 µm
  curve_lines_1mm.ngc      chains of 1 mm lines on a smooth closed curve in the XZ plane
                           (G64 P0.05 Q0.02), three passes stepped in Y
  helix_chain.ngc          a tangent line into a three-turn helix, a tangent line out, and an
                           S-bend of two tangent arcs
  five_axis_chain.ngc      the A-C mill in machine coordinates: 1 mm lines along which A and C
                           turn smoothly while X, Y, Z follow a curve (G64 P0.05)

Run: python3 tools/plan_programs.py tests/fixtures/plan
"""
import math
import os
import sys


def fmt(x, digits=4):
    s = f"{x:.{digits}f}"
    return "0" if s.strip("-0.") == "" else s


def spiral():
    out = ["(Spiral of tangent G2 arcs: 5 deg each, radius shrinking 1.5 % per arc)",
           "G21 G17 G90 G64 P0.05", "G0 Z5", "G0 X60 Y0", "G1 Z-1 F3000"]
    # Start at (60, 0) heading -Y (clockwise about the origin).
    x, y = 60.0, 0.0
    heading = -math.pi / 2
    radius = 60.0
    sweep = math.radians(5.0)
    first = True
    while radius > 10.0:
        # Clockwise: the centre lies to the right of the heading.
        cx = x + radius * math.sin(heading)
        cy = y - radius * math.cos(heading)
        angle = math.atan2(y - cy, x - cx) - sweep
        ex = cx + radius * math.cos(angle)
        ey = cy + radius * math.sin(angle)
        feed = " F12000" if first else ""
        out.append(f"G2 X{fmt(ex)} Y{fmt(ey)} I{fmt(cx - x)} J{fmt(cy - y)}{feed}")
        first = False
        x, y = float(fmt(ex)), float(fmt(ey))
        heading -= sweep
        radius *= 0.985
    out += ["G0 Z5", "M2"]
    return out


def curve_lines():
    out = ["(Chains of 1 mm lines on a smooth closed curve in XZ, as naive CAM writes them)",
           "G21 G90 G64 P0.05 Q0.02", "G0 Z30"]

    def point(t):
        r = 20.0 + 5.0 * math.cos(3.0 * t)
        return r * math.cos(t), 10.0 + 0.6 * r * math.sin(t)

    # Points about 1 mm apart along the curve.
    ts = [0.0]
    while ts[-1] < 2 * math.pi:
        t = ts[-1]
        x0, z0 = point(t)
        x1, z1 = point(t + 1e-4)
        speed = math.hypot(x1 - x0, z1 - z0) / 1e-4
        ts.append(t + 1.0 / speed)
    ts[-1] = 2 * math.pi
    for k, y in enumerate([-10.0, 0.0, 10.0]):
        x, z = point(0.0)
        out.append(f"G0 X{fmt(x, 3)} Y{fmt(y, 3)}")
        out.append(f"G1 Z{fmt(z, 3)} F3000")
        out.append("F12000")
        for t in ts[1:]:
            x, z = point(t)
            out.append(f"X{fmt(x, 3)} Z{fmt(z, 3)}")
        out.append("G0 Z30")
    out.append("M2")
    return out


def helix_chain():
    return ["(Tangent line into a helix of three turns, tangent line out, and an S-bend of tangent arcs)",
            "G21 G17 G90 G64 P0.05",
            "G0 X-40 Y20 Z0",
            "G1 X0 Y20 F9000",
            "G2 X0 Y20 Z-6 I0 J-20 P3",
            "G1 X40 Y20",
            "G2 X60 Y0 I0 J-20",
            "G3 X80 Y-20 I20 J0",
            "G1 X80 Y-60",
            "M2"]


def five_axis():
    out = ["(A-C mill, machine coordinates: 1 mm lines, A and C turning smoothly along the way)",
           "G21 G90 G94 G64 P0.05", "G0 X0 Y0 Z0 A0 C0"]
    n = 240
    for k in range(1, n + 1):
        s = k / n
        x = 40.0 * math.sin(math.pi * s)
        y = -30.0 + 60.0 * s
        z = -10.0 * math.sin(2 * math.pi * s)
        a = 15.0 * (1 - math.cos(math.pi * s))
        c = 60.0 * s
        feed = " F6000" if k == 1 else ""
        out.append(f"G1 X{fmt(x, 3)} Y{fmt(y, 3)} Z{fmt(z, 3)} A{fmt(a, 3)} C{fmt(c, 3)}{feed}")
    out.append("M2")
    return out


def main():
    folder = sys.argv[1]
    for name, lines in [("spiral_tangent_arcs.ngc", spiral()),
                        ("curve_lines_1mm.ngc", curve_lines()),
                        ("helix_chain.ngc", helix_chain()),
                        ("five_axis_chain.ngc", five_axis())]:
        with open(os.path.join(folder, name), "w") as f:
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

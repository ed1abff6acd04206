#!/usr/bin/env python3
"""A NURBS of NX CL data evaluated by geomdl (PyPI package), for tests/apt_clsf.rs.

    nurbs_oracle.py FILE COUNT

FILE holds the curve as NX writes it (CLSF): the GOTO before `NURBS/` is the first control
point; `KNOT/` records give each distinct knot after 0 once, `CNTRL/` records the other
control points (x,y,z[,weight]). Prints COUNT + 1 points (mm) evenly spaced in the
parameter, one `x y z` a line.
"""

import sys

from geomdl import NURBS


def main():
    path, count = sys.argv[1], int(sys.argv[2])
    start, knots, points = None, [], []
    for line in open(path):
        line = line.strip()
        if line.startswith("GOTO/") and not points:
            start = [float(v) for v in line[5:].split(",")[:3]]
        elif line.startswith("KNOT/"):
            knots += [float(v) for v in line[5:].split(",")]
        elif line.startswith("CNTRL/"):
            points.append([float(v) for v in line[6:].split(",")])
    degree = len(points) - len(knots) + 1
    control = [start + [1.0]] + [p if len(p) == 4 else p + [1.0] for p in points]
    curve = NURBS.Curve()
    curve.degree = degree
    curve.ctrlpts = [p[:3] for p in control]
    curve.weights = [p[3] for p in control]
    last = knots[-1]
    curve.knotvector = [0.0] * (degree + 1) + knots[:-1] + [last] * (degree + 1)
    for k in range(count + 1):
        x, y, z = curve.evaluate_single(last * k / count)
        print(f"{x:.9f} {y:.9f} {z:.9f}")


main()

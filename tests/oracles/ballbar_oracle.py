#!/usr/bin/env python3
"""ISO 230-4 figures of a cncsim ballbar trace, computed here with numpy/scipy only.

Usage: ballbar_oracle.py POLAR_CSV CENTRE_A1_MM CENTRE_A2_MM RADIUS_MM

Reads the traced points (polar.csv: direction, t_s, angle_deg, radial_deviation_um, then the
plane's two coordinates in mm) and prints JSON, per direction: the least-squares circle
(geometric, scipy.optimize.least_squares) and the circular deviation G about its centre; the
minimum-zone circle (a linear programme on the radii linearised about the centre, solved by
scipy's HiGHS and re-linearised until the centre stops moving) and its zone width; the radial
deviation F about the programmed centre. And the circular hysteresis H: both directions about
the least-squares centre of all points, interpolated on a 0.1 degree grid.
"""
import csv
import json
import sys

import numpy as np
from scipy.optimize import least_squares, linprog


def read(path):
    points = {"ccw": [], "cw": []}
    with open(path) as f:
        rows = csv.reader(f)
        next(rows)
        for row in rows:
            points[row[0]].append((float(row[4]), float(row[5])))
    return {k: np.array(v) * 1e-3 for k, v in points.items()}


def lsq_circle(p, start):
    def residual(x):
        return np.hypot(p[:, 0] - x[0], p[:, 1] - x[1]) - x[2]

    r0 = np.mean(np.hypot(p[:, 0] - start[0], p[:, 1] - start[1]))
    fit = least_squares(residual, [start[0], start[1], r0], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return fit.x[:2], fit.x[2]


def zone(p, c):
    r = np.hypot(p[:, 0] - c[0], p[:, 1] - c[1])
    return r.max() - r.min()


def min_zone(p, start):
    c = np.array(start, dtype=float)
    for _ in range(20):
        d = p - c
        r = np.hypot(d[:, 0], d[:, 1])
        u = d / r[:, None]
        # Variables: dx, dy, lo, hi. Minimise hi - lo subject to
        # lo <= r_i - u_i . (dx, dy) <= hi.
        n = len(r)
        a_upper = np.column_stack([-u[:, 0], -u[:, 1], np.zeros(n), -np.ones(n)])
        a_lower = np.column_stack([u[:, 0], u[:, 1], np.ones(n), np.zeros(n)])
        res = linprog(
            [0.0, 0.0, -1.0, 1.0],
            A_ub=np.vstack([a_upper, a_lower]),
            b_ub=np.concatenate([-r, r]),
            bounds=[(None, None)] * 4,
            method="highs",
        )
        if not res.success:
            raise RuntimeError(res.message)
        step = res.x[:2]
        c = c + step
        if np.hypot(*step) < 1e-13:
            break
    return c, zone(p, c)


def main():
    path, c1, c2, radius = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    nominal = np.array([c1, c2]) * 1e-3
    radius *= 1e-3
    points = read(path)
    out = {}
    for direction, p in points.items():
        centre, rho = lsq_circle(p, nominal)
        mz_centre, mz = min_zone(p, centre)
        r_nominal = np.hypot(p[:, 0] - nominal[0], p[:, 1] - nominal[1]) - radius
        out[direction] = {
            "circular_deviation_um": zone(p, centre) * 1e6,
            "circular_deviation_min_zone_um": mz * 1e6,
            "radial_deviation_max_um": r_nominal.max() * 1e6,
            "radial_deviation_min_um": r_nominal.min() * 1e6,
            "least_squares_centre_offset_um": ((centre - nominal) * 1e6).tolist(),
            "least_squares_radius_mm": rho * 1e3,
        }
    both = np.vstack([points["ccw"], points["cw"]])
    centre, rho = lsq_circle(both, nominal)
    grid = np.arange(3600) * 0.1
    radial = {}
    for direction, p in points.items():
        d = p - centre
        angle = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
        order = np.argsort(angle)
        radial[direction] = np.interp(grid, angle[order], np.hypot(d[:, 0], d[:, 1])[order], period=360.0)
    out["circular_hysteresis_um"] = float(np.max(np.abs(radial["ccw"] - radial["cw"]))) * 1e6
    json.dump(out, sys.stdout, indent=1)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Time-optimal acceleration-limited traversal of planned paths, by TOPP-RA.

The oracle for cncsim's planner on real programs: the shortest time to follow the same
geometry (the path cncsim plans, corner and tangent blends included) from rest to rest,
with per-axis velocity and acceleration limits and no jerk limit. A jerk-limited plan
can never be faster, so cncsim's cycle time divided by this is at least 1.

Input (JSON file given as the only argument):
  {"velocity": [v per axis], "acceleration": [a per axis],
   "chains": [[[q0, q1, ...], ...], ...]}          # SI units; each chain rest to rest
Output (JSON on stdout):
  {"chains": [seconds per chain], "total": seconds, "toppra": version}

Each chain's points are joined by a cubic spline over their cumulative chord length
(toppra.SplineInterpolator); TOPP-RA (toppra.algorithm.TOPPRA, seidel solver) is solved on a
grid of at most 20 000 points along it.
"""
import importlib.metadata
import json
import sys

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint

MAX_GRID = 20_000


def chain_time(points, velocity, acceleration):
    q = np.asarray(points, dtype=float)
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    keep = np.concatenate(([True], step > 1e-12))
    q = q[keep]
    if len(q) < 2:
        return 0.0
    ss = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))))
    if len(q) == 2:
        # A straight line: the spline needs three points.
        q = np.vstack([q[0], 0.5 * (q[0] + q[1]), q[1]])
        ss = np.array([0.0, 0.5 * ss[-1], ss[-1]])
    path = toppra.SplineInterpolator(ss, q)
    n = q.shape[1]
    vlim = np.column_stack([-np.asarray(velocity), np.asarray(velocity)])
    alim = np.column_stack([-np.asarray(acceleration), np.asarray(acceleration)])
    grid = ss if len(ss) <= MAX_GRID else np.linspace(0.0, ss[-1], MAX_GRID)
    instance = toppra.algorithm.TOPPRA(
        [toppra.constraint.JointVelocityConstraint(vlim),
         toppra.constraint.JointAccelerationConstraint(alim)],
        path,
        gridpoints=grid,
        solver_wrapper="seidel",
    )
    trajectory = instance.compute_trajectory(0.0, 0.0)
    if trajectory is None:
        raise RuntimeError("TOPP-RA found no parameterisation")
    assert n == len(velocity)
    return float(trajectory.duration)


def main():
    with open(sys.argv[1]) as f:
        problem = json.load(f)
    times = [chain_time(c, problem["velocity"], problem["acceleration"]) for c in problem["chains"]]
    version = importlib.metadata.version("toppra")
    json.dump({"chains": times, "total": sum(times), "toppra": version}, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()

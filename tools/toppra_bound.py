#!/usr/bin/env python3
"""Time-optimal acceleration-limited traversal of planned paths, by TOPP-RA.

The oracle for cncsim's planner on real programs: the shortest time to follow the same
geometry (the path cncsim plans, corner and tangent blends included) from rest to rest,
with per-axis velocity and acceleration limits and no jerk limit. A jerk-limited plan
can never be faster, so cncsim's cycle time divided by this is at least 1.

Input (JSON file given as the only argument):
  {"velocity": [v per axis], "acceleration": [a per axis],
   "chains": [{"points": [[q0, q1, ...], ...],     # SI units; each chain rest to rest
               "feeds": [null | {"speed": F, "weights": [w0, w1, ...]}, ...]}, ...]}
Output (JSON on stdout):
  {"chains": [seconds per chain], "total": seconds, "toppra": version}

Each chain's points are joined by a cubic spline over their cumulative chord length
(toppra.SplineInterpolator); TOPP-RA (toppra.algorithm.TOPPRA, seidel solver) is solved on a
grid of at most 20 000 points along it. Besides the per-axis limits, the programmed feed holds
where a point has one: the path speed in the feed metric, |W·dq/dt| <= F (W the per-axis
weights, e.g. 1 on X, Y, Z and 0 on rotary axes), a bound on the squared path velocity that
TOPP-RA takes as a first-order constraint. Between two points with different feeds (the
grid being coarser than the points) the looser of the two holds, so the result stays a lower
bound.
"""
import importlib.metadata
import json
import sys

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from toppra.constraint import DiscretizationType, LinearConstraint

MAX_GRID = 20_000


class FeedConstraint(LinearConstraint):
    """The programmed feed: |W·q'(s)|·ṡ <= F, i.e. ṡ² <= F²/|W·q'(s)|², per grid point.

    `feeds` are the chain's points' feeds (None: no feed) at path coordinates `ss`.
    """

    def __init__(self, ss, feeds, dof):
        super().__init__()
        self.ss = ss
        self.feeds = feeds
        self.dof = dof
        self.discretization_type = DiscretizationType.Collocation
        self._format_string = "    Programmed feed\n"

    def _cap(self, feed, derivative):
        # The largest ṡ² the feed allows with this tangent (unbounded without a feed, or where
        # the feed metric does not measure the motion).
        if feed is None:
            return np.inf
        speed = np.linalg.norm(np.asarray(feed["weights"]) * derivative)
        return feed["speed"] ** 2 / speed**2 if speed > 0.0 else np.inf

    def compute_constraint_params(self, path, gridpoints):
        derivatives = path(gridpoints, 1)
        xbound = np.zeros((len(gridpoints), 2))
        for g, (s, dq) in enumerate(zip(gridpoints, derivatives)):
            # The points on either side of the grid point; the looser of their caps.
            right = min(int(np.searchsorted(self.ss, s)), len(self.ss) - 1)
            left = max(right - 1, 0) if self.ss[right] > s else right
            cap = max(self._cap(self.feeds[left], dq), self._cap(self.feeds[right], dq))
            xbound[g, 1] = min(cap, 1e300)
        return None, None, None, None, None, None, xbound


def chain_time(points, feeds, velocity, acceleration):
    q = np.asarray(points, dtype=float)
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    keep = np.concatenate(([True], step > 1e-12))
    q = q[keep]
    feeds = [f for f, k in zip(feeds, keep) if k]
    if len(q) < 2:
        return 0.0
    ss = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))))
    if len(q) == 2:
        # A straight line: the spline needs three points.
        q = np.vstack([q[0], 0.5 * (q[0] + q[1]), q[1]])
        ss = np.array([0.0, 0.5 * ss[-1], ss[-1]])
        feeds = [feeds[0], feeds[0], feeds[1]]
    path = toppra.SplineInterpolator(ss, q)
    n = q.shape[1]
    vlim = np.column_stack([-np.asarray(velocity), np.asarray(velocity)])
    alim = np.column_stack([-np.asarray(acceleration), np.asarray(acceleration)])
    grid = ss if len(ss) <= MAX_GRID else np.linspace(0.0, ss[-1], MAX_GRID)
    constraints = [
        toppra.constraint.JointVelocityConstraint(vlim),
        toppra.constraint.JointAccelerationConstraint(alim),
    ]
    if any(f is not None for f in feeds):
        constraints.append(FeedConstraint(ss, feeds, n))
    instance = toppra.algorithm.TOPPRA(
        constraints,
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
    times = [
        chain_time(c["points"], c["feeds"], problem["velocity"], problem["acceleration"])
        for c in problem["chains"]
    ]
    version = importlib.metadata.version("toppra")
    json.dump({"chains": times, "total": sum(times), "toppra": version}, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()

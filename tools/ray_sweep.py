#!/usr/bin/env python3
"""Run a cncsim sweep on a Ray cluster: one Ray task per shard, each calling the `cncsim`
binary on a worker (`cncsim sweep FILE --shard K/N`), the shards' results gathered here and
merged with `cncsim merge`. The merged files equal those of the same sweep run on one machine
(wall times aside).

    pip install ray                      # on this machine and on every worker
    python3 tools/ray_sweep.py --sweep sweeps/mill_controllers.toml \\
        --cncsim target/release/cncsim --shards 8 --out out/ray_mill

Without --address a local Ray instance is started (--num-cpus, default all cores). On a
cluster (Ray's cluster launcher, or KubeRay on Kubernetes), run this on the head node or pass
--address ray://HEAD:10001; every worker needs the `cncsim` binary at the --cncsim path (built
for the worker's platform: `cargo build --release`, or a container image with it) and the
repository's scenario, model and program files at the same absolute paths as here (a shared
filesystem, or the image). Each shard runs in a temporary folder on its worker, removed when
it is done; its results come back through Ray (run a shard by hand with `cncsim sweep
--shard K/N` to keep per-run outputs).
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

import ray


@ray.remote(num_cpus=1)
def run_shard(cncsim, sweep, k, n, cwd):
    """Runs shard k of n in a fresh folder and returns its results.json (text) and status.
    The folder (with the shard's per-run outputs) is removed from the worker afterwards."""
    with tempfile.TemporaryDirectory(prefix=f"cncsim_shard_{k}_of_{n}_") as out:
        done = subprocess.run(
            [cncsim, "sweep", sweep, "--shard", f"{k}/{n}", "--jobs", "1", "--out", out],
            capture_output=True,
            text=True,
            cwd=cwd,
        )
        path = os.path.join(out, "results.json")
        results = open(path, encoding="utf-8").read() if os.path.exists(path) else None
    return {
        "shard": k,
        "returncode": done.returncode,
        "stderr": done.stderr[-4000:],
        "results": results,
        "host": os.uname().nodename,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweep", required=True, help="the sweep file")
    parser.add_argument("--cncsim", required=True, help="path of the cncsim binary (on the workers)")
    parser.add_argument("--shards", type=int, required=True, help="number of shards (Ray tasks)")
    parser.add_argument("--out", required=True, help="folder for the merged results")
    parser.add_argument("--address", help="Ray cluster address (default: start a local instance)")
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local instance")
    args = parser.parse_args()
    if args.shards < 1:
        sys.exit("--shards: expected at least 1")
    sweep = os.path.abspath(args.sweep)
    cncsim = os.path.abspath(args.cncsim)
    cwd = os.getcwd()

    if args.address:
        ray.init(address=args.address)
    else:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False)
    tasks = [run_shard.remote(cncsim, sweep, k, args.shards, cwd) for k in range(1, args.shards + 1)]
    shards = ray.get(tasks)
    ray.shutdown()

    # Shards with results (exit 0, or 1 when some run of the shard failed: its row says why).
    folders = []
    for s in sorted(shards, key=lambda s: s["shard"]):
        if s["results"] is None or s["returncode"] not in (0, 1):
            sys.stderr.write(f"shard {s['shard']} on {s['host']} failed (exit {s['returncode']}):\n{s['stderr']}\n")
            sys.exit(2)
        folder = os.path.join(args.out, "shards", f"{s['shard']}_of_{args.shards}")
        os.makedirs(folder, exist_ok=True)
        with open(os.path.join(folder, "results.json"), "w", encoding="utf-8") as f:
            f.write(s["results"])
        rows = len(json.loads(s["results"])["rows"])
        print(f"shard {s['shard']}/{args.shards} on {s['host']}: {rows} runs")
        folders.append(folder)
    merged = subprocess.run([cncsim, "merge", *folders, "--out", args.out])
    sys.exit(merged.returncode)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Run a cncsim sweep on a Ray cluster whose workers share no filesystem with this machine:
one Ray task per shard, each running the `cncsim` binary shipped from here on the sweep's
files shipped from here, in a folder of its own on its worker (`cncsim sweep FILE --shard
K/N`); the shards' results come back through Ray and are merged here with `cncsim merge`. The
merged files equal those of the same sweep run on one machine (wall times aside).

    pip install ray                      # on this machine and on every worker
    python3 tools/ray_sweep.py --sweep sweeps/mill_controllers.toml \\
        --cncsim target/release/cncsim --shards 8 --out out/ray_mill

What is shipped: the binary's bytes, and one zip of every file the sweep reads, as listed by
`cncsim sweep FILE --inputs` (the sweep file, its scenarios, each scenario's machine URDF,
drives file, meshes and package.xml manifests, programs, tool tables, FMUs, stock shapes),
stored relative to their deepest common folder, so that the relative paths the files write
to each other hold on the worker too. Both go into Ray's object store once and every shard
task reads them from there. The binary must run on the workers' platform (built for it, e.g.
`cargo build --release` on the same OS and CPU family).

Without --address a local Ray instance is started (--num-cpus, default all cores). On a
cluster (Ray's cluster launcher, or KubeRay on Kubernetes) run this on the head node or pass
--address ray://HEAD:10001.

A shard whose worker process dies is run again, up to --max-retries times (default 2). Each
shard's results.json is written into OUT/shards/K_of_N/ as soon as it arrives, so a driver
that was stopped goes on with --resume: the shards that have results are not run again.
OUT/ray_digest.txt records what the shards were run from (the shipped files, the binary and
--shards); a resume from anything else is refused (exit 2).

Exit status: merge's (0, or 1 when some run failed: its row says why); 2 when the input is
bad, a shard failed (its shard, host and stderr are printed) or a resume does not match;
130 when interrupted (the shards that arrived are kept for --resume).
"""

import argparse
import hashlib
import io
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import zipfile

import ray

# The file in OUT recording what the shards there were run from.
DIGEST_FILE = "ray_digest.txt"


def fail(message):
    """Ends the driver with status 2 (bad input, a failed shard, a mismatched resume)."""
    sys.stderr.write(f"ray_sweep: {message}\n")
    sys.exit(2)


def write_atomically(path, data):
    """Writes `data` (bytes) to `path` through a temporary name beside it, renamed into place:
    a reader (or a resume after a kill) sees the whole file or none."""
    partial = f"{path}.partial-{os.getpid()}"
    with open(partial, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(partial, path)


def placed(path):
    """Where a file sits in the shipped tree: its folder with symbolic links resolved (as the
    OS resolves them when cncsim opens the file), its own name as written. Relative paths
    written in the file are resolved from that folder, here and on the worker alike."""
    path = os.path.abspath(path)
    return os.path.join(os.path.realpath(os.path.dirname(path)), os.path.basename(path))


def sweep_inputs(cncsim, sweep):
    """The absolute paths of every file the sweep reads, the sweep file first, each once
    (`cncsim sweep FILE --inputs`)."""
    listed = subprocess.run([cncsim, "sweep", sweep, "--inputs"], capture_output=True, text=True)
    if listed.returncode != 0:
        fail(f"`{cncsim} sweep {sweep} --inputs` failed (exit {listed.returncode}):\n{listed.stderr}")
    paths = [placed(sweep)]
    for line in listed.stdout.splitlines():
        if line.strip() and placed(line) not in paths:
            paths.append(placed(line))
    return paths


def pack(paths):
    """One zip (bytes) of the files at `paths`, stored relative to their deepest common folder,
    and the digest of what it holds (names and contents, not the zip's own bytes). Ends the
    driver naming the first file that cannot be read."""
    root = os.path.commonpath([os.path.dirname(p) for p in paths])
    digest = hashlib.sha256()
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as bundle:
        for path in paths:
            try:
                with open(path, "rb") as f:
                    data = f.read()
            except OSError as e:
                fail(f"{path}: an input of the sweep cannot be read ({e.strerror})")
            name = os.path.relpath(path, root)
            bundle.writestr(name, data)
            digest.update(f"{name}\0{len(data)}\0".encode())
            digest.update(data)
    return buffer.getvalue(), os.path.relpath(paths[0], root), digest


@ray.remote(num_cpus=1)
def run_shard(bundle, binary, sweep, k, n):
    """Runs shard k of n in a fresh folder of its own on the worker: the shipped files
    unpacked into inputs/, the binary written beside as ./cncsim. Returns the shard's
    results.json (text, None when it wrote none), cncsim's exit status and the end of its
    stderr, the worker's host name and the seconds taken. The folder (with the shard's
    per-run outputs) is removed afterwards."""
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix=f"cncsim_shard_{k}_of_{n}_") as work:
        with zipfile.ZipFile(io.BytesIO(bundle)) as files:
            files.extractall(os.path.join(work, "inputs"))
        exe = os.path.join(work, "cncsim")
        with open(exe, "wb") as f:
            f.write(binary)
        os.chmod(exe, 0o755)
        # Packages the driver found on its package path (`package://` meshes, `$(find …)`)
        # were shipped inside inputs/: the worker searches there.
        env = dict(os.environ)
        env["ROS_PACKAGE_PATH"] = os.pathsep.join(
            [os.path.join(work, "inputs")] + ([env["ROS_PACKAGE_PATH"]] if env.get("ROS_PACKAGE_PATH") else [])
        )
        done = subprocess.run(
            ["./cncsim", "sweep", os.path.join("inputs", sweep), "--shard", f"{k}/{n}",
             "--jobs", "1", "--out", "out"],
            capture_output=True,
            text=True,
            cwd=work,
            env=env,
        )
        path = os.path.join(work, "out", "results.json")
        results = open(path, encoding="utf-8").read() if os.path.exists(path) else None
    return {
        "shard": k,
        "returncode": done.returncode,
        "stderr": done.stderr[-4000:],
        "results": results,
        "host": socket.gethostname(),
        "seconds": time.monotonic() - started,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sweep", required=True, help="the sweep file")
    parser.add_argument("--cncsim", required=True, help="the cncsim binary (shipped to the workers)")
    parser.add_argument("--shards", type=int, required=True, help="number of shards (Ray tasks)")
    parser.add_argument("--out", required=True, help="folder for the shards' and the merged results")
    parser.add_argument("--address", help="Ray cluster address (default: start a local instance)")
    parser.add_argument("--num-cpus", type=int, help="CPUs of the local instance")
    parser.add_argument("--max-retries", type=int, default=2,
                        help="times a shard whose worker dies is run again (default 2)")
    parser.add_argument("--resume", action="store_true",
                        help="go on with the shards in --out: run only those without results")
    args = parser.parse_args()
    if args.shards < 1:
        fail("--shards: expected at least 1")
    if args.max_retries < 0:
        fail("--max-retries: expected 0 or more")
    n = args.shards
    cncsim = os.path.abspath(args.cncsim)
    out = os.path.abspath(args.out)

    # What the shards run: the binary's bytes (kept: merge runs a copy of them at the end, so
    # the --cncsim file may change or go meanwhile) and the sweep's files, zipped.
    try:
        with open(cncsim, "rb") as f:
            binary = f.read()
    except OSError as e:
        fail(f"{cncsim}: the cncsim binary cannot be read ({e.strerror})")
    bundle, sweep, digest = pack(sweep_inputs(cncsim, args.sweep))
    digest.update(b"binary\0")
    digest.update(binary)
    digest.update(f"shards\0{n}".encode())
    digest = digest.hexdigest()

    # OUT/shards/K_of_N/results.json of each shard; a resume keeps those already there, but
    # only when OUT's digest is this run's (as `cncsim sweep --resume` does with its runs).
    folders = [os.path.join(out, "shards", f"{k}_of_{n}") for k in range(1, n + 1)]
    results = [os.path.join(folder, "results.json") for folder in folders]
    digest_path = os.path.join(out, DIGEST_FILE)
    try:
        with open(digest_path, encoding="utf-8") as f:
            found = f.read().strip()
    except OSError:
        found = None
    if args.resume and found is not None and found != digest:
        fail(f"{out}: --resume: the folder holds the shards of another sweep (or of this one with "
             f"other inputs, another binary or another --shards): its digest is {found}, this "
             f"run's {digest}; resume with what wrote it, or give another --out")
    resuming = args.resume and found is not None
    if not resuming:
        # A fresh start: the results of an earlier run in OUT are not this run's.
        for path in results:
            if os.path.exists(path):
                os.remove(path)
    os.makedirs(out, exist_ok=True)
    write_atomically(digest_path, (digest + "\n").encode())
    todo = [k for k in range(1, n + 1) if not os.path.exists(results[k - 1])]
    if args.resume:
        have = n - len(todo)
        rest = f"running the other {len(todo)}" if todo else "nothing to submit"
        print(f"resuming: {have} of {n} shards have results in {out}; {rest}", flush=True)

    failed, pending = [], {}
    if todo:
        if args.address:
            ray.init(address=args.address)
        else:
            ray.init(num_cpus=args.num_cpus, include_dashboard=False)
        try:
            # The zip and the binary go into the object store once; every task gets the refs
            # (Ray hands a task its arguments' values, fetched to its node).
            bundle_ref, binary_ref = ray.put(bundle), ray.put(binary)
            task = run_shard.options(max_retries=args.max_retries)
            pending = {task.remote(bundle_ref, binary_ref, sweep, k, n): k for k in todo}
            print(f"submitted {len(pending)} shards", flush=True)
            # Each shard's results are written as soon as they arrive; the others go on.
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    k = pending.pop(ref)
                    try:
                        s = ray.get(ref)
                    except ray.exceptions.RayError as e:
                        failed.append(f"shard {k}/{n}: its task failed (after --max-retries "
                                      f"{args.max_retries}):\n{e}")
                        continue
                    # Exit 0, or 1 when some run of the shard failed (its row says why), with
                    # results: the shard is done. Anything else (bad input, interrupted,
                    # crashed) is not.
                    if s["results"] is None or s["returncode"] not in (0, 1):
                        failed.append(f"shard {k}/{n} on {s['host']} failed (exit {s['returncode']}):\n"
                                      f"{s['stderr']}")
                        continue
                    os.makedirs(folders[k - 1], exist_ok=True)
                    write_atomically(results[k - 1], s["results"].encode("utf-8"))
                    runs = len(json.loads(s["results"])["rows"])
                    print(f"shard {k}/{n} on {s['host']}: {runs} runs, {s['seconds']:.1f} s", flush=True)
        except KeyboardInterrupt:
            # The running shards are interrupted too (each removes its folder on its worker).
            for ref in pending:
                ray.cancel(ref)
            ray.wait(list(pending), num_returns=len(pending), timeout=10)
            have = sum(os.path.exists(path) for path in results)
            sys.stderr.write(f"interrupted: {have} of {n} shards have results in {out}; "
                             "--resume goes on with the others\n")
            sys.exit(130)
        finally:
            ray.shutdown()
    if failed:
        for message in failed:
            sys.stderr.write(f"ray_sweep: {message}\n")
        fail(f"{len(failed)} of {n} shards failed; the {n - len(failed)} others are in {out}/shards "
             "(--resume runs only the failed ones)")

    # The merge, with a private copy of the binary that ran the shards.
    with tempfile.TemporaryDirectory(prefix="cncsim_ray_merge_") as own:
        exe = os.path.join(own, "cncsim")
        with open(exe, "wb") as f:
            f.write(binary)
        os.chmod(exe, 0o755)
        merged = subprocess.run([exe, "merge", *folders, "--out", out])
    sys.exit(merged.returncode)


if __name__ == "__main__":
    main()

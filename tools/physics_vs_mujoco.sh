#!/usr/bin/env bash
# cncsim's physics step against MuJoCo's on the same machine, timed in one session: the
# criterion benchmark `servo_period` (physics step cases), then tools/mujoco/xyz_table_anchor.py
# (the XYZ table in MuJoCo 4.0 with the same masses, armatures, backlash and guide contacts), and
# the ratios. Needs a Python with `pip install mujoco==4.0.0 numpy` (CNCSIM_MUJOCO_PYTHON, default
# python3). QUICK=1: one MuJoCo timing run without waiting for a quiet machine.
# Usage: tools/physics_vs_mujoco.sh
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
python="${CNCSIM_MUJOCO_PYTHON:-python3}"
if ! "$python" -c "import mujoco, numpy" 2>/dev/null; then
    echo "error: $python cannot import mujoco and numpy; pip install mujoco==4.0.0 numpy, or set CNCSIM_MUJOCO_PYTHON" >&2
    exit 2
fi
target="${CARGO_TARGET_DIR:-$here/target}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$here"
cargo bench --bench servo_period -- "^physics step" | tee "$work/cncsim.txt"
"$python" tools/mujoco/xyz_table_anchor.py | tee "$work/mujoco.txt"
"$python" - "$target/criterion" "$work/mujoco.txt" <<'PY'
import json, os, re, sys
criterion, mujoco_out = sys.argv[1], sys.argv[2]
rows = [("rigid joints", "rigid, no friction"),
        ("guide contacts + backlash", "backlash+contacts")]
# MuJoCo's (b'') column: one mj_step call over the cncsim benchmark's case (constant forces).
mj = {}
for line in open(mujoco_out):
    for _, name in rows:
        if line.startswith(name + " ") and "[" in line:
            cells = re.findall(r"([0-9.]+) \[[0-9.]+-[0-9.]+\]", line)
            mj[name] = float(cells[-1])
print("\nphysics step, 0.25 ms, XYZ table: median µs (cncsim: criterion; MuJoCo: one mj_step call, same case)")
print(f"{'case':<28} {'cncsim':>8} {'MuJoCo':>8} {'cncsim / MuJoCo':>16}")
for ours, theirs in rows:
    folder = f"physics step (0.25 ms), XYZ table, {ours}"
    with open(os.path.join(criterion, folder, "new", "estimates.json")) as f:
        us = json.load(f)["median"]["point_estimate"] / 1e3
    print(f"{ours:<28} {us:8.2f} {mj[theirs]:8.2f} {us / mj[theirs]:15.2f}×")
PY

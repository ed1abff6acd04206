#!/usr/bin/env bash
# Peak resident memory of a run against its duration: the XYZ table contouring circles for
# 6 minutes and for one hour (benches/long_run), recorded every 4th tick with the analytic
# model beside the physics, as the default run is. A run streams its setpoints, metrics, CSV
# and recording, so both should need about the same memory.
# Usage: tools/long_run_memory.sh [path/to/cncsim]   (default: target/release/cncsim)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
bin="${1:-$here/target/release/cncsim}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cp "$here/benches/long_run/hour_circles.toml" "$work/"
sed -i "s#^machine = .*#machine = \"$here/models/xyz_table.urdf\"#" "$work/hour_circles.toml"
printf '%-9s %12s %12s %12s %12s\n' circles "simulated s" "wall s" "peak RSS MB" "rrd+csv MB"
for circles in 10 96; do
    sed "s/repeat \[96\]/repeat [$circles]/" "$here/benches/long_run/hour_circles.ngc" > "$work/hour_circles.ngc"
    /usr/bin/time -f '%M' -o "$work/rss" "$bin" run "$work/hour_circles.toml" --out "$work/out" > "$work/log" 2>&1
    simulated=$(grep -o '"sim_time_s": [0-9.]*' "$work/out/metrics.json" | grep -o '[0-9.]*$')
    wall=$(grep -o '"wall_time_s": [0-9.]*' "$work/out/metrics.json" | grep -o '[0-9.]*$')
    files=$(du -cm "$work/out/run.rrd" "$work/out/trace.csv" | tail -1 | cut -f1)
    printf '%-9s %12.1f %12.1f %12.1f %12s\n' "$circles" "$simulated" "$wall" "$(($(cat "$work/rss") / 1024)).$(($(cat "$work/rss") % 1024 * 10 / 1024))" "$files"
    rm -rf "$work/out"
done

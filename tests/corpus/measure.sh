#!/usr/bin/env bash
# How many real part programs in a directory cncsim decodes: `tests/corpus/measure.sh CNCSIM DIR`
# runs `CNCSIM inspect` on every file of DIR (the format recognised by content, then by
# extension) and prints one line per file and the count. CNCSIM is a built cncsim binary.
set -uo pipefail
cncsim=$1
directory=$2
decoded=0
total=0
for file in "$directory"/*; do
    [ -f "$file" ] || continue
    total=$((total + 1))
    if message=$("$cncsim" inspect "$file" 2>&1 >/dev/null); then
        decoded=$((decoded + 1))
        echo "decoded  $(basename "$file")"
    else
        echo "refused  $(basename "$file"): $(echo "$message" | head -1 | cut -c1-160)"
    fi
done
echo "$decoded of $total decoded"

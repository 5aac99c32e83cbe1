#!/usr/bin/env bash
# The measured-sizing grid over every plant axis in one command (docs/estimation.md, "The grid"):
#
#   scripts/grid.sh OUT [ROBOKEY]
#
# sweeps experiments/grid.toml three times (OUT/measured, OUT/world, OUT/configured), counts
# each point's secret bits against the camera eavesdropper under the sizing of its folder,
# then runs the independent eavesdropper (scripts/independent-eve.py, needs numpy) on the
# measured folder's blocks and writes the table to OUT/grid.md (its rows to OUT/grid.json).
# ROBOKEY: the binary (default target/release/robokey). About 8 CPU-minutes for the secrecy
# runs (the measured sizing's slip blocks most of it), and the independent eavesdropper's after.
set -euo pipefail
out=${1:?usage: scripts/grid.sh OUT [ROBOKEY]}
robokey=${2:-target/release/robokey}
root=$(cd "$(dirname "$0")/.." && pwd)
for sizing in measured world configured; do
    "$robokey" sweep "$root/experiments/grid.toml" -o "$out/$sizing"
    "$robokey" secrecy "$out/$sizing" --adversary camera --sizing "$sizing" > "$out/$sizing.log"
done
python3 "$root/scripts/independent-eve.py" "$out/measured" --world "$out/world" \
    --configured "$out/configured" --robokey "$robokey" --out "$out/grid.md"

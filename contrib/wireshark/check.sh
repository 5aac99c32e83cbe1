#!/usr/bin/env bash
# Checks the Wireshark dissector against robokey's own parser on a capture:
#   contrib/wireshark/check.sh CAPTURE ROBOKEY_BINARY
# Fails on any Lua error (tshark reports them on stderr but exits 0) and on any frame whose
# type, session, seq, step or carried numbers differ between the two.
set -euo pipefail
capture=$1; robokey=$2
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
fields=(frame.number robokey.type robokey.session robokey.seq robokey.step
        robokey.y.px robokey.y.py robokey.y.theta
        robokey.u0.right robokey.u0.left robokey.u1.right robokey.u1.left
        robokey.sample.px robokey.sample.py robokey.sample.theta
        robokey.first.v robokey.first.omega robokey.second.v robokey.second.omega)
# Heuristic dissectors first: a test capture's ephemeral port may be one Wireshark assigns to
# another protocol (e.g. 47000).
tshark -r "$capture" -X lua_script:"$here/robokey.lua" -o udp.try_heuristic_first:TRUE -T fields -E separator=/t \
    "${fields[@]/#/-e}" > "$work/tshark.tsv" 2> "$work/tshark.err"
if grep -q "Lua:" "$work/tshark.err"; then
    echo "dissector: Lua errors:" >&2; cat "$work/tshark.err" >&2; exit 1
fi
"$robokey" frames "$capture" > "$work/robokey.tsv"
python3 - "$work/tshark.tsv" "$work/robokey.tsv" <<'PY'
import math, sys
theirs = [l.rstrip("\n").split("\t") for l in open(sys.argv[1])]
ours = [l.rstrip("\n").split("\t") for l in open(sys.argv[2])]
if len(theirs) != len(ours) or not ours:
    sys.exit(f"dissector: {len(theirs)} frames from tshark, {len(ours)} from robokey")
compared = skipped = 0
for t, o in zip(theirs, ours):
    if o[1] == "undecodable":
        skipped += 1
        continue
    numbers = [float(x) for x in o[5].split(",")] if o[5] else []
    shown = [float(x) for x in t[5:] if x]
    same = t[:5] == o[:5] and len(shown) == len(numbers) and all(
        math.isclose(a, b, rel_tol=1e-13, abs_tol=1e-300) for a, b in zip(shown, numbers))
    if not same:
        sys.exit(f"dissector: frame {o[0]} differs:\n  tshark  {t}\n  robokey {o}")
    compared += 1
print(f"dissector: {compared} frames decoded alike by tshark and robokey ({skipped} undecodable skipped)")
PY

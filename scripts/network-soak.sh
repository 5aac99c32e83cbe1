#!/usr/bin/env bash
# Runs N paired lockstep sessions through the relay with a fault mix and tallies the outcomes:
#   scripts/network-soak.sh NAME SESSIONS [relay fault options…]
# e.g. scripts/network-soak.sh mix 50 --loss 0.1 --duplicate 0.05 --reorder 0.05 --corrupt 0.01 --delay 1±1
# Prints one table row: confirmed (both sides), one-sided, unconfirmed, aborted, silent
# mismatches (two written key files that differ: must be 0), mean key bits of confirmed sessions,
# and the datagrams the session layer rejected (all sessions, both sides) by reason.
set -euo pipefail
name=$1; sessions=$2; shift 2
bin=${ROBOKEY:-target/release/robokey}
out=${SOAK_DIR:-robokey-out/soak}/$name
rm -rf "$out"; mkdir -p "$out"
"$bin" pair --out "$out" > /dev/null
pairing=$out/pairing.key
port_of() { sed -n 's/.* on \([0-9.:]*\).*/\1/p' "$1" | head -1; }
for i in $(seq 1 "$sessions"); do
  d=$out/$i; mkdir -p "$d"
  "$bin" robot --listen 127.0.0.1:0 --pace lockstep --step-timeout-ms 20 --silence-timeout 1 \
    --pairing "$pairing" --key-out "$d/robot.key" --report "$d/robot.json" > "$d/robot.out" 2>&1 &
  robot=$!
  until [ -s "$d/robot.out" ]; do sleep 0.02; done
  "$bin" relay --listen 127.0.0.1:0 --forward "$(port_of "$d/robot.out")" --seed "$i" --idle-exit 2 "$@" > "$d/relay.out" 2>&1 &
  relay=$!
  until [ -s "$d/relay.out" ]; do sleep 0.02; done
  "$bin" controller --robot "$(port_of "$d/relay.out")" --pace lockstep --silence-timeout 1 \
    --pairing "$pairing" --key-out "$d/controller.key" --report "$d/controller.json" > "$d/controller.out" 2>&1 || true
  wait "$robot" || true
  wait "$relay" || true
done
python3 - "$out" "$name" "$sessions" <<'PY'
import json, os, sys
out, name, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
both = one = unconf = aborted = silent = 0
bits = []
rejected = {}
for i in range(1, n + 1):
    d = os.path.join(out, str(i))
    r = json.load(open(os.path.join(d, "robot.json")))
    c = json.load(open(os.path.join(d, "controller.json")))
    keys = [open(os.path.join(d, f)).read() for f in ("robot.key", "controller.key") if os.path.exists(os.path.join(d, f))]
    if len(keys) == 2 and keys[0] != keys[1]:
        silent += 1
    for side in (r, c):
        for why, count in side["frames_rejected"].items():
            rejected[why] = rejected.get(why, 0) + count
    outcomes = {r["outcome"], c["outcome"]}
    if outcomes == {"confirmed"}:
        both += 1; bits.append(c["key_bits"])
    elif "confirmed" in outcomes:
        one += 1
    elif "aborted" in outcomes:
        aborted += 1
    else:
        unconf += 1
mean = sum(bits) / len(bits) if bits else 0
why = ", ".join(f"{k} {v}" for k, v in sorted(rejected.items()) if v) or "none"
print(f"| {name} | {n} | {both} | {one} | {unconf} | {aborted} | {silent} | {mean:.1f} | {why} |")
PY

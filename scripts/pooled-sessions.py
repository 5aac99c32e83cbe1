#!/usr/bin/env python3
"""Runs lockstep sessions between two real agents that pool into their stores, and sums up.

    scripts/pooled-sessions.py OUT --sessions N [--mode private|odometry] [--config FILE]
                               [--set FIELD=VALUE …] [--kill-trials K] [--seed S] [--eve] [--robot-world PRESET|FILE]
                               [-- relay fault options…]

Every session: the robot agent (simulated plant; in private mode also the world's motion
capture and camera), Eve's camera recorder (private mode), the relay with the given faults and a
capture, and the controller; both agents with --store OUT/robot and OUT/controller and --key-out
for the raw session keys. Afterwards: raw bits pooled, blocks, final key bits per session and per
second of robot time, leak, ε, `robokey keys list` of both stores (identical IDs required) and
`robokey keys get` equal on both sides.

With --eve (private mode), Eve's camera and commands adversaries run on every session's capture
and camera log, and their disagreement with the robot's raw bits is summed over all sessions;
then, for every block that made a key, `robokey eve --block` on the records of the sessions the
block's report names (`session_ids`, in block order) prints her realised bound beside the
committed key (a WARNING where the key exceeds it). With --robot-world, the robot agent's simulated plant is that world (`robot --world`)
while both parties keep their configuration, and Eve knows the world (`eve --world`).
With --summary-only, OUT is not run again, only summed up.

With --kill-trials K, K more sessions follow, each of which kills one agent with SIGKILL during
the post-processing that follows the session, in turn: the robot, or the controller, a random
0–250 ms after the controller pooled the session; the controller as soon as it prints a committed
key (between its commit and the robot's); the robot as soon as it prints one (between its commit
and its CommitAck). The next session is a recovery run, after which both stores must list
identical keys with equal bits. The relay then delays each datagram by 2 ms so that
post-processing lasts long enough to be hit.

The default relay faults are the README's mix: --loss 0.1 --duplicate 0.05 --reorder 0.05
--corrupt 0.01 --delay 1±1. ROBOKEY (env) names the binary (default target/release/robokey).
"""

import argparse
import hashlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time

BIN = os.environ.get("ROBOKEY", "target/release/robokey")
MIX = ["--loss", "0.1", "--duplicate", "0.05", "--reorder", "0.05", "--corrupt", "0.01",
       "--delay", "1±1"]
# The relay's idle exit (s): past the robot's default --block-timeout (30 s), so that it never
# leaves while the robot waits for the controller (which repeats its last fragment every 5 s
# while it computes a block's estimate); it is stopped once both agents end.
RELAY_IDLE_EXIT = 31


def robokey(*args, check=True):
    out = subprocess.run([BIN, *args], capture_output=True, text=True)
    if check and out.returncode != 0:
        sys.exit(f"robokey {' '.join(args)} failed ({out.returncode}): {out.stdout}{out.stderr}")
    return out


def start(args, out_path):
    """Starts robokey with stdout and stderr to a file; waits for its first line."""
    log = open(out_path, "w")
    process = subprocess.Popen([BIN, *args], stdout=log, stderr=subprocess.STDOUT, text=True)
    deadline = time.time() + 10
    while time.time() < deadline:
        text = open(out_path).read()
        if "\n" in text:
            return process, text
        time.sleep(0.01)
    sys.exit(f"{args[0]} printed nothing within 10 s")


def address_after(text, marker):
    match = re.search(re.escape(marker) + r"([0-9.:\[\]]+)", text)
    if not match:
        sys.exit(f"no address after {marker!r} in {text!r}")
    return match.group(1)


def settings(a):
    """The configuration every process of a session gets: the user's file and --set options,
    then the mode."""
    options = ["--config", a.config] if a.config else []
    options += [x for s in a.set for x in ("--set", s)]
    if a.mode == "private":
        options += ["--set", "sensing.mode=private"]
    return options


def session(a, d, index, kill=None):
    """One session in folder d; with kill = (victim, delay s), SIGKILL the victim that long
    after the controller pooled the session. Returns what the kill hit, if it did."""
    os.makedirs(d, exist_ok=True)
    common = ["--pace", "lockstep", "--pairing", a.pairing]
    common += settings(a)
    robot_args = ["robot", "--listen", "127.0.0.1:0", "--step-timeout-ms", "20",
                  "--store", os.path.join(a.out, "robot"), "--key-out", f"{d}/robot.key",
                  "--report", f"{d}/robot.json"] + common
    if a.mode == "private":
        robot_args += ["--mocap", "127.0.0.1:0", "--camera", "127.0.0.1:0"]
    if a.robot_world:
        robot_args += ["--world", a.robot_world]
    robot, _ = start(robot_args, f"{d}/robot.out")
    while "listening on" not in open(f"{d}/robot.out").read():
        time.sleep(0.01)
    robot_text = open(f"{d}/robot.out").read()
    recorder = None
    if a.mode == "private":
        camera = address_after(robot_text, "camera on ")
        recorder = subprocess.Popen([BIN, "record", "--from", camera, "--out", f"{d}/camera.csv"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    faults = ["--delay", "2"] if kill else a.faults
    relay, relay_text = start(["relay", "--listen", "127.0.0.1:0", "--forward",
                               address_after(robot_text, "listening on "), "--seed", str(index),
                               "--idle-exit", str(RELAY_IDLE_EXIT),
                               "--capture", f"{d}/capture.pcap"] + faults,
                              f"{d}/relay.out")
    controller_args = ["controller", "--robot", address_after(relay_text, "on "),
                       "--store", os.path.join(a.out, "controller"),
                       "--key-out", f"{d}/controller.key", "--report", f"{d}/controller.json"]
    controller_args += common
    if a.mode == "private":
        controller_args += ["--sensor", "mocap:" + address_after(robot_text, "motion capture on ")]
    log = open(f"{d}/controller.out", "w")
    controller = subprocess.Popen([BIN, *controller_args], stdout=subprocess.PIPE,
                                  stderr=log, text=True)
    hit = None
    if kill and kill[0] == "robot" and kill[1] == "commit":
        hit = kill_robot_at_commit(robot, f"{d}/robot.out")
    for line in controller.stdout:
        log.write(line)
        log.flush()
        if not kill or hit is not None:
            continue
        victim, moment = kill
        if victim == "controller" and moment == "commit" and " committed: " in line:
            controller.send_signal(signal.SIGKILL)
            hit = "controller killed at its commit"
            break
        if moment != "commit" and " pooled: " in line:
            time.sleep(moment)
            process = robot if victim == "robot" else controller
            if process.poll() is None:
                process.send_signal(signal.SIGKILL)
                hit = f"{victim} killed {moment * 1000:.0f} ms after pooling"
            else:
                hit = f"{victim} had ended before {moment * 1000:.0f} ms"
            if victim == "controller":
                break
    controller.wait()
    robot.wait()
    # Both agents ended: nothing more to forward.
    relay.send_signal(signal.SIGINT)
    relay.wait()
    if recorder:
        recorder.wait()
    if callable(hit):
        hit = hit()
    return hit or "no kill: the session ended without a committed key"


def kill_robot_at_commit(robot, out_path):
    """Kills the robot as soon as its output says it committed a key (a watcher thread);
    returns a function that says what happened."""
    import threading
    result = []

    def watch():
        while robot.poll() is None:
            if " committed: " in open(out_path).read():
                robot.send_signal(signal.SIGKILL)
                result.append("robot killed at its commit")
                return
            time.sleep(0.001)
    thread = threading.Thread(target=watch)
    thread.start()
    return lambda: (thread.join(), result[0] if result else None)[1]


def stores_agree(a):
    """Both stores list the same IDs with the same status (settled, or pending: the peer has
    not acknowledged it yet), and every settled key has the same bits on both sides."""
    lists = {}
    for role in ("robot", "controller"):
        lists[role] = json.loads(robokey("keys", "list", "--json", "--store",
                                         os.path.join(a.out, role), "--pairing",
                                         a.pairing).stdout)
    listed = sorted((k["id"], k["status"]) for k in lists["controller"])
    if listed != sorted((k["id"], k["status"]) for k in lists["robot"]):
        return False, lists
    for key_id in (i for i, status in listed if status == "settled"):
        bits = {role: robokey("keys", "get", "--store", os.path.join(a.out, role), "--pairing",
                              a.pairing, key_id).stdout
                for role in ("robot", "controller")}
        if bits["robot"] != bits["controller"]:
            return False, lists
    return True, lists


def summary(a, folders):
    pooled = {"robot": 0, "controller": 0}
    blocks, robot_seconds, eve = [], 0.0, {}
    for d in folders:
        for role in pooled:
            path = f"{d}/{role}.json"
            if not os.path.exists(path):
                continue
            r = json.load(open(path))
            post = r.get("post") or {}
            pooled[role] += post.get("session_bits", 0)
            if role == "controller":
                blocks += post.get("blocks", [])
            else:
                robot_seconds += r["steps_done"] * a.sample_time
    keyed = [b for b in blocks if b["length"] > 0]
    key_bits = sum(b["length"] for b in keyed)
    print(f"sessions: {len(folders)}, robot time {robot_seconds:.0f} s")
    print(f"raw bits pooled: robot {pooled['robot']}, controller {pooled['controller']}")
    for b in blocks:
        print(f"block {b['block']}: {b['bits']} raw bits of {b['sessions']} sessions, "
              f"sample {b['sample_bits']} ({b['sample_errors']} differ), reconciled "
              f"{b['reconciled_bits']}, leak {b['leak_ec']} + {b['leak_confirmation']}, "
              f"H_min {b['h_min']:.0f}, key {b['length']} bits"
              + (f" — no key: {b['reason'][:90]}…" if b.get("reason") else ""))
    print(f"final key bits: {key_bits} in {len(keyed)} keys; "
          f"{key_bits / max(len(folders), 1):.1f} per session, "
          f"{key_bits / max(robot_seconds, 1e-9):.3f} per second of robot time")


def eve_summary(a, folders):
    """Eve on every session's capture and camera log, with the sessions' --set options (the
    capture's terms must match hers): disagreements with the robot's raw bits."""
    pattern = re.compile(r"^(controller|eve\[(\w+)\]).*?differs from the robot's raw bits on "
                         r"(\d+) of (\d+) bits", re.M)
    totals = {}
    for d in folders:
        out = robokey("eve", "--capture", f"{d}/capture.pcap", "--camera-log", f"{d}/camera.csv",
                      *settings(a), *world(a), "--robot-key", f"{d}/robot.key",
                      "--controller-key", f"{d}/controller.key", "--out", f"{d}/eve").stdout
        for match in pattern.finditer(out):
            who = match.group(2) or match.group(1)
            wrong, bits = totals.get(who, (0, 0))
            totals[who] = (wrong + int(match.group(3)), bits + int(match.group(4)))
    for who, (wrong, bits) in totals.items():
        name = "the controller" if who == "controller" else f"Eve ({who})"
        print(f"{name} differs from the robot's raw bits on {wrong} of {bits} "
              f"({100 * wrong / max(bits, 1):.2f} %)")


def world(a):
    """Eve's --world option: the robot's world when it has one of its own."""
    return ["--world", a.robot_world] if a.robot_world else []


def slice_id(session, slice_):
    """The pool ID of a multilevel session's slice (docs/postprocessing.md, "Multilevel
    slices"): the session's own for slice 0, else the first 4 bytes of
    SHA-256("robokey/slice-id/v1" ‖ session u32 ‖ slice u8), as 8 hex digits."""
    if slice_ == 0:
        return session
    digest = hashlib.sha256(b"robokey/slice-id/v1" + bytes.fromhex(session)
                            + bytes([slice_])).digest()
    return digest[:4].hex()


def session_folders(folders):
    """Each session's folder by its ID (hex, as the agents' reports write it): from the
    robot's report, else the controller's; also by its multilevel slices' IDs."""
    named = {}
    for d in folders:
        for role in ("robot", "controller"):
            path = f"{d}/{role}.json"
            if os.path.exists(path):
                session = json.load(open(path)).get("session")
                if session:
                    for slice_ in range(3):
                        named.setdefault(slice_id(session, slice_), d)
    return named


def block_members(block, named):
    """The folders of the sessions a controller's block report names (`session_ids`, in
    block order), or why they cannot be found."""
    ids = block.get("session_ids")
    if not ids:
        return None, "its report does not name its sessions (an agent before session_ids)"
    missing = [i for i in ids if i not in named]
    if missing:
        return None, f"sessions {', '.join(missing)} have no folder here"
    return [named[i] for i in ids], None


def block_check(a, folders):
    """`robokey eve --block` on every block the controller's reports say made a key, over
    the sessions the block report names, in its order."""
    named = session_folders(folders)
    # A multilevel block's slices pool the same sessions: one run checks every slice's block.
    checked = set()
    for d in folders:
        path = f"{d}/controller.json"
        if not os.path.exists(path):
            continue
        for b in (json.load(open(path)).get("post") or {}).get("blocks", []):
            if b["length"] == 0:
                continue
            members, why = block_members(b, named)
            if members is None:
                print(f"block {b['block']}: {why}: not checked")
                continue
            if (path, tuple(members)) in checked:
                continue
            checked.add((path, tuple(members)))
            args = ["eve", *settings(a), *world(a), "--block", path]
            for m in members:
                args += ["--capture", f"{m}/capture.pcap", "--camera-log", f"{m}/camera.csv",
                         "--robot-key", f"{m}/robot.key"]
            names = ", ".join(sorted(os.path.basename(m) for m in members))
            print(f"$ robokey eve … --block {path} ({len(members)} sessions: {names})")
            out = robokey(*args).stdout
            for line in out.splitlines():
                if line.startswith(("block ", "WARNING", "eve: the world is not")):
                    print(line)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out")
    p.add_argument("--sessions", type=int, required=True)
    p.add_argument("--mode", choices=["private", "odometry"], default="private")
    p.add_argument("--config", metavar="FILE")
    p.add_argument("--set", action="append", default=[])
    p.add_argument("--kill-trials", type=int, default=0)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--eve", action="store_true")
    p.add_argument("--robot-world", metavar="PRESET|FILE",
                   help="the robot agent's simulated world (robot --world); Eve is given it")
    p.add_argument("--summary-only", action="store_true")
    p.add_argument("faults", nargs="*")
    a = p.parse_args()
    a.faults = a.faults or MIX
    a.sample_time = float(re.search(r"^T = (\S+)", robokey("config", *settings(a)).stdout,
                                    re.M).group(1))
    a.pairing = os.path.join(a.out, "pairing.key")
    folders = [os.path.join(a.out, f"session-{i:03}") for i in range(a.sessions)]
    if not a.summary_only:
        shutil.rmtree(a.out, ignore_errors=True)
        os.makedirs(a.out)
        robokey("pair", "--out", a.out)
        started = time.time()
        for i, d in enumerate(folders):
            session(a, d, i)
        print(f"{a.sessions} sessions in {time.time() - started:.0f} s wall")
    summary(a, folders)
    if a.eve:
        eve_summary(a, folders)
        block_check(a, folders)
    agree, lists = stores_agree(a)
    print(f"stores agree: {agree}")
    for role in ("robot", "controller"):
        print(f"$ robokey keys list --store {a.out}/{role} --pairing {a.pairing}")
        print(robokey("keys", "list", "--store", os.path.join(a.out, role), "--pairing",
                      a.pairing).stdout, end="")
    if not agree:
        sys.exit("the stores differ")
    rng = random.Random(a.seed)
    failures = 0
    for t in range(a.kill_trials):
        victim = ("robot", "controller")[t % 2]
        moment = "commit" if t % 4 >= 2 else rng.uniform(0.0, 0.25)
        d = os.path.join(a.out, f"kill-{t:02}")
        hit = session(a, d, 1000 + t, kill=(victim, moment))
        recovery = os.path.join(a.out, f"kill-{t:02}-recovery")
        session(a, recovery, 2000 + t)
        agree, lists = stores_agree(a)
        failures += not agree
        notes = []
        for role in ("robot", "controller"):
            path = f"{recovery}/{role}.json"
            post = json.load(open(path)).get("post", {}) if os.path.exists(path) else {}
            if post.get("torn_bytes") or post.get("keys_recovered"):
                notes.append(f"{role} recovered {post['torn_bytes']} torn bytes, "
                             f"{post['keys_recovered']} keys")
        print(f"trial {t + 1}: {hit}; after recovery: {len(lists['controller'])} keys, "
              f"stores agree: {agree}" + (f" ({'; '.join(notes)})" if notes else ""))
    if a.kill_trials:
        print(f"kill trials: {a.kill_trials}, stores disagreeing after recovery: {failures}")
        if failures:
            sys.exit(1)


if __name__ == "__main__":
    main()

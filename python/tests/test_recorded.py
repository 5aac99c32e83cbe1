"""Reading what the network agents recorded: a capture's frames and a key store's listing,
equal to what ``robokey frames`` and ``robokey keys list --json`` print — never key bits."""

from __future__ import annotations

import json
import math
import os
import struct
from pathlib import Path
from typing import List

import pytest

import robokey

from conftest import ROOT

CAPTURES = sorted((ROOT / "crates" / "robokey-net" / "tests" / "captures").glob("*.pcap*"))


def _same_number(ours: float, theirs: str) -> bool:
    """A frame's number against the command's (Rust's shortest round-trip form)."""
    value = float(theirs)
    return (math.isnan(ours) and math.isnan(value)) or ours == value


@pytest.mark.parametrize("capture", CAPTURES, ids=lambda p: p.name)
def test_a_capture_reads_as_frames_read_lists_it(cli, capture):
    lines = cli("frames", str(capture)).stdout.splitlines()
    table = robokey.read_capture(capture)
    assert table.schema.equals(robokey.FRAME_SCHEMA)
    rows = table.to_pylist()
    assert len(rows) == len(lines) > 0
    for row, line in zip(rows, lines):
        cells = line.split("\t")
        assert row["index"] == int(cells[0])
        if cells[1] == "undecodable":
            assert row["error"] == cells[5] and row["type"] is None and row["numbers"] == []
            continue
        assert row["error"] is None
        assert [row["type"], row["session"], row["seq"], row["step"]] == [int(c) for c in cells[1:5]]
        numbers = cells[5].split(",") if cells[5] else []
        assert len(row["numbers"]) == len(numbers)
        assert all(_same_number(ours, theirs) for ours, theirs in zip(row["numbers"], numbers))


def _raw_ipv4_udp_pcap(payloads: List[bytes]) -> bytes:
    """A pcap (LINKTYPE_RAW) of UDP datagrams 127.0.0.1:1 → 127.0.0.1:2 with these payloads."""
    out = struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 101)
    for payload in payloads:
        udp = struct.pack(">HHHH", 1, 2, 8 + len(payload), 0) + payload
        ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, 17, 0,
                         bytes([127, 0, 0, 1]), bytes([127, 0, 0, 1])) + udp
        out += struct.pack("<IIII", 0, 0, len(ip), len(ip)) + ip
    return out


def test_a_datagram_that_is_no_robokey_frame_is_listed_with_why(cli, tmp_path):
    (tmp_path / "mixed.pcap").write_bytes(_raw_ipv4_udp_pcap([b"hello", b""]))
    rows = robokey.read_capture(tmp_path / "mixed.pcap").to_pylist()
    lines = cli("frames", str(tmp_path / "mixed.pcap")).stdout.splitlines()
    assert len(rows) == len(lines) == 2
    for row, line in zip(rows, lines):
        index, word, *_, error = line.split("\t")
        assert word == "undecodable" and row["error"] == error != ""
        assert row["index"] == int(index) and row["type"] is None and row["session"] is None


def test_a_capture_that_is_not_one_is_named(tmp_path):
    (tmp_path / "notes.pcap").write_text("not a capture\n")
    with pytest.raises(robokey.InputError, match="notes.pcap"):
        robokey.read_capture(tmp_path / "notes.pcap")
    with pytest.raises(OSError):
        robokey.read_capture(tmp_path / "missing.pcap")


def test_a_capture_cut_short_is_read_to_its_last_whole_packet_and_warned_of(cli, tmp_path):
    whole = (CAPTURES[0].parent / "relay-after-faults.pcap").read_bytes()
    (tmp_path / "cut.pcap").write_bytes(whole[: len(whole) - 7])
    with pytest.warns(UserWarning, match="cut.pcap"):
        table = robokey.read_capture(tmp_path / "cut.pcap")
    assert table.num_rows == len(cli("frames", str(tmp_path / "cut.pcap")).stdout.splitlines())


@pytest.fixture(scope="module")
def demo(cli, tmp_path_factory) -> Path:
    """A demo's stores (the settings of the command's own demo test: a settled key after
    three sessions), a 64-bit key taken from the controller's; each store's final-key bits
    in ``bits-<role>.hex`` before the take."""
    out = tmp_path_factory.mktemp("demo") / "demo"
    text = cli(
        "demo", "--out", str(out),
        "--set", "postprocess.block_bits=1600",
        "--set", "protocol.bits_per_doublet=2",
        "--max-sessions", "6",
    ).stdout
    key_id = text.split("  ID ")[1].split()[0]
    pairing = str(out / "pairing.key")
    for role in ("robot", "controller"):
        hex_bits = cli("keys", "get", "--store", str(out / role), "--pairing", pairing, key_id).stdout
        (out.parent / f"bits-{role}.hex").write_text(hex_bits.strip())
    cli("keys", "take", "--store", str(out / "controller"), "--pairing", pairing, "--bits", "64")
    return out


@pytest.mark.parametrize("role", ["robot", "controller"])
def test_a_store_lists_as_keys_list_json_never_its_bits(cli, demo, role):
    store, pairing = demo / role, demo / "pairing.key"
    expected = json.loads(cli("keys", "list", "--store", str(store), "--pairing", str(pairing), "--json").stdout)
    table = robokey.list_keys(store, pairing)
    assert table.schema.equals(robokey.KEY_SCHEMA)
    rows = table.to_pylist()
    assert len(rows) == len(expected) > 0
    for row, key in zip(rows, expected):
        key.setdefault("pending_reason", None)
        key.setdefault("basis", None)
        assert key["reconciliation"] in ("cascade", "ldpc") and key["leak_ec"] > 0
        assert row == key
    if role == "controller":
        assert rows[0]["taken_bits"] == 64 and len(rows[0]["taken"]) == 1
    bits = (demo.parent / f"bits-{role}.hex").read_text()
    assert len(bits) >= 16 and bits[:16] not in str(rows)


def test_a_store_is_opened_only_with_its_pairing(demo, tmp_path):
    with pytest.raises(robokey.InputError, match="not a store"):
        robokey.list_keys(tmp_path, demo / "pairing.key")
    with pytest.raises(robokey.InputError, match="missing"):
        robokey.list_keys(demo / "robot", tmp_path / "pairing.key")
    other = tmp_path / "other.key"
    other.write_bytes((demo / "pairing.key").read_bytes())
    os.chmod(other, 0o644)
    with pytest.raises(robokey.InputError, match="other.key"):
        robokey.list_keys(demo / "robot", other)
    with pytest.warns(UserWarning, match="other.key"):
        assert robokey.list_keys(demo / "robot", other, insecure_pairing_file=True).num_rows >= 1

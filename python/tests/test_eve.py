"""The eavesdroppers on a recorded session: ``robokey.eve`` returns the ``capture.json`` that
``robokey eve --capture … --out`` writes for the same inputs, and refuses what it refuses."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict, List

import pytest

import robokey

from conftest import ROOT

CAPTURES = sorted((ROOT / "crates" / "robokey-net" / "tests" / "captures").glob("*.pcap*"))
# The terms of the captured session (crates/robokey-net/tests/captures.rs).
SESSION = {"trajectory": {"laps": 1, "side_time": 2}}
SESSION_FLAGS = ["--set", "trajectory.laps=1", "--set", "trajectory.side_time=2"]
ODOMETRY = ["oracle", "mismatch", "soft", "identify", "transcript"]


def _command(cli: Any, tmp_path: Path, *args: str, session: List[str] = SESSION_FLAGS) -> Dict[str, Any]:
    """``capture.json`` of ``robokey eve args… --out``, for the captured session's terms."""
    out = tmp_path / "eve"
    cli("eve", *args, *session, "--out", str(out))
    report: Dict[str, Any] = json.loads((out / "capture.json").read_text())
    return report


@pytest.mark.parametrize("capture", CAPTURES, ids=lambda p: p.name)
def test_every_odometry_eavesdropper_hears_a_capture_as_the_command_does(cli, tmp_path, capture):
    ours = robokey.eve(capture, SESSION, strategy=ODOMETRY, seed=3)
    theirs = _command(cli, tmp_path, "--capture", str(capture), "--strategy", ",".join(ODOMETRY),
                      "--seed", "3")
    assert ours == theirs
    assert [s["strategy"] for s in ours["strategies"]] == ODOMETRY
    assert ours["frames"] > 0 and all(s["key_bits"] > 0 for s in ours["strategies"])


def test_explicit_starting_errors_and_the_default_strategy_are_the_commands(cli, tmp_path):
    capture = CAPTURES[0]
    ours = robokey.eve(capture, SESSION, strategy="identify", errors=(0.05, -0.02, 0, 0), seed=7)
    theirs = _command(cli, tmp_path, "--capture", str(capture), "--strategy", "identify",
                      "--errors", "0.05,-0.02,0,0", "--seed", "7")
    assert ours == theirs
    assert ours["strategies"][0]["start_errors"] == {"r": 0.05, "D": -0.02, "W": 0.0, "V": 0.0}
    default = robokey.eve(str(capture), SESSION)
    assert default == _command(cli, tmp_path / "default", "--capture", str(capture))
    assert len(default["strategies"]) == 1


def _error_after_name(text: str) -> str:
    """A message without the leading name of the input (``--errors 1,0,0,0:`` or
    ``errors=[…]:``)."""
    return text.split(": ", 1)[1]


@pytest.mark.parametrize(
    "keywords, flags",
    [
        ({"errors": (1, 0, 0, 0)}, ["--errors", "1,0,0,0"]),
        ({"errors": (0.1, 0.2)}, ["--errors", "0.1,0.2"]),
    ],
)
def test_starting_errors_out_of_range_are_refused_as_the_command_refuses_them(cli, keywords, flags):
    with pytest.raises(robokey.InputError) as caught:
        robokey.eve(CAPTURES[0], SESSION, **keywords)
    refused = cli("eve", "--capture", str(CAPTURES[0]), *SESSION_FLAGS, *flags, check=False)
    assert refused.returncode != 0
    assert _error_after_name(str(caught.value)) in refused.stderr


def test_inputs_that_do_not_fit_the_mode_are_named_as_keywords(cli, tmp_path):
    capture = CAPTURES[0]
    cases: List[Any] = [
        ({"strategy": "camera"}, "strategy= camera: does not apply in sensing.mode = odometry"),
        ({"camera_log": tmp_path / "camera.csv"}, "camera_log= is her camera's record"),
        ({"block": tmp_path / "report.json"}, "block= is a private-sensing block"),
    ]
    for keywords, message in cases:
        with pytest.raises(robokey.InputError, match=message):
            robokey.eve(capture, SESSION, **keywords)
    with pytest.raises(robokey.InputError, match="capture=: one capture at a time"):
        robokey.eve([capture, capture], SESSION)
    with pytest.raises(robokey.InputError, match="capture= of a private-sensing session needs"):
        robokey.eve(capture, {"sensing": {"mode": "private"}})
    # The same refusals from the command, with its flags.
    refused = cli("eve", "--capture", str(capture), "--strategy", "camera", check=False)
    assert refused.returncode == 2 and "--strategy camera: does not apply" in refused.stderr


def test_a_missing_capture_an_invalid_config_and_other_terms_are_named(tmp_path):
    with pytest.raises(OSError, match="missing.pcap"):
        robokey.eve(tmp_path / "missing.pcap", SESSION)
    with pytest.raises(robokey.ConfigError) as caught:
        robokey.eve(CAPTURES[0], {"protocol": {"delta_v": 0}})
    assert caught.value.field == "protocol.delta_v"
    with pytest.raises(robokey.InputError, match="trajectory.laps"):
        robokey.eve(CAPTURES[0])


def test_a_capture_cut_short_is_heard_to_its_end_and_warned_of(cli, tmp_path):
    whole = CAPTURES[0].read_bytes()
    cut = tmp_path / "cut.pcap"
    cut.write_bytes(whole[: len(whole) * 2 // 3])
    with pytest.warns(UserWarning, match="cut.pcap: the file ends inside"):
        ours = robokey.eve(cut, SESSION, seed=3)
    assert ours == _command(cli, tmp_path, "--capture", str(cut), "--seed", "3")
    assert ours["shortfalls"] and ours["frames"] < robokey.eve(CAPTURES[0], SESSION)["frames"]


# A private-sensing session recorded by loopback agents, as crates/robokey-cli/tests/
# private_network.rs records one: the robot's simulated world with its motion capture and
# Eve's camera, `robokey record` of the camera, the relay's capture, the controller.
PRIVATE_FLAGS = ["--set", "sensing.mode=private"]
PRIVATE = {"sensing": {"mode": "private"}}


class _Started:
    """A ``robokey`` process whose first ``lines`` lines of stdout were read; the rest is
    drained by a thread so that it never blocks on a full pipe."""

    def __init__(self, binary: Path, args: List[str], lines: int) -> None:
        import subprocess
        import threading

        self.process = subprocess.Popen([str(binary), *args], stdout=subprocess.PIPE,
                                        stderr=subprocess.DEVNULL)
        assert self.process.stdout is not None
        self.lines = [self.process.stdout.readline().decode() for _ in range(lines)]
        threading.Thread(target=self.process.stdout.read, daemon=True).start()

    def after(self, marker: str, line: int = -1) -> str:
        """The address after ``marker`` in a line read, up to a comma or the end."""
        assert marker in self.lines[line], self.lines
        return self.lines[line].split(marker)[1].split(",")[0].strip()

    def wait(self) -> int:
        return self.process.wait(timeout=120)


@pytest.fixture(scope="module")
def private_session(cli: Any, tmp_path_factory: Any) -> Path:
    folder: Path = tmp_path_factory.mktemp("private-session")
    cli("pair", "--out", str(folder))
    pairing = str(folder / "pairing.key")
    robot = _Started(cli.binary, [
        "robot", "--listen", "127.0.0.1:0", "--pace", "lockstep", "--step-timeout-ms", "2000",
        "--silence-timeout", "5", "--pairing", pairing, "--seed", "5",
        "--key-out", str(folder / "robot.key"), "--report", str(folder / "robot.json"),
        *PRIVATE_FLAGS, "--mocap", "127.0.0.1:0", "--camera", "127.0.0.1:0",
    ], 2)
    recorder = _Started(cli.binary, ["record", "--from", robot.after("camera on ", 0),
                                     "--out", str(folder / "camera.csv")], 0)
    relay = _Started(cli.binary, [
        "relay", "--listen", "127.0.0.1:0", "--forward", robot.after(" on "),
        "--capture", str(folder / "capture.pcap"), "--idle-exit", "3",
    ], 1)
    cli("controller", "--robot", relay.after(" on "), "--pace", "lockstep",
        "--silence-timeout", "5", "--pairing", pairing,
        "--sensor", "mocap:" + robot.after("motion capture on ", 0),
        "--key-out", str(folder / "controller.key"), "--report", str(folder / "controller.json"),
        *PRIVATE_FLAGS)
    assert robot.wait() == 0 and relay.wait() == 0 and recorder.wait() == 0
    return folder


def _recorded(folder: Path) -> Dict[str, Path]:
    return {"capture": folder / "capture.pcap", "camera_log": folder / "camera.csv",
            "robot_key": folder / "robot.key", "controller_key": folder / "controller.key"}


def _flags(files: Dict[str, Path]) -> List[str]:
    return [a for name, path in files.items() for a in ("--" + name.replace("_", "-"), str(path))]


def test_the_private_eavesdroppers_hear_a_loopback_session_as_the_command_does(
    cli, tmp_path, private_session
):
    files = _recorded(private_session)
    ours = robokey.eve(files.pop("capture"), PRIVATE, **files)
    theirs = _command(cli, tmp_path, *_flags(_recorded(private_session)), session=PRIVATE_FLAGS)
    assert ours == theirs
    assert [s["strategy"] for s in ours["strategies"]] == ["camera", "commands"]
    assert all(s["key_bits"] > 0 and s["doublets"] for s in ours["strategies"])


def _block_report(folder: Path, raw_bits: int, length: int) -> Path:
    """An agent report whose one block pooled ``raw_bits`` bits into a key of ``length``."""
    block = {"block": 0, "sessions": 1, "bits": raw_bits, "sample_bits": 0, "sample_errors": 0, "sampled": [],
             "reconciled_bits": raw_bits, "leak_ec": 0, "leak_confirmation": 0, "h_min": 0.0,
             "length": length}
    path = folder / f"report-{raw_bits}-{length}.json"
    path.write_text(json.dumps({"post": {"blocks": [block]}}))
    return path


def test_her_bound_over_a_block_and_a_block_of_another_size_are_the_commands(
    cli, tmp_path, private_session
):
    files = _recorded(private_session)
    raw_bits = int(files["robot_key"].read_text().split()[1].split("=")[1])
    report = _block_report(tmp_path, raw_bits, 10**6)
    capture = files.pop("capture")
    ours = robokey.eve([capture], PRIVATE, block=report, strategy="camera",
                       **{k: [v] for k, v in files.items()})
    theirs = _command(cli, tmp_path, *_flags(_recorded(private_session)), "--block", str(report),
                      "--strategy", "camera", session=PRIVATE_FLAGS)
    assert ours == theirs
    assert ours["block"]["raw_bits"] == raw_bits and ours["block"]["exceeds"] is True
    assert len(ours["sessions"]) == 1
    wrong = _block_report(tmp_path, raw_bits + 2, 10)
    with pytest.raises(robokey.InputError) as caught:
        robokey.eve(capture, PRIVATE, block=wrong, **files)
    refused = cli("eve", *_flags(_recorded(private_session)), "--block", str(wrong),
                  *PRIVATE_FLAGS, check=False)
    assert refused.returncode == 2
    message = f"block 0 pooled {raw_bits + 2} raw bits of 1 sessions, the captures' robot keys hold {raw_bits}"
    assert message in str(caught.value) and message in refused.stderr
    assert str(caught.value).startswith("block= ")

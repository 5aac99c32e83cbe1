"""``robokey.threat`` against ``robokey threat --json``: the same figures, and the camera
named in frames worth its per-instant equivalent."""

import json

import pytest

import robokey

PRIVATE = {"sensing.mode": "private", "postprocess.block_bits": 2000}


def test_threat_equals_the_command_line(cli, tmp_path):
    config = tmp_path / "private.toml"
    config.write_text('[sensing]\nmode = "private"\n[postprocess]\nblock_bits = 2000\n')
    done = cli("threat", "--config", str(config), "--fps", "5", "--frame-std", "8", "--json")
    printed = json.loads(done.stdout)
    figures = robokey.threat(PRIVATE, fps=[5], frame_std=[8])
    assert figures == printed
    (camera,) = figures["cameras"]
    # 5 frames/s at T = 0.2 s: at the worst phase one frame sits at each mid instant.
    assert camera["per_instant_mm"] == pytest.approx([8.0, 8.0, 8.0])
    assert figures["break_even"]["kind"] == "between"


def test_fps_without_frame_std_is_named():
    with pytest.raises(robokey.InputError, match="fps and frame_std"):
        robokey.threat(PRIVATE, fps=[30])

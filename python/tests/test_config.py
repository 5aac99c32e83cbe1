"""Configurations as dicts and TOML strings, and the named errors."""

import pytest

import robokey


def test_dict_nested_dotted_and_toml_are_the_same_configuration():
    nested = robokey.run({"protocol": {"delta_v": 0.03}, "trajectory": {"laps": 1}})
    dotted = robokey.run({"protocol.delta_v": 0.03, "trajectory.laps": 1})
    text = robokey.run("[protocol]\ndelta_v = 0.03\n[trajectory]\nlaps = 1\n")
    assert nested["metrics"] == dotted["metrics"] == text["metrics"]
    assert nested["config"] == dotted["config"] == text["config"]
    assert "delta_v = 0.03" in nested["config"]


def test_numpy_scalars_are_numbers():
    np = pytest.importorskip("numpy")
    ours = robokey.run({"protocol": {"delta_v": np.float64(0.03)}, "trajectory": {"laps": np.int64(1)}})
    plain = robokey.run({"protocol": {"delta_v": 0.03}, "trajectory": {"laps": 1}})
    assert ours["metrics"] == plain["metrics"]


def test_seed_sets_run_seed():
    assert robokey.run(seed=7)["seed"] == 7
    assert robokey.run()["seed"] == 2023
    assert robokey.run({"run": {"seed": 7}})["metrics"] == robokey.run(seed=7)["metrics"]


def test_a_value_out_of_range_names_field_value_and_allowed_as_the_cli_does(cli):
    with pytest.raises(robokey.ConfigError) as raised:
        robokey.run({"protocol": {"delta_v": 0}})
    error = raised.value
    assert isinstance(error, ValueError)
    assert (error.origin, error.field, error.value) == ("config", "protocol.delta_v", "0.0")
    assert error.allowed == "> 0, or protocol.delta_omega > 0, while protocol.enabled = true"
    done = cli("run", "--delta-v", "0", "--out", "/nonexistent/never-written", check=False)
    assert done.returncode == 2
    # The same message, but for what set the field: the flag there, the argument here.
    assert done.stderr.strip() == "error: --delta-v 0: " + str(error).split(": ", 1)[1]


def test_errors_blame_seed_as_the_cli_blames_its_flag():
    with pytest.raises(robokey.ConfigError) as raised:
        robokey.run(seed=-1)
    assert raised.value.origin == "seed=-1"
    assert str(raised.value).startswith("seed=-1: ")


def test_parse_errors_have_no_field():
    for config in ({"controller": {"gain": 1.0}}, {"controller": {"kp": "fast"}}, "[protocol\n"):
        with pytest.raises(robokey.ConfigError) as raised:
            robokey.run(config)
        error = raised.value
        assert (error.field, error.value, error.allowed) == (None, None, None)
        assert str(error).startswith("config: ")
    with pytest.raises(robokey.ConfigError, match=r"unknown field `controller.gain` \(allowed here: kp, kd"):
        robokey.run({"controller": {"gain": 1.0}})
    with pytest.raises(robokey.ConfigError, match='invalid type: string "fast", expected f64'):
        robokey.run({"controller": {"kp": "fast"}})


def test_values_toml_cannot_hold_are_named():
    with pytest.raises(robokey.ConfigError) as raised:
        robokey.run({"protocol": {"delta_v": object()}})
    assert raised.value.field == "protocol.delta_v"
    assert raised.value.allowed == "a bool, int, float, str, list, tuple or dict"
    with pytest.raises(robokey.ConfigError, match="allowed: None, a dict or a TOML string"):
        robokey.run(3)


def test_a_sweep_is_not_a_run():
    with pytest.raises(robokey.ConfigError, match="holds a sweep; run it with `robokey.sweep`"):
        robokey.run({"sweep": {"protocol.delta_v": [0.02]}})

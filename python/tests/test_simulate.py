"""eqtrack.simulate equals plant_sim sim bit for bit (through the CSV's round-trip floats),
and bad input raises ValueError with the command line's message."""

import json

import numpy as np
import pytest

import eqtrack
from conftest import REPO, cli, read_csv, same_bits


@pytest.mark.parametrize(
    "scenario",
    [
        "seed.toml",  # the seed, SO(3)
        "sensors_se3.toml",  # SE(3) with sensors (the pose filter)
        "slew_so3.toml",  # a waypoint path (its file beside it)
        "wheels_slew.toml",  # reaction wheels: the wheel_speed_i and wheel_cmd_i columns
        "se2_vessel.toml",  # SE(2): a planar vessel, its waypoints and allocation
    ],
)
def test_simulate_equals_the_cli_bit_for_bit(scenario, plant_sim, tmp_path):
    path = REPO / "scenarios" / scenario
    code, _, err = cli(plant_sim, "sim", "--scenario", str(path), "--out", str(tmp_path))
    assert code == 0, err
    header, cols = read_csv(tmp_path / "trajectory.csv")
    run = eqtrack.simulate(str(path))
    assert list(run.columns) == header, "the columns are exactly trajectory.csv's, in order"
    for name in header:
        assert same_bits(run.columns[name], cols[name]), f"column {name} differs"
    with open(tmp_path / "summary.json") as f:
        assert run.summary == json.load(f)


def test_overrides_are_the_scenarios_keys(plant_sim, tmp_path):
    path = REPO / "scenarios" / "seed.toml"
    code, _, err = cli(plant_sim, "sim", "--scenario", str(path), "--law", "gt", "--out", str(tmp_path))
    assert code == 0, err
    _, cols = read_csv(tmp_path / "trajectory.csv")
    gt = eqtrack.simulate(path, law="gt")
    assert gt.summary["law"] == "gt"
    assert same_bits(gt.columns["tau_0"], cols["tau_0"])
    eqt = eqtrack.simulate(path)
    assert not same_bits(eqt.columns["tau_0"], gt.columns["tau_0"])
    # a table is merged key by key; TOML text works as a path does
    text = eqtrack.builtin_scenario("seed")
    short = eqtrack.simulate(text, duration=1.0, controller={"kd": 2.0})
    assert short.summary["duration"] == 1.0
    assert len(short.columns["t"]) == 101


def test_the_error_frame_is_a_controller_key(plant_sim, tmp_path):
    """The default law forms its error at the reference; the papers' form is one key away,
    exactly as the command line flies it, and a bad frame is refused naming the key."""
    path = REPO / "scenarios" / "se3_circle.toml"
    default = eqtrack.simulate(path, duration=5.0)
    assert default.summary["error_frame"] == "reference"
    world = eqtrack.simulate(path, duration=5.0, controller={"error_frame": "world"})
    assert "error_frame" not in world.summary
    assert not same_bits(default.columns["tau_0"], world.columns["tau_0"])
    text = path.read_text().replace("[controller]", '[controller]\nerror_frame = "world"').replace(
        "duration = 60.0", "duration = 5.0"
    )
    (tmp_path / "world.toml").write_text(text)
    code, _, err = cli(plant_sim, "sim", "--scenario", str(tmp_path / "world.toml"), "--out", str(tmp_path / "w"))
    assert code == 0, err
    _, cols = read_csv(tmp_path / "w" / "trajectory.csv")
    assert same_bits(world.columns["tau_0"], cols["tau_0"])
    with pytest.raises(ValueError, match="controller.error_frame"):
        eqtrack.simulate(path, controller={"error_frame": "up"})


def _cli_error(plant_sim, tmp_path, text):
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    code, _, err = cli(plant_sim, "sim", "--scenario", str(bad), "--out", str(tmp_path / "o"))
    assert code == 2, err
    return bad, err.strip().removeprefix("error: ")


def test_a_bad_key_raises_the_cli_message(plant_sim, tmp_path):
    text = eqtrack.builtin_scenario("seed") + "\nbogus_key = 1\n"
    bad, message = _cli_error(plant_sim, tmp_path, text)
    with pytest.raises(ValueError) as e:
        eqtrack.simulate(str(bad))
    assert str(e.value) == message
    assert "bogus_key" in str(e.value)
    # the same key as an override is refused the same way
    with pytest.raises(ValueError, match="bogus_key"):
        eqtrack.simulate(REPO / "scenarios" / "seed.toml", bogus_key=1)


def test_a_bad_value_and_a_missing_file_raise_the_cli_message(plant_sim, tmp_path):
    text = eqtrack.builtin_scenario("seed").replace("control_period = 0.01", "control_period = -0.01")
    assert text != eqtrack.builtin_scenario("seed")
    bad, message = _cli_error(plant_sim, tmp_path, text)
    with pytest.raises(ValueError) as e:
        eqtrack.simulate(bad)
    assert str(e.value) == message
    missing = tmp_path / "missing.toml"
    code, _, err = cli(plant_sim, "sim", "--scenario", str(missing), "--out", str(tmp_path / "m"))
    assert code == 2
    with pytest.raises(ValueError) as e:
        eqtrack.simulate(str(missing))
    assert str(e.value) == err.strip().removeprefix("error: ")
    with pytest.raises(ValueError, match="law"):
        eqtrack.simulate(REPO / "scenarios" / "seed.toml", law="pid")
    with pytest.raises(ValueError, match="path or TOML"):
        eqtrack.simulate(42)


def test_to_pandas():
    import pandas as pd
    run = eqtrack.simulate(eqtrack.builtin_scenario("seed"), duration=0.5)
    df = run.to_pandas()
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns) == list(run.columns)
    assert np.array_equal(df["t"].to_numpy(), run.columns["t"])


def test_a_scenario_moved_with_the_world_flies_the_same_flight(plant_sim, tmp_path):
    """`plant_sim move` writes se3_circle moved (1000, -700, 300) m and turned by 0.7 rad
    about z; the package flies it as the original: every torque and error the same, the pose
    moved with the world (docs/invariance.md)."""
    src = REPO / "scenarios" / "se3_circle.toml"
    out = tmp_path / "moved"
    code, _, err = cli(
        plant_sim, "move", "--scenario", str(src), "--offset", "1000,-700,300", "--heading", "0.7", "--out", str(out)
    )
    assert code == 0, err
    here = eqtrack.simulate(src, duration=5.0)
    there = eqtrack.simulate(out / "se3_circle.toml", duration=5.0)
    for name in ["tau_0", "tau_4", "lyapunov", "attitude_error", "velocity_error"]:
        a, b = np.asarray(here.columns[name]), np.asarray(there.columns[name])
        assert np.max(np.abs(a - b) / (1.0 + np.abs(a))) < 1e-6, name
    c, s = np.cos(0.7), np.sin(0.7)
    x = c * np.asarray(here.columns["q_03"]) - s * np.asarray(here.columns["q_13"]) + 1000.0
    assert np.max(np.abs(x - np.asarray(there.columns["q_03"]))) < 1e-6
    # the comparison can fail: the unmoved pose is a kilometre from the moved one
    assert np.min(np.abs(np.asarray(here.columns["q_03"]) - np.asarray(there.columns["q_03"]))) > 100.0

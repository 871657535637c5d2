"""eqtrack.montecarlo equals plant_sim montecarlo's runs.csv, column for column."""

import pytest

import eqtrack
from conftest import cli, read_csv, same_bits


def check(cols, csv_cols, header):
    assert list(cols) == header
    for name in header:
        if name == "law":
            assert list(cols[name]) == list(csv_cols[name])
        else:
            assert same_bits(cols[name], csv_cols[name]), f"column {name} differs"


def test_the_local_engine_equals_the_cli(plant_sim, tmp_path):
    code, _, err = cli(plant_sim, "montecarlo", "--runs", "200", "--seed", "1", "--out", str(tmp_path))
    assert code == 0, err
    header, csv_cols = read_csv(tmp_path / "runs.csv")
    cols = eqtrack.montecarlo(runs=200, seed=1)
    check(cols, csv_cols, header)
    assert len(cols["run"]) == 800
    one = eqtrack.montecarlo(runs=20, seed=3, laws=("gt",), threads=1)
    assert set(one["law"]) == {"gt"}


def test_bad_study_inputs_raise(plant_sim):
    with pytest.raises(ValueError, match="`pid` is not a law"):
        eqtrack.montecarlo(runs=2, laws=("pid",))
    with pytest.raises(ValueError, match="runs: must be at least 1"):
        eqtrack.montecarlo(runs=0)
    with pytest.raises(ValueError, match="engine: 'spark' is not an engine"):
        eqtrack.montecarlo(runs=2, engine="spark")
    with pytest.raises(ValueError, match="unknown option"):
        eqtrack.montecarlo(runs=2, workers=3)
    with pytest.raises(ValueError, match="defined on so3"):
        eqtrack.montecarlo(scenario=eqtrack.builtin_scenario("se3_circle"), runs=2)

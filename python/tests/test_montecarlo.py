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


def test_the_gil_is_released_while_rust_works():
    import threading
    import time

    started, done = threading.Event(), threading.Event()
    ticks = 0

    def study():
        started.set()
        eqtrack.montecarlo(runs=200, seed=1, threads=1)  # about 1.4 s of Rust on one thread
        done.set()

    t = threading.Thread(target=study)
    t.start()
    started.wait()
    t0 = time.perf_counter()
    # Python keeps running beside the study: with the GIL held, this thread would wait
    # until the study returned and count almost nothing
    while not done.is_set():
        ticks += 1
    elapsed = time.perf_counter() - t0
    t.join()
    assert elapsed > 0.3, f"the study took only {elapsed:.2f} s: too short to tell"
    assert ticks > 1_000_000, f"the main thread ran only {ticks} times in {elapsed:.2f} s"


def test_garbage_shards_are_refused_never_a_crash():
    import os
    import random

    from eqtrack import _native

    good = _native.montecarlo_shard(None, 4, 1, ["eqt"], 0, 2)
    other = _native.montecarlo_shard(None, 4, 1, ["eqt"], 1, 2)
    merged = _native.montecarlo_merge(None, 4, 1, ["eqt"], [other, good])
    assert list(merged["run"]) == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="shard 1 of 2 is missing"):
        _native.montecarlo_merge(None, 4, 1, ["eqt"], [good])
    with pytest.raises(ValueError, match="another study"):
        _native.montecarlo_merge(None, 5, 1, ["eqt"], [good, other])
    rng = random.Random(7)
    for _ in range(300):
        b = bytearray(good)
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(b))
            b[i] = rng.randrange(256)
        if rng.random() < 0.3:
            b = b[: rng.randrange(len(b))]
        try:
            _native.montecarlo_merge(None, 4, 1, ["eqt"], [bytes(b), other])
        except ValueError:
            pass
    for n in (0, 1, 7, 64, 4096):
        with pytest.raises(ValueError):
            _native.montecarlo_merge(None, 4, 1, ["eqt"], [os.urandom(n), other])
    with pytest.raises(ValueError, match="I must be less than N"):
        _native.montecarlo_shard(None, 4, 1, ["eqt"], 2, 2)


def test_odd_overrides_are_refused_with_a_message():
    with pytest.raises(ValueError, match="cannot be written as TOML"):
        eqtrack.simulate(eqtrack.builtin_scenario("seed"), duration=object())
    with pytest.raises(ValueError, match="integer out of range"):
        eqtrack.simulate(eqtrack.builtin_scenario("seed"), plant_substeps=2**70)
    with pytest.raises(ValueError):
        eqtrack.simulate(eqtrack.builtin_scenario("seed"), controller=[1, 2])
    with pytest.raises(ValueError):
        eqtrack.simulate(eqtrack.builtin_scenario("seed"), controller={"kp": float("nan")})
    with pytest.raises(ValueError):
        eqtrack.montecarlo(runs=2, overrides={"duration": -1.0})

//! The example plant against the real `controller_node`, in lockstep: its trajectory is
//! `plant_sim sim`'s bit for bit (the public API is complete), and a plant that sends no
//! scenario fingerprint is accepted.

use pair_tests::{Csv, Proc, TempDir, run, serial};
use std::path::Path;
use std::time::Duration;

/// One comparison: the example plant (`group`, `estimator` variant) against
/// `controller_node --builtin <builtin>` for `seconds`, and `plant_sim sim` of `source`.
struct Case<'a> {
    group: &'a str,
    source: &'a [&'a str],
    builtin: &'a str,
    seconds: &'a str,
    n: usize,
    m: usize,
    estimator: &'a str,
}

/// The truth-fed example on a built-in scenario.
fn builtin<'a>(group: &'a str, builtin: &'a str, seconds: &'a str, n: usize, m: usize) -> Case<'a> {
    Case {
        group,
        source: &[],
        builtin,
        seconds,
        n,
        m,
        estimator: "truth",
    }
}

/// Runs the case, the simulation writing to `sim`, and compares every Q, V and τ entry of the
/// example's output with the simulation's trajectory, bit for bit.
fn example_matches_sim(sim: &str, c: &Case) {
    let Case {
        group,
        builtin,
        seconds,
        n,
        m,
        estimator,
        ..
    } = *c;
    let source: Vec<&str> = if c.source.is_empty() {
        vec!["--builtin", builtin]
    } else {
        c.source.to_vec()
    };
    let _g = serial();
    let mut args = vec!["sim", "--out", sim];
    args.extend_from_slice(&source);
    let (code, out) = run("plant_sim", &args, Duration::from_secs(120));
    assert_eq!(code, 0, "{out}");
    let reference = Csv::read(&Path::new(sim).join("trajectory.csv"));
    let name = format!("t-example-{group}");
    // a built-in scenario by name, or the scenario file the simulation flies
    let by_name = ["--builtin", builtin];
    let mut ctl_args = vec!["--name", &name];
    ctl_args.extend_from_slice(if builtin.is_empty() {
        &source
    } else {
        &by_name
    });
    let mut ctl = Proc::start("controller_node", &ctl_args);
    let mut plant = Proc::start_path(
        Path::new(env!("CARGO_BIN_EXE_example_plant")),
        &[&name, group, "lockstep", seconds, estimator],
    );
    let status = plant.wait_timeout(Duration::from_secs(120));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", plant.output());
    let ctl_status = ctl.wait_timeout(Duration::from_secs(5));
    assert_eq!(
        ctl_status.and_then(|s| s.code()),
        Some(0),
        "{}",
        ctl.output()
    );
    let lines = plant.stdout_lines();
    let steps = (seconds.parse::<f64>().unwrap() / 0.01).round() as usize;
    assert_eq!(lines.len(), steps + 1, "one line per tick");
    let mut cols: Vec<String> = Vec::new();
    cols.extend((0..n).flat_map(|i| (0..n).map(move |j| format!("q_{i}{j}"))));
    cols.extend((0..m).map(|i| format!("v_{i}")));
    cols.extend((0..m).map(|i| format!("tau_{i}")));
    let expected: Vec<Vec<f64>> = cols.iter().map(|c| reference.col(c)).collect();
    for (k, line) in lines.iter().enumerate() {
        let cells: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(cells[0] as usize, k);
        assert_eq!(*cells.last().unwrap(), 0.0, "tick {k}: every command fresh");
        for (c, col) in cols.iter().enumerate() {
            let (got, want) = (cells[2 + c], expected[c][k]);
            assert_eq!(
                got.to_bits(),
                want.to_bits(),
                "tick {k}, {col}: example {got:e} vs sim {want:e}"
            );
        }
    }
}

#[test]
fn the_example_plant_flies_the_spacecraft_through_its_thrusters_bit_for_bit() {
    let d = TempDir::new("example-spacecraft");
    let scenario = pair_tests::repo("scenarios/spacecraft.toml");
    let source = ["--scenario", scenario.to_str().unwrap()];
    let case = Case {
        group: "spacecraft",
        source: &source,
        builtin: "",
        seconds: "20",
        n: 3,
        m: 3,
        estimator: "truth",
    };
    example_matches_sim(&d.join("sim"), &case);
}

#[test]
fn the_example_plant_reproduces_the_seed_simulation_bit_for_bit() {
    let d = TempDir::new("example-so3");
    example_matches_sim(&d.join("sim"), &builtin("so3", "seed", "20", 3, 3));
}

#[test]
fn the_example_plant_reproduces_the_se3_simulation_bit_for_bit() {
    let d = TempDir::new("example-se3");
    example_matches_sim(&d.join("sim"), &builtin("se3", "se3_circle", "10", 4, 6));
}

#[test]
fn the_example_plant_with_its_complementary_filter_reproduces_the_simulation_bit_for_bit() {
    // the seed scenario with the example's exact IMU and filter as [sensors] and [estimator]
    let seed = include_str!("../../scenarios/seed.toml");
    let d = TempDir::new("example-cf");
    let scenario = d.join("seed_cf.toml");
    std::fs::write(
        &scenario,
        format!(
            "{seed}\n[sensors]\ndirections = [ {{ world = [0.0, 0.0, 1.0] }}, {{ world = [1.0, 0.0, 0.0] }} ]\n\
             [estimator]\nkind = \"complementary\"\nkp = 1.0\nki = 0.3\nweights = [1.0, 1.0]\n"
        ),
    )
    .unwrap();
    let source = ["--scenario", scenario.as_str()];
    let case = Case {
        source: &source,
        estimator: "complementary",
        ..builtin("so3", "seed", "20", 3, 3)
    };
    example_matches_sim(&d.join("sim"), &case);
    // the filter's estimate is what the controller saw: the run differs from the truth-fed one
    let (code, out) = run(
        "plant_sim",
        &["sim", "--builtin", "seed", "--out", &d.join("truth")],
        Duration::from_secs(120),
    );
    assert_eq!(code, 0, "{out}");
    let truth = Csv::read(&Path::new(&d.join("truth")).join("trajectory.csv")).col("tau_0");
    let cf = Csv::read(&Path::new(&d.join("sim")).join("trajectory.csv")).col("tau_0");
    assert!(truth.iter().zip(&cf).any(|(a, b)| a != b));
}

#[test]
fn the_example_plant_with_its_equivariant_filter_reproduces_the_simulation_bit_for_bit() {
    // the seed scenario with the example's exact IMU and its EqF's noise model
    let seed = include_str!("../../scenarios/seed.toml");
    let d = TempDir::new("example-eqf");
    let scenario = d.join("seed_eqf.toml");
    std::fs::write(
        &scenario,
        format!(
            "{seed}\n[sensors]\ndirections = [ {{ world = [0.0, 0.0, 1.0] }}, {{ world = [1.0, 0.0, 0.0] }} ]\n\
             [estimator]\nkind = \"eqf\"\ngyro_noise = 0.002\nbias_walk = 1e-5\ndirection_noise = [0.01, 0.01]\n"
        ),
    )
    .unwrap();
    let source = ["--scenario", scenario.as_str()];
    let case = Case {
        source: &source,
        estimator: "eqf",
        ..builtin("so3", "seed", "20", 3, 3)
    };
    example_matches_sim(&d.join("sim"), &case);
}

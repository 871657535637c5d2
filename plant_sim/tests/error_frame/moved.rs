//! Moved flights (docs/maths.md, "World-frame invariance"): a scenario moved about a kilometre
//! and turned about z — its initial pose, its reference, its waypoint file — flies the same
//! flight with the default `error_frame = "reference"`. The pose columns of `trajectory.csv`
//! move with the world; every other column is unchanged.

use crate::common::{ok, run};
use eqtrack_controller::group::{MatrixLieGroup, So3};
use nalgebra::{Matrix3, Matrix4, Vector3};
use pair_tests::{read_csv, repo};
use scenario::moving::{WorldMotion, move_scenario};
use std::path::Path;

/// A motion of the world: a turn about z and a translation.
type Motion = (Matrix3<f64>, Vector3<f64>);

/// The world's motion of the moved flights: a turn by 0.7 rad about z and a translation of
/// about 1.26 km.
fn kilometre() -> Motion {
    (
        So3::exp(&Vector3::new(0.0, 0.0, 0.7)),
        Vector3::new(1000.0, -700.0, 300.0),
    )
}

/// The motion as `plant_sim move` takes it: the heading of the turn about z, and the shift.
fn world(m: &Motion) -> WorldMotion {
    let (rt, t) = m;
    WorldMotion {
        heading: rt[(1, 0)].atan2(rt[(0, 0)]),
        offset: [t[0], t[1], t[2]],
    }
}

/// `plant_sim sim` of a scenario file; its trajectory.csv.
fn fly(file: &Path, out: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    ok(&run(&[
        "sim",
        "--scenario",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    let (h, rows) = read_csv(&out.join("trajectory.csv"));
    let rows = rows
        .iter()
        .map(|r| r.iter().map(|x| x.parse().unwrap_or(f64::NAN)).collect())
        .collect();
    (h, rows)
}

/// Flies `text` as it is and moved by `m`; compares the two trajectories row by row: the
/// largest difference, relative to 1 + |value|, of the pose from the first pose moved with the
/// world, and of every other column from its value in the first.
fn compare_moved(m: &Motion, name: &str, text: &str, waypoints: Option<&str>) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let (here, there) = (dir.path().join("here"), dir.path().join("there"));
    std::fs::create_dir_all(&here).unwrap();
    std::fs::create_dir_all(&there).unwrap();
    std::fs::write(here.join("s.toml"), text).unwrap();
    if let Some(w) = waypoints {
        std::fs::copy(repo(&format!("scenarios/{w}")), here.join(w)).unwrap();
    }
    // the scenario and its waypoint file moved as `plant_sim move` moves them
    let moved = move_scenario(text, name, Some(&here), &world(m)).unwrap();
    moved.write(&there, "s.toml").unwrap();
    let (h, a) = fly(&here.join("s.toml"), &dir.path().join("out-here"));
    let (h2, b) = fly(&there.join("s.toml"), &dir.path().join("out-there"));
    assert_eq!(h, h2);
    assert_eq!(a.len(), b.len());
    let (rt, t) = m;
    let mut tm = Matrix4::identity();
    tm.fixed_view_mut::<3, 3>(0, 0).copy_from(rt);
    tm.fixed_view_mut::<3, 1>(0, 3).copy_from(t);
    let qcol = |name: &str| h.iter().position(|c| c == name);
    let q_at = |row: &[f64]| Matrix4::from_fn(|i, j| row[qcol(&format!("q_{i}{j}")).unwrap()]);
    let mut worst = 0.0f64;
    for (ra, rb) in a.iter().zip(&b) {
        // the pose moved with the world
        let expected = tm * q_at(ra);
        let got = q_at(rb);
        worst = worst.max((got - expected).norm() / (1.0 + expected.norm()));
        for (c, col) in h.iter().enumerate() {
            if col.starts_with("q_") {
                continue;
            }
            if ra[c].is_nan() && rb[c].is_nan() {
                continue; // an empty cell in both
            }
            let d = (ra[c] - rb[c]).abs() / (1.0 + ra[c].abs());
            worst = worst.max(d);
        }
    }
    eprintln!("{name}: largest difference {worst:e}");
    worst
}

#[test]
fn se3_circle_flies_the_same_flight_a_kilometre_away_and_turned() {
    let text = std::fs::read_to_string(repo("scenarios/se3_circle.toml")).unwrap();
    let worst = compare_moved(&kilometre(), "se3_circle", &text, None);
    assert!(worst <= 1e-6, "se3_circle: the flight changed by {worst:e}");
}

#[test]
fn slew_se3_flies_the_same_flight_a_kilometre_away_and_turned() {
    let text = std::fs::read_to_string(repo("scenarios/slew_se3.toml")).unwrap();
    let worst = compare_moved(&kilometre(), "slew_se3", &text, Some("slew_se3.csv"));
    assert!(worst <= 1e-6, "slew_se3: the flight changed by {worst:e}");
}

#[test]
fn a_set_point_hold_flies_the_same_flight_a_kilometre_away_and_turned() {
    let circle = std::fs::read_to_string(repo("scenarios/se3_circle.toml")).unwrap();
    let head = &circle[..circle.find("[reference]").unwrap()];
    let text = format!(
        "{head}[reference]\nsetpoint = {{ rotation = [0.2, -0.4, 0.3], position = [1.0, 2.0, 0.5] }}\n"
    )
    .replace("duration = 60.0", "duration = 20.0");
    let worst = compare_moved(&kilometre(), "set-point", &text, None);
    assert!(worst <= 1e-6, "set-point: the flight changed by {worst:e}");
}

/// The same comparison catches the papers' form, which flies a different flight when the
/// world is moved only 3 m and turned (near enough to the origin for its run to finish): the
/// comparison above can fail.
#[test]
fn with_error_frame_world_the_moved_flight_differs() {
    let text = std::fs::read_to_string(repo("scenarios/se3_circle.toml"))
        .unwrap()
        .replace("[controller]", "[controller]\nerror_frame = \"world\"")
        .replace("duration = 60.0", "duration = 10.0");
    let m = (
        So3::exp(&Vector3::new(0.0, 0.0, 0.7)),
        Vector3::new(2.0, -2.0, 1.0),
    );
    let worst = compare_moved(&m, "se3_circle, world", &text, None);
    assert!(
        worst > 1e-2,
        "the world-frame law flew the same flight moved 3 m: {worst:e}"
    );
    // and the default law, on the same motion, does not
    let text = text.replace("[controller]\nerror_frame = \"world\"", "[controller]");
    let worst = compare_moved(&m, "se3_circle", &text, None);
    assert!(worst <= 1e-6, "{worst:e}");
}

/// `error_frame = "world"` on SE(3) warns, once, where its damping under the zero-order hold
/// stops being stable: `se3_circle` (h = 10 ms, K_d = 1.5) 15 m from the origin from the start,
/// and not at the origin; the law at the reference never warns.
#[test]
fn the_world_form_warns_where_its_damping_loses_stability() {
    let circle = std::fs::read_to_string(repo("scenarios/se3_circle.toml")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let fly = |name: &str, text: String| {
        let file = dir.path().join(format!("{name}.toml"));
        std::fs::write(&file, text).unwrap();
        let out = run(&[
            "sim",
            "--scenario",
            file.to_str().unwrap(),
            "--out",
            dir.path().join(name).to_str().unwrap(),
        ]);
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let world = circle.replace("[controller]", "[controller]\nerror_frame = \"world\"");
    let far = |text: &str| {
        text.replace("position = [0.0, 0.0, 0.0]", "position = [15.0, 0.0, 0.0]")
            .replace(
                "position = [2.0, -1.0, 1.2]",
                "position = [17.0, -1.0, 1.2]",
            )
            .replace("duration = 60.0", "duration = 2.0")
    };
    let warned = fly("world-far", far(&world));
    let lines: Vec<&str> = warned
        .lines()
        .filter(|l| l.starts_with("warning:"))
        .collect();
    assert_eq!(
        lines,
        [
            "warning: t = 0 s: the reference is 15.000 m from the world origin, where error_frame = \"world\" loses stability (see docs/maths.md); error_frame = \"reference\" does not depend on it"
        ],
        "{warned}"
    );
    let near = fly(
        "world-near",
        world.replace("duration = 60.0", "duration = 2.0"),
    );
    assert!(!near.contains("warning:"), "{near}");
    let reference = fly("reference-far", far(&circle));
    assert!(!reference.contains("warning:"), "{reference}");
}

/// The bound itself: `h·λ_max(I⁻¹ Ad_{Q_d}ᵀ K_d Ad_{Q_d}) < 2`, against an eigenvalue
/// computed directly, on `se3_circle`'s inertia and damping along the x axis.
#[test]
fn the_warning_bound_is_the_damping_eigenvalue() {
    use eqtrack_controller::group::Se3;
    use nalgebra::{SMatrix, SymmetricEigen};
    let inertia =
        SMatrix::<f64, 6, 6>::from_diagonal(&nalgebra::Vector6::new(0.8, 1.0, 1.2, 2.0, 2.0, 2.0));
    let kd = SMatrix::<f64, 6, 6>::identity() * 1.5;
    let h = 0.01;
    let mut flips = 0;
    let mut last = true;
    for i in 0..400 {
        let x = f64::from(i) * 0.05;
        let mut q = Matrix4::identity();
        q[(0, 3)] = x;
        let a = Se3::adjoint(&q);
        let s = inertia.map(|v| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 });
        let lambda = SymmetricEigen::new(s * a.transpose() * kd * a * s)
            .eigenvalues
            .max();
        let holds =
            eqtrack_controller::law::world_damping_holds::<Se3, f64, 4, 6>(&q, &inertia, &kd, h);
        assert_eq!(holds, h * lambda < 2.0, "x = {x}: λ_max = {lambda}");
        flips += usize::from(holds != last);
        last = holds;
    }
    assert_eq!(
        flips, 1,
        "the damping holds near the origin and fails far away"
    );
}

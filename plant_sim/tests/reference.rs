//! References as inputs, through the binary: `plant_sim reference` on the waypoint scenarios,
//! a start on the reference under zero-order hold, and bad waypoint files.

mod common;

use common::{run, text};
use std::path::{Path, PathBuf};
use std::process::Command;

use pair_tests::repo;

/// A fresh temporary directory (removed when dropped).
fn temp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

/// A CSV's header and rows, as numbers.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let (header, rows) = pair_tests::read_csv(path);
    let numbers = rows
        .iter()
        .map(|r| r.iter().map(|x| x.parse().unwrap()).collect())
        .collect();
    (header, numbers)
}

fn cols(header: &[String], rows: &[Vec<f64>], prefix: &str, count: usize) -> Vec<Vec<f64>> {
    let idx: Vec<usize> = (0..count)
        .map(|i| {
            let name = format!("{prefix}_{i}");
            header
                .iter()
                .position(|h| *h == name)
                .unwrap_or_else(|| panic!("no {name}"))
        })
        .collect();
    rows.iter()
        .map(|r| idx.iter().map(|j| r[*j]).collect())
        .collect()
}

/// `τ_d = I V̇_d − ad_{V_d}ᵀ I V_d` in every row of `reference.csv` (SO(3): `ad_V = V×`, so
/// `ad_Vᵀ I V = (I V) × V`; SE(3) with I = diag(J, m·1): the torque part `J ω̇ − (J ω) × ω −
/// (m v) × v`, the force part `m v̇ − (m v) × ω`).
#[test]
fn reference_csv_satisfies_the_euler_poincare_feedforward_on_both_groups() {
    let cross = |a: &[f64], b: &[f64]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    for (name, m) in [("slew_so3", 3), ("slew_se3", 6)] {
        let out_tmp = temp();
        let out = out_tmp.path().to_path_buf();
        let o = run(&[
            "reference",
            "--scenario",
            repo(&format!("scenarios/{name}.toml")).to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(out.join("reference.png").exists() && out.join("reference.svg").exists());
        let (h, rows) = read_csv(&out.join("reference.csv"));
        assert_eq!(rows.len(), 1601, "0 to 16 s at 0.01 s");
        let n = if m == 3 { 3 } else { 4 };
        assert_eq!(h.len(), 1 + n * n + 3 * m);
        let (v, a, tau) = (
            cols(&h, &rows, "vd", m),
            cols(&h, &rows, "vd_dot", m),
            cols(&h, &rows, "tau_d", m),
        );
        let j = [[0.824, 0.0, 0.12], [0.0, 1.135, 0.0], [0.12, 0.0, 1.759]];
        let (j, mass) = if m == 3 {
            (j, 0.0)
        } else {
            ([[0.8, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.2]], 2.0)
        };
        let mul = |x: &[f64]| -> [f64; 3] {
            std::array::from_fn(|r| (0..3).map(|c| j[r][c] * x[c]).sum())
        };
        let (mut worst, mut peak) = (0.0f64, 0.0f64);
        for k in 0..rows.len() {
            let (w, wd) = (&v[k][..3], &a[k][..3]);
            let jw = mul(w);
            let jwd = mul(wd);
            let c = cross(&jw, w);
            let mut want: Vec<f64> = (0..3).map(|i| jwd[i] - c[i]).collect();
            if m == 6 {
                let (u, ud) = (&v[k][3..], &a[k][3..]);
                let mu: Vec<f64> = u.iter().map(|x| mass * x).collect();
                let cu = cross(&mu, u);
                let cw = cross(&mu, w);
                for i in 0..3 {
                    want[i] -= cu[i];
                    want.push(0.0);
                }
                for i in 0..3 {
                    want[3 + i] = mass * ud[i] - cw[i];
                }
            }
            for i in 0..m {
                worst = worst.max((tau[k][i] - want[i]).abs());
                peak = peak.max(tau[k][i].abs());
            }
        }
        eprintln!("{name}: |τ_d − (I V̇_d − ad_Vᵀ I V_d)| ≤ {worst:e} (peak |τ_d| {peak})");
        assert!(peak > 0.5, "a real manoeuvre");
        assert!(worst < 1e-12 * peak.max(1.0), "{name}: {worst:e}");
    }
}

/// The largest attitude error of `slew_so3` started exactly on its reference (first
/// waypoint, at rest) at control period `h`, through the binary.
fn on_reference_error(h: f64) -> f64 {
    let d_tmp = temp();
    let d = d_tmp.path().to_path_buf();
    let toml = std::fs::read_to_string(repo("scenarios/slew_so3.toml"))
        .unwrap()
        .replace("rotation = [0.3, -0.3, 0.2]", "rotation = [0.0, 0.0, 0.0]")
        .replace("control_period = 0.01", &format!("control_period = {h}"))
        .replace(
            "waypoints = \"slew_so3.csv\"",
            &format!("waypoints = {:?}", repo("scenarios/slew_so3.csv")),
        );
    let file = d.join("onref.toml");
    std::fs::write(&file, toml).unwrap();
    let out = d.join("out");
    let o = run(&[
        "sim",
        "--scenario",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let (hd, rows) = read_csv(&out.join("trajectory.csv"));
    let j = hd.iter().position(|c| c == "attitude_error").unwrap();
    rows.iter().map(|r| r[j]).fold(0.0f64, f64::max)
}

/// Started on the reference, the loop stays within the zero-order hold's error: small, and
/// first order in the period (halving the period halves it), so it is the hold's and nothing
/// else's.
#[test]
fn a_start_on_the_waypoint_reference_stays_within_the_hold_error() {
    let (e1, e2) = (on_reference_error(0.01), on_reference_error(0.005));
    eprintln!(
        "start on the reference: largest attitude error {e1:e} rad at h = 0.01 s, {e2:e} at 0.005 s"
    );
    assert!(e1 < 1e-2, "left the reference by {e1:e} rad");
    let ratio = e1 / e2;
    assert!(
        (1.6..2.5).contains(&ratio),
        "error ratio {ratio} for h halved: not the hold's O(h)"
    );
}

/// Each bad waypoint file: exit 2, no panic, a message naming the file, line and column.
#[test]
fn bad_waypoint_files_name_file_line_and_column() {
    let d_tmp = temp();
    let d = d_tmp.path().to_path_buf();
    let cases = [
        (
            "unsorted",
            "t,rx,ry,rz\n0,0,0,0\n2,1,0,0\n1,0,1,0\n",
            "line 4, column 1 (`t`)",
        ),
        (
            "repeated",
            "t,rx,ry,rz\n0,0,0,0\n0,1,0,0\n",
            "line 3, column 1 (`t`)",
        ),
        (
            "nonfinite",
            "t,rx,ry,rz\n0,0,0,0\n1,0,nan,0\n",
            "line 3, column 3 (`ry`)",
        ),
        ("columns", "t,rx,rz\n0,0,0\n", "line 1, column 3 (`ry`)"),
        ("short", "t,rx,ry,rz\n0,0,0\n", "line 2, column 4 (`rz`)"),
        (
            "notnumber",
            "t,rx,ry,rz\n0,x,0,0\n",
            "line 2, column 2 (`rx`)",
        ),
    ];
    let mut many = String::from("t,rx,ry,rz\n");
    for i in 0..40 {
        many.push_str(&format!("{i},0,0,0\n"));
    }
    let base = std::fs::read_to_string(repo("scenarios/slew_so3.toml")).unwrap();
    for (tag, csv, want) in cases
        .iter()
        .map(|(a, b, c)| (*a, b.to_string(), c.to_string()))
        .chain(std::iter::once((
            "many",
            many,
            "line 35, column 1 (`t`): too many waypoints".to_owned(),
        )))
    {
        std::fs::write(d.join(format!("{tag}.csv")), csv).unwrap();
        let file = d.join(format!("{tag}.toml"));
        std::fs::write(&file, base.replace("slew_so3.csv", &format!("{tag}.csv"))).unwrap();
        let o = run(&["reference", "--scenario", file.to_str().unwrap()]);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{tag}: {t}");
        assert!(!t.contains("panicked"), "{tag}: {t}");
        assert!(
            t.contains(&format!("{tag}.csv: {want}")),
            "{tag}: want `{want}` in {t}"
        );
    }
}

/// `slew_{group}` with `path = "through"` (and `extra` lines replaced in the scenario), its
/// waypoints from `csv` (default: the shipped file), written into a fresh directory.
fn through_scenario(
    group: &str,
    csv: Option<&str>,
    edits: &[(&str, &str)],
) -> (tempfile::TempDir, PathBuf) {
    let tmp = temp();
    let d = tmp.path();
    let name = format!("slew_{group}");
    let mut toml = std::fs::read_to_string(repo(&format!("scenarios/{name}.toml"))).unwrap();
    let waypoints = match csv {
        Some(text) => {
            std::fs::write(d.join("w.csv"), text).unwrap();
            "w.csv".to_owned()
        }
        None => repo(&format!("scenarios/{name}.csv")).display().to_string(),
    };
    let line = format!("waypoints = \"{name}.csv\"");
    assert!(toml.contains(&line));
    toml = toml.replace(
        &line,
        &format!("waypoints = {waypoints:?}\npath = \"through\""),
    );
    for (from, to) in edits {
        assert!(toml.contains(from), "template changed: {from}");
        toml = toml.replace(from, to);
    }
    let file = d.join("s.toml");
    std::fs::write(&file, toml).unwrap();
    (tmp, file)
}

#[test]
fn a_through_path_reference_satisfies_the_feedforward_and_never_stops_inside() {
    for group in ["so3", "se3"] {
        let (_tmp, file) = through_scenario(group, None, &[]);
        let out = file.parent().unwrap().join("out");
        let o = run(&[
            "reference",
            "--scenario",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("path = \"through\""), "{}", text(&o));
        let (h, rows) = read_csv(&out.join("reference.csv"));
        let m = if group == "so3" { 3 } else { 6 };
        let v = cols(&h, &rows, "vd", m);
        // moving at every interior waypoint (t = 4, 7, 10 s: rows 400, 700, 1000)
        for k in [400, 700, 1000] {
            let speed: f64 = v[k].iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!(speed > 0.05, "{group}: |V_d| = {speed} at row {k}");
        }
        // the feedforward: checked against the model's own algebra by the library test; here
        // `I V̇_d − ad_{V_d}ᵀ I V_d` recomputed from the CSV's columns on SO(3)
        if group == "so3" {
            let (a, tau) = (cols(&h, &rows, "vd_dot", 3), cols(&h, &rows, "tau_d", 3));
            let j = [[0.824, 0.0, 0.12], [0.0, 1.135, 0.0], [0.12, 0.0, 1.759]];
            let mul = |x: &[f64]| -> [f64; 3] {
                std::array::from_fn(|r| (0..3).map(|c| j[r][c] * x[c]).sum())
            };
            let mut worst = 0.0f64;
            for k in 0..rows.len() {
                let (jw, jwd) = (mul(&v[k]), mul(&a[k]));
                let w = &v[k];
                let c = [
                    jw[1] * w[2] - jw[2] * w[1],
                    jw[2] * w[0] - jw[0] * w[2],
                    jw[0] * w[1] - jw[1] * w[0],
                ];
                for i in 0..3 {
                    worst = worst.max((tau[k][i] - (jwd[i] - c[i])).abs());
                }
            }
            eprintln!("slew_so3 through: |τ_d − (I V̇_d − ad_Vᵀ I V_d)| ≤ {worst:e}");
            assert!(worst < 1e-12, "{worst:e}");
        }
        // the report exists and, with the 5 N·m limit, has no warning
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("reference.json")).unwrap())
                .unwrap();
        assert_eq!(json["warnings"].as_array().map(Vec::len), Some(0), "{json}");
        assert!(json["angular_speed"]["value"].as_f64().unwrap() > 0.3);
        assert_eq!(json["speed"].is_null(), group == "so3");
    }
}

/// One turn of `a` rad about z in `span` s, at rest at both ends: the quintic's peak
/// acceleration `a·10/(√3·span²)` at `σ = (3 − √3)/6`, and `τ_z = J_zz·α` there (about one
/// axis, `ω × Jω = 0` when J has z as a principal axis).
#[test]
fn the_feasibility_report_warns_on_the_right_axis_at_the_right_time() {
    // 1.5 rad about z between t = 1 and t = 2: peak α = 1.5·5.7735 = 8.66 rad/s² at
    // t = 1 + 0.2113 s; with J_zz = 1.759 the feedforward peaks at 15.2 N·m on z, x and y
    // need nothing (J's off-diagonal 0.12 couples x: τ_x = 0.12·α = 1.04 N·m).
    let csv = "t,rx,ry,rz\n1,0,0,0\n2,0,0,1.5\n";
    let strict_fail = |limit: &str| {
        let (_tmp, file) = through_scenario(
            "so3",
            Some(csv),
            &[
                ("torque_limit = 5.0", limit),
                ("duration = 16.0", "duration = 3.0"),
            ],
        );
        let out = file.parent().unwrap().join("out");
        let args = |strict: bool| {
            let mut a = vec![
                "reference".to_owned(),
                "--scenario".to_owned(),
                file.display().to_string(),
                "--out".to_owned(),
                out.display().to_string(),
            ];
            if strict {
                a.push("--strict".to_owned());
            }
            a
        };
        let plain = Command::new(env!("CARGO_BIN_EXE_plant_sim"))
            .args(args(false))
            .output()
            .unwrap();
        let strict = Command::new(env!("CARGO_BIN_EXE_plant_sim"))
            .args(args(true))
            .output()
            .unwrap();
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("reference.json")).unwrap())
                .unwrap();
        (plain, strict, json)
    };
    let (plain, strict, json) = strict_fail("torque_limit = 10.0");
    let t = text(&plain);
    assert_eq!(
        plain.status.code(),
        Some(0),
        "a warning, not a refusal: {t}"
    );
    assert_eq!(strict.status.code(), Some(1), "{}", text(&strict));
    assert!(text(&strict).contains("--strict"), "{}", text(&strict));
    let warnings = json["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{json}");
    let w = &warnings[0];
    assert_eq!(w["axis"], 2, "{json}");
    assert_eq!(w["limit"], 10.0);
    let alpha = 1.5 * 10.0 / 3f64.sqrt();
    let want_t = 1.0 + (3.0 - 3f64.sqrt()) / 6.0;
    let peak = w["peak"]["value"].as_f64().unwrap();
    let at = w["peak"]["t"].as_f64().unwrap();
    eprintln!(
        "warning: axis 2 peak {peak} at t = {at} (analytic {} at {want_t})",
        1.759 * alpha
    );
    assert!(
        (at - want_t).abs() <= 0.01,
        "peak at {at}, want {want_t} within one period"
    );
    assert!(
        (peak - 1.759 * alpha).abs() < 0.01 * 1.759 * alpha,
        "{peak}"
    );
    // the message names the axis, the time and both numbers
    assert!(
        t.contains("warning: axis 2 (τ_z): the feedforward alone needs |τ_z| = ")
            && t.contains(&format!("at t = {at:.4} s, above the torque limit 10")),
        "{t}"
    );
    // a feasible limit: no warning, exit 0 even with --strict
    let (plain, strict, json) = strict_fail("torque_limit = 20.0");
    assert_eq!(plain.status.code(), Some(0), "{}", text(&plain));
    assert_eq!(strict.status.code(), Some(0), "{}", text(&strict));
    assert!(!text(&plain).contains("warning"), "{}", text(&plain));
    assert_eq!(json["warnings"].as_array().map(Vec::len), Some(0));
}

#[test]
fn compare_paths_flies_the_waypoints_both_ways() {
    let out_tmp = temp();
    let out = out_tmp.path().to_path_buf();
    let o = run(&[
        "reference",
        "--scenario",
        repo("scenarios/slew_so3.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--compare-paths",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(out.join("paths.png").exists() && out.join("paths.svg").exists());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("paths.json")).unwrap()).unwrap();
    let speed = |i: usize| {
        json["reports"][i][1]["angular_speed"]["value"]
            .as_f64()
            .unwrap()
    };
    eprintln!("peak |ω_d|: stop {}, through {}", speed(0), speed(1));
    assert_eq!(json["reports"][0][0], "stop");
    assert_eq!(json["reports"][1][0], "through");
    // flying through needs less peak speed than stopping at every waypoint
    assert!(speed(1) < speed(0), "{json}");
    let o = run(&[
        "reference",
        "--builtin",
        "seed",
        "--out",
        out.to_str().unwrap(),
        "--compare-paths",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("has no `[reference] waypoints`"),
        "{}",
        text(&o)
    );
}

//! References as inputs, through the binary: `plant_sim reference` on the waypoint scenarios,
//! a start on the reference under zero-order hold, and bad waypoint files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_plant_sim"))
        .args(args)
        .output()
        .expect("plant_sim starts")
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

fn temp(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("eqtrack-ref-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// Columns of a CSV by name.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(str::to_owned).collect();
    let rows = r
        .records()
        .map(|rec| rec.unwrap().iter().map(|x| x.parse().unwrap()).collect())
        .collect();
    (header, rows)
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
        let out = temp(name);
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
    let d = temp(&format!("onref-{h}"));
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
    let d = temp("bad");
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

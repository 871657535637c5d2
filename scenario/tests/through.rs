//! `[reference] path` and the waypoint file's velocity columns: what is read, what is refused
//! (file, line, column or key named), and the fingerprint (unchanged for stop paths).

use scenario::{PathKind, Scenario};

use pair_tests::repo;

/// `slew_so3.toml` (or `slew_se3.toml`) with `extra` appended to `[reference]` and its
/// waypoints replaced by `csv`, in a fresh directory; loaded.
fn load(group: &str, tag: &str, extra: &str, csv: Option<&str>) -> Result<Scenario, String> {
    let _ = tag;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let name = format!("slew_{group}");
    let toml = std::fs::read_to_string(repo(&format!("scenarios/{name}.toml"))).unwrap();
    let waypoints = match csv {
        Some(text) => {
            std::fs::write(dir.join("w.csv"), text).unwrap();
            "w.csv".to_owned()
        }
        None => repo(&format!("scenarios/{name}.csv")).display().to_string(),
    };
    let toml = toml.replace(
        &format!("waypoints = \"{name}.csv\""),
        &format!("waypoints = {waypoints:?}\n{extra}"),
    );
    let file = dir.join("s.toml");
    std::fs::write(&file, toml).unwrap();
    Scenario::from_file(&file).map_err(|e| e.to_string())
}

#[test]
fn path_kind_and_velocity_columns_are_read() {
    let stop = load("so3", "default", "", None).unwrap();
    assert_eq!(stop.path.as_ref().unwrap().kind, PathKind::Stop);
    let explicit = load("so3", "explicit", "path = \"stop\"", None).unwrap();
    assert_eq!(explicit, stop);
    let through = load("so3", "through", "path = \"through\"", None).unwrap();
    assert_eq!(through.path.as_ref().unwrap().kind, PathKind::Through);
    assert!(
        through
            .path
            .as_ref()
            .unwrap()
            .velocities
            .iter()
            .all(Option::is_none)
    );
    let csv = "t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0,0.5,-0.25,0\n4,1,1,0,,,\n6,0,0,0,0,0,0\n";
    let s = load("so3", "given", "path = \"through\"", Some(csv)).unwrap();
    let p = s.path.as_ref().unwrap();
    assert_eq!(p.velocities[0], None);
    assert_eq!(p.velocities[1], Some(vec![0.5, -0.25, 0.0]));
    assert_eq!(p.velocities[3], Some(vec![0.0; 3]));
    assert_eq!(p.lines, vec![2, 3, 4, 5]);
    // the velocity given is the path's velocity at the waypoint
    let path = s.path::<eqtrack_controller::So3, 3, 3>().unwrap().unwrap();
    let v = path.sample(2.0).v;
    assert!(
        (v - nalgebra::Vector3::new(0.5, -0.25, 0.0)).norm() < 1e-12,
        "{v}"
    );
    // SE(3): six velocity columns, angular then linear
    let csv = "t,rx,ry,rz,x,y,z,wx,wy,wz,vx,vy,vz\n0,0,0,0,0,0,0,,,,,,\n2,0,0,1,1,0,0,0,0,0.5,1,0,0\n4,0,0,0,2,0,0,,,,,,\n";
    let s = load("se3", "se3", "path = \"through\"", Some(csv)).unwrap();
    assert_eq!(
        s.path.as_ref().unwrap().velocities[1],
        Some(vec![0.0, 0.0, 0.5, 1.0, 0.0, 0.0])
    );
}

#[test]
fn bad_path_keys_and_velocity_columns_are_refused_naming_where() {
    let cases: [(&str, &str, &str, Option<&str>, &str); 13] = [
        // a velocity so large that the path overflows along the leg
        (
            "se3",
            "huge",
            "path = \"through\"",
            Some(
                "t,rx,ry,rz,x,y,z,wx,wy,wz,vx,vy,vz\n0,0,0,0,0,0,0,,,,,,\n1,0,0,1.5,1,0,0,0,0,0.5,1,0,1e168\n2,0,0,3,2,1,0,,,,,,\n",
            ),
            "w.csv: line 3, column 1 (`t`): the path between t = 0 s and t = 1 s is not finite",
        ),
        (
            "so3",
            "kind",
            "path = \"curvy\"",
            None,
            "key `reference.path`: unknown path kind `curvy`",
        ),
        ("so3", "number", "path = 3", None, "path"),
        (
            "so3",
            "stopvel",
            "",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0,0.5,0,0\n4,0,0,0,,,\n"),
            "w.csv: line 3, column 5 (`wx`): a velocity is honoured only with `path = \"through\"`",
        ),
        (
            "so3",
            "firstmoves",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,0,0.1,0\n2,1,0,0,,,\n"),
            "w.csv: line 2, column 6 (`wy`): the first waypoint must be at rest",
        ),
        (
            "so3",
            "lastmoves",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0,0,0,-1\n"),
            "w.csv: line 3, column 7 (`wz`): the last waypoint must be at rest",
        ),
        (
            "so3",
            "partial",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0,0.5,,0\n4,0,0,0,,,\n"),
            "w.csv: line 3, column 6 (`wy`): empty while other velocity columns",
        ),
        (
            "so3",
            "nan",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0,0.5,nan,0\n4,0,0,0,,,\n"),
            "w.csv: line 3, column 6 (`wy`): `nan` is not a finite number",
        ),
        (
            "so3",
            "header",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wz\n0,0,0,0,,\n"),
            "w.csv: line 1, column 6 (`wy`)",
        ),
        (
            "se3",
            "se3header",
            "path = \"through\"",
            Some("t,rx,ry,rz,x,y,z,wx,wy,wz\n0,0,0,0,0,0,0,,,\n"),
            "w.csv: line 1, column 11 (`vx`)",
        ),
        (
            "so3",
            "fields",
            "path = \"through\"",
            Some("t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n2,1,0,0\n"),
            "w.csv: line 3, column 5 (`wx`): expected 7 values, found 4",
        ),
        // the case: 1 rad between t = 1.0 and the next double, on either kind
        (
            "so3",
            "tinyleg",
            "",
            Some("t,rx,ry,rz\n0,0,0,0\n1.0,0,0,0\n1.0000000000000002,1,0,0\n3,1,0,0\n"),
            "w.csv: line 4, column 1 (`t`): the leg from t = 1 s to t = 1.0000000000000002 s lasts 2.220446049250313e-16 s, shorter than the control period 0.01 s",
        ),
        (
            "so3",
            "tinyleg2",
            "path = \"through\"",
            Some("t,rx,ry,rz\n0,0,0,0\n1.0,0,0,0\n1.005,1,0,0\n3,1,0,0\n"),
            "w.csv: line 4, column 1 (`t`): the leg from t = 1 s to t = 1.005 s",
        ),
    ];
    for (group, tag, extra, csv, want) in cases {
        let e = load(group, tag, extra, csv).unwrap_err();
        assert!(e.contains(want), "{tag}: want `{want}` in `{e}`");
    }
    // a set-point has no waypoints to pass
    let seed = include_str!("../../scenarios/seed.toml");
    let at = seed.find("[reference]").unwrap();
    let text = format!(
        "{}[reference]\nsetpoint = {{ rotation = [0.0, 0.0, 1.0] }}\npath = \"through\"\n",
        &seed[..at]
    );
    let e = Scenario::from_toml(&text, "sp", "sp")
        .unwrap_err()
        .to_string();
    assert!(e.contains("key `reference.path`: applies to"), "{e}");
}

#[test]
fn stop_paths_keep_their_fingerprint_and_through_paths_have_their_own() {
    let stop = load("so3", "fp-stop", "", None).unwrap();
    let explicit = load("so3", "fp-explicit", "path = \"stop\"", None).unwrap();
    let through = load("so3", "fp-through", "path = \"through\"", None).unwrap();
    assert_eq!(stop.fingerprint(), explicit.fingerprint());
    assert_ne!(stop.fingerprint(), through.fingerprint());
    let csv = std::fs::read_to_string(repo("scenarios/slew_so3.csv")).unwrap();
    let given = csv
        .replace("t,rx,ry,rz", "t,rx,ry,rz,wx,wy,wz")
        .lines()
        .enumerate()
        .map(|(i, l)| match i {
            0 => l.to_owned(),
            2 => format!("{l},0,0,0.3"),
            _ => format!("{l},,,"),
        })
        .collect::<Vec<_>>()
        .join("\n");
    let with = load("so3", "fp-given", "path = \"through\"", Some(&given)).unwrap();
    assert_ne!(with.fingerprint(), through.fingerprint());
}

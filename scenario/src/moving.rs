//! Moving a scenario with the world (docs/invariance.md): the same task written in a world
//! frame that is turned by a heading about the vertical and shifted by an offset. Every
//! quantity the scenario gives in world axes or at a world position moves with it:
//!
//! - poses (`[initial]` and `[reference]` `rotation` and `position`, the set-point, every
//!   waypoint of the waypoint file): `(R, x) ↦ (R_T R, R_T x + t)`;
//! - world directions and world wrenches (`[sensors] directions[].world`,
//!   `[plant] disturbance_world`, `[estimator] initial_attitude` as a rotation, the `value` of
//!   a position fix's `[[sensors.fault]]` bias): turned by `R_T`;
//! - body quantities (velocities, feedforward, body disturbances, the vehicle) and the
//!   vertical (gravity, buoyancy, the accelerometer's "up") are unchanged: the turn is about
//!   the vertical.
//!
//! A moved scenario flies the same flight as the original with the default
//! `error_frame = "reference"`: its pose columns move with the world and every other column
//! is unchanged. Noise drawn in world axes (position fixes) is drawn in the new axes, so a
//! scenario with position fixes flies the same flight only when it is moved without a turn.

use crate::{ScenarioError, waypoints};
use eqtrack_controller::GroupKind;
use eqtrack_controller::group::{MatrixLieGroup, So3};
use nalgebra::{Matrix3, Vector3};
use std::path::{Path, PathBuf};
use toml::{Table, Value};

/// A motion of the world frame: a turn by `heading` (rad) about the vertical `z`, then a
/// shift by `offset` (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldMotion {
    /// The turn about `z` (rad).
    pub heading: f64,
    /// The shift (m, in the new world axes).
    pub offset: [f64; 3],
}

impl WorldMotion {
    /// The turn `R_T`.
    pub fn rotation(&self) -> Matrix3<f64> {
        So3::exp(&Vector3::new(0.0, 0.0, self.heading))
    }

    /// A direction or a world-axes vector turned: `R_T v`.
    pub fn turn(&self, v: [f64; 3]) -> [f64; 3] {
        let w = self.rotation() * Vector3::from(v);
        [w[0], w[1], w[2]]
    }

    /// A position moved: `R_T x + t`.
    pub fn place(&self, x: [f64; 3]) -> [f64; 3] {
        let w = self.turn(x);
        [
            w[0] + self.offset[0],
            w[1] + self.offset[1],
            w[2] + self.offset[2],
        ]
    }

    /// An attitude given as a rotation vector turned: `log(R_T exp(r))` (without a turn, `r`
    /// itself, to the bit).
    pub fn rotate(&self, r: [f64; 3]) -> [f64; 3] {
        if self.heading == 0.0 {
            return r;
        }
        let w = So3::log(&(self.rotation() * So3::exp(&Vector3::from(r))));
        [w[0], w[1], w[2]]
    }

    /// Whether this is the identity (no turn, no shift).
    pub fn is_identity(&self) -> bool {
        self.heading == 0.0 && self.offset == [0.0; 3]
    }
}

/// A scenario moved with the world: its text and its moved waypoint file, if it has one.
#[derive(Debug, Clone, PartialEq)]
pub struct MovedScenario {
    /// The moved scenario's TOML.
    pub text: String,
    /// The moved waypoint file's name (the original's file name; the moved scenario names it
    /// so, to be written beside it) and its text.
    pub waypoints: Option<(String, String)>,
}

impl MovedScenario {
    /// Writes the scenario to `dir/<file_name>` and its waypoint file beside it (under the
    /// name the scenario gives); returns the scenario's path.
    pub fn write(&self, dir: &Path, file_name: &str) -> Result<PathBuf, ScenarioError> {
        let io = |path: &Path| {
            let path = path.display().to_string();
            move |source| ScenarioError::Io { path, source }
        };
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        if let Some((name, text)) = &self.waypoints {
            let path = dir.join(name);
            if let Some(parent) = path.parent() {
                std::fs::create_dir_all(parent).map_err(io(parent))?;
            }
            std::fs::write(&path, text).map_err(io(&path))?;
        }
        let path = dir.join(file_name);
        std::fs::write(&path, &self.text).map_err(io(&path))?;
        Ok(path)
    }
}

fn invalid(origin: &str, key: &str, message: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        origin: origin.to_owned(),
        key: key.to_owned(),
        message: message.into(),
    }
}

/// The numbers at `table[key]` (whole numbers read as numbers, as the loader reads them), if
/// the key is there; refused naming the key when it is not a list of `len` numbers (`len`
/// 0: any multiple of 3).
fn numbers(
    origin: &str,
    table: &Table,
    prefix: &str,
    key: &str,
    len: usize,
) -> Result<Option<Vec<f64>>, ScenarioError> {
    let Some(v) = table.get(key) else {
        return Ok(None);
    };
    let name = format!("{prefix}{key}");
    let what = if len == 0 {
        "a list of 3 or 6 numbers".to_owned()
    } else {
        format!("a list of {len} numbers")
    };
    let xs: Option<Vec<f64>> = v.as_array().and_then(|list| {
        list.iter()
            .map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
            .collect()
    });
    match xs {
        Some(xs) if (len == 0 && !xs.is_empty() && xs.len() % 3 == 0) || xs.len() == len => {
            Ok(Some(xs))
        }
        _ => Err(invalid(origin, &name, format!("expected {what}"))),
    }
}

/// The three numbers at `table[key]`, if the key is there.
fn three(
    origin: &str,
    table: &Table,
    prefix: &str,
    key: &str,
) -> Result<Option<[f64; 3]>, ScenarioError> {
    Ok(numbers(origin, table, prefix, key, 3)?.map(|x| [x[0], x[1], x[2]]))
}

fn put(table: &mut Table, key: &str, xs: &[f64]) {
    table.insert(
        key.to_owned(),
        Value::Array(xs.iter().map(|x| Value::Float(*x)).collect()),
    );
}

/// Moves the pose `rotation` / `position` keys of `table`; on SE(2) the heading `[θ]` and the
/// planar position `[x, y]`: `(θ, x) ↦ (θ + h, R(h) x + t)`.
fn move_pose(
    m: &WorldMotion,
    origin: &str,
    table: &mut Table,
    prefix: &str,
    group: GroupKind,
) -> Result<(), ScenarioError> {
    if group == GroupKind::Se2 {
        if let Some(r) = numbers(origin, table, prefix, "rotation", 1)? {
            put(table, "rotation", &[r[0] + m.heading]);
        }
        if let Some(x) = numbers(origin, table, prefix, "position", 2)? {
            let p = m.place([x[0], x[1], 0.0]);
            put(table, "position", &[p[0], p[1]]);
        }
        return Ok(());
    }
    if let Some(r) = three(origin, table, prefix, "rotation")? {
        put(table, "rotation", &m.rotate(r));
    }
    if let Some(x) = three(origin, table, prefix, "position")? {
        put(table, "position", &m.place(x));
    }
    Ok(())
}

fn sub<'a>(table: &'a mut Table, key: &str) -> Option<&'a mut Table> {
    table.get_mut(key).and_then(Value::as_table_mut)
}

/// Moves a scenario's text with the world by `m` (the module's list says what moves).
/// `origin` names the scenario in errors and `base` is the folder its waypoint file is
/// relative to. The scenario is validated first, so a scenario that does not load is refused
/// with the loader's error; on SO(3) only a turn is accepted (it has no positions).
pub fn move_scenario(
    text: &str,
    origin: &str,
    base: Option<&Path>,
    m: &WorldMotion,
) -> Result<MovedScenario, ScenarioError> {
    for (i, x) in [m.heading, m.offset[0], m.offset[1], m.offset[2]]
        .iter()
        .enumerate()
    {
        if !x.is_finite() {
            let key = ["heading", "offset x", "offset y", "offset z"][i];
            return Err(invalid(origin, key, format!("must be finite (got {x})")));
        }
    }
    let scenario = crate::Scenario::from_toml_in(text, origin, origin, base)?;
    if scenario.group == GroupKind::Se2 && m.offset[2] != 0.0 {
        return Err(invalid(
            origin,
            "offset z",
            "an SE(2) scenario lives in the plane: it can be turned and shifted in x and y only (offset z 0)",
        ));
    }
    if scenario.group == GroupKind::So3 && m.offset != [0.0; 3] {
        return Err(invalid(
            origin,
            "offset",
            "an SO(3) scenario has no positions: it can only be turned (give a heading, offset 0,0,0)",
        ));
    }
    let mut doc: Table = text
        .parse()
        .map_err(|e: toml::de::Error| ScenarioError::Parse {
            origin: origin.to_owned(),
            message: e.to_string(),
        })?;
    let waypoint_file = move_table(&mut doc, origin, m, scenario.group)?;
    let waypoints = match waypoint_file {
        None => None,
        Some((file, name)) => {
            let path = base.map_or_else(|| PathBuf::from(&file), |b| b.join(&file));
            let csv = std::fs::read_to_string(&path).map_err(|source| ScenarioError::Io {
                path: path.display().to_string(),
                source,
            })?;
            let file = path.display().to_string();
            Some((name, move_waypoints(&csv, &file, scenario.group, m)?))
        }
    };
    let body = toml::to_string(&doc).map_err(|e| ScenarioError::Parse {
        origin: origin.to_owned(),
        message: e.to_string(),
    })?;
    let [x, y, z] = m.offset;
    let text = format!(
        "# {origin} moved with the world: turned by {:?} rad about z, shifted by ({x:?}, {y:?}, {z:?}) m\n{body}",
        m.heading
    );
    Ok(MovedScenario { text, waypoints })
}

/// Moves the world quantities of a scenario's table; returns its waypoint file as the scenario
/// gave it and the name the moved scenario gives it.
fn move_table(
    doc: &mut Table,
    origin: &str,
    m: &WorldMotion,
    group: GroupKind,
) -> Result<Option<(String, String)>, ScenarioError> {
    if let Some(t) = sub(doc, "initial") {
        move_pose(m, origin, t, "initial.", group)?;
    }
    let mut waypoint_file = None;
    if let Some(t) = sub(doc, "reference") {
        move_pose(m, origin, t, "reference.", group)?;
        if let Some(s) = sub(t, "setpoint") {
            move_pose(m, origin, s, "reference.setpoint.", group)?;
        }
        if let Some(file) = t
            .get("waypoints")
            .and_then(Value::as_str)
            .map(str::to_owned)
        {
            // the moved file is written beside the moved scenario, under its own name only:
            // never over the original, wherever the original's path points
            let name = Path::new(&file).file_name().map_or_else(
                || "waypoints.csv".to_owned(),
                |n| n.to_string_lossy().into_owned(),
            );
            t.insert("waypoints".to_owned(), Value::String(name.clone()));
            waypoint_file = Some((file, name));
        }
    }
    if group == GroupKind::Se2 {
        // (τ, f_x, f_y): the torque about z stays, the force turns
        if let Some(t) = sub(doc, "plant")
            && let Some(xs) = numbers(origin, t, "plant.", "disturbance_world", 3)?
        {
            let f = m.turn([xs[1], xs[2], 0.0]);
            put(t, "disturbance_world", &[xs[0], f[0], f[1]]);
        }
        return Ok(waypoint_file);
    }
    if let Some(t) = sub(doc, "plant")
        && let Some(xs) = numbers(origin, t, "plant.", "disturbance_world", 0)?
    {
        let turned: Vec<f64> = xs
            .chunks_exact(3)
            .flat_map(|c| m.turn([c[0], c[1], c[2]]))
            .collect();
        put(t, "disturbance_world", &turned);
    }
    if let Some(t) = sub(doc, "sensors")
        && let Some(ds) = t.get_mut("directions").and_then(Value::as_array_mut)
    {
        for (j, d) in ds.iter_mut().enumerate() {
            if let Some(d) = d.as_table_mut()
                && let Some(w) = three(origin, d, &format!("sensors.directions[{j}]."), "world")?
            {
                put(d, "world", &m.turn(w));
            }
        }
    }
    // a position fix's bias is in world axes; every other sensor's is in body axes
    if let Some(t) = sub(doc, "sensors")
        && let Some(fs) = t.get_mut("fault").and_then(Value::as_array_mut)
    {
        for (j, f) in fs.iter_mut().enumerate() {
            if let Some(f) = f.as_table_mut()
                && f.get("sensor").and_then(Value::as_str) == Some("position")
                && let Some(v) = three(origin, f, &format!("sensors.fault[{j}]."), "value")?
            {
                put(f, "value", &m.turn(v));
            }
        }
    }
    if let Some(t) = sub(doc, "estimator")
        && let Some(r) = three(origin, t, "estimator.", "initial_attitude")?
    {
        put(t, "initial_attitude", &m.rotate(r));
    }
    Ok(waypoint_file)
}

/// A waypoint file moved with the world, read as the loader reads it
/// ([`waypoints::parse`]; `file` names it in errors): each pose moved, the times and the
/// optional body velocities as they were (a velocity left to be chosen stays empty).
pub fn move_waypoints(
    text: &str,
    file: &str,
    group: GroupKind,
    m: &WorldMotion,
) -> Result<String, ScenarioError> {
    let spec = waypoints::parse(text, file, group)?;
    let se3 = group == GroupKind::Se3;
    let speeds = waypoints::velocity_header(group);
    let given = spec.velocities.iter().any(Option::is_some);
    let mut header: Vec<&str> = waypoints::header(group).to_vec();
    if given {
        header.extend(speeds);
    }
    let mut out = vec![header.join(",")];
    for ((t, pose), v) in spec.times.iter().zip(&spec.poses).zip(&spec.velocities) {
        let mut row: Vec<String> = vec![format!("{t:?}")];
        if group == GroupKind::Se2 {
            // the heading (stored as the rotation (0, 0, θ)) and the planar position
            let p = m.place(pose.position);
            row.extend([pose.rotation[2] + m.heading, p[0], p[1]].map(|x| format!("{x:?}")));
        } else {
            row.extend(m.rotate(pose.rotation).map(|x| format!("{x:?}")));
        }
        if se3 {
            row.extend(m.place(pose.position).map(|x| format!("{x:?}")));
        }
        if given {
            match v {
                Some(v) => row.extend(v.iter().map(|x| format!("{x:?}"))),
                None => row.extend(speeds.iter().map(|_| String::new())),
            }
        }
        out.push(row.join(","));
    }
    Ok(out.join("\n") + "\n")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Scenario;

    fn scenario_text(name: &str) -> String {
        std::fs::read_to_string(format!(
            "{}/../scenarios/{name}.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap()
    }

    fn dir() -> PathBuf {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"))
    }

    const KM: WorldMotion = WorldMotion {
        heading: 0.7,
        offset: [1000.0, -700.0, 300.0],
    };

    #[test]
    fn every_world_quantity_moves_and_every_body_quantity_stays() {
        let moved =
            move_scenario(&scenario_text("pil_hexarotor"), "pil", Some(&dir()), &KM).unwrap();
        let a = Scenario::from_toml_in(&scenario_text("pil_hexarotor"), "a", "a", Some(&dir()))
            .unwrap();
        let b = Scenario::from_toml_in(&moved.text, "b", "b", Some(&dir())).unwrap();
        let close = |x: &[f64], y: &[f64]| {
            x.iter()
                .zip(y)
                .all(|(p, q)| (p - q).abs() <= 1e-9 * (1.0 + p.abs()))
        };
        assert!(close(&b.initial.position, &KM.place(a.initial.position)));
        assert!(close(&b.initial.rotation, &KM.rotate(a.initial.rotation)));
        assert!(close(
            &b.reference.position,
            &KM.place(a.reference.position)
        ));
        assert_eq!(b.initial.velocity, a.initial.velocity);
        let w = a.disturbance_world.clone().unwrap();
        let turned: Vec<f64> = w
            .chunks(3)
            .flat_map(|c| KM.turn([c[0], c[1], c[2]]))
            .collect();
        assert!(close(b.disturbance_world.as_ref().unwrap(), &turned));
        let (sa, sb) = (a.sensors.unwrap(), b.sensors.unwrap());
        for (da, db) in sa.directions.iter().zip(&sb.directions) {
            assert!(close(&db.world, &KM.turn(da.world)));
        }
        assert_eq!(a.plant_inertia, b.plant_inertia);
        assert_eq!(a.vehicle, b.vehicle);
    }

    #[test]
    fn whole_numbers_and_the_estimators_initial_attitude_move_too() {
        // whole numbers where the loader takes them, and an initial attitude estimate
        let text = scenario_text("eqf_se3")
            .replace("[plant]", "[plant]\ndisturbance_world = [0, 0, 1, 2, 0, 0]")
            .replace("position = [2.0, -1.0, 1.2]", "position = [2, -1, 1]")
            .replace(
                "kind = \"eqf\"",
                "kind = \"eqf\"\ninitial_attitude = [0.1, 0.2, -0.3]",
            )
            // a position fix's bias is in world axes; the gyro's and a direction's in body axes
            .replace(
                "[estimator]",
                "[[sensors.fault]]\nsensor = \"position\"\nt = 1\nkind = \"bias\"\nvalue = [1, 0, 2]\n\
                 [[sensors.fault]]\nsensor = \"gyro\"\nt = 1\nkind = \"bias\"\nvalue = [1, 0, 2]\n\
                 [[sensors.fault]]\nsensor = \"direction0\"\nt = 1\nkind = \"bias\"\nrotation = [1, 0, 2]\n\
                 [estimator]",
            );
        let a = Scenario::from_toml_in(&text, "a", "a", None).unwrap();
        let moved = move_scenario(&text, "a", None, &KM).unwrap();
        let b = Scenario::from_toml_in(&moved.text, "b", "b", None).unwrap();
        let close = |x: &[f64], y: &[f64]| {
            x.iter()
                .zip(y)
                .all(|(p, q)| (p - q).abs() <= 1e-9 * (1.0 + p.abs()))
        };
        assert!(close(&b.initial.position, &KM.place([2.0, -1.0, 1.0])));
        let w = b.disturbance_world.clone().unwrap();
        assert!(close(&w[..3], &KM.turn([0.0, 0.0, 1.0])));
        assert!(close(&w[3..], &KM.turn([2.0, 0.0, 0.0])));
        let (ra, rb) = (
            a.estimator.initial_attitude.unwrap(),
            b.estimator.initial_attitude.unwrap(),
        );
        assert!(close(&rb, &KM.rotate(ra)));
        let faults = |s: &Scenario| -> Vec<[f64; 3]> {
            s.sensors
                .as_ref()
                .unwrap()
                .faults
                .iter()
                .map(|f| match f.kind {
                    crate::sensing::SensorFaultKind::Bias(v) => v,
                    _ => unreachable!(),
                })
                .collect()
        };
        let (fa, fb) = (faults(&a), faults(&b));
        assert!(close(&fb[0], &KM.turn(fa[0])) && !close(&fb[0], &fa[0]));
        assert_eq!(fa[1..], fb[1..]);
        // a list of the wrong kind is refused naming the key, never a panic
        let bad = text.replace(
            "disturbance_world = [0, 0, 1, 2, 0, 0]",
            "disturbance_world = [0, \"x\", 1]",
        );
        assert!(move_scenario(&bad, "a", None, &KM).is_err());
    }

    #[test]
    fn a_waypoint_file_moves_pose_by_pose_and_keeps_its_velocities() {
        let text = "t,rx,ry,rz,x,y,z,wx,wy,wz,vx,vy,vz\n0.0,0.1,0.0,0.0,1.0,2.0,3.0,,,,,,\n2.0,0.0,0.0,0.5,0.0,0.0,0.0,0.1,0.0,0.0,0.2,0.0,0.0\n";
        let moved = move_waypoints(text, "w.csv", GroupKind::Se3, &KM).unwrap();
        let lines: Vec<&str> = moved.lines().collect();
        assert_eq!(lines[0], "t,rx,ry,rz,x,y,z,wx,wy,wz,vx,vy,vz");
        let cells: Vec<&str> = lines[2].split(',').collect();
        assert_eq!(cells.len(), 13);
        assert_eq!(&cells[7..], ["0.1", "0.0", "0.0", "0.2", "0.0", "0.0"]);
        let x: Vec<f64> = cells[4..7].iter().map(|c| c.parse().unwrap()).collect();
        assert_eq!(x, KM.offset.to_vec());
        assert!(lines[1].ends_with(",,,,,,"));
    }

    #[test]
    fn a_waypoint_file_given_by_a_path_is_written_beside_the_moved_scenario_never_over_it() {
        let abs = dir().join("slew_se3.csv").canonicalize().unwrap();
        let text = scenario_text("slew_se3").replace(
            "waypoints = \"slew_se3.csv\"",
            &format!("waypoints = {:?}", abs.display().to_string()),
        );
        assert!(
            text.contains(&abs.display().to_string()),
            "the template changed"
        );
        let moved = move_scenario(&text, "slew", None, &KM).unwrap();
        let (name, _) = moved.waypoints.as_ref().unwrap();
        assert_eq!(name, "slew_se3.csv");
        assert!(
            moved.text.contains("waypoints = \"slew_se3.csv\""),
            "{}",
            moved.text
        );
        let out = std::env::temp_dir().join(format!("eqtrack-moving-{}", std::process::id()));
        let path = moved.write(&out, "slew.toml").unwrap();
        assert!(out.join("slew_se3.csv").is_file());
        let b = Scenario::from_file(&path).unwrap();
        let a = Scenario::from_toml_in(&text, "slew", "slew", None).unwrap();
        let (pa, pb) = (a.path.unwrap(), b.path.unwrap());
        assert_eq!(pb.poses[1].position, KM.place(pa.poses[1].position));
        std::fs::remove_dir_all(&out).unwrap();
    }

    #[test]
    fn moving_by_nothing_keeps_the_scenario() {
        let none = WorldMotion {
            heading: 0.0,
            offset: [0.0; 3],
        };
        assert!(none.is_identity());
        let text = scenario_text("slew_se3");
        let moved = move_scenario(&text, "slew", Some(&dir()), &none).unwrap();
        let a = Scenario::from_toml_in(&text, "slew", "slew", Some(&dir())).unwrap();
        let b = Scenario::from_toml_in(&moved.text, "slew", "slew", Some(&dir())).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn bad_motions_are_refused_naming_what_is_wrong() {
        let so3 = scenario_text("slew_so3");
        let e = move_scenario(&so3, "slew_so3", Some(&dir()), &KM).unwrap_err();
        assert!(
            e.to_string()
                .contains("key `offset`: an SO(3) scenario has no positions"),
            "{e}"
        );
        let turn = WorldMotion {
            heading: 0.4,
            offset: [0.0; 3],
        };
        assert!(move_scenario(&so3, "slew_so3", Some(&dir()), &turn).is_ok());
        let nan = WorldMotion {
            heading: f64::NAN,
            offset: [0.0; 3],
        };
        let e = move_scenario(&scenario_text("se3_circle"), "c", None, &nan).unwrap_err();
        assert!(
            e.to_string()
                .contains("key `heading`: must be finite (got NaN)"),
            "{e}"
        );
        let e = move_scenario("group = 3", "bad", None, &turn).unwrap_err();
        assert!(e.to_string().starts_with("bad:"), "{e}");
    }
}

//! Waypoint files: `t,rx,ry,rz` (SO(3)) or `t,rx,ry,rz,x,y,z` (SE(3)), one waypoint per line,
//! `(rx, ry, rz)` the rotation vector (`R = exp(hat(r))`), `(x, y, z)` the position, and
//! optionally the body velocity at the waypoint: `wx,wy,wz` (SO(3)) or `wx,wy,wz,vx,vy,vz`
//! (SE(3), angular then linear, body frame), for `path = "through"`; a line leaves them empty
//! to have them chosen. Every error names the file, the line and the column.

use crate::{PathKind, PathSpec, Pose, ScenarioError};
use controller::GroupKind;
use controller::group::{MatrixLieGroup, OnGroup};
use controller::path::MAX_SEGMENTS;
use std::io::Read;
use std::path::Path;

/// The most waypoints a path holds.
pub const MAX_WAYPOINTS: usize = MAX_SEGMENTS + 1;

/// The largest waypoint file read (far more than 33 lines need).
const MAX_BYTES: u64 = 1 << 20;

/// The header a group's waypoint file must have.
pub fn header(group: GroupKind) -> &'static [&'static str] {
    match group {
        GroupKind::So3 => &["t", "rx", "ry", "rz"],
        GroupKind::Se3 => &["t", "rx", "ry", "rz", "x", "y", "z"],
    }
}

/// The optional velocity columns of a group's waypoint file.
pub fn velocity_header(group: GroupKind) -> &'static [&'static str] {
    match group {
        GroupKind::So3 => &["wx", "wy", "wz"],
        GroupKind::Se3 => &["wx", "wy", "wz", "vx", "vy", "vz"],
    }
}

/// Reads and checks a waypoint file for `group`.
pub fn read(path: &Path, group: GroupKind) -> Result<PathSpec, ScenarioError> {
    let file = path.display().to_string();
    let io = |source| ScenarioError::Io {
        path: file.clone(),
        source,
    };
    // at most MAX_BYTES: a waypoint file is small, and /dev/zero must not exhaust memory
    let mut text = String::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_BYTES + 1).read_to_string(&mut text))
        .map_err(io)?;
    if text.len() as u64 > MAX_BYTES {
        return Err(ScenarioError::Waypoints {
            file,
            line: 1,
            column: 1,
            name: "t".to_owned(),
            message: format!("larger than {MAX_BYTES} bytes: not a waypoint file"),
        });
    }
    parse(&text, &file, group)
}

/// Parses waypoint CSV text; `file` names it in errors.
pub fn parse(text: &str, file: &str, group: GroupKind) -> Result<PathSpec, ScenarioError> {
    let want = header(group);
    let err = |line: u64, column: usize, message: String| ScenarioError::Waypoints {
        file: file.to_owned(),
        line,
        column: column + 1,
        name: want.get(column).copied().unwrap_or("(extra)").to_owned(),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let head = reader
        .headers()
        .map_err(|e| err(1, 0, format!("unreadable header: {e}")))?
        .clone();
    for (i, name) in want.iter().enumerate() {
        match head.get(i) {
            Some(h) if h == *name => {}
            found => {
                return Err(err(
                    1,
                    i,
                    format!(
                        "header must be `{}` for {}, found `{}`",
                        want.join(","),
                        group.name(),
                        found.unwrap_or("")
                    ),
                ));
            }
        }
    }
    let speeds = velocity_header(group);
    let full: Vec<&str> = want.iter().chain(speeds).copied().collect();
    let expected = format!(
        "header must be `{}` for {}, optionally followed by `{}`",
        want.join(","),
        group.name(),
        speeds.join(",")
    );
    let named = |column: usize| full.get(column).copied().unwrap_or("(extra)").to_owned();
    let columns = if head.len() == want.len() {
        want.len()
    } else {
        let header_err = |column: usize, message: String| ScenarioError::Waypoints {
            file: file.to_owned(),
            line: 1,
            column: column + 1,
            name: named(column),
            message,
        };
        for (i, name) in full.iter().enumerate().skip(want.len()) {
            match head.get(i) {
                Some(h) if h == *name => {}
                found => {
                    return Err(header_err(
                        i,
                        format!("{expected}, found `{}`", found.unwrap_or("")),
                    ));
                }
            }
        }
        if head.len() > full.len() {
            return Err(header_err(full.len(), expected));
        }
        full.len()
    };
    let err = |line: u64, column: usize, message: String| ScenarioError::Waypoints {
        file: file.to_owned(),
        line,
        column: column + 1,
        name: named(column),
        message,
    };
    let mut spec = PathSpec {
        file: file.to_owned(),
        kind: PathKind::Stop,
        times: Vec::new(),
        poses: Vec::new(),
        velocities: Vec::new(),
        lines: Vec::new(),
    };
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            err(line, 0, format!("unreadable line: {e}"))
        })?;
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != columns {
            return Err(err(
                line,
                record.len().min(columns),
                format!("expected {columns} values, found {}", record.len()),
            ));
        }
        if spec.times.len() == MAX_WAYPOINTS {
            return Err(err(
                line,
                0,
                format!("too many waypoints: at most {MAX_WAYPOINTS}"),
            ));
        }
        let number = |i: usize, field: &str| -> Result<f64, ScenarioError> {
            let v: f64 = field
                .parse()
                .map_err(|_| err(line, i, format!("`{field}` is not a number")))?;
            if !v.is_finite() {
                return Err(err(line, i, format!("`{field}` is not a finite number")));
            }
            Ok(v)
        };
        let mut x = [0.0; 7];
        for (i, field) in record.iter().enumerate().take(want.len()) {
            x[i] = number(i, field)?;
        }
        // the velocity: every field empty (chosen) or every field a number (given)
        let given: Vec<&str> = record.iter().skip(want.len()).collect();
        let velocity = if given.iter().all(|f| f.is_empty()) {
            None
        } else if let Some(j) = given.iter().position(|f| f.is_empty()) {
            return Err(err(
                line,
                want.len() + j,
                format!(
                    "empty while other velocity columns of the line are given: give all of `{}` or none",
                    speeds.join(",")
                ),
            ));
        } else {
            let mut v = Vec::with_capacity(given.len());
            for (j, field) in given.iter().enumerate() {
                v.push(number(want.len() + j, field)?);
            }
            Some(v)
        };
        if let Some(last) = spec.times.last()
            && x[0] <= *last
        {
            return Err(err(
                line,
                0,
                format!("times must increase strictly: {} after {last}", x[0]),
            ));
        }
        spec.times.push(x[0]);
        spec.poses.push(Pose {
            rotation: [x[1], x[2], x[3]],
            position: [x[4], x[5], x[6]],
        });
        spec.velocities.push(velocity);
        spec.lines.push(line);
    }
    if spec.times.is_empty() {
        return Err(err(
            2,
            0,
            "no waypoints (at least one line after the header)".to_owned(),
        ));
    }
    Ok(spec)
}

/// Checks a read waypoint file against the scenario: every leg at least one control period
/// long (a shorter leg moves between two ticks, so no sample shows its speed), and velocities
/// only where they are honoured — with `path = "through"`, and zero at the first and last
/// waypoint (the path is at rest before and after) — and the path built once on the group
/// (a leg that misses its waypoint in floating point is refused). Errors name the file, the
/// line and the column.
pub fn check_legs(spec: &PathSpec, group: GroupKind, period: f64) -> Result<(), ScenarioError> {
    let err = |i: usize, column: usize, name: &str, message: String| ScenarioError::Waypoints {
        file: spec.file.clone(),
        line: spec.lines.get(i).copied().unwrap_or(0),
        column: column + 1,
        name: name.to_owned(),
        message,
    };
    for i in 1..spec.times.len() {
        let leg = spec.times[i] - spec.times[i - 1];
        if leg < period {
            return Err(err(
                i,
                0,
                "t",
                format!(
                    "the leg from t = {} s to t = {} s lasts {leg:e} s, shorter than the control period {period} s: it would move between two control ticks, so no tick sees its speed",
                    spec.times[i - 1],
                    spec.times[i]
                ),
            ));
        }
    }
    let first = header(group).len();
    let names = velocity_header(group);
    let last = spec.times.len().saturating_sub(1);
    for (i, v) in spec.velocities.iter().enumerate() {
        let Some(v) = v else { continue };
        if spec.kind == PathKind::Stop {
            return Err(err(
                i,
                first,
                names[0],
                "a velocity is honoured only with `path = \"through\"` in [reference] (a stop path is at rest at every waypoint)".to_owned(),
            ));
        }
        if (i == 0 || i == last)
            && let Some(j) = v.iter().position(|x| *x != 0.0)
        {
            return Err(err(
                i,
                first + j,
                names[j],
                format!(
                    "the {} waypoint must be at rest (the path is held at rest {} it): give 0 or leave it empty",
                    if i == 0 { "first" } else { "last" },
                    if i == 0 { "before" } else { "after" }
                ),
            ));
        }
    }
    group.dispatch(Build(spec))
}

/// Builds the path once, so what only the construction finds (a leg that misses its waypoint
/// in floating point) is refused at load time, naming the waypoint's line.
struct Build<'a>(&'a PathSpec);

impl OnGroup for Build<'_> {
    type Output = Result<(), ScenarioError>;
    fn run<G: MatrixLieGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let spec = self.0;
        let path = crate::build_path::<G, N, M>(spec).map_err(|e| {
            let index = match e {
                controller::Error::NotIncreasing { index }
                | controller::Error::NotAtRest { index }
                | controller::Error::MissesWaypoint { index } => index,
                _ => 0,
            };
            ScenarioError::Waypoints {
                file: spec.file.clone(),
                line: spec.lines.get(index).copied().unwrap_or(0),
                column: 1,
                name: "t".to_owned(),
                message: e.to_string(),
            }
        })?;
        // every leg finite along its way, not only at its ends (sixteen samples per leg)
        for (i, seg) in path.segments().enumerate() {
            for k in 0..=16 {
                let t = seg.t0 + (seg.t1 - seg.t0) * f64::from(k) / 16.0;
                let s = seg.sample::<G>(t);
                // squares finite too: the law's energies square the velocity
                let finite = s.q.iter().all(|x| x.is_finite())
                    && s.v.norm_squared().is_finite()
                    && s.v_dot.norm_squared().is_finite();
                if !finite {
                    return Err(ScenarioError::Waypoints {
                        file: spec.file.clone(),
                        line: spec.lines.get(i + 1).copied().unwrap_or(0),
                        column: 1,
                        name: "t".to_owned(),
                        message: format!(
                            "the path between t = {} s and t = {} s is not finite at t = {t} s: a velocity, position or time is too large",
                            seg.t0, seg.t1
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(text: &str, group: GroupKind) -> String {
        parse(text, "w.csv", group).unwrap_err().to_string()
    }

    #[test]
    fn an_oversized_file_is_refused_without_reading_it_all() {
        let path = std::env::temp_dir().join(format!("eqtrack-big-{}.csv", std::process::id()));
        let mut text = String::from("t,rx,ry,rz\n");
        while text.len() as u64 <= MAX_BYTES {
            text.push_str("0,0,0,0\n");
        }
        std::fs::write(&path, text).unwrap();
        let m = read(&path, GroupKind::So3).unwrap_err().to_string();
        let _ = std::fs::remove_file(&path);
        assert!(m.contains("larger than 1048576 bytes"), "{m}");
    }

    #[test]
    fn a_good_file_is_read() {
        let p = parse(
            "t,rx,ry,rz\n0,0,0,0\n2, 1.5,0,0\n5,0,2,0\n",
            "w.csv",
            GroupKind::So3,
        )
        .unwrap();
        assert_eq!(p.times, vec![0.0, 2.0, 5.0]);
        assert_eq!(p.poses[1].rotation, [1.5, 0.0, 0.0]);
        let p = parse("t,rx,ry,rz,x,y,z\n0,0,0,0,1,2,3\n", "w.csv", GroupKind::Se3).unwrap();
        assert_eq!(p.poses[0].position, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn every_error_names_file_line_and_column() {
        let so3 = GroupKind::So3;
        let cases = [
            ("t,rx,ry\n0,0,0\n", "line 1, column 4 (`rz`)"),
            ("t,rx,ry,rz,x\n", "line 1, column 5"),
            ("t,rx,ry,rz\n0,0,0,0\n0,1,0,0\n", "line 3, column 1 (`t`)"),
            ("t,rx,ry,rz\n1,0,0,0\n0.5,1,0,0\n", "line 3, column 1 (`t`)"),
            ("t,rx,ry,rz\n0,0,abc,0\n", "line 2, column 3 (`ry`)"),
            ("t,rx,ry,rz\n0,0,0,inf\n", "line 2, column 4 (`rz`)"),
            ("t,rx,ry,rz\n0,0,0,NaN\n", "line 2, column 4 (`rz`)"),
            ("t,rx,ry,rz\n0,0,0\n", "line 2, column 4 (`rz`)"),
            ("t,rx,ry,rz\n0,0,0,0,9\n", "line 2, column 5"),
            ("t,rx,ry,rz\n", "line 2"),
        ];
        for (text, want) in cases {
            let m = msg(text, so3);
            assert!(m.starts_with("w.csv: "), "{m}");
            assert!(m.contains(want), "`{text}` gave `{m}`, expected `{want}`");
        }
        let many: String = std::iter::once("t,rx,ry,rz\n".to_owned())
            .chain((0..=MAX_WAYPOINTS).map(|i| format!("{i},0,0,0\n")))
            .collect();
        let m = msg(&many, so3);
        assert!(m.contains(&format!("line {}", MAX_WAYPOINTS + 2)), "{m}");
        assert!(m.contains("too many waypoints"), "{m}");
        let m = msg("t,rx,ry,rz\n0,0,0,0\n", GroupKind::Se3);
        assert!(m.contains("line 1, column 5 (`x`)"), "{m}");
    }
}

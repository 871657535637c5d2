//! Waypoint files: `t,rx,ry,rz` (SO(3)) or `t,rx,ry,rz,x,y,z` (SE(3)), one waypoint per line,
//! `(rx, ry, rz)` the rotation vector (`R = exp(hat(r))`), `(x, y, z)` the position, and
//! optionally the body velocity at the waypoint: `wx,wy,wz` (SO(3)) or `wx,wy,wz,vx,vy,vz`
//! (SE(3), angular then linear, body frame), for `path = "through"`; a line leaves them empty
//! to have them chosen. Every error names the file, the line and the column.

use crate::{PathKind, PathSpec, Pose, ScenarioError};
use eqtrack_controller::GroupKind;
use eqtrack_controller::group::{BuiltinGroup, OnGroup};
use eqtrack_controller::path::MAX_SEGMENTS;
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
        GroupKind::Se2 => &["t", "theta", "x", "y"],
    }
}

/// The optional velocity columns of a group's waypoint file.
pub fn velocity_header(group: GroupKind) -> &'static [&'static str] {
    match group {
        GroupKind::So3 => &["wx", "wy", "wz"],
        GroupKind::Se3 => &["wx", "wy", "wz", "vx", "vy", "vz"],
        GroupKind::Se2 => &["w", "vx", "vy"],
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
    let mut columns = Columns::new(file, group);
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let head = reader
        .headers()
        .map_err(|e| columns.err(1, 0, format!("unreadable header: {e}")))?
        .clone();
    columns.count = columns.check_header(&head)?;
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
            columns.err(line, 0, format!("unreadable line: {e}"))
        })?;
        columns.read_line(&record, &mut spec)?;
    }
    if spec.times.is_empty() {
        return Err(columns.err(
            2,
            0,
            "no waypoints (at least one line after the header)".to_owned(),
        ));
    }
    Ok(spec)
}

/// A waypoint file's columns while it is parsed: the group's names, and where errors point.
struct Columns<'a> {
    /// The file, as errors name it.
    file: &'a str,
    /// The group the file is read for.
    group: GroupKind,
    /// The pose columns, which every line has.
    pose: &'static [&'static str],
    /// The optional velocity columns.
    speeds: &'static [&'static str],
    /// How many values each line holds (the header's columns, once checked).
    count: usize,
}

impl<'a> Columns<'a> {
    /// The columns of `group`'s waypoint file named `file`, before its header is read.
    fn new(file: &'a str, group: GroupKind) -> Self {
        let pose = header(group);
        Columns {
            file,
            group,
            pose,
            speeds: velocity_header(group),
            count: pose.len(),
        }
    }

    /// The name of the 0-based `column` (`(extra)` past the last velocity column).
    fn name(&self, column: usize) -> String {
        self.pose
            .iter()
            .chain(self.speeds)
            .nth(column)
            .copied()
            .unwrap_or("(extra)")
            .to_owned()
    }

    /// An error at `line` and the 0-based `column`.
    fn err(&self, line: u64, column: usize, message: String) -> ScenarioError {
        ScenarioError::Waypoints {
            file: self.file.to_owned(),
            line,
            column: column + 1,
            name: self.name(column),
            message,
        }
    }

    /// Checks the header: the pose columns, then either nothing or every velocity column;
    /// returns how many values each line must hold.
    fn check_header(&self, head: &csv::StringRecord) -> Result<usize, ScenarioError> {
        for (i, name) in self.pose.iter().enumerate() {
            match head.get(i) {
                Some(h) if h == *name => {}
                found => {
                    return Err(self.err(
                        1,
                        i,
                        format!(
                            "header must be `{}` for {}, found `{}`",
                            self.pose.join(","),
                            self.group.name(),
                            found.unwrap_or("")
                        ),
                    ));
                }
            }
        }
        if head.len() == self.pose.len() {
            return Ok(self.pose.len());
        }
        let expected = format!(
            "header must be `{}` for {}, optionally followed by `{}`",
            self.pose.join(","),
            self.group.name(),
            self.speeds.join(",")
        );
        let full = self.pose.len() + self.speeds.len();
        for (j, name) in self.speeds.iter().enumerate() {
            let i = self.pose.len() + j;
            match head.get(i) {
                Some(h) if h == *name => {}
                found => {
                    return Err(self.err(
                        1,
                        i,
                        format!("{expected}, found `{}`", found.unwrap_or("")),
                    ));
                }
            }
        }
        if head.len() > full {
            return Err(self.err(1, full, expected));
        }
        Ok(full)
    }

    /// Reads one line of values into `spec`: its count, the waypoint limit, the pose, the
    /// velocity, then the time's order.
    fn read_line(
        &self,
        record: &csv::StringRecord,
        spec: &mut PathSpec,
    ) -> Result<(), ScenarioError> {
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != self.count {
            return Err(self.err(
                line,
                record.len().min(self.count),
                format!("expected {} values, found {}", self.count, record.len()),
            ));
        }
        if spec.times.len() == MAX_WAYPOINTS {
            return Err(self.err(
                line,
                0,
                format!("too many waypoints: at most {MAX_WAYPOINTS}"),
            ));
        }
        let mut x = [0.0; 7];
        for (i, field) in record.iter().enumerate().take(self.pose.len()) {
            x[i] = self.number(line, i, field)?;
        }
        let velocity = self.velocity(line, record)?;
        if let Some(last) = spec.times.last()
            && x[0] <= *last
        {
            return Err(self.err(
                line,
                0,
                format!("times must increase strictly: {} after {last}", x[0]),
            ));
        }
        spec.times.push(x[0]);
        spec.poses.push(match self.group {
            // the heading as the rotation (0, 0, θ) about z, the position (x, y, 0)
            GroupKind::Se2 => Pose {
                rotation: [0.0, 0.0, x[1]],
                position: [x[2], x[3], 0.0],
            },
            _ => Pose {
                rotation: [x[1], x[2], x[3]],
                position: [x[4], x[5], x[6]],
            },
        });
        spec.velocities.push(velocity);
        spec.lines.push(line);
        Ok(())
    }

    /// The line's velocity: every field empty (chosen, `None`) or every field a number (given).
    fn velocity(
        &self,
        line: u64,
        record: &csv::StringRecord,
    ) -> Result<Option<Vec<f64>>, ScenarioError> {
        let given: Vec<&str> = record.iter().skip(self.pose.len()).collect();
        if given.iter().all(|f| f.is_empty()) {
            return Ok(None);
        }
        if let Some(j) = given.iter().position(|f| f.is_empty()) {
            return Err(self.err(
                line,
                self.pose.len() + j,
                format!(
                    "empty while other velocity columns of the line are given: give all of `{}` or none",
                    self.speeds.join(",")
                ),
            ));
        }
        let mut v = Vec::with_capacity(given.len());
        for (j, field) in given.iter().enumerate() {
            v.push(self.number(line, self.pose.len() + j, field)?);
        }
        Ok(Some(v))
    }

    /// The value in the 0-based `column` of `line`: a finite number.
    fn number(&self, line: u64, column: usize, field: &str) -> Result<f64, ScenarioError> {
        let v: f64 = field
            .parse()
            .map_err(|_| self.err(line, column, format!("`{field}` is not a number")))?;
        if !v.is_finite() {
            return Err(self.err(line, column, format!("`{field}` is not a finite number")));
        }
        Ok(v)
    }
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
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let spec = self.0;
        let path = crate::build_path::<G, N, M>(spec).map_err(|e| {
            let index = match e {
                eqtrack_controller::Error::NotIncreasing { index }
                | eqtrack_controller::Error::NotAtRest { index }
                | eqtrack_controller::Error::MissesWaypoint { index } => index,
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
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("big.csv");
        let mut text = String::from("t,rx,ry,rz\n");
        while text.len() as u64 <= MAX_BYTES {
            text.push_str("0,0,0,0\n");
        }
        std::fs::write(&path, text).unwrap();
        let m = read(&path, GroupKind::So3).unwrap_err().to_string();
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

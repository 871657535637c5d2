//! Waypoint files: `t,rx,ry,rz` (SO(3)) or `t,rx,ry,rz,x,y,z` (SE(3)), one waypoint per line,
//! `(rx, ry, rz)` the rotation vector (`R = exp(hat(r))`), `(x, y, z)` the position. Every
//! error names the file, the line and the column.

use crate::{PathSpec, Pose, ScenarioError};
use controller::GroupKind;
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
    if head.len() > want.len() {
        return Err(err(
            1,
            want.len(),
            format!("header must be `{}` for {}", want.join(","), group.name()),
        ));
    }
    let mut spec = PathSpec {
        file: file.to_owned(),
        times: Vec::new(),
        poses: Vec::new(),
    };
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            err(line, 0, format!("unreadable line: {e}"))
        })?;
        let line = record.position().map_or(0, |p| p.line());
        if record.len() != want.len() {
            return Err(err(
                line,
                record.len().min(want.len()),
                format!("expected {} values, found {}", want.len(), record.len()),
            ));
        }
        if spec.times.len() == MAX_WAYPOINTS {
            return Err(err(
                line,
                0,
                format!("too many waypoints: at most {MAX_WAYPOINTS}"),
            ));
        }
        let mut x = [0.0; 7];
        for (i, field) in record.iter().enumerate() {
            let v: f64 = field
                .parse()
                .map_err(|_| err(line, i, format!("`{field}` is not a number")))?;
            if !v.is_finite() {
                return Err(err(line, i, format!("`{field}` is not a finite number")));
            }
            x[i] = v;
        }
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

//! A flight moved with the world (docs/invariance.md): a scenario and the same scenario moved
//! by [`WorldMotion`] are flown, and their `trajectory.csv` tables compared column by column.
//! With the default `error_frame = "reference"` every part of the loop is independent of where
//! the world frame is, so:
//!
//! - the pose columns move with the world: `q_ij` and `qhat_ij` as `T Q`, the positions
//!   `xhat_i` and the fixes `pos_i` as `R_T x + t`, the world velocity `vhat_i` as `R_T v`;
//! - the covariance `cov_i`, whose axes turn with the world, is compared only when the world
//!   is not turned;
//! - every other column is unchanged.
//!
//! Each column's largest difference is relative to `1 + |expected value|`; a run is the same
//! flight when none exceeds [`TOLERANCE`].

use eqtrack_controller::GroupKind;
use nalgebra::{Matrix3, Matrix4, Vector3};
use plant::SimError;
use plant::output::{Cell, trajectory_table};
use plant::trajectory::SimulatedTrajectory;
use scenario::moving::WorldMotion;
use serde::Serialize;

/// The largest relative difference of a column that is still the same flight.
pub const TOLERANCE: f64 = 1e-6;

/// How a column is expected to change when the world moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Expect {
    /// Unchanged.
    Same,
    /// An entry of a pose matrix: `T Q`.
    Pose,
    /// A world position: `R_T x + t`.
    Position,
    /// A vector in world axes: `R_T v`.
    Turned,
    /// Its axes turn with the world and it is not compared under a turn.
    NotUnderTurn,
}

/// One column's comparison.
#[derive(Debug, Clone, Serialize)]
pub struct ColumnCheck {
    /// The column's name.
    pub column: String,
    /// How it should have changed.
    pub expect: Expect,
    /// Its largest relative difference from what was expected (0 when not compared).
    pub worst: f64,
    /// The time of that difference (s).
    pub t: f64,
}

/// A comparison of a flight and the flight moved with the world.
#[derive(Debug, Clone, Serialize)]
pub struct MovedCheck {
    /// The motion.
    pub heading: f64,
    /// The motion's shift (m).
    pub offset: [f64; 3],
    /// Rows compared.
    pub rows: usize,
    /// Every column.
    pub columns: Vec<ColumnCheck>,
}

impl MovedCheck {
    /// The column with the largest difference.
    pub fn worst(&self) -> Option<&ColumnCheck> {
        self.columns
            .iter()
            .max_by(|a, b| a.worst.total_cmp(&b.worst))
    }

    /// Whether the moved flight is the same flight (every column within [`TOLERANCE`]).
    pub fn same_flight(&self) -> bool {
        self.columns.iter().all(|c| c.worst <= TOLERANCE)
    }
}

/// How `column` changes when the world moves (the module's list).
pub fn expect(column: &str) -> Expect {
    let prefixed = |p: &str| {
        column
            .strip_prefix(p)
            .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
    };
    if prefixed("q_") || prefixed("qhat_") {
        Expect::Pose
    } else if prefixed("xhat_") || prefixed("pos_") {
        Expect::Position
    } else if prefixed("vhat_") {
        Expect::Turned
    } else if prefixed("cov_") {
        Expect::NotUnderTurn
    } else {
        Expect::Same
    }
}

/// The table of a flight: header and the cells' values (`NaN` for an empty cell).
pub fn table(traj: &SimulatedTrajectory) -> Result<(Vec<String>, Vec<Vec<f64>>), SimError> {
    let mut rows = Vec::new();
    let header = trajectory_table(traj, |r| {
        rows.push(r.iter().map(Cell::value).collect());
        Ok(())
    })?;
    Ok((header, rows))
}

/// Where a table's moving columns are, and the motion as a pose `T`.
struct Moved {
    n: usize,
    rt: Matrix3<f64>,
    offset: Vector3<f64>,
    tm: Matrix4<f64>,
    /// The first column of each pose matrix.
    poses: Vec<usize>,
    /// The first column of each 3-vector, and whether it is a position (else a direction).
    vectors: Vec<(usize, bool)>,
}

impl Moved {
    fn new(group: GroupKind, m: &WorldMotion, header: &[String]) -> Moved {
        let n = match group {
            GroupKind::So3 | GroupKind::Se2 => 3,
            GroupKind::Se3 => 4,
        };
        let rt = m.rotation();
        let offset = Vector3::from(m.offset);
        // on SO(3) the top-left block of the pose T (n = 3) is all that is used
        let mut tm = Matrix4::<f64>::identity();
        tm.fixed_view_mut::<3, 3>(0, 0).copy_from(&rt);
        if n == 4 {
            tm.fixed_view_mut::<3, 1>(0, 3).copy_from(&offset);
        }
        if group == GroupKind::Se2 {
            // the planar pose T = [[R(h), (x, y)], [0, 1]]
            tm[(0, 2)] = offset[0];
            tm[(1, 2)] = offset[1];
        }
        let col = |name: String| header.iter().position(|c| *c == name);
        Moved {
            n,
            rt,
            offset,
            tm,
            poses: ["q_", "qhat_"]
                .iter()
                .filter_map(|p| col(format!("{p}00")))
                .collect(),
            vectors: [("xhat_", true), ("pos_", true), ("vhat_", false)]
                .iter()
                .filter_map(|(p, place)| col(format!("{p}0")).map(|at| (at, *place)))
                .collect(),
        }
    }

    /// The row `x` of the flight as the moved flight should have it.
    fn expected(&self, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        out.copy_from_slice(x);
        for &at in &self.poses {
            let q = Matrix4::from_fn(|i, j| match (i < n && j < n, i == j) {
                (true, _) => x[at + i * n + j],
                (false, diagonal) => f64::from(u8::from(diagonal)),
            });
            let moved = self.tm * q;
            for i in 0..n {
                for j in 0..n {
                    out[at + i * n + j] = moved[(i, j)];
                }
            }
        }
        for &(at, place) in &self.vectors {
            let mut v = self.rt * Vector3::new(x[at], x[at + 1], x[at + 2]);
            if place {
                v += self.offset;
            }
            out[at..at + 3].copy_from_slice(v.as_slice());
        }
    }
}

/// Compares a flight's table `a` with the table `b` of the same flight moved by `m`, on
/// `group`. Refuses tables of different shapes.
pub fn compare(
    group: GroupKind,
    m: &WorldMotion,
    a: &(Vec<String>, Vec<Vec<f64>>),
    b: &(Vec<String>, Vec<Vec<f64>>),
) -> Result<MovedCheck, String> {
    let ((ha, ra), (hb, rb)) = (a, b);
    if ha != hb {
        return Err(format!(
            "the moved flight's columns differ: {} against {}",
            ha.len(),
            hb.len()
        ));
    }
    if ra.len() != rb.len() {
        return Err(format!(
            "the moved flight has {} rows, the flight {}",
            rb.len(),
            ra.len()
        ));
    }
    let moved = Moved::new(group, m, ha);
    let turned = m.heading != 0.0;
    let mut columns: Vec<ColumnCheck> = ha
        .iter()
        .map(|c| ColumnCheck {
            column: c.clone(),
            expect: expect(c),
            worst: 0.0,
            t: 0.0,
        })
        .collect();
    // the expected value of every column of one row of the moved flight
    let mut expected = vec![0.0; ha.len()];
    for (x, y) in ra.iter().zip(rb) {
        moved.expected(x, &mut expected);
        for (c, check) in columns.iter_mut().enumerate() {
            if check.expect == Expect::NotUnderTurn && turned {
                continue;
            }
            let (e, got) = (expected[c], y[c]);
            let d = if e.is_nan() && got.is_nan() {
                0.0 // empty in both (a tick without a fix)
            } else if e.is_nan() || got.is_nan() {
                f64::INFINITY
            } else {
                (got - e).abs() / (1.0 + e.abs())
            };
            if d > check.worst || (d.is_nan() && !check.worst.is_nan()) {
                check.worst = d;
                check.t = x[0];
            }
        }
    }
    Ok(MovedCheck {
        heading: m.heading,
        offset: m.offset,
        rows: ra.len(),
        columns,
    })
}

/// The check's summary, one line per kind of column: the largest difference among them and
/// where.
pub fn summary_text(check: &MovedCheck) -> String {
    let mut out = String::new();
    for kind in [
        Expect::Pose,
        Expect::Position,
        Expect::Turned,
        Expect::NotUnderTurn,
        Expect::Same,
    ] {
        let of_kind = check.columns.iter().filter(|c| c.expect == kind);
        let Some(w) = of_kind.max_by(|a, b| a.worst.total_cmp(&b.worst)) else {
            continue;
        };
        let what = match kind {
            Expect::Same => "unchanged columns",
            Expect::Pose => "poses moved (T Q)",
            Expect::Position => "positions moved (R_T x + t)",
            Expect::Turned => "world vectors turned (R_T v)",
            Expect::NotUnderTurn if check.heading != 0.0 => {
                out.push_str("  covariance: not compared (its axes turn with the world)\n");
                continue;
            }
            Expect::NotUnderTurn => "covariance",
        };
        out.push_str(&format!(
            "  {what:<30} largest difference {:.3e} ({} at t = {} s)\n",
            w.worst, w.column, w.t
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_classified_by_their_names() {
        assert_eq!(expect("q_03"), Expect::Pose);
        assert_eq!(expect("qhat_12"), Expect::Pose);
        assert_eq!(expect("xhat_2"), Expect::Position);
        assert_eq!(expect("pos_0"), Expect::Position);
        assert_eq!(expect("vhat_1"), Expect::Turned);
        assert_eq!(expect("cov_5"), Expect::NotUnderTurn);
        for same in [
            "t", "v_3", "tau_0", "dhat_4", "dir0_1", "acc_2", "u_cmd_3", "position",
        ] {
            assert_eq!(expect(same), Expect::Same, "{same}");
        }
    }

    #[test]
    fn a_column_that_does_not_move_as_expected_is_found() {
        let m = WorldMotion {
            heading: 0.0,
            offset: [10.0, 0.0, 0.0],
        };
        let header: Vec<String> = ["t", "v_0"]
            .into_iter()
            .map(str::to_owned)
            .chain((0..3).flat_map(|i| (0..3).map(move |j| format!("q_{i}{j}"))))
            .collect();
        let row = |v: f64| vec![0.0, v, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let a = (header.clone(), vec![row(1.0)]);
        let b = (header.clone(), vec![row(1.0)]);
        let so3 = compare(GroupKind::So3, &m, &a, &b).unwrap();
        assert!(so3.same_flight());
        let c = (header.clone(), vec![row(1.01)]);
        let check = compare(GroupKind::So3, &m, &a, &c).unwrap();
        assert!(!check.same_flight());
        assert_eq!(check.worst().unwrap().column, "v_0");
        let turn = WorldMotion {
            heading: 0.5,
            offset: [0.0; 3],
        };
        // an unturned attitude under a turn is a difference
        assert!(
            !compare(GroupKind::So3, &turn, &a, &b)
                .unwrap()
                .same_flight()
        );
        let short = (header[..3].to_vec(), vec![vec![0.0; 3]]);
        assert!(compare(GroupKind::So3, &m, &a, &short).is_err());
    }
}

//! Actuator geometry and the effectiveness matrix (docs/maths.md, "Control allocation").

use crate::wheels::Wheel;
use crate::{Commands, MAX_ACTUATORS};
use core::fmt;
use nalgebra::{RealField, SMatrix, SVector, Vector3};

/// One actuator, in body axes with the body origin at the centre of mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Actuator<T> {
    /// Where it acts, `p_j` (m).
    pub position: [T; 3],
    /// The direction of its thrust, `a_j` (normalised here; a zero or non-finite axis is
    /// refused).
    pub axis: [T; 3],
    /// `c_j`: the reaction torque per unit thrust about its own axis (m), signed: `c_j > 0`
    /// means the reaction torque points along `+a_j` (a rotor's drag torque).
    pub torque_per_thrust: T,
    /// The least command, `min_j` (N).
    pub min: T,
    /// The largest command, `max_j` (N).
    pub max: T,
}

/// Why a geometry is refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GeometryError<T, const K: usize> {
    /// No actuator, or more than [`MAX_ACTUATORS`].
    Count {
        /// How many were given.
        count: usize,
    },
    /// The wrench dimension is neither 3 (SO(3)) nor 6 (SE(3)).
    Dimension,
    /// Actuator `index` has a non-finite number in `field`.
    NonFinite {
        /// The actuator (0-based).
        index: usize,
        /// `position`, `axis`, `torque_per_thrust`, `min` or `max`.
        field: &'static str,
    },
    /// Actuator `index` has a zero axis.
    ZeroAxis {
        /// The actuator (0-based).
        index: usize,
    },
    /// Actuator `index` has `min > max`.
    MinAboveMax {
        /// The actuator (0-based).
        index: usize,
        /// Its `min`.
        min: T,
        /// Its `max`.
        max: T,
    },
    /// The actuators cannot produce every wrench: the directions they miss.
    DoesNotSpan(LostDirections<T, K>),
    /// A planar geometry's actuator `index` leaves the plane: a non-zero z in its
    /// `position` or `axis`, or a reaction torque (`torque_per_thrust`) about an in-plane axis.
    OutOfPlane {
        /// The actuator (0-based).
        index: usize,
        /// `position`, `axis` or `torque_per_thrust`.
        field: &'static str,
    },
}

impl<T: Copy> GeometryError<T, 6> {
    /// An actuator's own refusal (not finite, a zero axis, `min > max`) in a geometry of
    /// another dimension; what concerns the whole geometry becomes
    /// [`GeometryError::Dimension`].
    fn of_actuator<const K: usize>(self) -> GeometryError<T, K> {
        match self {
            GeometryError::NonFinite { index, field } => GeometryError::NonFinite { index, field },
            GeometryError::ZeroAxis { index } => GeometryError::ZeroAxis { index },
            GeometryError::MinAboveMax { index, min, max } => {
                GeometryError::MinAboveMax { index, min, max }
            }
            GeometryError::Count { count } => GeometryError::Count { count },
            GeometryError::OutOfPlane { index, field } => {
                GeometryError::OutOfPlane { index, field }
            }
            GeometryError::Dimension | GeometryError::DoesNotSpan(_) => GeometryError::Dimension,
        }
    }
}

/// The wrench directions a geometry cannot produce: an orthonormal basis of the complement
/// of the span of its effectiveness columns, in (torque, force) coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LostDirections<T, const K: usize> {
    directions: [SVector<T, K>; K],
    count: usize,
}

impl<T: RealField + Copy, const K: usize> LostDirections<T, K> {
    /// The lost directions (unit vectors).
    pub fn directions(&self) -> &[SVector<T, K>] {
        &self.directions[..self.count]
    }
}

/// The name of wrench coordinate `i` of a `K`-dimensional wrench.
fn coordinate(k: usize, i: usize) -> &'static str {
    const NAMES: [&str; 6] = ["τx", "τy", "τz", "fx", "fy", "fz"];
    if k == 3 || k == 6 { NAMES[i] } else { "?" }
}

impl<T: RealField + Copy + fmt::Display, const K: usize> fmt::Display for LostDirections<T, K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (n, d) in self.directions().iter().enumerate() {
            if n > 0 {
                write!(f, "; ")?;
            }
            // a coordinate axis by its name, any other direction by its components
            let tiny = T::from_subset(&1e-9);
            let big: usize = (0..K).filter(|&i| d[i].abs() > tiny).count();
            if big == 1 {
                let i = (0..K).find(|&i| d[i].abs() > tiny).unwrap_or(0);
                write!(f, "{}", coordinate(K, i))?;
            } else {
                write!(f, "(")?;
                for i in 0..K {
                    let x = if d[i].abs() > tiny { d[i] } else { T::zero() };
                    write!(
                        f,
                        "{}{} {:.3}",
                        if i > 0 { ", " } else { "" },
                        coordinate(K, i),
                        x
                    )?;
                }
                write!(f, ")")?;
            }
        }
        Ok(())
    }
}

impl<T: RealField + Copy + fmt::Display, const K: usize> fmt::Display for GeometryError<T, K> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GeometryError::Count { count } => {
                write!(f, "{count} actuators: a vehicle has 1 to {MAX_ACTUATORS}")
            }
            GeometryError::Dimension => {
                write!(f, "the wrench has 3 (SO(3), SE(2)) or 6 (SE(3)) components")
            }
            GeometryError::NonFinite { index, field } => {
                write!(f, "actuator {index}: `{field}` is not a finite number")
            }
            GeometryError::ZeroAxis { index } => {
                write!(f, "actuator {index}: `axis` is zero (it needs a direction)")
            }
            GeometryError::MinAboveMax { index, min, max } => {
                write!(f, "actuator {index}: `min` = {min} is above `max` = {max}")
            }
            GeometryError::DoesNotSpan(lost) => write!(
                f,
                "the actuators cannot produce every wrench: they miss {lost}"
            ),
            GeometryError::OutOfPlane { index, field } => write!(
                f,
                "actuator {index}: `{field}` leaves the plane of a planar (SE(2)) vehicle"
            ),
        }
    }
}

/// The actuators of a vehicle as the allocator uses them: the effectiveness matrix `B`
/// (`K` × [`MAX_ACTUATORS`], column `j` the wrench of a unit command of actuator `j`, zero
/// past the count) and the bounds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Geometry<T, const K: usize> {
    b: SMatrix<T, K, MAX_ACTUATORS>,
    count: usize,
    min: Commands<T>,
    max: Commands<T>,
}

impl<T: RealField + Copy, const K: usize> Geometry<T, K> {
    /// Checks the actuators and builds `B` (docs/maths.md, "Control allocation", the
    /// effectiveness column `[p × a + c a ; a]`, the torque rows alone when `K` = 3). Refuses
    /// a count outside 1..=12, a non-finite number, a zero axis, `min > max`, and a geometry
    /// whose columns do not span the `K`-dimensional wrench space (naming what it misses).
    pub fn new(actuators: &[Actuator<T>]) -> Result<Self, GeometryError<T, K>> {
        Self::with_wheels(actuators, &[])
    }

    /// [`Geometry::new`] with reaction wheels after the actuators: wheel `i` is column `actuators.len() + i`, `(−g_i, 0)` with its axis made unit
    /// (its motor's torque `u` on the wheel puts `−u g_i` on the body), bounded by
    /// `±max_torque`. Together they count at most [`MAX_ACTUATORS`], at least one, and must
    /// span the wrench space (wheels give torque only: on SE(3) the actuators give the force).
    /// A wheel's error names its column (docs/maths.md, "Reaction wheels").
    pub fn with_wheels(
        actuators: &[Actuator<T>],
        wheels: &[Wheel<T>],
    ) -> Result<Self, GeometryError<T, K>> {
        if K != 3 && K != 6 {
            return Err(GeometryError::Dimension);
        }
        let count = actuators.len() + wheels.len();
        Self::from_columns(count, |j| {
            let Some(w) = j.checked_sub(actuators.len()).map(|i| &wheels[i]) else {
                let a = &actuators[j];
                return Ok((column::<T, K>(j, a)?, a.min, a.max));
            };
            // a wheel is a pure torque: an actuator at the origin whose thrust is zero and
            // whose reaction torque is −1 per unit command, checked as one
            let pure = Actuator {
                position: [T::zero(); 3],
                axis: w.axis,
                torque_per_thrust: -T::one(),
                min: -w.max_torque,
                max: w.max_torque,
            };
            let mut c = column::<T, K>(j, &pure)?;
            for r in 3..K {
                c[r] = T::zero();
            }
            Ok((c, pure.min, pure.max))
        })
    }

    /// A planar vehicle's geometry (SE(2), `K` = 3, wrenches `(τ, f_x, f_y)`): actuator `j`
    /// at `(x, y)` in the body plane thrusting along the in-plane axis `a` (made unit) has the
    /// column `(x a_y − y a_x, a_x, a_y)`, the rows `(τ_z, f_x, f_y)` of its SE(3) column
    /// (docs/maths.md, "Control allocation"). Positions and axes are in the plane: their z
    /// entries are 0, and a reaction torque about the axis (`torque_per_thrust`) would lie in
    /// the plane, so it must be 0 too. The same refusals as [`Geometry::new`], and
    /// [`GeometryError::Dimension`] for a `K` other than 3.
    pub fn planar(actuators: &[Actuator<T>]) -> Result<Self, GeometryError<T, K>> {
        if K != 3 {
            return Err(GeometryError::Dimension);
        }
        Self::from_columns(actuators.len(), |j| {
            let a = &actuators[j];
            let out = [
                ("position", a.position[2]),
                ("axis", a.axis[2]),
                ("torque_per_thrust", a.torque_per_thrust),
            ];
            if let Some((field, _)) = out.iter().find(|(_, x)| *x != T::zero()) {
                return Err(GeometryError::OutOfPlane { index: j, field });
            }
            let full = column::<T, 6>(j, a).map_err(GeometryError::of_actuator)?;
            let mut c = SVector::<T, K>::zeros();
            for (r, row) in [2, 3, 4].into_iter().enumerate() {
                c[r] = full[row];
            }
            Ok((c, a.min, a.max))
        })
    }

    /// `count` columns, column `j` and its bounds `(min, max)` from `column_of(j)` (in order,
    /// the first error returned): refuses a count outside 1..=[`MAX_ACTUATORS`] and columns
    /// that do not span the wrench space.
    fn from_columns(
        count: usize,
        mut column_of: impl FnMut(usize) -> Result<(SVector<T, K>, T, T), GeometryError<T, K>>,
    ) -> Result<Self, GeometryError<T, K>> {
        if count == 0 || count > MAX_ACTUATORS {
            return Err(GeometryError::Count { count });
        }
        let mut g = Geometry {
            b: SMatrix::zeros(),
            count,
            min: Commands::zeros(),
            max: Commands::zeros(),
        };
        for j in 0..count {
            let (c, min, max) = column_of(j)?;
            g.b.set_column(j, &c);
            g.min[j] = min;
            g.max[j] = max;
        }
        let lost = lost_directions(&g.b);
        if lost.count > 0 {
            return Err(GeometryError::DoesNotSpan(lost));
        }
        Ok(g)
    }

    /// The effectiveness matrix `B`.
    pub fn effectiveness(&self) -> &SMatrix<T, K, MAX_ACTUATORS> {
        &self.b
    }

    /// The number of actuators.
    pub fn count(&self) -> usize {
        self.count
    }

    /// The actuators' bounds `(min, max)` (0 past the count).
    pub fn bounds(&self) -> (Commands<T>, Commands<T>) {
        (self.min, self.max)
    }

    /// The wrench `B u` of commands `u`.
    pub fn wrench(&self, u: &Commands<T>) -> SVector<T, K> {
        self.b * u
    }

    /// The same geometry with actuator `j`'s column scaled by `factor`: an actuator that
    /// produces only `factor` times its command (a loss of effectiveness, docs/maths.md,
    /// "Control allocation"). The bounds, in commands, stay. Out of range: unchanged.
    pub fn scaled(&self, j: usize, factor: T) -> Self {
        let mut g = *self;
        if j < self.count {
            let c = g.b.column(j) * factor;
            g.b.set_column(j, &c);
        }
        g
    }
}

/// Actuator `j`'s effectiveness column, after its checks.
fn column<T: RealField + Copy, const K: usize>(
    j: usize,
    a: &Actuator<T>,
) -> Result<SVector<T, K>, GeometryError<T, K>> {
    let finite = |xs: &[T], field| {
        if xs.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(GeometryError::NonFinite { index: j, field })
        }
    };
    finite(&a.position, "position")?;
    finite(&a.axis, "axis")?;
    finite(&[a.torque_per_thrust], "torque_per_thrust")?;
    finite(&[a.min], "min")?;
    finite(&[a.max], "max")?;
    if a.min > a.max {
        return Err(GeometryError::MinAboveMax {
            index: j,
            min: a.min,
            max: a.max,
        });
    }
    let axis = Vector3::from(a.axis);
    let norm = axis.norm();
    if norm <= T::zero() || !norm.is_finite() {
        return Err(GeometryError::ZeroAxis { index: j });
    }
    let axis = axis / norm;
    let torque = Vector3::from(a.position).cross(&axis) + axis * a.torque_per_thrust;
    let mut c = SVector::<T, K>::zeros();
    for i in 0..3 {
        c[i] = torque[i];
        if K == 6 {
            c[3 + i] = axis[i];
        }
    }
    Ok(c)
}

/// An orthonormal basis of the wrench directions `B`'s columns miss: modified Gram–Schmidt
/// (twice) over the columns, then over the coordinate axes; what is left of an axis longer
/// than a relative tolerance is a lost direction.
pub(crate) fn lost_directions<T: RealField + Copy, const K: usize>(
    b: &SMatrix<T, K, MAX_ACTUATORS>,
) -> LostDirections<T, K> {
    let scale = b.amax().max(T::one());
    let tol = T::default_epsilon().sqrt() * scale;
    let mut basis = [SVector::<T, K>::zeros(); K];
    let mut rank = 0;
    let push = |v: SVector<T, K>, rank: &mut usize, basis: &mut [SVector<T, K>; K]| {
        let mut r = v;
        for _ in 0..2 {
            for q in basis.iter().take(*rank) {
                r -= q * q.dot(&r);
            }
        }
        let n = r.norm();
        if n > tol && *rank < K {
            basis[*rank] = r / n;
            *rank += 1;
            true
        } else {
            false
        }
    };
    for j in 0..MAX_ACTUATORS {
        push(b.column(j).into_owned(), &mut rank, &mut basis);
    }
    let spanned = rank;
    let mut lost = LostDirections {
        directions: [SVector::zeros(); K],
        count: 0,
    };
    for i in 0..K {
        let mut e = SVector::<T, K>::zeros();
        e[i] = scale;
        if push(e, &mut rank, &mut basis) {
            lost.directions[lost.count] = basis[rank - 1];
            lost.count += 1;
        }
    }
    debug_assert_eq!(spanned + lost.count, K);
    lost
}

//! The validated pieces of a scenario: the reference's series terms, states, poses and the waypoint path.

use crate::Scenario;
use eqtrack_controller::Path as GroupPath;
use eqtrack_controller::group::BuiltinGroup;
use nalgebra::{SMatrix, SVector};

/// One cosine term of a feedforward axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// Amplitude.
    pub amplitude: f64,
    /// Angular frequency (rad/s).
    pub frequency: f64,
    /// Phase (rad).
    pub phase: f64,
}

/// One feedforward axis: `offset + Σ amplitude·cos(frequency·t + phase)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// Constant part.
    pub offset: f64,
    /// Cosine terms.
    pub terms: Vec<Term>,
}

/// A configuration and velocity: `Q = [[exp(hat(rotation)), position], [0, 1]]` (SO(3): the
/// rotation alone) and the body velocity.
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpec {
    /// Rotation vector (rad).
    pub rotation: [f64; 3],
    /// Position (SE(3) only; zero on SO(3)).
    pub position: [f64; 3],
    /// Body velocity, m entries.
    pub velocity: Vec<f64>,
}

/// A pose: `Q = [[exp(hat(rotation)), position], [0, 1]]` (SO(3): the rotation alone).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation vector (rad).
    pub rotation: [f64; 3],
    /// Position (SE(3) only; zero on SO(3)).
    pub position: [f64; 3],
}

/// How a path treats its interior waypoints (`[reference] path`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PathKind {
    /// `"stop"` (the default): rest-to-rest geodesic legs, at rest at every waypoint.
    #[default]
    Stop,
    /// `"through"`: C² quintic Hermite legs that fly through the interior waypoints.
    Through,
}

impl PathKind {
    /// The scenario's name of the kind.
    pub fn name(self) -> &'static str {
        match self {
            PathKind::Stop => "stop",
            PathKind::Through => "through",
        }
    }
}

/// A reference given as poses at times: a set-point (one pose) or a path through waypoints.
#[derive(Debug, Clone, PartialEq)]
pub struct PathSpec {
    /// Where it came from: the waypoint file, or `setpoint`.
    pub file: String,
    /// Stop at every waypoint, or fly through them.
    pub kind: PathKind,
    /// Waypoint times, strictly increasing.
    pub times: Vec<f64>,
    /// Waypoint poses.
    pub poses: Vec<Pose>,
    /// The body velocity given at each waypoint (m entries), `None`: chosen.
    pub velocities: Vec<Option<Vec<f64>>>,
    /// The file line of each waypoint (0 for a set-point).
    pub lines: Vec<u64>,
}

/// The path of a [`PathSpec`] on its group: the stop path (`Path::through`) or the
/// through-path (`Path::flying`, with the velocities given).
pub fn build_path<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    spec: &PathSpec,
) -> Result<GroupPath<f64, G, N, M>, eqtrack_controller::Error> {
    let poses: Vec<SMatrix<f64, N, N>> = spec
        .poses
        .iter()
        .map(|p| Scenario::pose::<N>(p.rotation, p.position))
        .collect();
    match spec.kind {
        PathKind::Stop => GroupPath::through(&spec.times, &poses),
        PathKind::Through => {
            let given: Vec<Option<SVector<f64, M>>> = spec
                .velocities
                .iter()
                .map(|v| {
                    v.as_ref()
                        .map(|v| SVector::from_fn(|i, _| v.get(i).copied().unwrap_or(f64::NAN)))
                })
                .collect();
            GroupPath::flying(&spec.times, &poses, &given)
        }
    }
}

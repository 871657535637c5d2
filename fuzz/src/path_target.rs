//! The path target: waypoint-file text through `scenario::waypoints::parse` and `check_legs`
//! on the group its header names and both path kinds, every accepted path built (`Path::through`,
//! `Path::flying`), sampled and handed to the law (a finite torque or a typed error, never a
//! NaN), then streamed: its segments in plan messages (`WireSegment`, `check_plan`), with one
//! field of one segment overwritten by a value chosen from the input (the wire fields `shape`,
//! `t0`, `t1`, `start`, `twists`), checked, and what passes evaluated as the controller would.

use crate::Outcome;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::rng::Gen;
use crate::scenario_target::{INTERESTING, join_lines, number_spans, random_number, split_lines};
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::path::{MAX_SEGMENTS, Path};
use eqtrack_controller::{BuiltinGroup, GroupKind, Law};
use ipc_types::plan::{SHAPE_REST, SHAPE_THROUGH};
use ipc_types::{MAX_M, MAX_N, PLAN_WINDOW, PlanMsg, WireSegment, check_plan};
use nalgebra::{SMatrix, SVector};
use scenario::waypoints::{check_legs, parse};
use scenario::{PathKind, PathSpec, Scenario, ScenarioError};

/// The control period the legs are checked against (the streamed legs too).
const PERIOD: f64 = 0.01;

/// Seed files: the shipped slews, and through-path files with velocity columns.
const SEEDS: [&str; 8] = [
    include_str!("../../scenarios/slew_so3.csv"),
    include_str!("../../scenarios/slew_se3.csv"),
    include_str!("../../scenarios/slew_se2.csv"),
    "t,theta,x,y,w,vx,vy\n0,0,0,0,,,\n1,1.5,1,0,0.5,1,0\n2,3,2,1,,,\n3,-3,2,1,,,\n4,0,1e3,-1e3,,,\n",
    "t,rx,ry,rz,wx,wy,wz\n0,0,0,0,,,\n1,0.5,0,0,0.3,0,0.1\n2,0.5,1,0,,,\n2.5,0.5,1,0,0,0,0\n4,3.5,0,1,,,\n5,0,0,0,0,0,0\n",
    "t,rx,ry,rz,x,y,z,wx,wy,wz,vx,vy,vz\n0,0,0,0,0,0,0,,,,,,\n1,0,0,1.5,1,0,0,0,0,0.5,1,0,0\n2,0,0,3,2,1,0,,,,,,\n3,0,0,3,2,1,0,,,,,,\n4,1,1,1,0,0,1,,,,,,\n",
    "t,rx,ry,rz\n0.5,0,0,0\n1.7,0,0,1\n3,0,0,2.5\n4.1,0,0,3.8\n5.6,0,0,5\n7,0,0,4\n",
    "t,rx,ry,rz,x,y,z\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0,0\n0.02,3.14159,0,0,1e3,0,0\n",
];

/// Values one wire field is overwritten with (the recording target's floats too).
pub(crate) const FIELD_VALUES: [f64; 12] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    0.0,
    -0.0,
    1e308,
    -1e308,
    1e-308,
    0.005,
    2.0,
    -1.0,
    1e6,
];

/// The seed corpus and the mutator of the path target.
pub(crate) struct Corpus {
    items: Vec<Vec<u8>>,
}

impl Corpus {
    /// The seed files.
    pub(crate) fn new() -> Corpus {
        Corpus {
            items: SEEDS.iter().map(|t| t.as_bytes().to_vec()).collect(),
        }
    }

    /// One case: a seed with 1–8 mutations (numbers, empty fields, lines, bytes).
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        let mut data = g.pick(&self.items).clone();
        for _ in 0..g.mutation_count() {
            let other = g.pick(&self.items);
            match g.below(12) {
                0..=4 => {
                    let spans = number_spans(&data);
                    if spans.is_empty() {
                        byte_op(g, ByteOp::Overwrite, &mut data, other);
                        continue;
                    }
                    let (s, e) = *g.pick(&spans);
                    let new = match g.below(4) {
                        0 => (*g.pick(&INTERESTING)).to_owned(),
                        1 => String::new(), // an empty field
                        _ => random_number(g),
                    };
                    data.splice(s..e, new.into_bytes());
                }
                5..=7 => {
                    let mut lines = split_lines(&data);
                    let i = g.below(lines.len());
                    match g.below(4) {
                        0 => {
                            lines.remove(i);
                        }
                        1 => {
                            let copy = lines[i].clone();
                            lines.insert(g.below(lines.len() + 1), copy);
                        }
                        2 => {
                            let j = g.below(lines.len());
                            lines.swap(i, j);
                        }
                        _ => {
                            let theirs = split_lines(other);
                            lines.truncate(i);
                            let from = g.below(theirs.len() + 1);
                            lines.extend_from_slice(&theirs[from..]);
                        }
                    }
                    data = join_lines(&lines);
                }
                8 => {
                    // a column more or fewer on one line
                    let mut lines = split_lines(&data);
                    let i = g.below(lines.len());
                    if g.chance(1, 2) {
                        lines[i].extend_from_slice(b",");
                    } else if let Some(at) = lines[i].iter().rposition(|b| *b == b',') {
                        lines[i].truncate(at);
                    }
                    data = join_lines(&lines);
                }
                9 => {
                    // many waypoints
                    let mut lines = split_lines(&data);
                    if let Some(last) = lines.last().cloned() {
                        for _ in 0..g.below(40) {
                            lines.push(last.clone());
                        }
                    }
                    data = join_lines(&lines);
                }
                _ => {
                    let op = *g.pick(&[
                        ByteOp::BitFlip,
                        ByteOp::Overwrite,
                        ByteOp::Insert,
                        ByteOp::Delete,
                        ByteOp::Truncate,
                    ]);
                    byte_op(g, op, &mut data, other);
                }
            }
        }
        data.truncate(MAX_INPUT);
        data
    }
}

/// The report's name of a waypoint-file refusal: the column and the message's first words.
fn refusal(e: &ScenarioError) -> String {
    match e {
        ScenarioError::Waypoints { name, message, .. } => {
            let words: Vec<&str> = message
                .split_whitespace()
                .filter(|w| w.chars().all(char::is_alphabetic))
                .take(3)
                .collect();
            format!("Waypoints({name}): {}", words.join(" "))
        }
        other => format!("{other:?}").chars().take(24).collect(),
    }
}

/// FNV-1a of the input: picks the planted wire fault, so a case replays exactly.
fn fnv(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Builds, samples, flies and streams one accepted path on its group.
struct Exercise<'a> {
    spec: &'a PathSpec,
    hash: u64,
}

/// The EqT law with unit inertia and gains: what the fuzzed paths' samples are handed to.
pub(crate) fn unit_controller<G: BuiltinGroup<N, M>, const N: usize, const M: usize>()
-> eqtrack_controller::Controller<f64, G, N, M> {
    eqtrack_controller::Controller::<f64, G, N, M>::new(eqtrack_controller::ControllerConfig {
        law: Law::Eqt,
        error_frame: eqtrack_controller::ErrorFrame::World,
        inertia: SMatrix::identity(),
        k: SMatrix::identity(),
        kd: SMatrix::identity(),
        torque_limit: None,
    })
    .expect("a valid configuration")
}

/// The law on a desired sample from the identity at rest: a finite torque or an error.
pub(crate) fn law_on<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    controller: &eqtrack_controller::Controller<f64, G, N, M>,
    sample: &eqtrack_controller::PathSample<f64, N, M>,
) {
    let inertia = SMatrix::<f64, M, M>::identity();
    let desired = sample.desired::<G>(&inertia);
    if let Ok(out) = controller.compute(&G::identity(), &SVector::zeros(), &desired) {
        assert!(
            out.torque.iter().all(|x| x.is_finite()),
            "a NaN torque from a path sample: {:?}",
            out.torque.as_slice()
        );
    }
}

impl OnGroup for Exercise<'_> {
    type Output = Result<(), String>;

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let spec = self.spec;
        let poses: Vec<SMatrix<f64, N, N>> = spec
            .poses
            .iter()
            .map(|p| Scenario::pose::<N>(p.rotation, p.position))
            .collect();
        let path = scenario::build_path::<G, N, M>(spec).map_err(|e| {
            format!(
                "Path: {}",
                crate::scenario_target::controller_error_kind(&e)
            )
        })?;
        let controller = unit_controller::<G, N, M>();
        // through every waypoint when the numbers are moderate (a leg between huge positions
        // or times keeps only the digits the largest number leaves)
        let scale = poses.iter().map(|q| q.norm()).fold(1.0f64, f64::max);
        let moderate = scale < 1e6 && spec.times.iter().all(|t| t.abs() < 1e6);
        for (t, q) in spec.times.iter().zip(&poses) {
            let s = path.sample(*t);
            if moderate {
                assert!(
                    (s.q - q).norm() <= 1e-6 * scale,
                    "not through the waypoint at t = {t}: {}",
                    (s.q - q).norm()
                );
            }
            law_on(&controller, &s);
        }
        let (t0, t1) = (spec.times[0], spec.times[spec.times.len() - 1]);
        for k in 0..=16 {
            let s = path.sample(t0 - 1.0 + (t1 - t0 + 2.0) * f64::from(k) / 16.0);
            law_on(&controller, &s);
        }
        // streamed: every window the planner would publish is accepted as it is
        let pieces: Vec<WireSegment> = path.segments().map(link::wire::wire_segment).collect();
        for window in pieces.chunks(PLAN_WINDOW) {
            let mut msg = PlanMsg::new(link::wire::wire_group(G::KIND));
            msg.count = window.len() as u32;
            msg.segments[..window.len()].copy_from_slice(window);
            assert_eq!(
                check_plan(&msg, link::wire::wire_group(G::KIND), PERIOD),
                Ok(()),
                "a planner's own window is refused"
            );
            // one field of one segment overwritten, chosen by the input's hash
            let h = self.hash;
            let i = (h % window.len() as u64) as usize;
            let value = FIELD_VALUES[((h >> 8) % FIELD_VALUES.len() as u64) as usize];
            let seg = &mut msg.segments[i];
            match (h >> 16) % 5 {
                0 => seg.t0 = value,
                1 => seg.t1 = value,
                2 => {
                    seg.shape = match (h >> 24) % 3 {
                        0 => SHAPE_REST,
                        1 => SHAPE_THROUGH,
                        _ => (h >> 32) as u32,
                    }
                }
                3 => seg.start[((h >> 24) % (MAX_N * MAX_N) as u64) as usize] = value,
                _ => seg.twists[((h >> 24) % (5 * MAX_M) as u64) as usize] = value,
            }
            if check_plan(&msg, link::wire::wire_group(G::KIND), PERIOD).is_err() {
                continue;
            }
            // what the controller does with an accepted message
            let mut streamed = Path::<f64, G, N, M>::hold(poses[0]).expect("finite first pose");
            for w in msg.used() {
                if streamed.push(link::wire::segment::<N, M>(w)).is_err() {
                    break;
                }
            }
            for w in msg.used() {
                for t in [w.t0, 0.5 * (w.t0 + w.t1), w.t1] {
                    law_on(&controller, &streamed.sample(t));
                }
            }
        }
        Ok(())
    }
}

/// Checks one waypoint-file input on the group its header names (SE(3) when the fifth
/// column is `x`, SE(2) when the second is `theta`) and both path kinds.
pub(crate) fn check(input: &[u8]) -> Outcome {
    let text = String::from_utf8_lossy(input);
    let hash = fnv(input);
    let header = text.lines().next().unwrap_or("");
    let column = |i: usize| header.split(',').nth(i).map(str::trim);
    let group = if column(4) == Some("x") {
        GroupKind::Se3
    } else if column(1) == Some("theta") {
        GroupKind::Se2
    } else {
        GroupKind::So3
    };
    let mut spec = match parse(&text, "fuzz.csv", group) {
        Ok(s) => s,
        Err(e) => return Outcome::Rejected(refusal(&e)),
    };
    assert!(spec.times.len() <= MAX_SEGMENTS + 1);
    let mut first_refusal = None;
    let mut accepted = false;
    for kind in [PathKind::Through, PathKind::Stop] {
        spec.kind = kind;
        if let Err(e) = check_legs(&spec, group, PERIOD) {
            first_refusal.get_or_insert_with(|| refusal(&e));
            continue;
        }
        match group.dispatch(Exercise { spec: &spec, hash }) {
            Ok(()) => accepted = true,
            Err(kind) => {
                first_refusal.get_or_insert(kind);
            }
        }
    }
    match (accepted, first_refusal) {
        (true, _) => Outcome::Accepted,
        (false, Some(kind)) => Outcome::Rejected(kind),
        (false, None) => Outcome::Rejected("nothing".to_owned()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_seed_is_accepted() {
        for seed in SEEDS {
            assert_eq!(check(seed.as_bytes()), Outcome::Accepted, "{seed}");
        }
    }
}

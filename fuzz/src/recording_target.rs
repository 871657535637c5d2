//! The recording target: what `plant_sim replay` and `plant_sim export` read back from a run's
//! flight recording and hand to the estimator and the controller. An input is one record of a
//! run with sensors (`messages.log`: the record and its sensor block) followed by one entry of
//! `plans.log`. The record goes through `Record::from_bytes`; an accepted one must encode and
//! decode to the same bytes, and its sensor samples go through both groups' estimators (the
//! complementary filter of `sensors_so3`, the EqF pose filter of `eqf_se3`) as replay steps
//! them. The plan entry goes through `PlanEntry::from_bytes`, and an accepted message through
//! `control_cycle::PlanIntake::take` on the streamed reference of its group, as replay hands
//! it to the controller; what it appends is sampled and handed to the law (a finite torque or
//! a typed error, never a NaN). Seeds: records of the first ticks of the two sensor scenarios,
//! and the plan messages of the shipped slews (both path kinds).

use crate::Outcome;
use crate::mutate::{ByteOp, MAX_INPUT, byte_op};
use crate::path_target::{FIELD_VALUES, law_on, unit_controller};
use crate::rng::Gen;
use control_cycle::PlanIntake;
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::{BuiltinGroup, GroupKind, Source, Trajectory};
use ipc_types::{CommandMsg, MAX_M, PLAN_WINDOW, PlanMsg, StateMsg, WireSegment};
use nalgebra::SVector;
use plant::estimation::Estimation;
use recorder::{PlanEntry, RECORD_BYTES, Record, SENSOR_BYTES, SensorRecord};
use scenario::{PathKind, Scenario};
use std::path::Path;
use std::sync::OnceLock;

/// Bytes of the record part of an input (the record and its sensor block).
const RECORD_PART: usize = RECORD_BYTES + SENSOR_BYTES;

/// The scenarios the inputs are checked with: the two sensor scenarios' estimators, the two
/// slews' streamed references.
struct Scenarios {
    sensors: [Scenario; 2],
    slews: [Scenario; 3],
}

fn scenarios() -> &'static Scenarios {
    static S: OnceLock<Scenarios> = OnceLock::new();
    S.get_or_init(|| {
        let load = |name: &str| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../scenarios")
                .join(format!("{name}.toml"));
            Scenario::from_file(&path).expect("a shipped scenario loads")
        };
        Scenarios {
            sensors: [load("sensors_so3"), load("eqf_se3")],
            slews: [load("slew_so3"), load("slew_se3"), load("slew_se2")],
        }
    })
}

/// The seed corpus and the mutator of the recording target.
pub(crate) struct Corpus {
    records: Vec<Vec<u8>>,
    plans: Vec<Vec<u8>>,
}

/// Records of the first ticks of a sensor scenario, as the plant of the pair writes them.
struct SeedRecords<'a> {
    s: &'a Scenario,
    out: &'a mut Vec<Vec<u8>>,
}

impl OnGroup for SeedRecords<'_> {
    type Output = ();
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) {
        let s = self.s;
        let mut body = s.plant_body::<G, N, M>().expect("the scenario's body");
        let mut e = Estimation::new(s, s.control_period, &[])
            .expect("the scenario's estimator")
            .expect("the scenario has sensors");
        let torque = SVector::<f64, M>::from_fn(|i, _| 0.1 * (i as f64 + 1.0));
        for k in 0..4u64 {
            let (q_hat, v_hat, row) = e.measure(k, &body, &torque);
            let mut state = StateMsg::new(link::wire::wire_group(s.group));
            state.seq = k;
            state.t = k as f64 * s.control_period;
            state.set_state(&q_hat, &v_hat);
            let mut truth = StateMsg::new(link::wire::wire_group(s.group));
            truth.set_state(body.configuration(), &body.velocity());
            let mut cmd = CommandMsg::new(link::wire::wire_group(s.group));
            cmd.seq = k;
            cmd.tau[..M].copy_from_slice(torque.as_slice());
            let r = Record {
                cycle: k,
                decision: link::Decision::Fresh,
                misses_in_row: 0,
                deadline_ns: k * 1_000_000,
                applied: [0.0; MAX_M],
                state,
                command: Some((cmd, k * 1_000_000 + 5)),
                sensors: Some(row.sensor_record(&truth)),
            };
            let mut b = vec![0u8; RECORD_PART];
            r.write_into(&mut b);
            self.out.push(b);
            body.advance(&torque, s.control_period, 1);
        }
    }
}

/// The plan entries of a slew's path, window by window, as the recorder keeps them.
struct SeedPlans<'a> {
    s: &'a Scenario,
    out: &'a mut Vec<Vec<u8>>,
}

impl OnGroup for SeedPlans<'_> {
    type Output = ();
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) {
        let spec = self.s.path.as_ref().expect("a slew has waypoints");
        for kind in [PathKind::Stop, PathKind::Through] {
            let mut spec = spec.clone();
            spec.kind = kind;
            let path = scenario::build_path::<G, N, M>(&spec).expect("the slew's path");
            let pieces: Vec<WireSegment> = path.segments().map(link::wire::wire_segment).collect();
            for (i, window) in pieces.chunks(PLAN_WINDOW).enumerate() {
                let mut msg = PlanMsg::new(link::wire::wire_group(G::KIND));
                msg.seq = i as u64 + 1;
                msg.planner_pid = 4242;
                msg.first_index = (i * PLAN_WINDOW) as u32;
                msg.count = window.len() as u32;
                msg.segments[..window.len()].copy_from_slice(window);
                self.out.push(
                    PlanEntry {
                        seen_after: i as u64,
                        msg,
                    }
                    .to_bytes()
                    .to_vec(),
                );
            }
        }
    }
}

impl Corpus {
    /// The seeds: records of the sensor scenarios' first ticks, the slews' plan entries.
    pub(crate) fn new() -> Corpus {
        let sc = scenarios();
        let (mut records, mut plans) = (Vec::new(), Vec::new());
        for s in &sc.sensors {
            s.group.dispatch(SeedRecords {
                s,
                out: &mut records,
            });
        }
        for s in &sc.slews {
            s.group.dispatch(SeedPlans { s, out: &mut plans });
        }
        Corpus { records, plans }
    }

    /// One case: a seed record and a seed plan entry, with 1–8 mutations (f64 fields set to
    /// chosen values, counts and flags changed, byte-level operations).
    pub(crate) fn generate(&self, g: &mut Gen) -> Vec<u8> {
        let mut data = g.pick(&self.records).clone();
        let plan: &Vec<u8> = g.pick(&self.plans);
        data.extend_from_slice(plan);
        for _ in 0..g.mutation_count() {
            match g.below(10) {
                0..=5 => {
                    // an 8-byte-aligned f64 (every float of both parts is aligned)
                    let slots = data.len() / 8;
                    if slots == 0 {
                        continue;
                    }
                    let at = 8 * g.below(slots);
                    let v = if g.chance(1, 4) {
                        f64::from_bits(g.u64())
                    } else {
                        *g.pick(&FIELD_VALUES)
                    };
                    data[at..at + 8].copy_from_slice(&v.to_le_bytes());
                }
                6 | 7 => {
                    // a flag, count or length: the record's presence bytes, the sensor
                    // block's bits and direction count, the plan's group and count
                    let spots = [
                        8,
                        9,
                        10,
                        RECORD_BYTES,
                        RECORD_BYTES + 4,
                        RECORD_PART + 16 + 4,
                        RECORD_PART + 16 + 28,
                    ];
                    let at = *g.pick(&spots);
                    if at + 4 <= data.len() {
                        let v: u32 = match g.below(4) {
                            0 => 0,
                            1 => g.below(16) as u32,
                            2 => u32::MAX,
                            _ => g.u32(),
                        };
                        data[at..at + 4].copy_from_slice(&v.to_le_bytes());
                    }
                }
                _ => {
                    let other: &Vec<u8> = if g.chance(1, 2) {
                        g.pick(&self.records)
                    } else {
                        g.pick(&self.plans)
                    };
                    let op = *g.pick(&ByteOp::ALL);
                    byte_op(g, op, &mut data, other);
                }
            }
        }
        data.truncate(MAX_INPUT);
        data
    }
}

/// The first words of a refusal, for the report.
fn kind(what: &str, e: &str) -> String {
    let words: Vec<&str> = e
        .split_whitespace()
        .filter(|w| w.chars().all(|c| c.is_alphabetic() || c == '_'))
        .take(3)
        .collect();
    format!("{what}: {}", words.join(" "))
}

/// Steps a fresh copy of `s`'s estimator three times over the samples, as replay does.
struct Estimate<'a> {
    s: &'a Scenario,
    sr: &'a SensorRecord,
}

impl OnGroup for Estimate<'_> {
    type Output = ();
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) {
        let Ok(Some(mut e)) = Estimation::new(self.s, self.s.control_period, &[]) else {
            panic!("the shipped scenario's estimator");
        };
        let truth = StateMsg {
            q: self.sr.q_true,
            v: self.sr.v_true,
            ..StateMsg::new(link::wire::wire_group(G::KIND))
        };
        let (q, v) = (truth.configuration::<N>(), truth.velocity::<M>());
        for _ in 0..3 {
            // whatever the samples, the filter returns (a non-finite estimate would be
            // refused by the controller's state check; the panic is what is looked for)
            let _ = e.estimate::<N, M>(self.sr.samples, &q, &v);
        }
    }
}

/// Hands an accepted plan message to a streamed reference of its group, as replay does, and
/// the pieces it appended to the law.
struct Intake<'a> {
    s: &'a Scenario,
    msg: &'a PlanMsg,
}

impl OnGroup for Intake<'_> {
    type Output = Result<(), String>;
    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let mut reference = control_cycle::streamed_reference::<G, N, M>(self.s)
            .expect("the slew's streamed reference");
        let Source::Path(path) = &mut reference else {
            panic!("a streamed reference is a path");
        };
        let mut intake = PlanIntake::default();
        intake
            .take(self.msg, path)
            .map_err(|e| format!("PlanIntake::take: {e:?}"))?;
        assert_eq!(intake.received, 1);
        assert_eq!(intake.last, (self.msg.planner_pid, self.msg.seq));
        let controller = unit_controller::<G, N, M>();
        let times: Vec<f64> = path
            .path()
            .segments()
            .flat_map(|seg| [seg.t0, 0.5 * (seg.t0 + seg.t1), seg.t1])
            .collect();
        for t in times {
            law_on(&controller, &path.path().sample(t));
        }
        // the reference moves on as in a run
        for _ in 0..3 {
            reference.advance();
            let d = reference.desired();
            let _ = controller.compute(&G::identity(), &SVector::zeros(), &d);
        }
        Ok(())
    }
}

/// Checks one recording input.
pub(crate) fn check(input: &[u8]) -> Outcome {
    let (rec, plan) = input.split_at(input.len().min(RECORD_PART));
    let record = match Record::from_bytes(rec) {
        Ok(r) => r,
        Err(e) => return Outcome::Rejected(kind("Record::from_bytes", &e)),
    };
    // decoding is idempotent: what was read encodes to bytes that read back the same
    let mut once = vec![0u8; rec.len()];
    record.write_into(&mut once);
    let again = Record::from_bytes(&once).expect("a decoded record's bytes decode");
    let mut twice = vec![0u8; rec.len()];
    again.write_into(&mut twice);
    assert_eq!(once, twice, "a record does not encode to itself");
    let sc = scenarios();
    if let Some(sr) = &record.sensors {
        for s in &sc.sensors {
            s.group.dispatch(Estimate { s, sr });
        }
    }
    let entry = match PlanEntry::from_bytes(plan) {
        Ok(e) => e,
        Err(e) => return Outcome::Rejected(kind("PlanEntry::from_bytes", &e)),
    };
    let s = match link::wire::group_kind(entry.msg.group) {
        Some(GroupKind::So3) => &sc.slews[0],
        Some(GroupKind::Se3) => &sc.slews[1],
        Some(GroupKind::Se2) => &sc.slews[2],
        None => {
            // the intake checks the group first: on either slew it is refused, typed
            let r = sc.slews[0].group.dispatch(Intake {
                s: &sc.slews[0],
                msg: &entry.msg,
            });
            return Outcome::Rejected(r.expect_err("an unknown group is refused"));
        }
    };
    match s.group.dispatch(Intake { s, msg: &entry.msg }) {
        Ok(()) => Outcome::Accepted,
        Err(e) => Outcome::Rejected(e),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seeds_are_accepted_and_their_records_hold_samples() {
        let c = Corpus::new();
        assert_eq!(c.records.len(), 8);
        assert!(c.plans.len() >= 4);
        for r in &c.records {
            for p in &c.plans {
                let mut input = r.clone();
                input.extend_from_slice(p);
                assert_eq!(check(&input), Outcome::Accepted);
            }
            assert!(Record::from_bytes(r).unwrap().sensors.is_some());
        }
    }

    #[test]
    fn so3_and_se3_are_both_seeded() {
        let c = Corpus::new();
        let groups: Vec<u32> = c
            .plans
            .iter()
            .map(|p| PlanEntry::from_bytes(p).unwrap().msg.group)
            .collect();
        assert!(groups.contains(&1) && groups.contains(&2), "{groups:?}");
    }
}

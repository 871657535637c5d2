//! The `params` board: a [`ParamMsg`] as a controller reads it before it answers a state.
//! Seeds: the boards of the first runs before any change, after one and after two (changes
//! made with the run's tuner, at cycles 40 and 120). Mutations: its fields (numbers set to
//! special values, integers to boundary values), whole gain sets scaled, symmetric pairs
//! and small perturbations of `K` and `K_d`, the sets crossed with other boards' or
//! swapped, bits flipped in its encoding. The receiver: the run's controller (now and then
//! another run's) answering a state near a set's first cycle, or anywhere.

use super::{BOARD_RUNS, CHANGE_CYCLES, Run, Seed, changes, gains, runs};
use crate::mutate::{ByteOp, byte_op, f64_value, u32_value, u64_value};
use crate::rng::Gen;
use crate::scenario_target::controller_error_kind;
use crate::{Outcome, ParamsCase, ParamsKind, ParamsReceiver};
use control_cycle::Responder;
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::{BuiltinGroup, GroupKind};
use ipc_types::{Gains, MAX_M, MAX_N, PROTOCOL_VERSION, ParamMsg, StateMsg};
use link::wire::wire_group;
use scenario::Scenario;

/// Bytes of an encoded [`Gains`]: the cycle and 70 numbers.
const GAINS_BYTES: usize = 8 + 8 * (MAX_N * MAX_N + MAX_M * MAX_M + 3 * MAX_M);
/// Bytes of an encoded [`ParamMsg`]: the header (version, group, seq, stamp, fingerprint)
/// and two gain sets (the struct's `repr(C)` layout, docs/wire.md).
pub(super) const BOARD_BYTES: usize = 32 + 2 * GAINS_BYTES;

/// The states answered are at most this far into the run (the reference is stepped there).
const SEQ_CAP: u64 = 200;

fn put_gains(out: &mut Vec<u8>, g: &Gains) {
    out.extend_from_slice(&g.cycle.to_le_bytes());
    for x in
        g.k.iter()
            .chain(&g.kd)
            .chain(&g.observer)
            .chain(&g.ki)
            .chain(&g.c)
    {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// A board's bytes: its fields in order, little-endian.
pub(super) fn encode(m: &ParamMsg) -> Vec<u8> {
    let mut out = Vec::with_capacity(BOARD_BYTES);
    out.extend_from_slice(&m.version.to_le_bytes());
    out.extend_from_slice(&m.group.to_le_bytes());
    for x in [m.seq, m.stamp_ns, m.fingerprint] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    put_gains(&mut out, &m.current);
    put_gains(&mut out, &m.previous);
    out
}

/// Reads little-endian fields off the front of a byte slice.
struct Reader<'a>(&'a [u8]);

impl Reader<'_> {
    fn take<const L: usize>(&mut self) -> [u8; L] {
        let (head, tail) = self.0.split_at(L);
        self.0 = tail;
        head.try_into().expect("split at L")
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn f64s<const L: usize>(&mut self) -> [f64; L] {
        std::array::from_fn(|_| f64::from_le_bytes(self.take()))
    }
    fn gains(&mut self) -> Gains {
        Gains {
            cycle: self.u64(),
            k: self.f64s(),
            kd: self.f64s(),
            observer: self.f64s(),
            ki: self.f64s(),
            c: self.f64s(),
        }
    }
}

/// The board of `bytes` (`None`: not [`BOARD_BYTES`] long).
pub(super) fn decode(bytes: &[u8]) -> Option<ParamMsg> {
    if bytes.len() != BOARD_BYTES {
        return None;
    }
    let mut r = Reader(bytes);
    Some(ParamMsg {
        version: r.u32(),
        group: r.u32(),
        seq: r.u64(),
        stamp_ns: r.u64(),
        fingerprint: r.u64(),
        current: r.gains(),
        previous: r.gains(),
    })
}

/// `(n, m)` of a group: the used part of `K` (n×n) and of the others (`K_d` m×m, m).
fn dims(group: GroupKind) -> (usize, usize) {
    match group {
        GroupKind::So3 | GroupKind::Se2 => (3, 3),
        GroupKind::Se3 => (4, 6),
    }
}

/// One of a set's arrays (0: `K`, 1: `K_d`, 2: the observer's `L`, 3: `K_I`, 4: `c`) and
/// the length of its used part on a group of `(n, m)`.
fn array(g: &mut Gains, which: usize, (n, m): (usize, usize)) -> (&mut [f64], usize) {
    match which {
        0 => (&mut g.k[..], n * n),
        1 => (&mut g.kd[..], m * m),
        2 => (&mut g.observer[..], m),
        3 => (&mut g.ki[..], m),
        _ => (&mut g.c[..], m),
    }
}

/// The seed boards.
pub(super) struct Seeds {
    items: Vec<Seed<ParamMsg>>,
}

impl Seeds {
    /// Each board run's board before any change, after one (from cycle 40) and after two
    /// (from cycle 120), as the plant writes them.
    pub(super) fn new() -> Seeds {
        let mut items = Vec::new();
        for (i, run) in runs().iter().take(BOARD_RUNS).enumerate() {
            let s = &run.scenario;
            let mut board = ParamMsg::new(wire_group(s.group), s.fingerprint(), gains(s, 0));
            board.stamp_ns = 5_000_000_000;
            items.push(Seed {
                run: i,
                input: board,
            });
            let mut tuner = run.tuner.clone();
            for ((key, value), cycle) in changes(run.name).iter().zip(CHANGE_CYCLES) {
                let change = tuner.apply(key, value).expect("a seed change is accepted");
                board = board.changed(gains(&change.scenario, cycle));
                board.stamp_ns += cycle * 10_000_000;
                items.push(Seed {
                    run: i,
                    input: board,
                });
            }
        }
        Seeds { items }
    }

    /// One case: a seed board with 1–8 mutations, for a receiver that mostly expects it.
    pub(super) fn generate(&self, g: &mut Gen) -> ParamsCase {
        let seed = g.pick(&self.items);
        let mut board = seed.input;
        let d = dims(runs()[seed.run].scenario.group);
        for _ in 0..g.mutation_count() {
            let op = g.pick_weighted(&BOARD_OPS);
            self.board_op(g, op, &mut board, d);
        }
        let run = if g.chance(9, 10) {
            seed.run
        } else {
            g.below(BOARD_RUNS)
        };
        let fingerprint = runs()[run].scenario.fingerprint();
        let receiver = ParamsReceiver {
            scenario: runs()[run].name,
            seq: state_seq(g, &board),
            fingerprint: match g.below(20) {
                0 => fingerprint ^ 1,
                1 => g.u64(),
                _ => fingerprint,
            },
        };
        ParamsCase {
            kind: ParamsKind::Board,
            receiver,
            bytes: encode(&board),
        }
    }

    /// Applies one mutation to `board`, whose run is on a group of dimensions `d`.
    fn board_op(&self, g: &mut Gen, op: BoardOp, board: &mut ParamMsg, d: (usize, usize)) {
        // the set the op acts on (if it acts on one): the current one mostly
        let gains = if g.chance(3, 4) {
            &mut board.current
        } else {
            &mut board.previous
        };
        match op {
            BoardOp::Bytes => {
                let mut bytes = encode(board);
                let op = *g.pick(&[ByteOp::BitFlip, ByteOp::Overwrite]);
                byte_op(g, op, &mut bytes, &[]);
                *board = decode(&bytes).expect("a flip keeps the length");
            }
            BoardOp::Entry => {
                let which = g.weighted(&[3, 3, 1, 1, 1]);
                let (xs, used) = array(gains, which, d);
                let i = if g.chance(4, 5) {
                    g.below(used)
                } else {
                    g.below(xs.len())
                };
                xs[i] = if g.chance(1, 3) {
                    plausible(g)
                } else {
                    f64_value(g)
                };
            }
            BoardOp::Int => set_int(g, board),
            BoardOp::Scale => {
                let which = g.weighted(&[3, 3, 1, 1, 1]);
                let factor = *g.pick(&FACTORS);
                let (xs, used) = array(gains, which, d);
                for x in &mut xs[..used] {
                    *x *= factor;
                }
            }
            BoardOp::Symmetric => {
                let which = g.below(2);
                let dim = if which == 0 { d.0 } else { d.1 };
                let (i, j) = (g.below(dim), g.below(dim));
                let x = if g.chance(1, 2) {
                    plausible(g)
                } else {
                    f64_value(g)
                };
                let (xs, _) = array(gains, which, d);
                xs[i * dim + j] = x;
                xs[j * dim + i] = x;
            }
            BoardOp::Perturb => {
                let which = g.below(2);
                let eps = *g.pick(&EPSILONS);
                let (xs, used) = array(gains, which, d);
                let scale = xs[..used].iter().fold(0.0f64, |a, x| a.max(x.abs()));
                let i = g.below(used);
                xs[i] += eps * scale.max(f64::MIN_POSITIVE);
            }
            BoardOp::Cross => {
                let donor = g.pick(&self.items).input;
                *gains = if g.chance(1, 2) {
                    donor.current
                } else {
                    donor.previous
                };
            }
            BoardOp::Sets => match g.below(4) {
                0 => std::mem::swap(&mut board.current, &mut board.previous),
                1 => board.previous.cycle = board.current.cycle.wrapping_add(1),
                2 => board.current.cycle = board.previous.cycle,
                _ => {
                    board.current.cycle = u64::MAX;
                    board.previous.cycle = u64::MAX;
                }
            },
        }
    }
}

/// The mutations of a board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum BoardOp {
    /// A bit flipped or a byte overwritten in the encoding.
    Bytes,
    /// One entry of a gain array set to a special or a plausible value.
    Entry,
    /// An integer field (version, group, seq, stamp, fingerprint, a set's cycle) set to a
    /// boundary or random value.
    Int,
    /// A gain array's used part multiplied by a factor (negative, zero, huge, tiny).
    Scale,
    /// `K` or `K_d`: entries (i, j) and (j, i) set to the same value.
    Symmetric,
    /// `K` or `K_d`: one entry moved by a relative epsilon (around the symmetry tolerance).
    Perturb,
    /// A set replaced by one of another seed board (maybe of the other group).
    Cross,
    /// The sets swapped, or their cycles made equal, inverted or the largest.
    Sets,
}

/// The mutations and their weights.
const BOARD_OPS: [(BoardOp, u32); 8] = [
    (BoardOp::Bytes, 6),
    (BoardOp::Entry, 30),
    (BoardOp::Int, 20),
    (BoardOp::Scale, 12),
    (BoardOp::Symmetric, 8),
    (BoardOp::Perturb, 8),
    (BoardOp::Cross, 6),
    (BoardOp::Sets, 6),
];

/// What [`BoardOp::Scale`] multiplies a gain array by.
const FACTORS: [f64; 13] = [
    -1.0, 0.0, 0.5, 2.0, 10.0, 1e3, 1e-3, 1e150, 1e-150, 1e300, 1e-300, 1e308, -0.0,
];

/// What [`BoardOp::Perturb`] moves an entry by, relative to the matrix's largest entry.
const EPSILONS: [f64; 9] = [1e-16, 1e-15, 1e-14, 1e-12, 1e-9, 1e-6, 1e-3, 0.1, -0.1];

/// A plausible gain: uniform in (-10, 10), three decimals.
fn plausible(g: &mut Gen) -> f64 {
    (g.u64() % 20_000) as f64 / 1000.0 - 10.0
}

/// One integer field of the board set to a boundary or random value (a set's cycle, often
/// a small one).
fn set_int(g: &mut Gen, b: &mut ParamMsg) {
    match g.below(7) {
        0 => b.version = u32_value(g, b.version),
        1 => b.group = u32_value(g, b.group),
        2 => b.seq = u64_value(g, b.seq),
        3 => b.stamp_ns = u64_value(g, b.stamp_ns),
        4 => b.fingerprint = u64_value(g, b.fingerprint),
        i => {
            let set = if i == 5 {
                &mut b.current
            } else {
                &mut b.previous
            };
            set.cycle = if g.chance(1, 2) {
                g.below(200) as u64
            } else {
                u64_value(g, set.cycle)
            };
        }
    }
}

/// The sequence number of the state the receiver answers: around a set's first cycle, early
/// in the run, or anywhere.
fn state_seq(g: &mut Gen, b: &ParamMsg) -> u64 {
    let near = |g: &mut Gen, c: u64| c.wrapping_add(g.below(4) as u64).wrapping_sub(1);
    match g.below(20) {
        0..=4 => near(g, b.current.cycle),
        5..=7 => near(g, b.previous.cycle),
        8..=14 => g.below(SEQ_CAP as usize) as u64,
        15 => 0,
        16 => u64::MAX,
        _ => g.u64(),
    }
}

/// The oracle: the board's gains for the receiver's state; accepted gains put in force in
/// the run's responder, which answers two states with them.
pub(super) fn check(run: &Run, r: &ParamsReceiver, bytes: &[u8]) -> Outcome {
    let Some(board) = decode(bytes) else {
        return Outcome::Rejected("ParamMsg: not a whole board".to_owned());
    };
    let group = wire_group(run.scenario.group).code();
    let gains = match board.gains_for(r.seq, group, r.fingerprint) {
        Err(e) => return Outcome::Rejected(format!("ParamMsg::gains_for: ParamInvalid::{e:?}")),
        Ok(g) => *g,
    };
    // the receiver's check of the board, as documented: its version, group and run, the
    // newest set not after the state, finite
    assert_eq!(
        board.version, PROTOCOL_VERSION,
        "gains_for: another version"
    );
    assert_eq!(board.group, group, "gains_for: another group");
    assert_eq!(board.fingerprint, r.fingerprint, "gains_for: another run");
    let expected = if r.seq >= board.current.cycle {
        board.current
    } else {
        board.previous
    };
    assert!(
        gains == expected && gains.cycle <= r.seq && gains.finite(),
        "gains_for({}) gave the set from cycle {} of a board with sets from {} and {}",
        r.seq,
        gains.cycle,
        board.current.cycle,
        board.previous.cycle
    );
    run.scenario.group.dispatch(Retuned {
        s: &run.scenario,
        gains: &gains,
        seq: r.seq,
    })
}

/// The run's responder, as `controller_node` builds it (the runs have no vehicle).
pub(super) fn responder<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    s: &Scenario,
) -> Responder<f64, G, N, M> {
    s.controller::<G, N, M>()
        .and_then(|c| Responder::new(c, s.rejection_config()))
        .expect("a run's scenario builds its responder")
}

/// Asserts that `r` runs with `gains` (its `K`, `K_d` and, for the terms it runs, `L`,
/// `K_I` and `c`), bit for bit.
fn assert_in_force<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    r: &Responder<f64, G, N, M>,
    gains: &Gains,
) {
    let same = |what: &str, xs: &mut dyn Iterator<Item = f64>, ys: &[f64]| {
        assert!(
            xs.zip(ys).all(|(x, y)| x.to_bits() == y.to_bits()),
            "retune: {what} not in force"
        );
    };
    let config = r.controller().config();
    // nalgebra iterates column-major: compare with the transposes
    same(
        "K",
        &mut config.k.transpose().iter().copied(),
        &gains.k[..N * N],
    );
    same(
        "K_d",
        &mut config.kd.transpose().iter().copied(),
        &gains.kd[..M * M],
    );
    let Some(terms) = r.rejection() else {
        return;
    };
    let c = terms.config();
    if let Some(o) = &c.observer {
        same("L", &mut o.gain.iter().copied(), &gains.observer[..M]);
    }
    if let Some(i) = &c.integral {
        same("K_I", &mut i.ki.iter().copied(), &gains.ki[..M]);
        same("c", &mut i.c.iter().copied(), &gains.c[..M]);
    }
}

/// The controller's side of accepted gains: the run's responder retuned, then answering
/// two consecutive states of the scenario's body from the receiver's (at most [`SEQ_CAP`]).
pub(super) struct Retuned<'a> {
    pub(super) s: &'a Scenario,
    pub(super) gains: &'a Gains,
    pub(super) seq: u64,
}

impl OnGroup for Retuned<'_> {
    type Output = Outcome;

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Outcome {
        let s = self.s;
        let mut retuned = responder::<G, N, M>(s);
        if let Err(e) = retuned.retune(self.gains) {
            return Outcome::Rejected(format!(
                "Responder::retune: eqtrack_controller::Error::{}",
                controller_error_kind(&e)
            ));
        }
        assert_in_force(&retuned, self.gains);
        // the scenario's own gains: the retuned responder answers as one never retuned
        let mut fresh = (gains(s, self.gains.cycle) == *self.gains).then(|| {
            (
                responder::<G, N, M>(s),
                s.reference_source::<G, N, M>()
                    .expect("the run's reference"),
            )
        });
        let mut body = s.plant_body::<G, N, M>().expect("the run's plant");
        let mut reference = s
            .reference_source::<G, N, M>()
            .expect("the run's reference");
        let mut applied = nalgebra::SVector::<f64, M>::zeros();
        let k0 = self.seq.min(SEQ_CAP);
        for k in k0..k0 + 2 {
            let mut st = StateMsg::new(wire_group(G::KIND));
            st.seq = k;
            st.t = k as f64 * s.control_period;
            st.control_period = s.control_period;
            st.set_state(body.configuration(), &body.velocity());
            st.set_applied(&applied);
            st.flags = ipc_types::flags::TUNABLE;
            st.fingerprint = s.fingerprint();
            let cmd = match retuned.respond(&mut reference, &st) {
                Ok(c) => c,
                Err(e) => {
                    return Outcome::Rejected(format!(
                        "Responder::respond: eqtrack_controller::Error::{}",
                        controller_error_kind(&e)
                    ));
                }
            };
            assert!(
                cmd.tau
                    .iter()
                    .chain(&cmd.observer)
                    .chain(&cmd.integral)
                    .all(|x| x.is_finite()),
                "a retuned responder answered with a non-finite number: tau {:?}, observer {:?}, integral {:?}",
                cmd.tau,
                cmd.observer,
                cmd.integral
            );
            if let Some((f, fr)) = &mut fresh {
                let before = f
                    .respond(fr, &st)
                    .expect("the scenario's own gains answer what they answered retuned");
                assert_eq!(
                    before.to_bytes(),
                    cmd.to_bytes(),
                    "retuned to the scenario's own gains, the responder answers otherwise"
                );
            }
            let torque = cmd.torque::<M>();
            body.advance(
                &(torque + s.disturbance_vector::<M>()),
                s.control_period,
                s.plant_substeps,
            );
            applied = torque;
        }
        Outcome::Accepted
    }
}

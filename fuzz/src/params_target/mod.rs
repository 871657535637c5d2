//! The params target: the run-time parameters of a tunable run, three inputs, a third of
//! the cases each (docs/live.md, "Tuning a running pair").
//!
//! * `board`: the `params` board ([`ipc_types::ParamMsg`]) a controller reads before it
//!   answers a state, through `gains_for` for that state; accepted gains through
//!   `control_cycle::Responder::retune` (the responder built as `controller_node` builds
//!   it), and the retuned responder answering two states of the scenario's body (a finite
//!   torque, and the scenario's own gains answer bit for bit as before the retune).
//! * `request`: a `param` request ([`ipc_types::ParamRequest`]) through
//!   `link::params::read_request`, then `scenario::tuning::Tuner::get` or `check`; an
//!   accepted change's scenario validates again, builds its controller and terms, resolves
//!   to non-empty finite numbers, and the running pair takes it (the controller's retune,
//!   or the estimator's); the answer's wire form is cut at a character boundary.
//! * `log`: `params.log` text through `recorder::params::parse_params`; an accepted file's
//!   changes, re-serialized (header and `serde_json` lines), parse back bit for bit, and
//!   replay applies the first ones with the tuner.
//!
//! The runs (`RUNS`): the built-in `seed` and `se3_circle`, the shipped `reject_so3` (the
//! observer), the same with an integral term (`reject_so3_integral`), and the shipped
//! `sensors_so3` (the estimator's gains).

mod board;
mod log;
mod request;
#[cfg(test)]
mod tests;

use crate::rng::Gen;
use crate::{Outcome, ParamsCase, ParamsKind};
use scenario::Scenario;
use scenario::tuning::Tuner;
use std::sync::OnceLock;

/// The runs' names: the scenarios the inputs are read for. The boards are those of the
/// first [`BOARD_RUNS`].
const RUNS: [&str; 5] = [
    "seed",
    "se3_circle",
    "reject_so3",
    "reject_so3_integral",
    "sensors_so3",
];

/// The runs that have boards (the estimator's gains are not on the board).
const BOARD_RUNS: usize = 4;

/// A run: its scenario and its tuner (the scenario's TOML table with its `name`, as the
/// plant's parameter thread has it).
struct Run {
    name: &'static str,
    scenario: Scenario,
    tuner: Tuner,
}

/// The text of run `name`'s scenario: a built-in, or a file in `scenarios/` (the integral
/// variant adds `integral = { ki = 1.0, c = 5.0 }` to `reject_so3`'s controller).
fn scenario_text(name: &str) -> String {
    if let Some((_, text)) = scenario::BUILTINS.iter().find(|(n, _)| *n == name) {
        return (*text).to_owned();
    }
    let file = name.strip_suffix("_integral").unwrap_or(name);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(format!("{file}.toml"));
    let text = std::fs::read_to_string(&path).expect("a shipped scenario reads");
    if file == name {
        text
    } else {
        text.replacen(
            "\n[controller]\n",
            "\n[controller]\nintegral = { ki = 1.0, c = 5.0 }\n",
            1,
        )
    }
}

/// The runs, built on first use.
fn runs() -> &'static [Run] {
    static RUNS_BUILT: OnceLock<Vec<Run>> = OnceLock::new();
    RUNS_BUILT.get_or_init(|| {
        RUNS.iter()
            .map(|name| {
                let mut table: toml::Table =
                    toml::from_str(&scenario_text(name)).expect("a seed scenario parses");
                table.insert("name".into(), toml::Value::String((*name).into()));
                let tuner = Tuner::new(table, "param set", None).expect("a seed scenario loads");
                Run {
                    name,
                    scenario: tuner.scenario().clone(),
                    tuner,
                }
            })
            .collect()
    })
}

/// One seed input (a board, a request or a `params.log` text) and the index of the run it
/// is for in [`runs`].
#[derive(Debug, Clone)]
struct Seed<T> {
    run: usize,
    input: T,
}

/// The run named `name` (`None`: not one of [`RUNS`]).
fn run_named(name: &str) -> Option<&'static Run> {
    runs().iter().find(|r| r.name == name)
}

/// The seed corpus and the mutator of the params target.
pub(crate) struct Corpus {
    boards: board::Seeds,
    requests: request::Seeds,
    logs: log::Seeds,
}

impl Corpus {
    /// The seed boards, requests and `params.log` files.
    pub(crate) fn new() -> Corpus {
        Corpus {
            boards: board::Seeds::new(),
            requests: request::Seeds::new(),
            logs: log::Seeds::new(),
        }
    }

    /// One case: a board, a request or a log (a third each), mutated.
    pub(crate) fn generate(&self, g: &mut Gen) -> ParamsCase {
        match g.below(3) {
            0 => self.boards.generate(g),
            1 => self.requests.generate(g),
            _ => self.logs.generate(g),
        }
    }
}

/// The oracle of one params case, by its kind.
pub(crate) fn check(case: &ParamsCase) -> Outcome {
    let Some(run) = run_named(case.receiver.scenario) else {
        return Outcome::Rejected("params: no such run".to_owned());
    };
    match case.kind {
        ParamsKind::Board => board::check(run, &case.receiver, &case.bytes),
        ParamsKind::Request => request::check(run, &case.bytes),
        ParamsKind::Log => log::check(run, &case.bytes),
    }
}

/// The changes a run's seeds make (key, value), in order, with its tuner (at cycles 40 and
/// 120).
fn changes(run: &str) -> [(&'static str, &'static str); 2] {
    match run {
        "seed" => [
            ("kd", "0.8"),
            ("kp", "[[1.0, 0.1, 0.0], [0.1, 2.0, 0.0], [0.0, 0.0, 3.0]]"),
        ],
        "se3_circle" => [
            ("kd", "2.0"),
            (
                "kp",
                "[[2.0, 0.0, 0.0, 0.0], [0.0, 1.2, 0.0, 0.0], [0.0, 0.0, 1.4, 0.0], [0.0, 0.0, 0.0, 4.0]]",
            ),
        ],
        "reject_so3" => [
            ("controller.disturbance_observer.gain", "30.0"),
            ("kd", "[[0.3, 0.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.0, 0.4]]"),
        ],
        "reject_so3_integral" => [
            ("controller.integral.ki", "2.0"),
            ("controller.integral.c", "[4.0, 5.0, 6.0]"),
        ],
        _ => [("estimator.kp", "3.0"), ("estimator.ki", "0.1")],
    }
}

/// The cycles the seed changes take effect at.
const CHANGE_CYCLES: [u64; 2] = [40, 120];

/// The gains of a scenario as the `params` board carries them (what the plant writes).
fn gains(s: &Scenario, cycle: u64) -> ipc_types::Gains {
    plant::tuning::gains(s, cycle)
}

//! `fuzz`: runs the stable-Rust fuzz harness on its targets, prints a report per target, and
//! exits 1 if any case panicked.
//!
//! ```text
//! fuzz [--target scenario|wire|path|recording|serial|shard|params|live|all] [--cases N] [--seed S] [--save]
//! fuzz --target wire --seed S --case I     # replay one case, panics not caught
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use clap::{Parser, ValueEnum};
use fuzz::{Outcome, Target};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Which targets to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Which {
    /// Scenario TOML.
    Scenario,
    /// Wire messages.
    Wire,
    /// Waypoint files and streamed path segments.
    Path,
    /// Flight recordings: records with sensor blocks, plan entries.
    Recording,
    /// The processor-in-the-loop serial line's frames.
    Serial,
    /// A Monte Carlo shard's bytes.
    Shard,
    /// Run-time parameters: the params board, param requests, params.log.
    Params,
    /// The live bridge's client messages: parser and session subscriptions.
    Live,
    /// Every target.
    All,
}

/// Fuzz the untrusted inputs (scenario TOML, wire messages, …) on stable Rust: deterministic,
/// seeded, mutation-based; fails when a case panics.
#[derive(Debug, Parser)]
#[command(name = "fuzz", version)]
struct Args {
    /// The target(s).
    #[arg(long, value_enum, default_value_t = Which::All)]
    target: Which,
    /// Cases per target.
    #[arg(long, default_value_t = 1_000_000)]
    cases: u64,
    /// The seed (case I of seed S is always the same input).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the panicking inputs to the findings directory.
    #[arg(long)]
    save: bool,
    /// The findings directory (default: target/fuzz-findings of the workspace).
    #[arg(long, requires = "save")]
    findings_dir: Option<PathBuf>,
    /// Replay one case without catching panics (the default panic hook prints it).
    #[arg(long, conflicts_with_all = ["cases", "save"])]
    case: Option<u64>,
}

fn targets(which: Which) -> Vec<Target> {
    match which {
        Which::Scenario => vec![Target::Scenario],
        Which::Wire => vec![Target::Wire],
        Which::Path => vec![Target::Path],
        Which::Recording => vec![Target::Recording],
        Which::Serial => vec![Target::Serial],
        Which::Shard => vec![Target::Shard],
        Which::Params => vec![Target::Params],
        Which::Live => vec![Target::Live],
        Which::All => Target::ALL.to_vec(),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(case) = args.case {
        for target in targets(args.target) {
            print_replay(target, args.seed, case);
        }
        return ExitCode::SUCCESS;
    }

    let dir = args
        .findings_dir
        .clone()
        .unwrap_or_else(fuzz::default_findings_dir);
    let start = Instant::now();
    let mut failed = false;
    for target in targets(args.target) {
        if !run_target(&args, target, &dir) {
            failed = true;
        }
    }
    println!(
        "total {:.2} s: {}",
        start.elapsed().as_secs_f64(),
        if failed { "PANICS FOUND" } else { "no panic" }
    );
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// Replays case `case` of seed `seed` on `target` (panics not caught) and prints it: the
/// case's context, its input and its outcome.
fn print_replay(target: Target, seed: u64, case: u64) {
    let (input, outcome) = fuzz::replay(target, seed, case);
    let context = input.context();
    println!("{target} case {case} of seed {seed}");
    if !context.is_empty() {
        println!("  {context}");
    }
    print_input(&input);
    match outcome {
        Outcome::Accepted => println!("  accepted"),
        Outcome::Rejected(kind) => println!("  rejected: {kind}"),
    }
}

/// Prints a replayed case's input: text inputs as (lossy) text, binary inputs as hex.
fn print_input(input: &fuzz::Case) {
    match input {
        fuzz::Case::Scenario(b)
        | fuzz::Case::Path(b)
        | fuzz::Case::Params(fuzz::ParamsCase {
            kind: fuzz::ParamsKind::Log,
            bytes: b,
            ..
        }) => {
            println!("  input:\n{}", String::from_utf8_lossy(b))
        }
        fuzz::Case::Live(b) => {
            println!("  input ({} bytes):", b.len());
            for m in fuzz::live_messages(b) {
                match m {
                    fuzz::LiveMessage::Text(t) => println!("    text {t:?}"),
                    fuzz::LiveMessage::Binary(b) => {
                        let hex: String = b.iter().map(|x| format!("{x:02x}")).collect();
                        println!("    binary {hex}");
                    }
                }
            }
        }
        fuzz::Case::Wire(fuzz::WireCase { bytes, .. })
        | fuzz::Case::Recording(bytes)
        | fuzz::Case::Serial(bytes)
        | fuzz::Case::Shard(bytes)
        | fuzz::Case::Params(fuzz::ParamsCase { bytes, .. }) => {
            let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
            println!("  input ({} bytes): {hex}", bytes.len())
        }
    }
}

/// Runs `args.cases` cases of `target` with a progress bar, prints the report and saves the
/// findings if asked; returns whether the target passed (no case panicked).
fn run_target(args: &Args, target: Target, dir: &Path) -> bool {
    let bar = progress_bar(target, args.cases);
    // Without a terminal indicatif draws nothing: print a line every 10 % instead.
    let hidden = bar.is_hidden();
    let tenth = (args.cases / 10).max(1);
    let mut next_line = tenth;
    let t0 = Instant::now();
    let report = fuzz::run_with(target, args.seed, 0..args.cases, fuzz::check, |done| {
        bar.set_position(done);
        if hidden && done >= next_line && done < args.cases {
            next_line += tenth;
            eprintln!(
                "fuzz: {target}: {done}/{} cases, {:.0} cases/s",
                args.cases,
                done as f64 / t0.elapsed().as_secs_f64().max(1e-9)
            );
        }
    });
    bar.finish_and_clear();
    println!("{report}");
    if report.passed() {
        return true;
    }
    if args.save {
        save_findings(&report, dir);
    }
    false
}

/// The progress bar of one target's run of `cases` cases, prefixed with the target's name.
fn progress_bar(target: Target, cases: u64) -> ProgressBar {
    let bar = ProgressBar::new(cases);
    bar.set_style(
        ProgressStyle::with_template(
            "{prefix:>8} [{elapsed_precise}] {wide_bar} {pos}/{len} ({per_sec}, eta {eta})",
        )
        .expect("valid progress template"),
    );
    bar.set_prefix(target.name());
    bar
}

/// Writes each panicking input of `report` to `dir`, printing where (or why not).
fn save_findings(report: &fuzz::Report, dir: &Path) {
    for finding in &report.panics {
        match finding.save(dir) {
            Ok(path) => println!("  saved {}", path.display()),
            Err(e) => {
                eprintln!("fuzz: cannot save a finding in {}: {e}", dir.display())
            }
        }
    }
}

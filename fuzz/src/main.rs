//! `fuzz`: runs the stable-Rust fuzz harness on the scenario, wire and path targets, prints a report
//! per target, and exits 1 if any case panicked.
//!
//! ```text
//! fuzz [--target scenario|wire|path|recording|all] [--cases N] [--seed S] [--save]
//! fuzz --target wire --seed S --case I     # replay one case, panics not caught
//! ```
#![forbid(unsafe_code)]
#![warn(missing_docs)]

use clap::{Parser, ValueEnum};
use fuzz::{Outcome, Target};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
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
    /// Every target.
    All,
}

/// Fuzz the untrusted inputs (scenario TOML, wire messages) on stable Rust: deterministic,
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
        Which::All => Target::ALL.to_vec(),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    if let Some(case) = args.case {
        for target in targets(args.target) {
            let (input, outcome) = fuzz::replay(target, args.seed, case);
            let context = input.context();
            println!("{target} case {case} of seed {}", args.seed);
            if !context.is_empty() {
                println!("  {context}");
            }
            match &input {
                fuzz::Case::Scenario(b) | fuzz::Case::Path(b) => {
                    println!("  input:\n{}", String::from_utf8_lossy(b))
                }
                fuzz::Case::Wire(fuzz::WireCase { bytes, .. }) | fuzz::Case::Recording(bytes) => {
                    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
                    println!("  input ({} bytes): {hex}", bytes.len())
                }
            }
            match outcome {
                Outcome::Accepted => println!("  accepted"),
                Outcome::Rejected(kind) => println!("  rejected: {kind}"),
            }
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
        let bar = ProgressBar::new(args.cases);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>8} [{elapsed_precise}] {wide_bar} {pos}/{len} ({per_sec}, eta {eta})",
            )
            .expect("valid progress template"),
        );
        bar.set_prefix(target.name());
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
        if !report.passed() {
            failed = true;
            if args.save {
                for finding in &report.panics {
                    match finding.save(&dir) {
                        Ok(path) => println!("  saved {}", path.display()),
                        Err(e) => {
                            eprintln!("fuzz: cannot save a finding in {}: {e}", dir.display())
                        }
                    }
                }
            }
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

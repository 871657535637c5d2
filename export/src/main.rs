//! `eqtrack-export`: a run's flight recording to MCAP (what `plant_sim export` runs).
//!
//! ```text
//! eqtrack-export OUT_DIR [--format mcap|jsonl] [--out FILE] [--compress]
//! ```
//!
//! Reads `OUT_DIR/messages.log` and writes `OUT_DIR/run.mcap` (or `run.jsonl`, or `--out`).
//! Exit codes as the other binaries': 0 done, 1 the output cannot be written, 2 bad input.
#![cfg_attr(not(test), warn(clippy::too_many_lines))]

use clap::{Parser, ValueEnum};
use export::{Format, export};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum FormatArg {
    /// MCAP, `ros2msg` schemas and CDR messages (Foxglove, PlotJuggler, Rerun).
    Mcap,
    /// One JSON object per message (the same messages; for checks and scripts).
    Jsonl,
}

#[derive(Parser)]
#[command(
    name = "eqtrack-export",
    version,
    about = "Exports a run's flight recording (messages.log) to MCAP"
)]
struct Cli {
    /// The run's output directory (holding messages.log), or the log file itself.
    #[arg(value_name = "OUT_DIR")]
    dir: PathBuf,
    /// The output format.
    #[arg(long, value_enum, default_value_t = FormatArg::Mcap)]
    format: FormatArg,
    /// The output file (default: OUT_DIR/run.mcap or OUT_DIR/run.jsonl).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// zstd-compress the MCAP chunks (needs the `zstd` feature).
    #[arg(long)]
    compress: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let log = if cli.dir.is_dir() {
        cli.dir.join(recorder::LOG_FILE)
    } else {
        cli.dir.clone()
    };
    let (format, name) = match cli.format {
        FormatArg::Mcap => (Format::Mcap, "run.mcap"),
        FormatArg::Jsonl => (Format::Jsonl, "run.jsonl"),
    };
    let out = cli.out.unwrap_or_else(|| {
        log.parent()
            .map_or_else(|| PathBuf::from(name), |d| d.join(name))
    });
    let started = Instant::now();
    match export(&log, &out, format, cli.compress) {
        Ok(done) => {
            let total: u64 = done.messages.values().sum();
            let per_topic: Vec<String> = done
                .messages
                .iter()
                .map(|(t, n)| format!("{t} {n}"))
                .collect();
            println!(
                "exported {} records of {} as {total} messages ({}) to {} in {:.2} s",
                done.records,
                log.display(),
                per_topic.join(", "),
                out.display(),
                started.elapsed().as_secs_f64()
            );
            if done.trailing_bytes > 0 {
                println!(
                    "the log ends {} bytes into a record (a recording cut short): exported up to the last whole record",
                    done.trailing_bytes
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("eqtrack-export: error: {e}");
            ExitCode::from(match e {
                export::ExportError::Input(_) => 2,
                export::ExportError::Output(_) => 1,
            })
        }
    }
}

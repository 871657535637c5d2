//! `plant_sim export`: runs `eqtrack-export` on a recording.

use clap::Args;
use plant::SimError;
use std::path::PathBuf;

#[derive(Args)]
pub(crate) struct ExportArgs {
    /// The run's output directory (holding messages.log).
    #[arg(value_name = "OUT_DIR")]
    dir: PathBuf,
    /// `mcap` (default), or `jsonl`: one JSON object per message, the same messages.
    #[arg(long, value_name = "FORMAT", default_value = "mcap", value_parser = ["mcap", "jsonl"])]
    format: String,
    /// The output file (default: OUT_DIR/run.mcap).
    #[arg(long, value_name = "FILE")]
    out: Option<PathBuf>,
    /// zstd-compress the MCAP chunks (eqtrack-export built with its `zstd` feature).
    #[arg(long)]
    compress: bool,
}

/// Runs `eqtrack-export` (beside this binary) with the same arguments; its exit status.
pub(crate) fn export_cmd(args: ExportArgs) -> Result<(), SimError> {
    let exe = std::env::current_exe()
        .map_err(|e| SimError::Run(format!("cannot locate plant_sim: {e}")))?;
    let path = exe.with_file_name("eqtrack-export");
    if !path.exists() {
        return Err(SimError::Run(format!(
            "{} not found: build it (cargo build --release --workspace)",
            path.display()
        )));
    }
    let mut cmd = std::process::Command::new(&path);
    cmd.arg(&args.dir).args(["--format", &args.format]);
    if let Some(out) = &args.out {
        cmd.arg("--out").arg(out);
    }
    if args.compress {
        cmd.arg("--compress");
    }
    let status = cmd
        .status()
        .map_err(|e| SimError::Run(format!("cannot start {}: {e}", path.display())))?;
    match status.code() {
        Some(0) => Ok(()),
        Some(2) => Err(SimError::Input(
            "the export refused its input (above)".to_owned(),
        )),
        _ => Err(SimError::Run(format!("eqtrack-export: {status}"))),
    }
}

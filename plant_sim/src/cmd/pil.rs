//! The processor-in-the-loop firmware's controller in process (`plant_sim sim
//! --controller-scalar f32`; docs/pil.md): the plant of the pair in lockstep, talking the
//! serial protocol to a `firmware_cycle::Cycle` built from the same configuration bytes the
//! firmware is built with. Every frame is encoded, framed and decoded as on the wire, so a
//! processor-in-the-loop run and this one differ only if the microcontroller computes
//! differently.

use eqtrack_serial_wire::{Deframer, MAX_ENCODED, encode};
use firmware_cycle::{Cycle, MAX_CONFIG};
use link::StopFlag;
use link::serial::{ByteLink, SerialCounts};
use plant::SimError;
use plant::pair::{Mode, PairOptions, SerialController, run_pair};
use scenario::Scenario;
use scenario::cli::ScenarioSource;
use std::collections::VecDeque;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// The firmware's configuration bytes for scenario `s` (what `scripts/pil.sh` builds the
/// firmware with, and what the in-process controller starts from).
pub(crate) fn config_bytes(s: &Scenario) -> Result<Vec<u8>, SimError> {
    let config = s.firmware_config()?;
    let mut buf = [0u8; MAX_CONFIG];
    let n = config
        .to_bytes(&mut buf)
        .map_err(|e| SimError::Input(format!("scenario `{}`: {e}", s.name)))?;
    Ok(buf[..n].to_vec())
}

/// The firmware's cycle behind a byte stream: bytes written are deframed and answered at once.
struct CycleLink {
    cycle: Cycle,
    deframer: Deframer,
    replies: VecDeque<u8>,
    frame: [u8; MAX_ENCODED],
}

impl ByteLink for CycleLink {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        for b in bytes {
            if let Some(Ok(frame)) = self.deframer.push(*b)
                && let Some(reply) = self.cycle.on_frame(&frame)
            {
                let n = encode(&reply, &mut self.frame)
                    .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
                self.replies.extend(&self.frame[..n]);
            }
        }
        Ok(())
    }
    fn read_some(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = buf.len().min(self.replies.len());
        for (o, b) in buf.iter_mut().zip(self.replies.drain(..n)) {
            *o = b;
        }
        Ok(n)
    }
    fn wait_readable(&mut self, timeout: Duration) {
        if self.replies.is_empty() {
            std::thread::sleep(timeout.min(Duration::from_millis(1)));
        }
    }
}

/// `sim --controller-scalar f32`: writes the lockstep pair's outputs into `out`.
pub(crate) fn sim_f32(
    s: Scenario,
    source: &ScenarioSource,
    out: Option<PathBuf>,
    stop: &StopFlag,
) -> Result<(), SimError> {
    let bytes = config_bytes(&s)?;
    // checked once here, where a bad configuration is the caller's error
    Cycle::from_bytes(&bytes)
        .map_err(|e| SimError::Input(format!("scenario `{}`: {e}", s.name)))?;
    let open = move || -> Result<Box<dyn ByteLink>, link::LinkError> {
        let cycle = Cycle::from_bytes(&bytes).map_err(|e| link::LinkError::Serial {
            what: "building the f32 controller".to_owned(),
            source: io::Error::new(io::ErrorKind::InvalidData, e.to_string()),
        })?;
        Ok(Box::new(CycleLink {
            cycle,
            deframer: Deframer::new(),
            replies: VecDeque::with_capacity(4 * MAX_ENCODED),
            frame: [0; MAX_ENCODED],
        }))
    };
    let out = out.unwrap_or_else(|| Path::new("out").join(format!("{}-f32", s.name)));
    let opts = PairOptions {
        source: source.clone(),
        record: false,
        thread_allocations: None,
        mode: Mode::Lockstep,
        rate_hz: 1.0 / s.control_period,
        wake: link::Wake::Event,
        transport: link::TransportKind::Iceoryx2,
        spawn: false,
        serial: Some(SerialController {
            name: "the in-process f32 controller".to_owned(),
            open: Arc::new(open),
            counts: Arc::new(SerialCounts::default()),
            corrupt: None,
            noise: None,
        }),
        run: format!("f32-{}", std::process::id()),
        out,
        miss_limit: 3,
        rt: link::rt::RtSettings::default(),
        controller_rt: link::rt::RtSettings::default(),
        record_every: 1,
        lockstep_timeout: Duration::from_secs(5),
        connect_timeout: Duration::from_secs(5),
        state_faults: Vec::new(),
        controller_fault_nan_torque: None,
        sample_faults: Vec::new(),
        tunable: false,
        stop: stop.clone(),
        scenario: s,
    };
    plant::trajectory::warn_world_frame(&opts.scenario, opts.scenario.steps());
    let (traj, summary) = run_pair(&opts)?;
    super::run::print_pair_summary(&summary, &opts.scenario.law_label(), &opts.out);
    super::sim::diverged(&traj, &opts.out)
}

/// `plant_sim pil-config`.
#[derive(clap::Args)]
pub(crate) struct PilConfigArgs {
    #[command(flatten)]
    source: ScenarioSource,
    /// Where to write the configuration's bytes.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
}

pub(crate) fn pil_config_cmd(args: PilConfigArgs) -> Result<(), SimError> {
    let s = args.source.load("seed")?;
    let bytes = config_bytes(&s)?;
    Cycle::from_bytes(&bytes)
        .map_err(|e| SimError::Input(format!("scenario `{}`: {e}", s.name)))?;
    std::fs::write(&args.out, &bytes)
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", args.out.display())))?;
    println!(
        "scenario `{}`: {} bytes of firmware configuration in {} (group {}, period {} s, fingerprint {:016x})",
        s.name,
        bytes.len(),
        args.out.display(),
        s.group.name(),
        s.control_period,
        s.fingerprint()
    );
    Ok(())
}

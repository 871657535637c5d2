//! The controller process that `plant_sim run` starts by itself: killed and reaped on drop,
//! so no zombie outlives the plant (a zombie's iceoryx2 node would never look dead).

use crate::SimError;
use crate::pair::PairOptions;
use link::TransportKind;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// The spawned `controller_node`, if any, and where it writes its real-time report.
pub struct Spawned(Option<Child>, Option<PathBuf>);

impl Spawned {
    /// Starts `controller_node` from this executable's directory with the run's scenario,
    /// name, transport and the controller's real-time settings; it writes what those did to
    /// `controller-realtime.json` in the output directory (nothing with `--no-spawn`).
    pub fn start(opts: &PairOptions) -> Result<Spawned, SimError> {
        if !opts.spawn || opts.serial.is_some() {
            return Ok(Spawned(None, None));
        }
        let exe = std::env::current_exe()
            .map_err(|e| SimError::Run(format!("cannot locate plant_sim: {e}")))?;
        let path = exe.with_file_name("controller_node");
        if !path.exists() {
            return Err(SimError::Run(format!(
                "{} not found: build it (cargo build --release --workspace) or start one by hand and pass --no-spawn",
                path.display()
            )));
        }
        let report = opts.out.join("controller-realtime.json");
        // a report left by an earlier run in the same directory must not stand in for this one
        let _ = std::fs::remove_file(&report);
        let mut cmd = Command::new(&path);
        cmd.args(opts.source.args("seed"))
            .args(["--name", &opts.run])
            .args(opts.controller_rt.args())
            .arg("--rt-report")
            .arg(&report)
            .stdin(Stdio::null());
        // the service manager's watchdog is the plant's: the controller it starts does not
        // answer to it (docs/pair-on-a-board.md, "Watchdogs")
        for var in [
            link::notify::SOCKET_VAR,
            link::notify::WATCHDOG_USEC_VAR,
            link::notify::WATCHDOG_PID_VAR,
        ] {
            cmd.env_remove(var);
        }
        if opts.transport == TransportKind::Uds {
            cmd.args(["--transport", "uds"]);
        }
        if let Some(k) = opts.controller_fault_nan_torque {
            cmd.args(["--fault-nan-torque", &k.to_string()]);
        }
        let child = cmd
            .spawn()
            .map_err(|e| SimError::Run(format!("cannot start {}: {e}", path.display())))?;
        eprintln!("plant_sim: started controller_node (pid {})", child.id());
        Ok(Spawned(Some(child), Some(report)))
    }

    /// Where the spawned controller writes its real-time report (`None`: not spawned).
    pub fn rt_report(&self) -> Option<&Path> {
        self.1.as_deref()
    }

    /// Its exit status, if it has exited.
    pub fn exited(&mut self) -> Option<ExitStatus> {
        self.0.as_mut().and_then(|c| c.try_wait().ok().flatten())
    }

    /// Waits up to `grace` for it to exit (then kills it); its exit code.
    pub fn finish(&mut self, grace: Duration) -> Option<i32> {
        let mut child = self.0.take()?;
        let until = Instant::now() + grace;
        loop {
            if let Ok(Some(status)) = child.try_wait() {
                return status.code();
            }
            if Instant::now() > until {
                let _ = child.kill();
                let _ = child.wait();
                eprintln!("plant_sim: controller_node did not exit within {grace:?}; killed");
                return None;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

impl Drop for Spawned {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

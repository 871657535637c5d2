//! Real-time settings of a process on a board: SCHED_FIFO priority, CPU affinity and locked
//! memory, applied once at start-up (docs/architecture.md, "Real-time settings"). A setting
//! the operating system refuses is a warning, not a failure: the process runs without it, and
//! the [`RtReport`] says what was applied, what was refused and why.

use nix::sched::{CpuSet, sched_getaffinity, sched_setaffinity};
use nix::sys::mman::{MlockAllFlags, mlockall};
use nix::unistd::Pid;
use std::fmt;

/// Bytes of stack written once by `--lock-memory`, so that its pages are resident (and,
/// with every future page locked, stay so) before the loop runs.
pub const PRETOUCHED_STACK: usize = 512 * 1024;

/// What to apply (the command line's `--rt-priority`, `--cpu`, `--lock-memory`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::Args))]
pub struct RtSettings {
    /// Run under SCHED_FIFO at this priority (1-99; needs CAP_SYS_NICE or an RLIMIT_RTPRIO
    /// of at least N, e.g. systemd's LimitRTPRIO).
    #[cfg_attr(feature = "clap", arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=99)))]
    pub rt_priority: Option<u8>,
    /// Pin the process to these CPUs, e.g. `1`, `0,2` or `2-3`.
    #[cfg_attr(feature = "clap", arg(long, value_name = "LIST", value_parser = parse_cpu_list))]
    pub cpu: Option<CpuList>,
    /// Lock all current and future pages in memory (mlockall) and pre-touch the stack, so the
    /// loop never waits for a page fault (needs CAP_IPC_LOCK or a large RLIMIT_MEMLOCK).
    #[cfg_attr(feature = "clap", arg(long))]
    pub lock_memory: bool,
}

/// A set of CPU numbers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CpuList(pub Vec<usize>);

impl fmt::Display for CpuList {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self.0.iter().map(usize::to_string).collect();
        f.write_str(&parts.join(","))
    }
}

/// Parses `1`, `0,2`, `2-3`, `0,2-3` (sorted, without repeats).
pub fn parse_cpu_list(text: &str) -> Result<CpuList, String> {
    let mut cpus = Vec::new();
    for part in text.split(',').map(str::trim) {
        let num = |s: &str| {
            s.trim()
                .parse::<usize>()
                .map_err(|_| format!("`{s}` in `{text}` is not a CPU number"))
        };
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b) = (num(a)?, num(b)?);
                if a > b {
                    return Err(format!("`{part}` in `{text}`: a range must go upwards"));
                }
                cpus.extend(a..=b);
            }
            None => cpus.push(num(part)?),
        }
    }
    if let Some(big) = cpus.iter().find(|&&c| c >= CpuSet::count()) {
        return Err(format!(
            "CPU {big} in `{text}`: at most {} CPUs can be named",
            CpuSet::count()
        ));
    }
    cpus.sort_unstable();
    cpus.dedup();
    Ok(CpuList(cpus))
}

/// One setting the operating system refused, and its reason.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Refused {
    /// `rt-priority`, `cpu` or `lock-memory`.
    pub setting: String,
    /// The OS's reason, e.g. `EPERM: Operation not permitted`.
    pub reason: String,
}

/// What [`RtSettings::apply`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RtReport {
    /// The process the settings were applied to.
    pub pid: u32,
    /// Settings in force, e.g. `SCHED_FIFO priority 80`, `cpu 1`, `memory locked`.
    pub applied: Vec<String>,
    /// Settings asked for and refused.
    pub refused: Vec<Refused>,
    /// The CPUs the process may run on after applying (read back).
    pub cpus_allowed: Vec<usize>,
    /// The scheduling policy and priority after applying (read back), e.g. `SCHED_FIFO 80`.
    pub scheduler: String,
}

impl RtReport {
    /// One line per setting for the log (`applied: ...`, `REFUSED ...: reason`).
    pub fn lines(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .applied
            .iter()
            .map(|a| format!("applied: {a}"))
            .collect();
        v.extend(self.refused.iter().map(|r| {
            format!(
                "warning: --{} refused ({}); running without it",
                r.setting, r.reason
            )
        }));
        v
    }

    /// Writes the report as JSON to `path` (through a temporary file and a rename, so a
    /// reader never sees half of it). `controller_node --rt-report FILE` uses it to tell the
    /// plant that started it what it applied (docs/architecture.md, "Real-time settings").
    pub fn write_json(&self, path: &std::path::Path) -> std::io::Result<()> {
        let tmp = path.with_extension("json.part");
        let text = serde_json::to_string_pretty(self).map_err(std::io::Error::other)?;
        std::fs::write(&tmp, text + "\n")?;
        std::fs::rename(&tmp, path)
    }

    /// Reads a report written by [`RtReport::write_json`].
    pub fn read_json(path: &std::path::Path) -> Result<RtReport, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
    }
}

fn errno(e: nix::errno::Errno) -> String {
    format!("{e:?}: {}", e.desc())
}

fn allowed_cpus() -> Vec<usize> {
    sched_getaffinity(Pid::from_raw(0))
        .map(|set| {
            (0..CpuSet::count())
                .filter(|&c| set.is_set(c).unwrap_or(false))
                .collect()
        })
        .unwrap_or_default()
}

fn scheduler() -> String {
    use thread_priority::unix::{
        RealtimeThreadSchedulePolicy as Rt, ThreadSchedulePolicy as P, thread_native_id,
        thread_schedule_policy_param,
    };
    match thread_schedule_policy_param(thread_native_id()) {
        Ok((P::Realtime(Rt::Fifo), p)) => format!("SCHED_FIFO {}", p.sched_priority),
        Ok((P::Realtime(Rt::RoundRobin), p)) => format!("SCHED_RR {}", p.sched_priority),
        Ok((P::Realtime(other), _)) => format!("{other:?}"),
        Ok((P::Normal(n), _)) => format!("{n:?} (not real time)"),
        Err(e) => format!("unknown ({e:?})"),
    }
}

/// Writes [`PRETOUCHED_STACK`] bytes of this thread's stack.
#[inline(never)]
fn pretouch_stack() {
    let mut buf = [0u8; PRETOUCHED_STACK];
    for i in (0..PRETOUCHED_STACK).step_by(4096) {
        buf[i] = 1;
    }
    std::hint::black_box(&mut buf);
}

impl RtSettings {
    /// Whether anything is asked for.
    pub fn any(&self) -> bool {
        self.rt_priority.is_some() || self.cpu.is_some() || self.lock_memory
    }

    /// The command-line flags that ask another process (a spawned `controller_node`) for
    /// these settings: `--rt-priority N`, `--cpu LIST`, `--lock-memory`.
    pub fn args(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(p) = self.rt_priority {
            a.extend(["--rt-priority".to_owned(), p.to_string()]);
        }
        if let Some(c) = &self.cpu {
            a.extend(["--cpu".to_owned(), c.to_string()]);
        }
        if self.lock_memory {
            a.push("--lock-memory".to_owned());
        }
        a
    }

    /// Applies the settings to the calling thread (threads and child processes started
    /// afterwards inherit the priority and the affinity; call it before starting any that
    /// should not). Never fails: a refusal is reported.
    pub fn apply(&self) -> RtReport {
        let mut r = RtReport::default();
        let mut refuse = |setting: &str, reason: String| {
            r.refused.push(Refused {
                setting: setting.to_owned(),
                reason,
            })
        };
        let mut applied = Vec::new();
        if let Some(cpus) = &self.cpu {
            let mut set = CpuSet::new();
            let online = allowed_cpus();
            let result = cpus
                .0
                .iter()
                .try_for_each(|&c| set.set(c))
                .and_then(|()| sched_setaffinity(Pid::from_raw(0), &set));
            match result {
                Ok(()) => applied.push(format!("cpu {cpus}")),
                Err(e) => refuse(
                    "cpu",
                    format!(
                        "{}; this process may run on CPUs {}",
                        errno(e),
                        CpuList(online)
                    ),
                ),
            }
        }
        if let Some(p) = self.rt_priority {
            use thread_priority::unix::{
                RealtimeThreadSchedulePolicy, ThreadSchedulePolicy, set_thread_priority_and_policy,
                thread_native_id,
            };
            use thread_priority::{ThreadPriority, ThreadPriorityValue};
            let result = ThreadPriorityValue::try_from(p)
                .map_err(|e| e.to_string())
                .and_then(|v| {
                    set_thread_priority_and_policy(
                        thread_native_id(),
                        ThreadPriority::Crossplatform(v),
                        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
                    )
                    .map_err(|e| match e {
                        thread_priority::Error::OS(code) => {
                            errno(nix::errno::Errno::from_raw(code))
                        }
                        other => format!("{other:?}"),
                    })
                });
            match result {
                Ok(()) => applied.push(format!("SCHED_FIFO priority {p}")),
                Err(e) => refuse("rt-priority", e),
            }
        }
        if self.lock_memory {
            match mlockall(MlockAllFlags::MCL_CURRENT | MlockAllFlags::MCL_FUTURE) {
                Ok(()) => {
                    pretouch_stack();
                    applied.push(format!(
                        "memory locked (current and future pages; {} KiB of stack pre-touched)",
                        PRETOUCHED_STACK / 1024
                    ));
                }
                Err(e) => refuse("lock-memory", errno(e)),
            }
        }
        r.applied = applied;
        r.pid = std::process::id();
        r.cpus_allowed = allowed_cpus();
        r.scheduler = scheduler();
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_lists_parse_and_bad_ones_say_why() {
        assert_eq!(parse_cpu_list("1").unwrap().0, vec![1]);
        assert_eq!(parse_cpu_list("3,0-1, 1").unwrap().0, vec![0, 1, 3]);
        assert!(parse_cpu_list("a").unwrap_err().contains("`a`"));
        assert!(parse_cpu_list("3-1").unwrap_err().contains("upwards"));
        assert!(parse_cpu_list("5000").unwrap_err().contains("5000"));
        assert!(parse_cpu_list("").is_err());
        assert_eq!(parse_cpu_list("0,2-3").unwrap().to_string(), "0,2,3");
    }

    #[test]
    fn settings_become_flags_and_reports_round_trip_through_json() {
        let s = RtSettings {
            rt_priority: Some(80),
            cpu: Some(CpuList(vec![0, 2, 3])),
            lock_memory: true,
        };
        assert_eq!(
            s.args(),
            ["--rt-priority", "80", "--cpu", "0,2,3", "--lock-memory"]
        );
        assert!(RtSettings::default().args().is_empty());
        let r = RtReport {
            pid: 42,
            applied: vec!["cpu 0".to_owned()],
            refused: vec![Refused {
                setting: "rt-priority".to_owned(),
                reason: "EPERM: Operation not permitted".to_owned(),
            }],
            cpus_allowed: vec![0],
            scheduler: "SCHED_OTHER".to_owned(),
        };
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let path = dir.join("r.json");
        r.write_json(&path).unwrap();
        assert_eq!(RtReport::read_json(&path).unwrap(), r);
        std::fs::write(&path, "{").unwrap();
        assert!(RtReport::read_json(&path).unwrap_err().contains("r.json"));
    }

    #[test]
    fn a_cpu_that_does_not_exist_is_refused_with_the_reason() {
        // in a thread, so the test process keeps its own affinity
        let r = std::thread::spawn(|| {
            RtSettings {
                cpu: Some(CpuList(vec![CpuSet::count() - 1])),
                ..RtSettings::default()
            }
            .apply()
        })
        .join()
        .unwrap();
        assert!(r.applied.is_empty(), "{r:?}");
        assert_eq!(r.refused.len(), 1, "{r:?}");
        assert_eq!(r.refused[0].setting, "cpu");
        assert!(r.refused[0].reason.contains("EINVAL"), "{r:?}");
        assert!(!r.cpus_allowed.is_empty());
    }
}

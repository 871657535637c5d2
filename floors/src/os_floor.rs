//! The floors `plant_sim bench-loop` measures the pair against, at the same rate and for the
//! same duration (docs/architecture.md, "The floors"):
//!
//! * the **operating-system floor**: `cyclictest` (Debian's rt-tests) waking at the loop's
//!   period, the wake-up latency of an absolute-time sleep on this machine. It inherits this
//!   process's 1 ns timer slack, as the plant runs with, and the plant's scheduling class
//!   (SCHED_OTHER, no priority);
//! * the **transport floor**: `transport_floor` (the `floors` crate's binary), two processes exchanging
//!   the pair's messages over iceoryx2 with nothing else, paced like the plant, in busy-poll
//!   and event modes.

use serde::Serialize;
use std::path::Path;
use std::process::Command;

/// cyclictest's wake-up latency, µs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct OsFloor {
    /// Wake-ups measured.
    pub cycles: u64,
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// Maximum.
    pub max_us: f64,
}

/// The bare iceoryx2 exchange's round trip, µs.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct TransportFloor {
    /// `spin` or `event`.
    pub wake: String,
    /// Round trips measured.
    pub cycles: u64,
    /// Median.
    pub p50_us: f64,
    /// 99th percentile.
    pub p99_us: f64,
    /// 99.9th percentile.
    pub p99_9_us: f64,
    /// Maximum.
    pub max_us: f64,
    /// Replies not there by the next tick.
    pub missed: u64,
    /// Median of the first leg (state written → seen by the other process), µs.
    pub leg1_p50_us: f64,
    /// Median of the last leg (reply written → seen), µs.
    pub leg2_p50_us: f64,
}

/// Runs `cyclictest` at `rate_hz` for `duration` s and reads its histogram (1 µs buckets up
/// to 20 ms; a latency beyond counts as overflow, above every percentile that is still in the
/// histogram).
pub fn os_floor(cyclictest: &Path, rate_hz: f64, duration: f64) -> Result<OsFloor, String> {
    link::clock::precise_sleeps(); // inherited by the child, as the plant runs with it
    let interval_us = ((1e6 / rate_hz).round() as u64).max(1);
    let out = Command::new(cyclictest)
        .args(["-q", "-t", "1", "-h", "20000"])
        .args(["-i", &interval_us.to_string()])
        .args([
            "-l",
            &((duration * rate_hz).round().max(1.0) as u64).to_string(),
        ])
        .output()
        .map_err(|e| format!("cannot run {}: {e}", cyclictest.display()))?;
    if !out.status.success() {
        return Err(format!(
            "{} failed ({}): {}",
            cyclictest.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    parse_cyclictest(&String::from_utf8_lossy(&out.stdout))
}

/// Percentiles from cyclictest's `-h` output: `<µs> <count>` lines, `# Max Latencies: N`,
/// `# Histogram Overflows: N`.
pub fn parse_cyclictest(text: &str) -> Result<OsFloor, String> {
    let mut buckets = Vec::new();
    let (mut max, mut overflow) = (None, 0u64);
    for line in text.lines() {
        let mut f = line.split_whitespace();
        match (f.next(), f.next()) {
            (Some(a), Some(b)) if a.bytes().all(|c| c.is_ascii_digit()) => {
                if let (Ok(us), Ok(n)) = (a.parse::<u64>(), b.parse::<u64>()) {
                    buckets.push((us, n));
                }
            }
            _ => {
                let value = |key: &str| {
                    line.strip_prefix(key)
                        .and_then(|r| r.split_whitespace().next())
                        .and_then(|v| v.parse::<u64>().ok())
                };
                if let Some(v) = value("# Max Latencies:") {
                    max = Some(v);
                }
                if let Some(v) = value("# Histogram Overflows:") {
                    overflow = v;
                }
            }
        }
    }
    let total: u64 = buckets.iter().map(|b| b.1).sum::<u64>() + overflow;
    let max = max.ok_or("cyclictest printed no `# Max Latencies:` line")?;
    if total == 0 {
        return Err("cyclictest measured no wake-up".into());
    }
    let quantile = |p: f64| {
        let want = (total as f64 * p).ceil() as u64;
        let mut seen = 0;
        for (us, n) in &buckets {
            seen += n;
            if seen >= want {
                return *us as f64;
            }
        }
        max as f64 // in the overflow
    };
    Ok(OsFloor {
        cycles: total,
        p50_us: quantile(0.5),
        p99_us: quantile(0.99),
        max_us: max as f64,
    })
}

/// Runs `transport_floor ping` (next to this executable) at `rate_hz` for `duration` s.
pub fn transport_floor(spin: bool, rate_hz: f64, duration: f64) -> Result<TransportFloor, String> {
    let exe = std::env::current_exe()
        .map_err(|e| format!("cannot locate this executable: {e}"))?
        .with_file_name("transport_floor");
    let wake = if spin { "spin" } else { "event" };
    let out = Command::new(&exe)
        .args(["ping", "--wake", wake])
        .args(["--rate-hz", &rate_hz.to_string(), "--duration", &duration.to_string()])
        .output()
        .map_err(|e| {
            format!(
                "cannot run {} (it is built with the workspace: cargo build --release --workspace): {e}",
                exe.display()
            )
        })?;
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("floor "))
        .ok_or_else(|| {
            format!(
                "{} printed no result ({}): {}",
                exe.display(),
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            )
        })?;
    let field = |key: &str| {
        line.split_whitespace()
            .find_map(|kv| kv.strip_prefix(key)?.strip_prefix('='))
            .and_then(|v| v.parse::<f64>().ok())
            .ok_or_else(|| format!("`{key}` missing in `{line}`"))
    };
    Ok(TransportFloor {
        wake: wake.to_owned(),
        cycles: field("cycles")? as u64,
        p50_us: field("p50_us")?,
        p99_us: field("p99_us")?,
        p99_9_us: field("p99_9_us")?,
        max_us: field("max_us")?,
        missed: field("missed")? as u64,
        leg1_p50_us: field("leg1_p50_us")?,
        leg2_p50_us: field("leg2_p50_us")?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cyclictest_histograms_give_percentiles() {
        let text = "000000 000000\n000010 000050\n000011 000045\n000020 000004\n\
                    # Total: 000000100\n# Min Latencies: 00010\n# Max Latencies: 00090\n\
                    # Histogram Overflows: 00001\n";
        let f = parse_cyclictest(text).unwrap();
        assert_eq!(f.cycles, 100);
        assert_eq!(f.p50_us, 10.0);
        assert_eq!(f.p99_us, 20.0);
        assert_eq!(f.max_us, 90.0);
        assert!(parse_cyclictest("nothing").is_err());
    }
}

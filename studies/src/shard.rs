//! The Monte Carlo study in shards (docs/simulations.md, "The Monte Carlo study in shards"):
//! `plant_sim montecarlo --shard I/N` flies only the runs whose index is `I` modulo `N` and
//! writes them, whole, to `shard.bin`; `--merge DIR...` reads the shards back, checks that
//! they are one study (the same scenario, samples and laws, every shard once) and puts the
//! runs back in the study's order, so every file it writes is the unsharded run's, byte for
//! byte. A Slurm array job runs one shard per task (`examples/slurm/`).
//!
//! `shard.bin`, little-endian: the magic `EQTRKMCS`, the format version (u32), the shard's
//! index and count (u32 each), the study's run count (u64), the scenario's fingerprint and
//! the samples' fingerprint (u64 each), the laws (u32 count, then each law's wire code as a
//! u32), the result count (u64); then each result: run (u64), law code (u32), the sample
//! (6 f64), the final attitude error, the two efforts (f64 each), the settling time (f64,
//! NaN for none), the series length (u64) and the series (4 f64 per step).

use crate::montecarlo::{RunResult, Sample};
use eqtrack_controller::Law;
use plant::SimError;
use std::path::Path;

/// The file a shard writes into its directory.
pub const SHARD_FILE: &str = "shard.bin";
const MAGIC: &[u8; 8] = b"EQTRKMCS";
const VERSION: u32 = 1;

/// The most shards a study is split into (a merge keeps one slot per shard).
pub const MAX_SHARDS: usize = 1 << 20;

/// Which share of the study: the runs whose index is `index` modulo `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// `I`, from 0.
    pub index: usize,
    /// `N`, at least 1.
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    /// `I/N` with `0 ≤ I < N` (a Slurm array's task id and task count).
    fn from_str(text: &str) -> Result<Shard, String> {
        let bad = |what: &str| format!("`{text}`: {what} (expected I/N with 0 <= I < N)");
        let (i, n) = text.split_once('/').ok_or_else(|| bad("no `/`"))?;
        let index: usize = i
            .trim()
            .parse()
            .map_err(|_| bad("I is not a whole number"))?;
        let count: usize = n
            .trim()
            .parse()
            .map_err(|_| bad("N is not a whole number"))?;
        if count == 0 {
            return Err(bad("N must be at least 1"));
        }
        if count > MAX_SHARDS {
            return Err(bad(&format!("N must be at most {MAX_SHARDS}")));
        }
        if index >= count {
            return Err(bad("I must be less than N"));
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// The study's runs of this shard, with their indices.
    pub fn select(&self, samples: &[Sample]) -> Vec<(usize, Sample)> {
        samples
            .iter()
            .copied()
            .enumerate()
            .filter(|(i, _)| i % self.count == self.index)
            .collect()
    }
}

/// What identifies the study a shard belongs to.
#[derive(Debug, Clone, PartialEq)]
pub struct Study {
    /// The study's run count.
    pub runs: usize,
    /// The base scenario's fingerprint.
    pub scenario: u64,
    /// A fingerprint of every sample's bits, in order (the seed or the samples file).
    pub samples: u64,
    /// The laws, in the study's order.
    pub laws: Vec<Law>,
}

impl Study {
    /// The study of `samples` and `laws` on a scenario of fingerprint `scenario`.
    pub fn new(scenario: u64, samples: &[Sample], laws: &[Law]) -> Study {
        // FNV-1a over the samples' bits
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        for s in samples {
            for x in s.r.iter().chain(&s.w) {
                for b in x.to_bits().to_le_bytes() {
                    h = (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
                }
            }
        }
        Study {
            runs: samples.len(),
            scenario,
            samples: h,
            laws: laws.to_vec(),
        }
    }
}

fn put_f64s(out: &mut Vec<u8>, xs: &[f64]) {
    for x in xs {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// Writes shard `shard` of `study` (its results) to `dir/shard.bin`.
pub fn write_shard(
    dir: &Path,
    shard: Shard,
    study: &Study,
    results: &[RunResult],
) -> Result<(), SimError> {
    let path = dir.join(SHARD_FILE);
    std::fs::write(&path, encode_shard(shard, study, results))
        .map_err(|e| SimError::Run(format!("cannot write {}: {e}", path.display())))
}

/// The bytes of `shard.bin` for shard `shard` of `study` (a Ray task returns them instead of
/// writing a file).
pub fn encode_shard(shard: Shard, study: &Study, results: &[RunResult]) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(MAGIC);
    for x in [VERSION, shard.index as u32, shard.count as u32] {
        b.extend_from_slice(&x.to_le_bytes());
    }
    for x in [study.runs as u64, study.scenario, study.samples] {
        b.extend_from_slice(&x.to_le_bytes());
    }
    b.extend_from_slice(&(study.laws.len() as u32).to_le_bytes());
    for l in &study.laws {
        b.extend_from_slice(&link::wire::law_code(*l).to_le_bytes());
    }
    b.extend_from_slice(&(results.len() as u64).to_le_bytes());
    for r in results {
        b.extend_from_slice(&(r.run as u64).to_le_bytes());
        b.extend_from_slice(&link::wire::law_code(r.law).to_le_bytes());
        put_f64s(&mut b, &r.sample.r);
        put_f64s(&mut b, &r.sample.w);
        let settling = r.settling_time.unwrap_or(f64::NAN);
        put_f64s(
            &mut b,
            &[
                r.final_attitude_error,
                r.effort_0_5,
                r.effort_0_20,
                settling,
            ],
        );
        b.extend_from_slice(&(r.series.len() as u64).to_le_bytes());
        for row in &r.series {
            put_f64s(&mut b, row);
        }
    }
    b
}

/// Reads a `shard.bin` field by field; every shortfall is an error naming the file.
struct Reader<'a> {
    b: &'a [u8],
    at: usize,
    path: &'a str,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], SimError> {
        let end = self.at.checked_add(n).filter(|e| *e <= self.b.len());
        let end = end.ok_or_else(|| {
            SimError::Input(format!(
                "shard {}: cut short at byte {} (not a whole shard file)",
                self.path, self.at
            ))
        })?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, SimError> {
        let mut a = [0u8; 4];
        a.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(a))
    }
    fn u64(&mut self) -> Result<u64, SimError> {
        let mut a = [0u8; 8];
        a.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(a))
    }
    fn f64(&mut self) -> Result<f64, SimError> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn law(&mut self) -> Result<Law, SimError> {
        let code = self.u32()?;
        link::wire::law_from_code(code)
            .ok_or_else(|| SimError::Input(format!("shard {}: unknown law code {code}", self.path)))
    }
    fn len(&mut self, each: usize, what: &str) -> Result<usize, SimError> {
        let n = self.u64()?;
        // a count that cannot fit in what is left is refused before anything is allocated
        let left = (self.b.len() - self.at) / each.max(1);
        usize::try_from(n)
            .ok()
            .filter(|n| *n <= left)
            .ok_or_else(|| {
                SimError::Input(format!(
                    "shard {}: {n} {what}, more than the file holds",
                    self.path
                ))
            })
    }
}

/// Reads `dir/shard.bin`: its shard, its study and its results.
pub fn read_shard(dir: &Path) -> Result<(Shard, Study, Vec<RunResult>), SimError> {
    let (shown, b) = read_file(dir)?;
    decode_shard(&b, &shown)
}

fn read_file(dir: &Path) -> Result<(String, Vec<u8>), SimError> {
    let path = dir.join(SHARD_FILE);
    let shown = path.display().to_string();
    let b = std::fs::read(&path)
        .map_err(|e| SimError::Input(format!("shard {shown}: cannot read it: {e}")))?;
    Ok((shown, b))
}

/// Decodes [`encode_shard`]'s bytes (`shown` names them in errors): its shard, its study and
/// its results. Every shortfall or inconsistency is an error, never a panic.
pub fn decode_shard(b: &[u8], shown: &str) -> Result<(Shard, Study, Vec<RunResult>), SimError> {
    let mut r = Reader {
        b,
        at: 0,
        path: shown,
    };
    if r.take(8)? != MAGIC {
        return Err(SimError::Input(format!(
            "shard {shown}: not a Monte Carlo shard (no EQTRKMCS magic)"
        )));
    }
    let version = r.u32()?;
    if version != VERSION {
        return Err(SimError::Input(format!(
            "shard {shown}: format version {version}, this build reads {VERSION}"
        )));
    }
    let (index, count) = (r.u32()? as usize, r.u32()? as usize);
    let (runs, scenario, samples) = (r.u64()? as usize, r.u64()?, r.u64()?);
    let n_laws = r.u32()? as usize;
    let laws = (0..n_laws.min(16))
        .map(|_| r.law())
        .collect::<Result<Vec<_>, _>>()?;
    let n = r.len(4 * 8 + 8 + 4 + 12 * 8, "results")?;
    let mut results = Vec::with_capacity(n);
    for _ in 0..n {
        let (run, law) = (r.u64()? as usize, r.law()?);
        let mut v = [0.0; 6];
        for x in &mut v {
            *x = r.f64()?;
        }
        let (fin, e5, e20, settling) = (r.f64()?, r.f64()?, r.f64()?, r.f64()?);
        let steps = r.len(32, "series steps")?;
        let mut series = Vec::with_capacity(steps);
        for _ in 0..steps {
            series.push([r.f64()?, r.f64()?, r.f64()?, r.f64()?]);
        }
        results.push(RunResult {
            run,
            law,
            sample: Sample {
                r: [v[0], v[1], v[2]],
                w: [v[3], v[4], v[5]],
            },
            final_attitude_error: fin,
            effort_0_5: e5,
            effort_0_20: e20,
            settling_time: (!settling.is_nan()).then_some(settling),
            series,
        });
    }
    if r.at != b.len() || count == 0 || count > MAX_SHARDS || index >= count || n_laws > 16 {
        return Err(SimError::Input(format!(
            "shard {shown}: not a whole shard file (shard {index} of {count}, {} bytes over)",
            b.len() - r.at
        )));
    }
    let study = Study {
        runs,
        scenario,
        samples,
        laws,
    };
    Ok((Shard { index, count }, study, results))
}

/// Joins the shards in `dirs` into the study's results, in the unsharded run's order (by
/// run, then by law in the study's order). Refuses shards of different studies, a shard
/// given twice, a missing shard, or a shard whose runs are not its share, naming which.
pub fn merge(dirs: &[&Path], expected: &Study) -> Result<Vec<RunResult>, SimError> {
    let shards = dirs
        .iter()
        .map(|dir| {
            let (_, b) = read_file(dir)?;
            Ok((dir.display().to_string(), b))
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    merge_encoded(&shards, expected)
}

/// [`merge`] over shards already in memory: `(name, bytes)` pairs, each the bytes of
/// [`encode_shard`] (a Ray driver's results), named in errors.
pub fn merge_encoded(
    shards: &[(String, Vec<u8>)],
    expected: &Study,
) -> Result<Vec<RunResult>, SimError> {
    let mut seen: Vec<Option<&str>> = Vec::new();
    let mut all = Vec::new();
    for (name, bytes) in shards {
        let (shard, study, results) = decode_shard(bytes, &format!("{name}/{SHARD_FILE}"))?;
        if study != *expected {
            return Err(SimError::Input(format!(
                "shard {name}: another study ({} runs, laws {:?}, scenario {:016x}, samples {:016x}) than this one ({} runs, laws {:?}, scenario {:016x}, samples {:016x}): give --merge the same --scenario, --runs, --seed (or --samples) and --laws as the shards",
                study.runs,
                study.laws.iter().map(|l| l.name()).collect::<Vec<_>>(),
                study.scenario,
                study.samples,
                expected.runs,
                expected.laws.iter().map(|l| l.name()).collect::<Vec<_>>(),
                expected.scenario,
                expected.samples
            )));
        }
        if seen.is_empty() {
            seen = vec![None; shard.count];
        }
        if shard.count != seen.len() {
            return Err(SimError::Input(format!(
                "shard {name}: one of {} shards, the others are of {}",
                shard.count,
                seen.len()
            )));
        }
        if let Some(first) = seen[shard.index] {
            return Err(SimError::Input(format!(
                "shard {} of {} given twice: {} and {name}",
                shard.index, shard.count, first
            )));
        }
        seen[shard.index] = Some(name);
        // its share: runs index, index + count, ... below the study's run count, each once
        // per law (counted, not listed: the run count comes from the file)
        let share = (shard.index..study.runs).step_by(shard.count).len();
        let laws = study.laws.len();
        if results.len() != share.saturating_mul(laws)
            || results
                .iter()
                .enumerate()
                .any(|(k, r)| r.run != shard.index + (k / laws) * shard.count)
        {
            return Err(SimError::Input(format!(
                "shard {name}: its runs are not shard {} of {}'s share (interrupted?)",
                shard.index, shard.count
            )));
        }
        all.extend(results);
    }
    if let Some(missing) = seen.iter().position(Option::is_none) {
        return Err(SimError::Input(format!(
            "shard {missing} of {} is missing",
            seen.len()
        )));
    }
    let order = |l: Law| {
        expected
            .laws
            .iter()
            .position(|x| *x == l)
            .unwrap_or(usize::MAX)
    };
    all.sort_by_key(|r| (r.run, order(r.law)));
    Ok(all)
}

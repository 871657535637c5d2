//! Reading a run's recording back: [`LogReader`] for `messages.log`, [`read_plans`] for
//! `plans.log`. A file cut short (a SIGKILL) is read up to its last whole record or entry; a
//! file of another format version is refused, naming both versions.

use super::format::{
    HEADER_BYTES, Header, PLAN_ENTRY_BYTES, PLANS_FILE, PLANS_HEADER_BYTES, PlanEntry, Record,
    check_plans_header,
};
use crate::RecorderError;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// A log opened for reading: its header, then [`LogReader::next_record`] until `None`.
pub struct LogReader {
    input: BufReader<File>,
    path: PathBuf,
    /// The header.
    pub header: Header,
    /// Whole records in the file.
    pub records: u64,
    /// Bytes after the last whole record (a recording cut short mid-record).
    pub trailing_bytes: u64,
    read: u64,
}

impl LogReader {
    /// Opens `path` and reads its header.
    pub fn open(path: &Path) -> Result<LogReader, RecorderError> {
        let bad = |what: String| RecorderError::Input(format!("{}: {what}", path.display()));
        let file = File::open(path).map_err(|e| bad(format!("cannot open: {e}")))?;
        let len = file
            .metadata()
            .map_err(|e| bad(format!("cannot read its size: {e}")))?
            .len();
        let mut input = BufReader::with_capacity(1 << 16, file);
        let mut head = [0u8; HEADER_BYTES];
        input.read_exact(&mut head).map_err(|_| {
            bad(format!(
                "{len} bytes: shorter than the {HEADER_BYTES}-byte header of a flight recording"
            ))
        })?;
        let header = Header::from_bytes(&head).map_err(bad)?;
        let record_bytes = header.record_bytes() as u64;
        let body = len.saturating_sub(HEADER_BYTES as u64);
        Ok(LogReader {
            input,
            path: path.to_owned(),
            header,
            records: body / record_bytes,
            trailing_bytes: body % record_bytes,
            read: 0,
        })
    }

    /// The next whole record, `None` after the last one.
    pub fn next_record(&mut self) -> Result<Option<Record>, RecorderError> {
        if self.read == self.records {
            return Ok(None);
        }
        let mut b = [0u8; super::format::RECORD_BYTES + super::format::SENSOR_BYTES];
        let b = &mut b[..self.header.record_bytes()];
        let at = self.read;
        self.input
            .read_exact(b)
            .map_err(|e| RecorderError::Io(format!("{}: record {at}: {e}", self.path.display())))?;
        self.read += 1;
        Record::from_bytes(b)
            .map(Some)
            .map_err(|e| RecorderError::Input(format!("{}: record {at}: {e}", self.path.display())))
    }
}

/// A run's recorded plan messages (`dir/plans.log`), in the order the recorder saw them:
/// empty when the file does not exist (the run streamed nothing), whole entries only when it
/// was cut short.
pub fn read_plans(dir: &Path) -> Result<Vec<PlanEntry>, RecorderError> {
    let path = dir.join(PLANS_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => {
            return Err(RecorderError::Input(format!(
                "{}: cannot read: {e}",
                path.display()
            )));
        }
    };
    let bad = |what: String| RecorderError::Input(format!("{}: {what}", path.display()));
    check_plans_header(&bytes).map_err(bad)?;
    bytes[PLANS_HEADER_BYTES..]
        .chunks_exact(PLAN_ENTRY_BYTES)
        .enumerate()
        .map(|(i, b)| PlanEntry::from_bytes(b).map_err(|e| bad(format!("entry {i}: {e}"))))
        .collect()
}

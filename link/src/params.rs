//! Run-time parameters over iceoryx2 (docs/live.md, "Tuning a running pair"):
//!
//! * the run's `params` board: the plant writes the gains in force ([`ParamMsg`]) at the
//!   cycle boundary where a change takes effect ([`ParamsWriter`]); a controller answering a
//!   state with [`flags::TUNABLE`](ipc_types::flags::TUNABLE) reads it ([`ParamsReader`]).
//!   Writes and reads are blackboard copies: no allocation, no system call;
//! * the run's `param` request-response service: the plant's parameter thread serves it
//!   ([`ParamServer`]), `plant_sim param` asks ([`ask`]).
//!
//! Who may ask: iceoryx2 creates the services' shared memory and files readable and
//! writable by their owner only, so another user's process cannot open the service, and
//! cannot change a gain.

use crate::iceoryx2::{BoardReader, BoardWriter, create_node};
use crate::{LinkError, check_run_name, clock};
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::request_response::PortFactory as RrFactory;
use ipc_types::{Gains, PROTOCOL_VERSION, ParamMsg, ParamRequest, ParamResponse, padded_bytes};
use std::time::{Duration, Instant};

pub use ipc_types::param_op;

/// The plant's side of the `params` board.
pub struct ParamsWriter {
    out: BoardWriter<ParamMsg>,
    _node: Node<ipc::Service>,
    msg: ParamMsg,
}

impl ParamsWriter {
    /// Opens (or creates) run `run`'s `params` board and writes `first`, the scenario's
    /// gains, before any state goes out.
    pub fn open(run: &str, first: ParamMsg) -> Result<ParamsWriter, LinkError> {
        let names = check_run_name(run)?;
        // the plant's own node: the board is written on the loop's thread
        let node = create_node(&format!("{}-params", names.plant_node))?;
        let mut w = ParamsWriter {
            out: BoardWriter::open(&node, &names.params, "")?,
            _node: node,
            msg: first,
        };
        w.write();
        Ok(w)
    }

    fn write(&mut self) {
        self.msg.stamp_ns = clock::monotonic_ns();
        self.out.write(self.msg);
    }

    /// Puts `gains` in force from `gains.cycle` on (the previous set stays on the board for
    /// older states). Allocation-free.
    pub fn change(&mut self, gains: Gains) {
        self.msg = self.msg.changed(gains);
        self.write();
    }

    /// What the board holds.
    pub fn current(&self) -> &ParamMsg {
        &self.msg
    }
}

/// The controller's side of the `params` board.
pub struct ParamsReader {
    board: BoardReader<ParamMsg>,
    newest: Option<ParamMsg>,
    _node: Node<ipc::Service>,
}

impl ParamsReader {
    /// Opens run `run`'s `params` board for reading.
    pub fn open(run: &str) -> Result<ParamsReader, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&format!("{}-params", names.controller_node))?;
        Ok(ParamsReader {
            board: BoardReader::open(&node, &names.params, "")?,
            newest: None,
            _node: node,
        })
    }

    /// The newest write on the board (`None`: nothing written yet). Allocation-free.
    pub fn latest(&mut self) -> Option<&ParamMsg> {
        while let Some(m) = self.board.receive() {
            if self.newest.is_none_or(|n| m.stamp_ns >= n.stamp_ns) {
                self.newest = Some(m);
            }
        }
        self.newest.as_ref()
    }
}

/// The plant's `param` server: answers requests with the plant's own function.
pub struct ParamServer {
    server: Server<ipc::Service, ParamRequest, (), ParamResponse, ()>,
    _service: RrFactory<ipc::Service, ParamRequest, (), ParamResponse, ()>,
    _node: Node<ipc::Service>,
}

/// A request as the server hands it over: the operation, the key, the value text.
#[derive(Debug, Clone, PartialEq)]
pub struct Asked {
    /// [`ipc_types::param_op`].
    pub op: u32,
    /// The key (UTF-8; invalid bytes make the request invalid).
    pub key: String,
    /// The value's text (set).
    pub value: String,
}

/// The answer to give.
#[derive(Debug, Clone, PartialEq)]
pub struct Answer {
    /// Done or refused.
    pub ok: bool,
    /// A change: its first cycle.
    pub cycle: u64,
    /// The value, or why not.
    pub text: String,
}

/// NUL-padded bytes as text; `None` if they are not UTF-8.
fn utf8<const N: usize>(bytes: &[u8; N]) -> Option<&str> {
    let end = bytes.iter().position(|b| *b == 0).unwrap_or(N);
    core::str::from_utf8(&bytes[..end]).ok()
}

/// Reads a request: protocol version, operation, UTF-8 key and value.
pub fn read_request(r: &ParamRequest) -> Result<Asked, String> {
    if r.version != PROTOCOL_VERSION {
        return Err(format!(
            "request of protocol {}, this plant speaks {PROTOCOL_VERSION}",
            r.version
        ));
    }
    if r.op != ipc_types::param_op::GET && r.op != ipc_types::param_op::SET {
        return Err(format!("unknown operation {}", r.op));
    }
    let key = utf8(&r.key).ok_or("the key is not UTF-8")?;
    let value = utf8(&r.value).ok_or("the value is not UTF-8")?;
    Ok(Asked {
        op: r.op,
        key: key.to_owned(),
        value: value.to_owned(),
    })
}

/// The wire form of an answer (its text cut at a character boundary to fit).
pub fn response(a: &Answer) -> ParamResponse {
    let mut text = a.text.as_str();
    while text.len() > ipc_types::params::PARAM_TEXT_BYTES {
        let mut cut = ipc_types::params::PARAM_TEXT_BYTES;
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        text = &text[..cut];
    }
    ParamResponse {
        ok: u32::from(a.ok),
        cycle: a.cycle,
        text: padded_bytes(text),
        ..ParamResponse::default()
    }
}

/// The builder of the run's `param` service (request and response types set).
fn param_service(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<
    iceoryx2::service::builder::request_response::Builder<
        ParamRequest,
        (),
        ParamResponse,
        (),
        ipc::Service,
    >,
    LinkError,
> {
    let name: ServiceName = name
        .try_into()
        .map_err(|e| LinkError::iceoryx2("service name", e))?;
    Ok(node
        .service_builder(&name)
        .request_response::<ParamRequest, ParamResponse>())
}

impl ParamServer {
    /// Creates run `run`'s `param` service (its node on the calling thread).
    pub fn create(run: &str) -> Result<ParamServer, LinkError> {
        let names = check_run_name(run)?;
        let node = create_node(&names.tuning_node)?;
        let service = param_service(&node, &names.param)?
            .open_or_create()
            .map_err(|e| LinkError::iceoryx2(names.param.as_str(), e))?;
        let server = service
            .server_builder()
            .create()
            .map_err(|e| LinkError::iceoryx2(format!("{}: server", names.param), e))?;
        Ok(ParamServer {
            server,
            _service: service,
            _node: node,
        })
    }

    /// Answers every request waiting with `answer` (a request that cannot be read is
    /// refused with the reason); returns how many were answered.
    pub fn serve(&self, mut answer: impl FnMut(&Asked) -> Answer) -> usize {
        let mut n = 0;
        while let Ok(Some(active)) = self.server.receive() {
            let a = match read_request(&active) {
                Ok(asked) => answer(&asked),
                Err(why) => Answer {
                    ok: false,
                    cycle: 0,
                    text: why,
                },
            };
            let _ = active.send_copy(response(&a));
            n += 1;
        }
        n
    }
}

/// Asks run `run`'s plant: `op` on `key` (with `value` to set); waits up to `timeout`.
pub fn ask(
    run: &str,
    op: u32,
    key: &str,
    value: &str,
    timeout: Duration,
) -> Result<Answer, LinkError> {
    let names = check_run_name(run)?;
    if key.len() > ipc_types::params::PARAM_KEY_BYTES
        || value.len() > ipc_types::params::PARAM_VALUE_BYTES
    {
        return Err(LinkError::Param(format!(
            "the key may have at most {} bytes and the value {}",
            ipc_types::params::PARAM_KEY_BYTES,
            ipc_types::params::PARAM_VALUE_BYTES
        )));
    }
    let node = create_node(&names.param_node).map_err(|e| {
        LinkError::Param(format!(
            "cannot reach run `{run}`'s parameter service ({e}): iceoryx2's files and shared memory belong to the user who started the run, and only that user may change its parameters"
        ))
    })?;
    let service = param_service(&node, &names.param)?
        .open()
        .map_err(|e| {
            LinkError::Param(format!(
                "cannot open run `{run}`'s parameter service ({e:?}): is the run started with `plant_sim run --tunable`, by this user?"
            ))
        })?;
    let client = service
        .client_builder()
        .create()
        .map_err(|e| LinkError::iceoryx2(format!("{}: client", names.param), e))?;
    let request = ParamRequest {
        op,
        key: padded_bytes(key),
        value: padded_bytes(value),
        ..ParamRequest::default()
    };
    let pending = client
        .send_copy(request)
        .map_err(|e| LinkError::iceoryx2(format!("{}: request", names.param), e))?;
    let give_up = Instant::now() + timeout;
    loop {
        if let Ok(Some(r)) = pending.receive() {
            let r: &ParamResponse = &r;
            return Ok(Answer {
                ok: r.ok == 1,
                cycle: r.cycle,
                text: utf8(&r.text).unwrap_or("(not UTF-8)").to_owned(),
            });
        }
        if Instant::now() > give_up {
            return Err(LinkError::Param(format!(
                "run `{run}` did not answer within {:.1} s",
                timeout.as_secs_f64()
            )));
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_read_and_bad_ones_refused() {
        let good = ParamRequest {
            op: ipc_types::param_op::SET,
            key: padded_bytes("kd"),
            value: padded_bytes("0.8"),
            ..ParamRequest::default()
        };
        let a = read_request(&good).unwrap();
        assert_eq!((a.key.as_str(), a.value.as_str()), ("kd", "0.8"));
        let mut bad = good;
        bad.version += 1;
        assert!(read_request(&bad).unwrap_err().contains("protocol"));
        let mut bad = good;
        bad.op = 7;
        assert!(read_request(&bad).unwrap_err().contains("operation 7"));
        let mut bad = good;
        bad.key[0] = 0xff;
        assert!(read_request(&bad).unwrap_err().contains("UTF-8"));
    }

    #[test]
    fn a_long_answer_is_cut_at_a_character_boundary() {
        let text = "é".repeat(600);
        let r = response(&Answer {
            ok: false,
            cycle: 3,
            text,
        });
        let back = utf8(&r.text).unwrap();
        assert!(back.len() <= ipc_types::params::PARAM_TEXT_BYTES);
        assert!(back.chars().all(|c| c == 'é'));
        assert_eq!(r.cycle, 3);
    }
}

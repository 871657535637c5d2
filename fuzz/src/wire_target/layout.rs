//! The layout of the two encoded messages: the field tables, and reading and writing a field
//! in place.

use crate::MsgKind;

/// The type of a field of an encoded message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Ty {
    U32,
    U64,
    F64,
    /// The NUL-padded name.
    Name,
}

/// `(name, byte offset, type, count)` of the fields of an encoded
/// [`StateMsg`](ipc_types::StateMsg).
pub(super) const STATE_FIELDS: [(&str, usize, Ty, usize); 16] = [
    ("version", 0, Ty::U32, 1),
    ("group", 4, Ty::U32, 1),
    ("seq", 8, Ty::U64, 1),
    ("t", 16, Ty::F64, 1),
    ("control_period", 24, Ty::F64, 1),
    ("stamp_ns", 32, Ty::U64, 1),
    ("q", 40, Ty::F64, 16),
    ("v", 168, Ty::F64, 6),
    ("applied", 216, Ty::F64, 6),
    ("flags", 264, Ty::U32, 1),
    ("plant_pid", 268, Ty::U32, 1),
    ("fingerprint", 272, Ty::U64, 1),
    ("scenario", 280, Ty::Name, 1),
    ("wheels", 312, Ty::U32, 1),
    ("reserved_wheels", 316, Ty::U32, 1),
    ("wheel_speeds", 320, Ty::F64, 6),
];

/// The fields of an encoded [`CommandMsg`](ipc_types::CommandMsg).
pub(super) const COMMAND_FIELDS: [(&str, usize, Ty, usize); 39] = [
    ("version", 0, Ty::U32, 1),
    ("group", 4, Ty::U32, 1),
    ("seq", 8, Ty::U64, 1),
    ("state_received_ns", 16, Ty::U64, 1),
    ("stamp_ns", 24, Ty::U64, 1),
    ("compute_ns", 32, Ty::U64, 1),
    ("tau", 40, Ty::F64, 6),
    ("lyapunov", 88, Ty::F64, 1),
    ("observer", 96, Ty::F64, 6),
    ("integral", 144, Ty::F64, 6),
    ("previous_seq", 192, Ty::U64, 1),
    ("estimate_before", 200, Ty::F64, 6),
    ("z_before", 248, Ty::F64, 6),
    ("heap_allocations", 296, Ty::U64, 1),
    ("flags", 304, Ty::U32, 1),
    ("mismatch", 308, Ty::U32, 1),
    ("fingerprint", 312, Ty::U64, 1),
    ("expected_period", 320, Ty::F64, 1),
    ("scenario", 328, Ty::Name, 1),
    ("law", 360, Ty::U32, 1),
    ("plans_received", 364, Ty::U32, 1),
    ("plan_seq", 368, Ty::U64, 1),
    ("plan_pid", 376, Ty::U32, 1),
    ("failsafe", 380, Ty::U32, 1),
    ("actuators", 384, Ty::U32, 1),
    ("alloc_status", 388, Ty::U32, 1),
    ("demand", 392, Ty::F64, 6),
    ("achieved", 440, Ty::F64, 6),
    ("accounted", 488, Ty::F64, 6),
    ("u_previous", 536, Ty::F64, 12),
    ("u_cmd", 632, Ty::F64, 12),
    ("detected", 728, Ty::U32, 1),
    ("detected_kind", 732, Ty::U32, 1),
    ("detected_value", 736, Ty::F64, 1),
    ("detected_refined", 744, Ty::U32, 1),
    ("alarms", 748, Ty::U32, 1),
    ("statistic", 752, Ty::F64, 1),
    ("suspect", 760, Ty::U32, 1),
    ("reserved_detector", 764, Ty::U32, 1),
];

/// The field table of an encoded message of kind `kind`.
pub(super) fn fields(kind: MsgKind) -> &'static [(&'static str, usize, Ty, usize)] {
    match kind {
        MsgKind::State => &STATE_FIELDS,
        MsgKind::Command => &COMMAND_FIELDS,
    }
}

/// The width in bytes of one entry of a field of type `ty`.
pub(super) fn width(ty: Ty) -> usize {
    match ty {
        Ty::U32 => 4,
        Ty::U64 | Ty::F64 => 8,
        Ty::Name => ipc_types::NAME_BYTES,
    }
}

/// The little-endian u32 at `at`, if `data` is long enough.
pub(super) fn read_u32(data: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(data.get(at..at + 4)?.try_into().ok()?))
}

/// The little-endian u64 at `at`, if `data` is long enough.
pub(super) fn read_u64(data: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(data.get(at..at + 8)?.try_into().ok()?))
}

/// Writes `value` at `at`, as much of it as fits in `data` (an already shortened message
/// stays short).
pub(super) fn write_at(data: &mut [u8], at: usize, value: &[u8]) {
    if at < data.len() {
        let end = (at + value.len()).min(data.len());
        data[at..end].copy_from_slice(&value[..end - at]);
    }
}

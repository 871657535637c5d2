//! The parameters channel: one message per run-time parameter change of a run started with
//! `plant_sim run --tunable` (`params.log`, docs/live.md, "Tuning a running pair").

use crate::{Message, Value};
use recorder::ParamChange;

/// The message of one change: the cycle it took effect at, its time, the key, the new and
/// the previous value as TOML text and as numbers.
pub fn param_message(c: &ParamChange) -> Message {
    Message {
        schema: "eqtrack_msgs/msg/Param",
        topic: "/eqtrack/params",
        fields: vec![
            ("cycle", Value::U64(c.cycle)),
            ("t", Value::F64(c.t)),
            ("key", Value::Str(c.key.clone())),
            ("value", Value::Str(c.value.clone())),
            ("previous", Value::Str(c.previous.clone())),
            ("numbers", Value::F64s(c.numbers.clone())),
            ("previous_numbers", Value::F64s(c.previous_numbers.clone())),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_change_has_its_schema_and_fields() {
        let m = param_message(&ParamChange {
            cycle: 7,
            t: 0.07,
            key: "controller.kd".into(),
            value: "0.8".into(),
            previous: "0.5".into(),
            numbers: vec![0.8],
            previous_numbers: vec![0.5],
        });
        assert_eq!(
            m.schema_text(),
            "uint64 cycle\nfloat64 t\nstring key\nstring value\nstring previous\nfloat64[] numbers\nfloat64[] previous_numbers\n"
        );
        let j = m.json_fields();
        assert_eq!(
            (j["cycle"].as_u64(), j["key"].as_str()),
            (Some(7), Some("controller.kd"))
        );
        // CDR: the header, then cycle at offset 4 (8-aligned from the header's end)
        let cdr = m.cdr();
        assert_eq!(&cdr[..4], &[0, 1, 0, 0]);
        assert_eq!(u64::from_le_bytes(cdr[4..12].try_into().unwrap()), 7);
    }
}

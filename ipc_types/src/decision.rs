//! The plant's decision at each tick, as the flight recording and the live status carry it.

/// What the plant applied over a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// The command for this tick, on time.
    Fresh,
    /// A miss: hold the previous torque.
    Held,
    /// Too many misses in a row: the safe-mode torque.
    Safe,
}

impl Decision {
    /// The `command_status` column of a trajectory: 0 fresh, 1 held, 2 safe mode.
    pub fn code(self) -> u8 {
        match self {
            Decision::Fresh => 0,
            Decision::Held => 1,
            Decision::Safe => 2,
        }
    }

    /// The decision of a code (`None`: not 0, 1 or 2).
    pub fn from_code(code: u8) -> Option<Decision> {
        match code {
            0 => Some(Decision::Fresh),
            1 => Some(Decision::Held),
            2 => Some(Decision::Safe),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Decision;

    #[test]
    fn codes_round_trip_and_others_are_none() {
        for d in [Decision::Fresh, Decision::Held, Decision::Safe] {
            assert_eq!(Decision::from_code(d.code()), Some(d));
        }
        assert_eq!(Decision::from_code(3), None);
    }
}

//! The wire's own codes for what the maths crate calls a group and a law: the contract owns
//! them, so a message's layout and meaning do not change when the maths crate does. `link`
//! converts between these and `eqtrack_controller::GroupKind` / `eqtrack_controller::Law`.

/// A group on the wire: its code and its dimensions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireGroup {
    /// SO(3): code 1, n = 3, m = 3.
    So3,
    /// SE(3): code 2, n = 4, m = 6.
    Se3,
    /// SE(2): code 3, n = 3, m = 3.
    Se2,
}

impl WireGroup {
    /// Every group the wire knows.
    pub const ALL: [WireGroup; 3] = [WireGroup::So3, WireGroup::Se3, WireGroup::Se2];

    /// Its code in a message's `group` field.
    pub fn code(self) -> u32 {
        match self {
            WireGroup::So3 => 1,
            WireGroup::Se3 => 2,
            WireGroup::Se2 => 3,
        }
    }

    /// The group of a code (`None`: unknown).
    pub fn from_code(code: u32) -> Option<WireGroup> {
        WireGroup::ALL.into_iter().find(|g| g.code() == code)
    }

    /// `(n, m)`: the matrix size of a configuration and the dimension of the algebra.
    pub fn dims(self) -> (usize, usize) {
        match self {
            WireGroup::So3 => (3, 3),
            WireGroup::Se3 => (4, 6),
            WireGroup::Se2 => (3, 3),
        }
    }

    /// Its name in logs (`so3`, `se3`, `se2`).
    pub fn name(self) -> &'static str {
        match self {
            WireGroup::So3 => "so3",
            WireGroup::Se3 => "se3",
            WireGroup::Se2 => "se2",
        }
    }
}

/// A control law on the wire ([`crate::CommandMsg::law`]; 0 there says none).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WireLaw {
    /// EqT: code 1.
    Eqt,
    /// GT: code 2.
    Gt,
    /// nog: code 3.
    Nog,
    /// asym: code 4.
    Asym,
}

impl WireLaw {
    /// Every law the wire knows.
    pub const ALL: [WireLaw; 4] = [WireLaw::Eqt, WireLaw::Gt, WireLaw::Nog, WireLaw::Asym];

    /// Its code: 1 eqt, 2 gt, 3 nog, 4 asym.
    pub fn code(self) -> u32 {
        match self {
            WireLaw::Eqt => 1,
            WireLaw::Gt => 2,
            WireLaw::Nog => 3,
            WireLaw::Asym => 4,
        }
    }

    /// The law of a code (`None`: 0 or unknown).
    pub fn from_code(code: u32) -> Option<WireLaw> {
        WireLaw::ALL.into_iter().find(|l| l.code() == code)
    }

    /// Its name in logs and files (`eqt`, `gt`, `nog`, `asym`).
    pub fn name(self) -> &'static str {
        match self {
            WireLaw::Eqt => "eqt",
            WireLaw::Gt => "gt",
            WireLaw::Nog => "nog",
            WireLaw::Asym => "asym",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{WireGroup, WireLaw};

    #[test]
    fn codes_round_trip_and_unknown_codes_are_none() {
        for g in WireGroup::ALL {
            assert_eq!(WireGroup::from_code(g.code()), Some(g));
        }
        for l in WireLaw::ALL {
            assert_eq!(WireLaw::from_code(l.code()), Some(l));
        }
        for code in [0, 5, 99, u32::MAX] {
            assert_eq!(WireGroup::from_code(code), None);
            assert_eq!(WireLaw::from_code(code), None);
        }
        assert_eq!(WireGroup::Se3.dims(), (4, 6));
    }
}

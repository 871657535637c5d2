//! What the mutations of TOML text write: number and string values, known keys with values,
//! whole lines.

/// What replaces a number token.
pub(crate) const INTERESTING: [&str; 30] = [
    "nan",
    "inf",
    "-inf",
    "+inf",
    "0",
    "-0.0",
    "0.0",
    "1",
    "1e308",
    "1e309",
    "-1",
    "1e-320",
    "5e-324",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "\"\"",
    "[]",
    "[[1]]",
    "true",
    "{}",
    "0x10",
    "1_000",
    "100000",
    "100001",
    "1e9",
    "1e-9",
    "3.141592653589793",
    "1.5",
    "07",
];

/// What replaces the text of a string token.
pub(super) const STRINGS: [&str; 16] = [
    "reference",
    "world",
    "recentred",
    "up",
    "so3",
    "se3",
    "eqt",
    "gt",
    "nog",
    "asym",
    "",
    "SO3",
    "x",
    "é",
    "\\u0000",
    "a name that is longer than thirty-two bytes",
];

/// Known keys and values for [`TomlOp::SetKey`](super::mutation::TomlOp::SetKey).
pub(super) const KEYS: [(&str, &[&str]); 23] = [
    ("path", &["\"stop\"", "\"through\"", "\"curvy\"", "3"]),
    (
        "error_frame",
        &[
            "\"reference\"",
            "\"world\"",
            "\"recentred\"",
            "\"up\"",
            "\"\"",
            "3",
            "[\"world\"]",
        ],
    ),
    (
        "disturbance_observer",
        &[
            "{ gain = 20.0 }",
            "{ gain = 0.0 }",
            "{ gain = 1e300, limit = 1e-300 }",
            "{ gain = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], frame = \"world\" }",
            "{ gain = 5.0, frame = \"moon\" }",
            "{ gain = 1e-300, limit = [1.0, 1.0, 1.0] }",
        ],
    ),
    (
        "integral",
        &[
            "{ ki = 1.0, c = 5.0 }",
            "{ ki = 1e300, c = 1e300, limit = 1e-300 }",
            "{ ki = 1.0, c = 5.0, anti_windup = false }",
            "{ ki = -1.0, c = 5.0 }",
            "{ ki = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0], c = 1.0, limit = 0.1 }",
        ],
    ),
    (
        "disturbance_world",
        &[
            "[0.0, 0.0, 0.0]",
            "[0.0, 0.0, 0.0, 0.5, 0.0, 0.0]",
            "[1e300, 0.0, 0.0]",
            "[nan, 0.0, 0.0]",
        ],
    ),
    (
        "disturbance_steps",
        &[
            "[{ t = 0.0, value = [0.1, 0.0, 0.0] }]",
            "[{ t = 0.5, value = [0.0, 0.0, 0.0, 0.0, 1.0, 0.0] }, { t = 0.6, value = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0] }]",
            "[{ t = 1.0, value = [1e308, 0.0, 0.0] }, { t = 0.5, value = [0.0, 0.0, 0.0] }]",
            "[{ t = -0.0, value = [] }]",
        ],
    ),
    ("group", &["\"se3\"", "\"so3\"", "\"SE3\"", "\"x\"", "3"]),
    (
        "law",
        &["\"gt\"", "\"nog\"", "\"asym\"", "\"eqt\"", "\"pd\""],
    ),
    (
        "plant_substeps",
        &["0", "1", "100000", "100001", "-1", "1.5", "3"],
    ),
    ("reference_substeps", &["0", "1", "100000", "-1", "2"]),
    (
        "duration",
        &["1e9", "20.0", "0.015", "1e-300", "0.3", "1e12"],
    ),
    ("control_period", &["0.01", "1e-12", "0.3", "0", "0.1"]),
    ("name", &["\"x\"", "\"\"", "\"é\"", "1"]),
    (
        "torque_limit",
        &[
            "5.0",
            "[1.0, 2.0, 3.0]",
            "[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]",
            "0",
            "-1.0",
            "[1.0, 0.0, 1.0]",
        ],
    ),
    (
        "disturbance",
        &[
            "[0.0, 0.0, 0.0]",
            "[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]",
            "[]",
            "[1e300, 0.0, 0.0]",
        ],
    ),
    ("position", &["[1.0, 2.0, 3.0]", "[]", "[1e200, 0, 0]"]),
    (
        "inertia",
        &[
            "[[1.0]]",
            "[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, 0], [0, 0, 0, 0, 0, 1]]",
            "[[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]",
            "[[1e-300, 0.0, 0.0], [0.0, 1e-300, 0.0], [0.0, 0.0, 1e-300]]",
            "[[1e300, 0.0, 0.0], [0.0, 1e300, 0.0], [0.0, 0.0, 1e300]]",
        ],
    ),
    (
        "kp",
        &[
            "1.0",
            "0.0",
            "-1.0",
            "1e-300",
            "[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
        ],
    ),
    (
        "kd",
        &[
            "1.0",
            "1e300",
            "[[1, 0, 0], [0, 1, 0], [0, 0, 1]]",
            "[[1, 0, 0], [0, 1, 0]]",
        ],
    ),
    (
        "rotation",
        &[
            "[0.0, 0.0, 0.0]",
            "[3.141592653589793, 0.0, 0.0]",
            "[1e10, 0.0, 0.0]",
            "[0.0, 0.0]",
        ],
    ),
    (
        "velocity",
        &[
            "[0.0, 0.0, 0.0]",
            "[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]",
            "[1e300, 0.0, 0.0]",
        ],
    ),
    (
        "torque",
        &[
            "[]",
            "[{ offset = 1.0 }, {}, {}]",
            "[{}, {}, {}, {}, {}, {}]",
            "[{ terms = [{ amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }, { amplitude = 1, frequency = 1 }] }, {}, {}]",
            "[{ offset = 1e308, terms = [{ amplitude = 1e308, frequency = 1e308 }] }, {}, {}]",
        ],
    ),
    ("offset", &["0.0", "nan", "1e308"]),
];

/// Whole lines for [`TomlOp::InsertLine`](super::mutation::TomlOp::InsertLine).
pub(super) const LINES: [&str; 14] = [
    "error_frame = \"world\"",
    "error_frame = \"up\"",
    "[[x]]",
    "[plant]",
    "[controller]",
    "[initial]",
    "[reference]",
    "[x]",
    "[reference.torque]",
    "unknown = 1",
    "group = \"se3\"",
    "law = \"gt\"",
    "plant_substeps = 0",
    "# comment",
];

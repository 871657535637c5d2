//! The seed corpus of the scenario target: the built-in scenarios, and hand-written valid
//! scenarios that reach the optional keys the built-ins leave out.

use super::Corpus;
use scenario::BUILTINS;

/// Hand-written valid scenarios that reach the optional keys the built-ins leave out.
const EXTRA_SEEDS: [&str; 9] = [
    // the disturbance-rejection terms and the world and step disturbances
    include_str!("../../../scenarios/reject_so3.toml"),
    include_str!("../../../scenarios/reject_se3.toml"),
    // `[sensors]` and `[estimator]` on both groups, with either filter
    include_str!("../../../scenarios/sensors_so3.toml"),
    include_str!("../../../scenarios/sensors_se3.toml"),
    include_str!("../../../scenarios/eqf_so3.toml"),
    include_str!("../../../scenarios/eqf_se3.toml"),
    r#"name = "so3_everything"
group = "so3"
law = "gt"
duration = 1.0
control_period = 0.001
plant_substeps = 4
reference_substeps = 2

[plant]
inertia = [[2.0, 0.1, 0.0], [0.1, 1.5, 0.0], [0.0, 0.0, 1.0]]
torque_limit = [1.0, 2.0, 3.0]
disturbance = [0.01, -0.02, 0.0]

[controller]
inertia = [[2.1, 0.0, 0.0], [0.0, 1.4, 0.0], [0.0, 0.0, 1.1]]
kp = [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]
kd = [[0.5, 0.1, 0.0], [0.1, 0.5, 0.0], [0.0, 0.0, 0.5]]

[initial]
rotation = [0.1, -0.2, 0.3]
velocity = [0.0, 1.0, -1.0]

[reference]
rotation = [0.0, 0.5, 0.0]
velocity = [0.1, 0.0, 0.0]
torque = [
  { offset = 0.1, terms = [ { amplitude = 1.0, frequency = 1.0 }, { amplitude = 0.5, frequency = 3.0, phase = 1.0 } ] },
  { terms = [] },
  { offset = -0.2 },
]
"#,
    r#"group = "se3"
law = "eqt"
duration = 0.5
control_period = 0.05

[plant]
inertia = [
  [1, 0, 0, 0, 0, 0],
  [0, 1, 0, 0, 0, 0],
  [0, 0, 1, 0, 0, 0],
  [0, 0, 0, 3, 0, 0],
  [0, 0, 0, 0, 3, 0],
  [0, 0, 0, 0, 0, 3],
]
torque_limit = 10.0
disturbance = [0.0, 0.0, 0.0, 0.1, 0.0, -9.81]

[controller]
kp = 2.0
kd = [
  [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
  [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
  [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
  [0.0, 0.0, 0.0, 2.0, 0.0, 0.0],
  [0.0, 0.0, 0.0, 0.0, 2.0, 0.0],
  [0.0, 0.0, 0.0, 0.0, 0.0, 2.0],
]

[initial]
rotation = [0.0, 0.0, 0.0]
position = [1.0, 2.0, 3.0]
velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]

[reference]
rotation = [0.1, 0.2, 0.3]
velocity = [0.0, 0.0, 0.1, 1.0, 0.0, 0.0]
"#,
    r#"group = "so3"
law = "asym"
duration = 0.1
control_period = 0.01
[plant]
inertia = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[controller]
kp = 1
kd = 1
[initial]
rotation = [0.0, 0.0, 3.0]
velocity = [0.0, 0.0, 0.0]
[reference]
rotation = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0]
"#,
];

impl Corpus {
    /// The built-in scenarios and the extra seeds.
    pub(crate) fn new() -> Corpus {
        let items = BUILTINS
            .iter()
            .map(|(_, text)| *text)
            .chain(EXTRA_SEEDS)
            .map(|t| t.as_bytes().to_vec())
            .collect();
        Corpus { items }
    }
}

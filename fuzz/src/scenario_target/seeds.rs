//! The seed corpus of the scenario target: the built-in scenarios, and hand-written valid
//! scenarios that reach the optional keys the built-ins leave out.

use super::Corpus;
use scenario::BUILTINS;

/// Hand-written valid scenarios that reach the optional keys the built-ins leave out.
const EXTRA_SEEDS: [&str; 17] = [
    // the disturbance-rejection terms and the world and step disturbances
    include_str!("../../../scenarios/reject_so3.toml"),
    include_str!("../../../scenarios/reject_se3.toml"),
    // `[sensors]` and `[estimator]` on both groups, with either filter
    include_str!("../../../scenarios/sensors_so3.toml"),
    include_str!("../../../scenarios/sensors_se3.toml"),
    include_str!("../../../scenarios/eqf_so3.toml"),
    include_str!("../../../scenarios/eqf_se3.toml"),
    // SE(2): the planar vessel (its waypoint file replaced by a set-point) and a planar body
    // with the world-frame observer, a world disturbance and a waypoint-free path
    include_str!("../../../scenarios/se2_vessel.toml"),
    r#"group = "se2"
law = "eqt"
duration = 0.2
control_period = 0.01
[plant]
inertia = [[0.5, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]]
disturbance_world = [0.1, 0.5, -0.2]
[controller]
kp = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 2.0]]
kd = 1.5
error_frame = "recentred"
disturbance_observer = { gain = 5.0, frame = "world" }
[initial]
rotation = [2.0]
position = [1.5, -1.0]
velocity = [0.5, 0.3, -0.2]
[reference]
rotation = [0.0]
position = [0.0, 0.0]
velocity = [0.4, 0.4, 0.0]
torque = [{ offset = 0.0 }, { offset = 0.0 }, { offset = 0.32 }]
"#,
    // reaction wheels with friction, alone and beside thrusters, with momentum management
    include_str!("../../../scenarios/wheels_slew.toml"),
    include_str!("../../../scenarios/wheels_dump.toml"),
    // `[vehicle]` (actuators, gravity, buoyancy, added mass, drag, lag, a failure) and
    // `[allocation]`, on both groups
    VEHICLE_SE3,
    r#"group = "so3"
law = "eqt"
duration = 0.2
control_period = 0.01
[plant]
inertia = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
[controller]
kp = 1
kd = 1
[initial]
rotation = [0.3, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0]
[reference]
setpoint = { rotation = [0.0, 0.0, 0.0] }
[vehicle]
buoyancy = 2.0
buoyancy_centre = [0.0, 0.0, 0.1]
damping_linear = [0.1, 0.1, 0.1]
[[vehicle.actuator]]
position = [1.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
min = -1.0
max = 1.0
[[vehicle.actuator]]
position = [0.0, 1.0, 0.0]
axis = [0.0, 0.0, 1.0]
min = -1.0
max = 1.0
[[vehicle.actuator]]
position = [0.0, 0.0, 1.0]
axis = [1.0, 0.0, 0.0]
min = -1.0
max = 1.0
[[vehicle.actuator]]
position = [1.0, 1.0, 0.0]
axis = [0.0, 0.0, 1.0]
torque_per_thrust = 0.1
min = -0.5
max = 0.5
[[vehicle.failure]]
actuator = 1
t = 0.02
kind = "effectiveness"
factor = 0.5
reconfigure = false
[[vehicle.failure]]
actuator = 2
t = 0.05
kind = "dead"
[[vehicle.failure]]
actuator = 3
t = 0.07
kind = "stuck"
value = 0.25
[allocation]
weights = [1.0, 2.0, 1.0, 0.5]
preferred = [0.0, 0.1, 0.0, 0.0]
priority = "none"
budget = 2
[fault_detection]
window = 0.05
false_alarm_rate = 0.01
warmup = 0.0
calibration = 0.1
memory = 1.0
floor = 0.01
confirm = 0.02
unexplained = 1e-6
ambiguity = 1e-3
model_error = 0.1
"#,
    r#"group = "se3"
law = "eqt"
duration = 0.1
control_period = 0.01
[plant]
inertia = [[0.02, 0, 0, 0, 0, 0], [0, 0.02, 0, 0, 0, 0], [0, 0, 0.04, 0, 0, 0], [0, 0, 0, 1.5, 0, 0], [0, 0, 0, 0, 1.5, 0], [0, 0, 0, 0, 0, 1.5]]
[controller]
kp = 1
kd = 1
[initial]
rotation = [0.0, 0.0, 0.0]
position = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
[reference]
setpoint = { rotation = [0.3, 0.0, 0.0], position = [0.1, 0.0, 0.0] }
[vehicle]
gravity = 9.81
actuator_time_constant = 0.02
actuator_rate_limit = 200.0
[[vehicle.actuator]]
position = [0.25, 0.0, 0.0]
axis = [0.0, 0.479425538604, 0.87758256189]
torque_per_thrust = 0.016
min = 0.0
max = 8.0
[[vehicle.actuator]]
position = [0.125, 0.216506350946, 0.0]
axis = [0.415194695654, -0.239712769302, 0.87758256189]
torque_per_thrust = -0.016
min = 0.0
max = 8.0
[[vehicle.actuator]]
position = [-0.125, 0.216506350946, 0.0]
axis = [-0.415194695654, -0.239712769302, 0.87758256189]
torque_per_thrust = 0.016
min = 0.0
max = 8.0
[[vehicle.actuator]]
position = [-0.25, 0.0, 0.0]
axis = [0.0, 0.479425538604, 0.87758256189]
torque_per_thrust = -0.016
min = 0.0
max = 8.0
[[vehicle.actuator]]
position = [-0.125, -0.216506350946, 0.0]
axis = [0.415194695654, -0.239712769302, 0.87758256189]
torque_per_thrust = 0.016
min = 0.0
max = 8.0
[[vehicle.actuator]]
position = [0.125, -0.216506350946, 0.0]
axis = [-0.415194695654, -0.239712769302, 0.87758256189]
torque_per_thrust = -0.016
min = 0.0
max = 8.0
[[vehicle.failure]]
actuator = 4
t = 0.05
reconfigure = false
"#,
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
error_frame = "world"
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
    // `[[sensors.fault]]`: every kind, on every sensor
    r#"group = "se3"
law = "eqt"
duration = 0.2
control_period = 0.01
[plant]
inertia = [[1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 2, 0, 0], [0, 0, 0, 0, 2, 0], [0, 0, 0, 0, 0, 2]]
[controller]
kp = 1
kd = 1
[initial]
rotation = [0.3, 0.0, 0.0]
position = [0.0, 0.0, 0.0]
velocity = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
[reference]
setpoint = { rotation = [0.0, 0.0, 0.0], position = [0.1, 0.0, 0.0] }
[sensors]
seed = 3
gyro = { noise = 0.002, bias = [0.01, 0.0, 0.0] }
directions = [ { world = [1.0, 0.0, 0.0], noise = 0.01 }, { world = [0.0, 0.6, 0.8], noise = 0.01 } ]
accelerometer = { noise = 0.05 }
position = { noise = 0.005, rate_hz = 50.0 }
[[sensors.fault]]
sensor = "gyro"
t = 0.02
duration = 0.05
kind = "bias"
value = [0.1, 0.0, -0.1]
[[sensors.fault]]
sensor = "direction1"
t = 0.05
kind = "bias"
rotation = [0.0, 0.5, 0.0]
[[sensors.fault]]
sensor = "accelerometer"
t = 0.03
duration = 0.1
kind = "dropout"
[[sensors.fault]]
sensor = "position"
t = 0.04
kind = "stuck"
[[sensors.fault]]
sensor = "gyro"
t = 0.1
kind = "stuck"
[estimator]
kind = "eqf"
direction_noise = [0.01, 0.01, 1.0]
gate = true
false_alarm_rate = 0.1
health_window = 0.05
"#,
];

/// The eight-thruster ROV with a failure (the `rov_failure` scenario, its waypoint file
/// replaced by a set-point so that the text stands alone).
const VEHICLE_SE3: &str = include_str!("../../../scenarios/rov_failure.toml");

impl Corpus {
    /// The built-in scenarios and the extra seeds.
    pub(crate) fn new() -> Corpus {
        let items = BUILTINS
            .iter()
            .map(|(_, text)| *text)
            .map(str::to_owned)
            .chain(EXTRA_SEEDS.map(str::to_owned))
            .chain(failsafe_seeds())
            .map(|t| {
                t.replace(
                    "waypoints = \"rov_failure.csv\"",
                    "setpoint = { rotation = [0.0, 0.0, 0.5], position = [0.6, 0.3, -0.3] }",
                )
                .replace(
                    "waypoints = \"se2_vessel.csv\"",
                    "setpoint = { rotation = [0.5], position = [0.6, 0.3] }",
                )
                .into_bytes()
            })
            .collect();
        Corpus { items }
    }
}

/// `[failsafe]` on the seeds whose vehicle and estimator every event and action fit: the ROV
/// (gravity and buoyancy: `descend` and `surface`) and the gated estimator's seed.
fn failsafe_seeds() -> [String; 2] {
    let gated = EXTRA_SEEDS
        .iter()
        .find(|t| t.contains("gate = true"))
        .copied()
        .unwrap_or_default();
    [
        format!(
            "{VEHICLE_SE3}\n[failsafe]\nlink = \"warn\"\nactuators = \"surface\"\ntracking = \"descend\"\nascend_rate = 0.2\ndescend_rate = 0.4\ntracking_limit_attitude = 1.0\ntracking_limit_position = 2.0\nactuators_residual = 0.05\nclear_time = 0.05\n"
        ),
        format!(
            "{gated}\n[failsafe]\nestimator = \"hold\"\ntracking = \"damp\"\ntracking_limit_attitude = 0.5\n"
        ),
    ]
}

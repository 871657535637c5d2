//! `group = "se2"`: the planar format (a heading, a planar position, three-entry velocities,
//! planar thrusters) is read as documented, and what needs a third dimension is refused
//! naming the key.

use eqtrack_controller::GroupKind;
use eqtrack_controller::group::se2;
use nalgebra::{Matrix3, Vector2};
use scenario::Scenario;

fn scenarios(name: &str) -> String {
    std::fs::read_to_string(format!(
        "{}/../scenarios/{name}",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap()
}

fn circle() -> String {
    scenarios("se2_circle.toml")
}

/// The vessel with its waypoint file replaced by a set-point, so the text stands alone.
fn vessel() -> String {
    let text = scenarios("se2_vessel.toml");
    let stands = text.replace(
        "waypoints = \"se2_vessel.csv\"",
        "setpoint = { rotation = [0.5], position = [0.6, 0.3] }",
    );
    assert_ne!(text, stands, "the template changed");
    stands
}

fn error(text: &str) -> String {
    match Scenario::from_toml(text, "test", "test") {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn refused(text: &str, key: &str, what: &str) {
    let e = error(text);
    assert!(
        e.contains(&format!("key `{key}`")),
        "{e} does not name {key}"
    );
    assert!(e.contains(what), "{e} does not say {what}");
}

#[test]
fn a_planar_scenario_reads_a_heading_and_a_planar_position() {
    let s = Scenario::from_toml(&circle(), "test", "test").unwrap();
    assert_eq!(s.group, GroupKind::Se2);
    let q = Scenario::configuration::<3>(&s.initial);
    let expect = se2::pose(2.0, &Vector2::new(1.5, -1.0));
    assert!((q - expect).amax() < 1e-15, "{q}");
    assert_eq!(s.initial.velocity, vec![0.5, 0.3, -0.2]);
    // a heading of zero at the origin is the identity, not an SO(3) matrix with a position
    let q_d = Scenario::configuration::<3>(&s.reference);
    assert_eq!(q_d, Matrix3::identity());
}

#[test]
fn a_planar_vessel_has_planar_columns() {
    let s = Scenario::from_toml(&vessel(), "test", "test").unwrap();
    let v = s.vehicle.as_ref().unwrap();
    assert!(v.planar);
    let g = v.geometry::<3>().unwrap();
    let b = g.effectiveness();
    // thruster 0 at (0.5, 0.3) along (1, −1)/√2: (x a_y − y a_x, a_x, a_y)
    let h = core::f64::consts::FRAC_1_SQRT_2;
    let expect = [0.5 * -h - 0.3 * h, h, -h];
    for (r, e) in expect.iter().enumerate() {
        assert!((b[(r, 0)] - e).abs() < 1e-12, "row {r}: {}", b[(r, 0)]);
    }
}

#[test]
fn planar_keys_of_the_wrong_length_are_refused_naming_the_key() {
    // (text, from, to: the first occurrence replaced), the key named, what the message says
    let (c, v) = (circle(), vessel());
    let cases = [
        (
            &c,
            "rotation = [2.0]",
            "rotation = [2.0, 0.0, 0.0]",
            "initial.rotation",
            "a heading",
        ),
        (
            &c,
            "position = [1.5, -1.0]",
            "position = [1.5, -1.0, 0.0]",
            "initial.position",
            "x, y",
        ),
        (
            &c,
            "velocity = [0.5, 0.3, -0.2]",
            "velocity = [0.5, 0.3]",
            "initial.velocity",
            "ω, v_x, v_y",
        ),
        (
            &c,
            "kd = 1.5",
            "kd = [[1.0, 0.0], [0.0, 1.0]]",
            "controller.kd",
            "",
        ),
        (
            &v,
            "position = [0.5, 0.3]",
            "position = [0.5, 0.3, 0.0]",
            "vehicle.actuator[0].position",
            "x, y in the body plane",
        ),
        (
            &v,
            "axis = [0.707106781187, -0.707106781187]",
            "axis = [0.7, -0.7, 0.1]",
            "vehicle.actuator[0].axis",
            "in the body plane",
        ),
        (
            &v,
            "axis = [0.707106781187, -0.707106781187]",
            "axis = [0.0, 0.0]",
            "vehicle.actuator[0].axis",
            "zero",
        ),
    ];
    for (text, from, to, key, says) in cases {
        assert!(text.contains(from), "the scenario no longer has `{from}`");
        refused(&text.replacen(from, to, 1), key, says);
    }
    // two thrusters along x cannot turn the vessel about z or push it sideways
    let two = v.split("[[vehicle.actuator]]").next().unwrap().to_owned()
        + "[[vehicle.actuator]]\nposition = [0.5, 0.0]\naxis = [1.0, 0.0]\nmin = -1.0\nmax = 1.0\n\
           [[vehicle.actuator]]\nposition = [-0.5, 0.0]\naxis = [1.0, 0.0]\nmin = -1.0\nmax = 1.0\n";
    refused(&two, "vehicle.actuator", "cannot produce every wrench");
}

#[test]
fn what_needs_a_third_dimension_is_refused_on_se2_naming_the_key() {
    let c = circle();
    let v = vessel();
    let not_planar = "is not available on se2";
    for (text, key) in [
        (
            c.clone() + "[sensors]\nseed = 7\ngyro = { noise = 0.002 }\n",
            "sensors".to_owned(),
        ),
        (
            c.clone() + "[estimator]\nkind = \"complementary\"\nkp = 1.0\nki = 0.3\n",
            "estimator".to_owned(),
        ),
        (
            v.clone() + "[fault_detection]\n",
            "fault_detection".to_owned(),
        ),
        (
            c.clone() + "[failsafe]\ntracking = \"hold\"\n",
            "failsafe".to_owned(),
        ),
        (
            v.replace("[vehicle]\n", "[vehicle]\ngravity = 9.81\n"),
            "vehicle.gravity".to_owned(),
        ),
        (
            v.replace("[vehicle]\n", "[vehicle]\nbuoyancy = 1.0\n"),
            "vehicle.buoyancy".to_owned(),
        ),
        (
            v.replace(
                "[vehicle]\n",
                "[vehicle]\nbuoyancy_centre = [0.0, 0.0, 0.1]\n",
            ),
            "vehicle.buoyancy_centre".to_owned(),
        ),
        (
            v.clone()
                + "[[vehicle.wheel]]\naxis = [0.0, 0.0, 1.0]\ninertia = 0.01\nmax_torque = 0.1\nmax_speed = 600.0\n",
            "vehicle.wheel".to_owned(),
        ),
        (
            v.replacen("min = -40.0", "torque_per_thrust = 0.1\nmin = -40.0", 1),
            "vehicle.actuator[0].torque_per_thrust".to_owned(),
        ),
        (
            v.clone() + "[allocation]\npriority = \"tilt\"\n",
            "allocation.priority".to_owned(),
        ),
    ] {
        refused(&text, &key, not_planar);
    }
    // an explicit zero reaction torque is planar
    let zero = v.replacen("min = -40.0", "torque_per_thrust = 0.0\nmin = -40.0", 1);
    assert!(Scenario::from_toml(&zero, "test", "test").is_ok());
    // the processor-in-the-loop firmware does not fly se2
    let s = Scenario::from_toml(&c, "test", "test").unwrap();
    let e = s.firmware_config().unwrap_err().to_string();
    assert!(e.contains("key `group`") && e.contains("se2"), "{e}");
}

#[test]
fn a_planar_waypoint_file_reads_a_heading_and_a_planar_position() {
    let path = scenario::waypoints::parse(
        "t,theta,x,y,w,vx,vy\n0,0.5,1,2,,,\n2,-0.5,3,4,0.1,0.2,0.3\n",
        "w.csv",
        GroupKind::Se2,
    )
    .unwrap();
    assert_eq!(path.poses[0].rotation, [0.0, 0.0, 0.5]);
    assert_eq!(path.poses[1].position, [3.0, 4.0, 0.0]);
    assert_eq!(path.velocities[1], Some(vec![0.1, 0.2, 0.3]));
    let e = scenario::waypoints::parse("t,rx,ry,rz\n0,0,0,0\n", "w.csv", GroupKind::Se2)
        .unwrap_err()
        .to_string();
    assert!(e.contains("theta"), "{e}");
}

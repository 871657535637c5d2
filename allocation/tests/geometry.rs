//! Actuator geometry: the effectiveness column, and what is refused
//! (docs/maths.md, "Control allocation").

use eqtrack_allocation::{
    Actuator, Allocator, AllocatorError, Geometry, GeometryError, Priority, Status, presets,
};
use nalgebra::SVector;

fn rotor(position: [f64; 3], axis: [f64; 3], c: f64) -> Actuator<f64> {
    Actuator {
        position,
        axis,
        torque_per_thrust: c,
        min: 0.0,
        max: 8.0,
    }
}

#[test]
fn the_column_is_p_cross_a_plus_c_a_over_a_with_the_axis_normalised() {
    let a = rotor([0.3, -0.2, 0.1], [0.0, 0.0, 2.0], 0.02);
    let b = Geometry::<f64, 6>::new(&presets_plus(a)).unwrap();
    let col = b.effectiveness().column(6).into_owned();
    // a = e_z: p × a = (py, −px, 0) = (−0.2, −0.3, 0); + c a = (0, 0, 0.02)
    let want = SVector::<f64, 6>::from([-0.2, -0.3, 0.02, 0.0, 0.0, 1.0]);
    assert!((col - want).amax() < 1e-15, "{col}");
    // on SO(3): the torque rows alone
    let b3 = Geometry::<f64, 3>::new(&presets_plus(a)).unwrap();
    assert!((b3.effectiveness().column(6) - want.fixed_rows::<3>(0)).amax() < 1e-15);
    // c > 0: the reaction torque along +a
    let spin = rotor([0.0; 3], [1.0, 0.0, 0.0], 0.5);
    let b = Geometry::<f64, 6>::new(&presets_plus(spin)).unwrap();
    assert_eq!(b.effectiveness()[(0, 6)], 0.5);
}

/// The hexarotor plus one more actuator (column 6), so that the geometry spans.
fn presets_plus(extra: Actuator<f64>) -> Vec<Actuator<f64>> {
    let mut v = presets::hexarotor(0.25, 0.5, 0.016, 8.0).to_vec();
    v.push(extra);
    v
}

#[test]
fn the_presets_span_the_wrench_space() {
    assert!(Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).is_ok());
    assert!(Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).is_ok());
    assert!(Geometry::<f32, 6>::new(&presets::hexarotor(0.25f32, 0.5, 0.016, 8.0)).is_ok());
}

#[test]
fn a_geometry_that_misses_a_direction_is_refused_naming_it() {
    // an untilted hexarotor: every rotor along +z, so no force along x or y
    let flat = presets::hexarotor(0.25, 0.0, 0.016, 8.0);
    match Geometry::<f64, 6>::new(&flat) {
        Err(GeometryError::DoesNotSpan(lost)) => {
            assert_eq!(lost.directions().len(), 2);
            let text = GeometryError::DoesNotSpan(lost).to_string();
            assert!(text.contains("fx") && text.contains("fy"), "{text}");
            assert!(!text.contains("τz"), "{text}");
        }
        other => panic!("{other:?}"),
    }
    // four thrusters all pushing along x through the centre: no torque at all
    let through: Vec<_> = (0..4)
        .map(|_| rotor([0.0; 3], [1.0, 0.0, 0.0], 0.0))
        .collect();
    match Geometry::<f64, 3>::new(&through) {
        Err(e @ GeometryError::DoesNotSpan(_)) => {
            let text = e.to_string();
            assert!(
                text.contains("τx") && text.contains("τy") && text.contains("τz"),
                "{text}"
            );
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn bad_actuators_are_refused_naming_the_actuator_and_the_field() {
    let mut acts = presets::hexarotor(0.25, 0.5, 0.016, 8.0).to_vec();
    let check = |acts: &[Actuator<f64>], want: &str| {
        let e = Geometry::<f64, 6>::new(acts).unwrap_err();
        assert!(e.to_string().contains(want), "{e} lacks {want}");
    };
    acts[3].axis = [0.0; 3];
    check(&acts, "actuator 3: `axis` is zero");
    acts[3].axis = [0.0, 0.0, 1.0];
    acts[2].min = 9.0;
    check(&acts, "actuator 2: `min` = 9 is above `max` = 8");
    acts[2].min = 0.0;
    acts[4].position[1] = f64::NAN;
    check(&acts, "actuator 4: `position` is not a finite number");
    acts[4].position[1] = 0.0;
    acts[1].torque_per_thrust = f64::INFINITY;
    check(
        &acts,
        "actuator 1: `torque_per_thrust` is not a finite number",
    );
    acts[1].torque_per_thrust = 0.0;
    acts[0].axis = [f64::NAN, 0.0, 1.0];
    check(&acts, "actuator 0: `axis` is not a finite number");
    let thirteen: Vec<_> = (0..13).map(|_| acts[5]).collect();
    check(&thirteen, "13 actuators: a vehicle has 1 to 12");
    check(&[], "0 actuators");
}

#[test]
fn weights_and_preferred_need_one_positive_finite_entry_per_actuator() {
    let g = Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).unwrap();
    let e = Allocator::new(g, &[1.0; 5], &[], Priority::Torque).unwrap_err();
    assert_eq!(
        e,
        AllocatorError::Length {
            what: "weights",
            found: 5,
            expected: 6
        }
    );
    assert!(e.to_string().contains("`weights` has 5 entries"));
    let e = Allocator::new(g, &[1.0, 1.0, 0.0, 1.0, 1.0, 1.0], &[], Priority::Torque).unwrap_err();
    assert!(
        e.to_string()
            .contains("`weights` entry 2 must be positive and finite"),
        "{e}"
    );
    let e = Allocator::new(
        g,
        &[],
        &[0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0],
        Priority::Torque,
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("`preferred` entry 1 must be finite"),
        "{e}"
    );
}

#[test]
fn the_iteration_cap_stops_a_stage_with_a_finite_answer_within_the_bounds() {
    let g = Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).unwrap();
    let demand = SVector::<f64, 6>::from([0.5, -0.3, 1.2, 2.0, -1.0, 45.0]);
    let full = Allocator::new(g, &[], &[], Priority::Torque)
        .unwrap()
        .allocate(&demand);
    assert!(
        full.iterations > 1,
        "a saturated demand takes several iterations: {full:?}"
    );
    let capped = Allocator::new(g, &[], &[], Priority::Torque)
        .unwrap()
        .with_budget(1)
        .allocate(&demand);
    assert_eq!(capped.status, Status::Stopped);
    assert_eq!(Status::Stopped.code(), 3);
    assert!(
        capped
            .u
            .iter()
            .take(6)
            .all(|x| x.is_finite() && (0.0..=8.0).contains(x)),
        "{capped:?}"
    );
}

#[test]
fn a_demand_within_reach_needs_no_active_set_iteration() {
    // the W-nearest command producing the demand is every stage's optimum when it lies
    // within the bounds
    let g = Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).unwrap();
    let a = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let within = a.allocate(&SVector::from([0.1, -0.05, 0.02, 0.5, -0.3, 20.0]));
    assert_eq!((within.status, within.iterations), (Status::Met, 0));
    let past = a.allocate(&SVector::from([0.5, -0.3, 1.2, 2.0, -1.0, 45.0]));
    assert_eq!(past.status, Status::ForceGivenUp);
    assert!(past.iterations > 1, "{past:?}");
}

#[test]
fn the_tilt_priority_keeps_roll_pitch_and_thrust_where_the_torque_priority_cannot() {
    // the tilted hexarotor with rotor 2 dead, asked what the law asked of it just after
    let hexa = presets::hexarotor(0.25, 0.5, 0.016, 8.0);
    let demand = SVector::<f64, 6>::from([0.37, 0.26, 0.25, -0.98, -1.62, 16.97]);
    let with = |p: Priority| {
        let alloc = Allocator::new(Geometry::new(&hexa).unwrap(), &[], &[], p).unwrap();
        let mut bounds = alloc.bounds();
        bounds.fail(2, 0.0);
        let a = alloc.allocate_within(&demand, &bounds);
        assert_eq!(a.u[2], 0.0);
        assert!(a.u.iter().all(|x| (0.0..=8.0).contains(x)), "{:?}", a.u);
        let miss = a.achieved - demand;
        (
            a.status,
            [0, 1, 5].map(|i| miss[i].abs()),
            [2, 3, 4].map(|i| miss[i].abs()),
        )
    };
    let (status, kept, given) = with(Priority::Tilt);
    assert_eq!(status, Status::ForceGivenUp, "{kept:?} {given:?}");
    assert!(kept.iter().all(|m| *m < 1e-9), "{kept:?}");
    assert!(given.iter().any(|m| *m > 0.1), "{given:?}");
    // the torque priority keeps the yaw torque and so loses roll, pitch or thrust
    let (status, kept, _) = with(Priority::Torque);
    assert_eq!(status, Status::TorqueInfeasible);
    assert!(kept.iter().any(|m| *m > 0.1), "{kept:?}");
    // within reach, every priority gives the same command, bit for bit
    let hover = SVector::<f64, 6>::from([0.0, 0.0, 0.0, 0.0, 0.0, 14.7]);
    let u = |p: Priority| {
        let alloc = Allocator::new(Geometry::new(&hexa).unwrap(), &[], &[], p).unwrap();
        alloc.allocate(&hover).u
    };
    assert_eq!(u(Priority::Tilt), u(Priority::Torque));
    // on SO(3) there is only torque: tilt is the torque priority
    let spacecraft = presets::spacecraft_twelve(0.5, 1.0);
    let turn = SVector::<f64, 3>::from([3.0, -2.0, 5.0]);
    let u3 = |p: Priority| {
        let alloc = Allocator::new(Geometry::new(&spacecraft).unwrap(), &[], &[], p).unwrap();
        alloc.allocate(&turn)
    };
    assert_eq!(u3(Priority::Tilt), u3(Priority::Torque));
}

#[test]
fn the_directions_lost_are_those_the_actuators_left_free_do_not_span() {
    let rov = presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0);
    let alloc =
        Allocator::<f64, 6>::new(Geometry::new(&rov).unwrap(), &[], &[], Priority::Torque).unwrap();
    let mut control = eqtrack_allocation::VehicleControl::new(
        alloc,
        eqtrack_allocation::Restoring {
            weight: 0.0,
            buoyancy: 0.0,
            centre: nalgebra::Vector3::zeros(),
        },
        0.0,
        0.01,
    );
    assert!(control.lost_directions().directions().is_empty());
    // one horizontal thruster held: the other three still push every way
    control.fail(1, 0.0);
    assert!(control.lost_directions().directions().is_empty());
    // a second: one direction of the horizontal plane's three is lost
    control.fail(2, 0.0);
    assert_eq!(control.lost_directions().directions().len(), 1);
    // a weakened one still moves
    control.heal(2);
    let mut watch = eqtrack_allocation::SpanWatch::default();
    control.weaken(2, 0.3);
    assert!(control.lost_directions().directions().is_empty());
    assert!(!watch.lost(&control));
    // one so weak that its column is below the rank test's tolerance: that direction is lost,
    // as it was when the weak column was the allocator's own; the watch sees the factor change
    control.weaken(2, 1e-12);
    assert_eq!(control.lost_directions().directions().len(), 1);
    assert!(watch.lost(&control));
    // a factor below ε is taken as ε, and the allocation stays finite
    control.weaken(2, 1e-300);
    assert_eq!(control.factors()[2], f64::EPSILON);
    let demand = SVector::<f64, 6>::from([0.1, 0.1, 0.5, 30.0, 20.0, 10.0]);
    let a = control.actuate_demand(demand).allocation;
    assert!(a.u.iter().all(|x| x.is_finite()) && a.achieved.iter().all(|x| x.is_finite()));
}

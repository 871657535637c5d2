//! The oracle of the scenario target: parsing and validating, then what the processes do with
//! an accepted scenario; the report's names of the errors.

use crate::Outcome;
use eqtrack_controller::group::OnGroup;
use eqtrack_controller::{BuiltinGroup, Law, Quantity};
use scenario::{Scenario, ScenarioError};

/// Closed-loop cycles run on an accepted scenario, at most.
const CYCLES: usize = 3;
/// RKMK4 substeps one accepted case may spend per integrator (plant, reference): a scenario
/// asking for more substeps per period runs fewer cycles (down to one law evaluation and no
/// step), so a case stays cheap whatever `plant_substeps` says.
const SUBSTEP_BUDGET: usize = 2_000;

/// A coarse class of a TOML reader's message (`None`: none of these).
pub(crate) fn parse_class(message: &str) -> Option<&'static str> {
    [
        ("unknown field", "unknown field"),
        ("missing field", "missing field"),
        ("invalid type", "invalid type"),
        ("duplicate key", "duplicate key"),
        ("did not match any variant", "untagged: no variant matched"),
        ("invalid length", "invalid length"),
        ("invalid value", "invalid value"),
    ]
    .iter()
    .find(|(needle, _)| message.contains(needle))
    .map(|(_, class)| *class)
}

/// The report's name of a scenario error: the variant, and for `Invalid` the key (indices
/// shown as `*`, and `on se2` for a key a planar scenario refuses); for `Parse` a coarse
/// class of the parser's message.
pub(super) fn scenario_error_kind(e: &ScenarioError) -> String {
    match e {
        ScenarioError::Io { .. } => "ScenarioError::Io".to_owned(),
        ScenarioError::Parse { message, .. } => {
            let class = parse_class(message).unwrap_or("syntax or value");
            format!("ScenarioError::Parse ({class})")
        }
        ScenarioError::Invalid { key, message, .. } => {
            let mut k = String::with_capacity(key.len());
            let mut in_index = false;
            for c in key.chars() {
                match c {
                    '[' => {
                        in_index = true;
                        k.push_str("[*");
                    }
                    ']' => {
                        in_index = false;
                        k.push(']');
                    }
                    _ if in_index => {}
                    _ => k.push(c),
                }
            }
            if message.contains("is not available on se2") {
                k.push_str(", on se2");
            }
            format!("ScenarioError::Invalid ({k})")
        }
        ScenarioError::UnknownBuiltin(_) => "ScenarioError::UnknownBuiltin".to_owned(),
        ScenarioError::Waypoints { .. } => "ScenarioError::Waypoints".to_owned(),
    }
}

/// The report's name of a controller error: variant and quantity (no sizes or indices).
pub(crate) fn controller_error_kind(e: &eqtrack_controller::Error) -> String {
    use eqtrack_controller::Error as E;
    let q = |q: &Quantity| format!("{q:?}");
    match e {
        E::NonFinite(x) => format!("NonFinite({})", q(x)),
        E::NotSymmetric(x) => format!("NotSymmetric({})", q(x)),
        E::NotPositiveDefinite(x) => format!("NotPositiveDefinite({})", q(x)),
        E::NotPositive(x) => format!("NotPositive({})", q(x)),
        E::WrongShape { quantity, .. } => format!("WrongShape({})", q(quantity)),
        E::LawNotDefined { law, group } => format!("LawNotDefined({law:?}, {group})"),
        E::NoAttitude { group } => format!("NoAttitude({group})"),
        E::TooManyTerms { .. } => "TooManyTerms".to_owned(),
        E::NotIncreasing { .. } => "NotIncreasing".to_owned(),
        E::TooManySegments { .. } => "TooManySegments".to_owned(),
        E::NotAtRest { .. } => "NotAtRest".to_owned(),
        E::MissesWaypoint { .. } => "MissesWaypoint".to_owned(),
    }
}

/// `eqtrack_controller::Error` of one stage, as a rejection name.
fn stage(name: &str, e: eqtrack_controller::Error) -> String {
    format!(
        "{name}: eqtrack_controller::Error::{}",
        controller_error_kind(&e)
    )
}

/// What the processes do with an accepted scenario, on its group.
struct Exercise<'a>(&'a Scenario);

impl OnGroup for Exercise<'_> {
    type Output = Result<(), String>;

    fn run<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(self) -> Self::Output {
        let s = self.0;
        let controller = s
            .controller::<G, N, M>()
            .map_err(|e| stage("controller()", e))?;
        let mut reference = s
            .reference_generator::<G, N, M>()
            .map_err(|e| stage("reference_generator()", e))?;
        let mut body = s
            .plant_body::<G, N, M>()
            .map_err(|e| stage("plant_body()", e))?;
        let _ = s
            .feedforward::<M>()
            .map_err(|e| stage("feedforward()", e))?;
        // the disturbance-rejection terms, fed with the torque applied, as the node runs them
        let mut terms = eqtrack_controller::Rejection::new(
            s.rejection_config::<M>(),
            controller.config().torque_limit.as_ref(),
        )
        .map_err(|e| stage("Rejection::new()", e))?;
        let mut applied = nalgebra::SVector::<f64, M>::zeros();
        let world = s.world_disturbance::<M>();
        // a vehicle: the law's wrench through its allocation, as the controller side runs it
        let mut vehicle = vehicle_of::<M>(s)?;
        let most = s.plant_substeps.max(s.reference_substeps).max(1);
        let cycles = (SUBSTEP_BUDGET / most).min(CYCLES);
        // the sensors, their scripted faults and the filter (behind its gate), as the plant
        // side runs them: the estimate is finite whatever the samples
        let mut estimation = plant::estimation::Estimation::new(s, s.control_period, &[])
            .map_err(|e| format!("Estimation::new(): {e}"))?;
        firmware_checked::<N, M>(s, body.configuration(), &body.velocity());
        for k in 0..=cycles {
            let desired = reference.desired();
            if let Some(e) = &mut estimation {
                estimate_checked(e, k as u64, &body, &applied);
            }
            let (q, v) = (*body.configuration(), body.velocity());
            let out = if s.rejection_config::<M>().any() {
                controller
                    .compute_rejecting(
                        &mut terms,
                        &q,
                        &v,
                        &desired,
                        &applied,
                        s.control_period,
                        true,
                    )
                    .map_err(|e| stage("compute_rejecting()", e))?
            } else {
                controller
                    .compute(&q, &v, &desired)
                    .map_err(|e| stage("compute()", e))?
            };
            assert!(
                out.torque
                    .iter()
                    .chain(&out.observer)
                    .chain(&out.integral)
                    .all(|x| x.is_finite()),
                "the controller returned a non-finite number: {:?} {:?} {:?}",
                out.torque.as_slice(),
                out.observer.as_slice(),
                out.integral.as_slice()
            );
            if let Some(vehicle) = &mut vehicle {
                allocate_checked(vehicle, &out.torque, &G::rotation(&q));
                // what the failsafe's `actuators` event asks of it
                let _ = vehicle.lost_directions();
            }
            if s.failsafe.is_some() {
                failsafe_checked(&controller, &reference, &q, &v);
            }
            if k == cycles {
                break;
            }
            applied = out.torque;
            let total = out.torque + s.disturbance_at::<M>(k as u64);
            match &world {
                None => body.advance(&total, s.control_period, s.plant_substeps),
                Some(w) => body.advance_with_world(&total, w, s.control_period, s.plant_substeps),
            }
            reference.advance();
        }
        Ok(())
    }
}

/// Every action of the failsafe manager engaged at state `(q, v)` over `reference`: each
/// set-point is one the law answers with a finite torque.
fn failsafe_checked<G, R, const N: usize, const M: usize>(
    controller: &eqtrack_controller::Controller<f64, G, N, M>,
    reference: &R,
    q: &nalgebra::SMatrix<f64, N, N>,
    v: &nalgebra::SVector<f64, M>,
) where
    G: BuiltinGroup<N, M>,
    R: eqtrack_controller::reference::Trajectory<f64, N, M> + Clone,
{
    let rates = failsafe::setpoint::Rates {
        descend: 0.5,
        ascend: 0.3,
    };
    let inertia = controller.config().inertia;
    let mut reference = reference.clone();
    let mut sup = failsafe::setpoint::Setpoint::<f64, G, N, M>::new(*q, inertia, rates);
    sup.observe(q, v);
    for action in failsafe::Action::ALL {
        sup.engage(Some(action), reference.time());
        reference.advance();
        let desired = sup.desired(&reference.desired(), reference.time());
        if let Ok(out) = controller.compute(q, v, &desired) {
            assert!(
                out.torque.iter().all(|x| x.is_finite()),
                "{action:?}: a non-finite torque {:?}",
                out.torque.as_slice()
            );
        }
    }
}

/// The scenario's vehicle as the controller side allocates for it (`None`: no vehicle).
fn vehicle_of<const M: usize>(
    s: &Scenario,
) -> Result<Option<eqtrack_allocation::VehicleControl<f64, M>>, String> {
    let Some(v) = &s.vehicle else {
        return Ok(None);
    };
    let allocator = v.allocator::<M>().map_err(|_| "vehicle: allocator()")?;
    Ok(Some(eqtrack_allocation::VehicleControl::new(
        allocator,
        v.restoring(),
        v.actuator_rate_limit,
        s.control_period,
    )))
}

/// The processor-in-the-loop firmware's side of an accepted scenario: its configuration is
/// refused by name or makes bytes; bytes that make a cycle answer the scenario's first state
/// (`q`, `v`, as `link::serial::state_frame` sends it, the wheels at their initial speeds)
/// with finite numbers, or drop it; never a panic.
fn firmware_checked<const N: usize, const M: usize>(
    s: &Scenario,
    q: &nalgebra::SMatrix<f64, N, N>,
    v: &nalgebra::SVector<f64, M>,
) {
    use eqtrack_serial_wire::{Frame, StateFrame};
    let Ok(config) = s.firmware_config() else {
        return;
    };
    let mut buf = vec![0u8; firmware_cycle::MAX_CONFIG];
    let Ok(n) = config.to_bytes(&mut buf) else {
        return;
    };
    let Ok(mut cycle) = firmware_cycle::Cycle::from_bytes(&buf[..n]) else {
        return;
    };
    let _ = cycle.on_frame(&Frame::Hello(config.identity.clone()));
    let mut rows = q.transpose();
    if N == 4 {
        for (i, o) in config.origin.iter().enumerate() {
            rows[(3, i)] -= o;
        }
    }
    let narrow = |xs: &[f64]| xs.iter().take(16).map(|x| *x as f32).collect();
    let speeds: Vec<f64> = s
        .vehicle
        .iter()
        .flat_map(|v| v.wheels.iter().map(|w| w.speed))
        .collect();
    let state = StateFrame {
        seq: 0,
        t: 0.0,
        q: narrow(rows.as_slice()),
        v: v.iter().take(6).map(|x| *x as f32).collect(),
        applied: core::iter::repeat_n(0.0, M.min(6)).collect(),
        samples: None,
        wheel_speeds: speeds.iter().take(6).map(|x| *x as f32).collect(),
    };
    if let Some(Frame::Command(c)) = cycle.on_frame(&Frame::State(state)) {
        let u = c.allocation.iter().flat_map(|a| a.u_cmd.iter());
        assert!(
            c.tau.iter().chain(u).all(|x| x.is_finite()),
            "the firmware's cycle answered a non-finite number: {c:?}"
        );
    }
}

/// Tick `k` of the plant side's estimator (sensors, faults, filter and gate): the state it
/// hands the law must be finite, whatever the samples.
fn estimate_checked<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
    e: &mut plant::estimation::Estimation,
    k: u64,
    body: &eqtrack_controller::integrator::RigidBody<f64, G, N, M>,
    applied: &nalgebra::SVector<f64, M>,
) {
    let (q_hat, v_hat, _) = e.measure(k, body, applied);
    assert!(
        q_hat.iter().chain(v_hat.iter()).all(|x| x.is_finite()),
        "the estimator returned a non-finite state: {q_hat} {v_hat}"
    );
}

/// One allocation of the law's wrench `wrench` at attitude `r`: the commands (and the wrench
/// they give) must be finite and within the bounds, whatever the wrench (a demand that
/// overflows is answered with status 4).
fn allocate_checked<const M: usize>(
    vehicle: &mut eqtrack_allocation::VehicleControl<f64, M>,
    wrench: &nalgebra::SVector<f64, M>,
    r: &nalgebra::Matrix3<f64>,
) {
    let (lo, hi) = vehicle.bounds();
    let a = vehicle.actuate(wrench, r);
    let u = a.allocation.u;
    assert!(
        u.iter()
            .chain(a.allocation.achieved.iter())
            .all(|x| x.is_finite()),
        "the allocation returned a non-finite number: {a:?}"
    );
    for j in 0..eqtrack_allocation::MAX_ACTUATORS {
        let tol = 1e-9 * (1.0 + lo[j].abs().max(hi[j].abs()));
        assert!(
            u[j] >= lo[j] - tol && u[j] <= hi[j] + tol,
            "u[{j}] = {} outside [{}, {}]",
            u[j],
            lo[j],
            hi[j]
        );
    }
}

/// Checks one scenario input (bytes: invalid UTF-8 is replaced, so the parser still runs).
pub(crate) fn check(input: &[u8]) -> Outcome {
    let text = String::from_utf8_lossy(input);
    let s = match Scenario::from_toml(&text, "fuzz input", "fuzz") {
        Ok(s) => s,
        Err(e) => return Outcome::Rejected(scenario_error_kind(&e)),
    };
    let fp = s.fingerprint();
    assert_ne!(fp, 0, "Scenario::fingerprint is documented never to be 0");
    assert_eq!(fp, s.clone().fingerprint(), "fingerprint not deterministic");
    std::hint::black_box(s.steps());
    for law in Law::ALL {
        let _ = std::hint::black_box(s.clone().with_law(law));
    }
    moved(&text, &s);
    match s.group.dispatch(Exercise(&s)) {
        Ok(()) => Outcome::Accepted,
        Err(kind) => Outcome::Rejected(kind),
    }
}

/// An accepted scenario moved with the world (`plant_sim move`): moved by nothing it is the
/// same scenario; moved a kilometre (turned only, on SO(3)) it is moved or refused by name,
/// never a panic, and a moved text the loader takes has the same group and length.
fn moved(text: &str, s: &Scenario) {
    use scenario::moving::{WorldMotion, move_scenario};
    let none = WorldMotion {
        heading: 0.0,
        offset: [0.0; 3],
    };
    let same = move_scenario(text, "fuzz input", None, &none)
        .unwrap_or_else(|e| panic!("an accepted scenario did not move by nothing: {e}"));
    let back = Scenario::from_toml(&same.text, "fuzz input", "fuzz")
        .unwrap_or_else(|e| panic!("a scenario moved by nothing does not load: {e}"));
    assert_eq!(&back, s, "moved by nothing, the scenario changed");
    let far = WorldMotion {
        heading: 0.7,
        offset: match s.group {
            eqtrack_controller::GroupKind::So3 | eqtrack_controller::GroupKind::Se2 => [0.0; 3],
            eqtrack_controller::GroupKind::Se3 => [1000.0, -700.0, 300.0],
        },
    };
    if let Ok(m) = move_scenario(text, "fuzz input", None, &far)
        && let Ok(t) = Scenario::from_toml(&m.text, "fuzz input", "fuzz")
    {
        assert_eq!((t.group, t.steps()), (s.group, s.steps()));
    }
}

//! Bounded time (docs/vehicles.md, "Bounded time"): a warm start reaches the cold start's
//! optimum in fewer iterations, and a budget that runs out still answers a command within the
//! bounds that keeps what the finished stages reached.

use eqtrack_allocation::{
    Actuator, Allocator, Bounds, Commands, Geometry, MAX_ACTUATORS, Priority, Status, presets,
};
use nalgebra::SVector;
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

fn hexarotor() -> Allocator<f64, 6> {
    let g = Geometry::<f64, 6>::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).unwrap();
    Allocator::new(g, &[], &[], Priority::Torque).unwrap()
}

fn rov() -> Allocator<f64, 6> {
    let g = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
    Allocator::new(g, &[], &[], Priority::Torque).unwrap()
}

/// The ROV with a surge thruster on its centreline: its horizontal block has five thrusters,
/// past what the blocks' closed forms take, and the primal stages solve it.
fn rov_with_surge() -> Allocator<f64, 6> {
    let mut thrusters = presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0).to_vec();
    thrusters.push(Actuator {
        position: [0.2, 0.0, 0.0],
        axis: [1.0, 0.0, 0.0],
        torque_per_thrust: 0.0,
        min: -30.0,
        max: 30.0,
    });
    Allocator::new(
        Geometry::<f64, 6>::new(&thrusters).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap()
}

fn spacecraft() -> Allocator<f64, 3> {
    let g = Geometry::<f64, 3>::new(&presets::spacecraft_twelve(0.5, 3.0)).unwrap();
    Allocator::new(g, &[], &[], Priority::Torque).unwrap()
}

fn within<const K: usize>(a: &eqtrack_allocation::Allocation<f64, K>, b: &Bounds<f64>) -> bool {
    (0..MAX_ACTUATORS).all(|j| a.u[j].is_finite() && a.u[j] >= b.lo[j] && a.u[j] <= b.hi[j])
}

/// Along a trajectory of demands that saturate (and with a failed actuator), warm and cold
/// answers agree to 1e-12 of the largest bound; the warm ones take fewer iterations where the
/// primal method runs. Returns the iterations, cold and warm.
fn warm_equals_cold<const K: usize>(
    alloc: &Allocator<f64, K>,
    demand: impl Fn(f64) -> SVector<f64, K>,
    failed: &[(usize, f64)],
) -> (u32, u32) {
    let mut bounds = alloc.bounds();
    for &(j, v) in failed {
        bounds.fail(j, v);
    }
    let scale = 1.0 + bounds.hi.amax().max(bounds.lo.amax());
    let (mut cold_iterations, mut warm_iterations, mut saturated) = (0, 0, 0);
    let mut previous: Option<Commands<f64>> = None;
    for k in 0..400 {
        let d = demand(k as f64 * 0.01);
        let cold = alloc.allocate_within(&d, &bounds);
        let warm = alloc.allocate_from(&d, &bounds, previous.as_ref());
        assert!(cold.status != Status::Stopped && warm.status != Status::Stopped);
        assert!(within(&warm, &bounds), "{warm:?}");
        assert!(
            (warm.u - cold.u).amax() <= 1e-12 * scale,
            "tick {k}: warm {:?} cold {:?} differ by {:e}",
            warm.u,
            cold.u,
            (warm.u - cold.u).amax()
        );
        assert_eq!(warm.status, cold.status, "tick {k}");
        cold_iterations += cold.iterations;
        warm_iterations += warm.iterations;
        saturated += u32::from(cold.status != Status::Met);
        previous = Some(warm.u);
    }
    assert!(
        saturated > 100,
        "the trajectory saturates: {saturated} ticks"
    );
    (cold_iterations, warm_iterations)
}

#[test]
fn warm_starts_reach_the_cold_optimum_in_fewer_iterations() {
    let hex = |t: f64| {
        SVector::<f64, 6>::from([
            0.8 * t.sin(),
            0.6 * (1.3 * t).cos(),
            0.4 * (0.7 * t).sin(),
            2.0 * (0.5 * t).sin(),
            1.5 * (0.9 * t).cos(),
            38.0 + 8.0 * (0.6 * t).sin(),
        ])
    };
    let rov_demand = |t: f64| {
        SVector::<f64, 6>::from([
            15.0 * t.sin(),
            12.0 * (1.1 * t).cos(),
            10.0 * (0.7 * t).sin(),
            120.0 * (0.5 * t).cos(),
            90.0 * (0.8 * t).sin(),
            140.0 * (0.3 * t).cos(),
        ])
    };
    let sc = |t: f64| {
        SVector::<f64, 3>::from([
            4.0 * t.sin(),
            3.0 * (1.7 * t).cos(),
            2.5 * (0.4 * t).sin() + 1.0,
        ])
    };
    // the six-rotor hexarotor's two stages are solved by the dual method from the
    // unconstrained optimum (docs/maths.md, "Control allocation": stages 1 and 2 of a square
    // geometry), which takes no start: warm and cold are the same computation there; the
    // spacecraft's every stage in closed form ("decoupled geometries"), with no iteration; the
    // ROV's blocks by their reach (the dual method again, "geometries in blocks", or in closed
    // form with two thrusters of a block held); a block of five thrusters by the primal
    // stages, from the start
    for (name, dual, (cold, warm)) in [
        ("hexarotor", true, warm_equals_cold(&hexarotor(), hex, &[])),
        (
            "hexarotor, rotor 2 failed",
            true,
            warm_equals_cold(&hexarotor(), hex, &[(2, 3.0)]),
        ),
        ("rov", true, warm_equals_cold(&rov(), rov_demand, &[])),
        (
            "rov, thruster 5 failed",
            true,
            warm_equals_cold(&rov(), rov_demand, &[(5, 0.0)]),
        ),
        (
            "rov, thrusters 4 and 5 failed",
            true,
            warm_equals_cold(&rov(), rov_demand, &[(4, 0.0), (5, 10.0)]),
        ),
        (
            "rov with a surge thruster",
            false,
            warm_equals_cold(&rov_with_surge(), rov_demand, &[]),
        ),
        ("spacecraft", true, warm_equals_cold(&spacecraft(), sc, &[])),
    ] {
        if name == "spacecraft" {
            assert_eq!((cold, warm), (0, 0), "{name}: the closed form iterates");
        }
        if dual {
            assert_eq!(warm, cold, "{name}: warm {warm} iterations, cold {cold}");
        } else {
            assert!(warm < cold, "{name}: warm {warm} iterations, cold {cold}");
        }
        println!("{name}: {cold} iterations cold, {warm} warm");
    }
}

/// `½‖B_r u − d_r‖²` over rows `r`.
fn miss<const K: usize>(
    alloc: &Allocator<f64, K>,
    u: &Commands<f64>,
    d: &SVector<f64, K>,
    rows: core::ops::Range<usize>,
) -> f64 {
    let w = alloc.geometry().wrench(u) - d;
    rows.map(|i| w[i] * w[i]).sum::<f64>() * 0.5
}

/// With budgets 1, 2, 3, …: every answer is finite and within the bounds; short of the
/// iterations the optimum needs it says `Stopped`; the torque stage's objective never rises
/// with the budget, and once the torque stage has finished its optimum is kept (the force's
/// objective then never rises either).
fn budgets<const K: usize>(alloc: &Allocator<f64, K>, d: &SVector<f64, K>, bounds: &Bounds<f64>) {
    let full = alloc.allocate_within(d, bounds);
    assert!(full.status != Status::Stopped, "{full:?}");
    let torque = if K == 6 { 0..3 } else { 0..K };
    let best = miss(alloc, &full.u, d, torque.clone());
    let tol = 1e-9 * (1.0 + d.amax()).powi(2);
    let mut last = (f64::INFINITY, f64::INFINITY);
    let mut torque_done = false;
    for b in 1..=full.iterations + 1 {
        let a = alloc.with_budget(b).allocate_within(d, bounds);
        assert!(within(&a, bounds), "budget {b}: {a:?}");
        if b < full.iterations {
            assert_eq!(
                a.status,
                Status::Stopped,
                "budget {b} of {}",
                full.iterations
            );
            assert_eq!(a.iterations, b);
        } else {
            assert_eq!((a.u, a.status), (full.u, full.status), "budget {b}");
        }
        let t = miss(alloc, &a.u, d, torque.clone());
        let f = if K == 6 {
            miss(alloc, &a.u, d, 3..6)
        } else {
            0.0
        };
        assert!(
            t <= last.0 + tol,
            "budget {b}: the torque's miss rose from {} to {t}",
            last.0
        );
        if torque_done {
            assert!(
                (t - best).abs() <= tol,
                "budget {b}: the torque stage's optimum {best} lost: {t}"
            );
            assert!(
                f <= last.1 + tol,
                "budget {b}: the force's miss rose from {} to {f}",
                last.1
            );
        }
        torque_done |= (t - best).abs() <= tol;
        last = (t, f);
    }
    assert!(torque_done);
}

#[test]
fn a_spent_budget_answers_within_the_bounds_and_keeps_the_finished_stages() {
    let mut rng = ChaCha8Rng::seed_from_u64(43);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let (hex, rov, sc) = (hexarotor(), rov(), spacecraft());
    let mut long = 0;
    for i in 0..60 {
        let mut bounds = hex.bounds();
        if i % 3 == 1 {
            bounds.fail(i % 6, 4.0 * (x() + 1.0));
        }
        let d = SVector::<f64, 6>::from_fn(
            |r, _| if r < 3 { 1.5 * x() } else { 6.0 * x() } + if r == 5 { 40.0 } else { 0.0 },
        );
        budgets(&hex, &d, &bounds);
        long += u32::from(hex.allocate_within(&d, &bounds).iterations > 2);
        let mut bounds = rov.bounds();
        if i % 3 == 2 {
            bounds.fail(i % 8, 40.0 * x());
        }
        let d = SVector::<f64, 6>::from_fn(|r, _| if r < 3 { 40.0 * x() } else { 300.0 * x() });
        budgets(&rov, &d, &bounds);
        let d = SVector::<f64, 3>::from_fn(|_, _| 6.0 * x());
        budgets(&sc, &d, &sc.bounds());
    }
    assert!(long > 10, "the demands exercise the budget: {long}");
}

#[test]
fn the_spacecraft_preset_is_the_scenarios_twelve_thrusters() {
    let twelve: [Actuator<f64>; 12] = presets::spacecraft_twelve(0.5, 3.0);
    // two thrusters per signed axis, each pair a couple about one body axis
    for a in &twelve {
        assert_eq!((a.min, a.max, a.torque_per_thrust), (0.0, 3.0, 0.0));
        let r = nalgebra::Vector3::from(a.position);
        assert_eq!(r.norm(), 0.5);
        assert_eq!(r.dot(&nalgebra::Vector3::from(a.axis)), 0.0);
    }
    let g = Geometry::<f64, 3>::new(&twelve).unwrap();
    // any torque within 3 N·m on each axis is met
    let a = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let d = SVector::<f64, 3>::from([2.9, -2.9, 1.5]);
    assert_eq!(a.allocate(&d).status, Status::Met);
}

/// Within reach the answer is the closed form computed as it always was: `B W⁻¹`, a Cholesky
/// factorisation of `B W⁻¹ Bᵀ` and its solve, formed here afresh on every call, bit for bit
/// (so runs whose allocation never leaves the closed form keep their bytes).
#[test]
fn within_reach_the_answer_is_the_former_closed_form_bit_for_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(45);
    let mut unit = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    let weights = [1.0, 2.0, 0.5, 1.0, 3.0, 1.0, 1.0, 0.7];
    let preferred = [0.5, -1.0, 0.0, 2.0, 0.0, 1.0, -3.0, 0.2];
    let rovw = Allocator::new(*rov().geometry(), &weights, &preferred, Priority::Torque).unwrap();
    let mut inside = 0;
    let cases: [(Allocator<f64, 6>, &[f64], &[f64]); 3] = [
        (hexarotor(), &[], &[]),
        (rov(), &[], &[]),
        (rovw, &weights, &preferred),
    ];
    for (alloc, given_w, given_up) in cases {
        let g = alloc.geometry();
        let b = g.effectiveness();
        let (lo, hi) = g.bounds();
        let m = g.count();
        let top = given_w.iter().cloned().fold(1.0f64, f64::max);
        let w = Commands::<f64>::from_fn(|j, _| given_w.get(j).map_or(1.0, |x| x / top));
        let up = Commands::<f64>::from_fn(|j, _| {
            given_up.get(j).map_or(0.0, |p| p.max(lo[j]).min(hi[j]))
        });
        for _ in 0..200 {
            let u = Commands::<f64>::from_fn(|j, _| {
                if j < m {
                    lo[j] + (hi[j] - lo[j]) * (0.3 + 0.4 * unit())
                } else {
                    0.0
                }
            });
            let d = g.wrench(&u);
            let mut bw = *b;
            for (j, mut c) in bw.column_iter_mut().enumerate() {
                c /= w[j];
            }
            let ch = nalgebra::Cholesky::new(bw * b.transpose()).unwrap();
            let former = up + bw.transpose() * ch.solve(&(d - b * up));
            let a = alloc.allocate(&d);
            if a.iterations == 0 {
                inside += 1;
                assert_eq!(a.status, Status::Met);
                for j in 0..MAX_ACTUATORS {
                    assert_eq!(a.u[j].to_bits(), former[j].to_bits(), "u[{j}]");
                }
            }
        }
    }
    assert!(inside > 300, "{inside} demands within reach");
}

/// A loss of effectiveness told to the allocator (issue "Actuator failures found, not
/// announced"): the weakened thruster's column is scaled, so the wrench the vehicle really
/// produces is the demand again; telling it twice changes nothing; factor 1 is the allocator
/// itself, bit for bit.
#[test]
fn a_weakened_actuator_has_its_column_scaled() {
    use eqtrack_allocation::{Restoring, VehicleControl};
    let alloc = rov();
    assert_eq!(alloc.scaled(3, 1.0), alloc, "factor 1 changes no bit");
    let no_restoring = Restoring {
        weight: 0.0,
        buoyancy: 0.0,
        centre: nalgebra::Vector3::zeros(),
    };
    let r = nalgebra::Matrix3::identity();
    let demand = SVector::<f64, 6>::from([0.4, -0.3, 0.2, 12.0, -8.0, 30.0]);
    for (j, factor) in [(0, 0.5), (5, 0.3), (7, 0.9)] {
        // the vehicle as it really is
        let real = alloc.geometry().scaled(j, factor);
        let mut told = VehicleControl::new(alloc, no_restoring, 0.0, 0.01);
        let mut blind = told;
        told.weaken(j, factor);
        let once = told;
        told.weaken(j, factor);
        assert_eq!(told, once, "telling the same factor again changes nothing");
        assert_eq!(told.factors()[j], factor);
        let a = told.actuate(&demand, &r).allocation;
        assert_eq!(a.status, Status::Met);
        let produced = real.wrench(&a.u);
        assert!(
            (produced - demand).amax() < 1e-9,
            "actuator {j} at {factor}: the told allocation produces {produced:?}"
        );
        let b = blind.actuate(&demand, &r).allocation;
        assert!(
            (real.wrench(&b.u) - demand).amax() > 1e-3,
            "the blind allocation misses it"
        );
        assert!(
            (a.u[j] - b.u[j]).abs() > 1e-6,
            "the weakened thruster is asked differently"
        );
    }
    // two actuators weak: the allocator depends on the factors told, not on their order, bit
    // for bit, and keeps the healthy geometry (the thrust is its variable)
    let mut two = VehicleControl::new(alloc, no_restoring, 0.0, 0.01);
    two.weaken(1, 0.6);
    two.weaken(6, 0.25);
    let mut owt = VehicleControl::new(alloc, no_restoring, 0.0, 0.01);
    owt.weaken(6, 0.25);
    owt.weaken(1, 0.6);
    assert_eq!(two, owt, "the order told changes no bit");
    assert_eq!(two.allocator().geometry(), alloc.geometry());
    assert_ne!(two.allocator(), &alloc);
    // healed, an actuator told weak or stuck is the healthy one again
    let mut c = VehicleControl::new(alloc, no_restoring, 0.0, 0.01);
    let fresh = c;
    c.weaken(4, 0.5);
    c.fail(6, 12.0);
    assert_ne!(c, fresh);
    c.heal(4);
    c.heal(6);
    assert_eq!(c.bounds(), fresh.bounds(), "healed");
    assert_eq!(c.factors(), fresh.factors(), "healed");
    assert_eq!(c.allocator(), fresh.allocator(), "healed");
    // each change of the bounds told is counted (a weakness scales a column instead)
    assert_eq!(c.told(), fresh.told() + 3, "fail and two heals");
    assert_eq!(c.nominal_bounds(), alloc.geometry().bounds());
    // a factor that is not finite and positive is ignored
    let mut c = VehicleControl::new(alloc, no_restoring, 0.0, 0.01);
    let before = c;
    for bad in [0.0, -0.5, f64::NAN, f64::INFINITY] {
        c.weaken(2, bad);
    }
    c.weaken(99, 0.5);
    assert_eq!(c, before);
}

/// A weakness told over cycles (docs/maths.md, "Failure detection", *A weak actuator told over
/// cycles*): a reweighting begun, formed a few columns at a time and put in force leaves the
/// vehicle as `weaken` at once does, bit for bit, in `f64` and `f32`, on the ROV and the
/// hexarotor: from healthy, a refinement, a second actuator, one healed back to 1, in steps of
/// 1 to 7 columns and put in force before its updates are all made. Where another factor was
/// told while it was formed, it is `weaken` of its own tell at once; where the factor is the
/// one told, there is nothing to begin.
#[test]
fn a_reweighting_formed_over_cycles_is_weaken() {
    use eqtrack_allocation::{Restoring, VehicleControl};
    fn check<T: nalgebra::RealField + Copy>(alloc: Allocator<T, 6>, count: usize, seed: u64) {
        let none = Restoring {
            weight: T::zero(),
            buoyancy: T::zero(),
            centre: nalgebra::Vector3::zeros(),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for _ in 0..200 {
            let mut at_once = VehicleControl::new(alloc, none, T::zero(), nalgebra::convert(0.01));
            let mut staged = at_once;
            for _ in 0..4 {
                let j = (rng.next_u64() % count as u64) as usize;
                let k = match rng.next_u64() % 8 {
                    0 | 1 => 1.0,
                    // near and below the scalar's ε, where a downdate may break down and the
                    // factor is formed again
                    2 => [1e-4, 1e-7, 1e-12][(rng.next_u64() % 3) as usize],
                    _ => 0.05 + 0.9 * (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64,
                };
                let k: T = nalgebra::convert(k);
                let columns = 1 + (rng.next_u64() % 7) as usize;
                let early = rng.next_u64() % 5 == 0;
                let Some(mut r) = staged.reweighting(j, k) else {
                    assert_eq!(
                        staged.factors()[j],
                        k.max(T::default_epsilon()),
                        "nothing begun only for the factor told"
                    );
                    at_once.weaken(j, k);
                    assert_eq!(at_once, staged, "weaken of the factor told changes nothing");
                    continue;
                };
                assert_eq!(r.tell(), (j, k.max(T::default_epsilon())));
                let before = staged;
                let mut steps = 0;
                while !early && !staged.advance(&mut r, columns) {
                    steps += 1;
                    assert!(steps <= 8 * 6 + 1, "the steps end");
                }
                assert_eq!(staged, before, "nothing is in force before it is put");
                staged.reweight(&mut r);
                at_once.weaken(j, k);
                assert_eq!(
                    staged, at_once,
                    "actuator {j} at {k:?} in steps of {columns}"
                );
            }
            // a factor told while one was formed: over its own actuator, put in force over
            // it; over another, `weaken` of its own tell at once
            for (j, i, columns) in [(2, 2, 5), (0, count - 1, 3)] {
                let mut r = staged
                    .reweighting(j, nalgebra::convert(0.3))
                    .unwrap_or_else(|| {
                        staged
                            .reweighting(j, nalgebra::convert(0.4))
                            .expect("a new factor")
                    });
                let k = r.tell().1;
                staged.weaken(i, nalgebra::convert(0.7));
                at_once.weaken(i, nalgebra::convert(0.7));
                staged.advance(&mut r, columns);
                staged.reweight(&mut r);
                at_once.weaken(j, k);
                assert_eq!(staged, at_once, "actuator {i} told while {j}'s was formed");
            }
        }
    }
    check(rov(), 8, 1);
    check(hexarotor(), 6, 2);
    let rov32 = Allocator::<f32, 6>::new(
        eqtrack_allocation::Geometry::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap();
    check(rov32, 8, 3);
    let hexarotor32 = Allocator::<f32, 6>::new(
        eqtrack_allocation::Geometry::new(&presets::hexarotor(0.25, 0.5, 0.016, 8.0)).unwrap(),
        &[],
        &[],
        Priority::Torque,
    )
    .unwrap();
    check(hexarotor32, 6, 4);
}

/// A weak actuator's thrust as the allocator's variable (docs/maths.md, "Control allocation"):
/// the vehicle told of one or two weak actuators allocates what the allocator formed over the
/// scaled columns ([`Allocator::scaled`]) allocates, on the ROV (its blocks by their reach) with
/// unequal weights and a preferred command, the hexarotor (square: the dual stages) and the
/// twelve-thruster spacecraft; within reach and saturated, under a rate limit from the last
/// command, with a weak actuator also stuck, a weakness refined and one at 10⁻⁴. Each answer is
/// within the bounds, its status is the scaled allocator's and its wrench the one it reports.
#[test]
fn a_weak_actuator_allocated_in_its_thrust_is_the_scaled_allocator() {
    use eqtrack_allocation::{Restoring, VehicleControl};
    let none = Restoring {
        weight: 0.0,
        buoyancy: 0.0,
        centre: nalgebra::Vector3::zeros(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(47);
    let mut unit = move || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
    /// The vehicle told `weak` in turn (a factor told twice for an actuator is a refinement)
    /// and `stuck`, against `Allocator::scaled` by the last factors, over `demands` with the
    /// rate limit `rate` (per 0.01 s period); the saturated allocations among them.
    fn check<const K: usize>(
        alloc: &Allocator<f64, K>,
        weak: &[(usize, f64)],
        stuck: Option<(usize, f64)>,
        rate: f64,
        demands: &[SVector<f64, K>],
        none: Restoring<f64>,
    ) -> usize {
        let mut control = VehicleControl::new(*alloc, none, rate, 0.01);
        let mut factors = [1.0; MAX_ACTUATORS];
        for &(j, k) in weak {
            control.weaken(j, k);
            factors[j] = k;
        }
        let mut scaled = *alloc;
        for (j, &k) in factors.iter().enumerate() {
            if k != 1.0 {
                scaled = scaled.scaled(j, k);
            }
        }
        let mut told = scaled.bounds();
        if let Some((j, v)) = stuck {
            told.fail(j, v);
            control.fail(j, v);
        }
        let top = told.hi.amax().max(told.lo.amax());
        let mut previous: Option<Commands<f64>> = None;
        let mut saturated = 0;
        for d in demands {
            let mut bounds = told;
            if let (Some(p), true) = (&previous, rate > 0.0) {
                for j in 0..alloc.geometry().count() {
                    if bounds.hi[j] > bounds.lo[j] {
                        bounds.limit_rate(j, p[j], rate * 0.01);
                    }
                }
            }
            let want = scaled.allocate_from(d, &bounds, previous.as_ref());
            let got = control.actuate_demand(*d).allocation;
            let gap = (want.u - got.u).amax();
            assert!(
                gap < 1e-8 * top,
                "{weak:?} {stuck:?}: {d:?} allocated {:?}, the scaled allocator {:?}",
                got.u,
                want.u
            );
            assert_eq!(got.status, want.status, "{weak:?}: {d:?}");
            assert!(
                within(&got, &bounds),
                "{weak:?}: {:?} within the bounds",
                got.u
            );
            let produced = scaled.geometry().wrench(&got.u);
            assert!(
                (produced - got.achieved).amax() < 1e-8 * top,
                "the wrench it reports"
            );
            saturated += usize::from(want.status != Status::Met);
            previous = Some(got.u);
        }
        saturated
    }
    let mut demands = |scale: [f64; 6], n: usize| -> Vec<SVector<f64, 6>> {
        (0..n)
            .map(|i| {
                let grow = 0.2 + 2.0 * i as f64 / n as f64;
                SVector::from_fn(|a, _| (2.0 * unit() - 1.0) * scale[a] * grow)
            })
            .collect()
    };
    let rov = {
        let g = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
        let weights = [1.0, 0.5, 2.0, 1.0, 0.8, 1.5, 1.0, 3.0];
        let preferred = [2.0, -1.0, 0.0, 1.0, 3.0, -2.0, 0.5, 0.0];
        Allocator::new(g, &weights, &preferred, Priority::Torque).unwrap()
    };
    let d = demands([6.0, 6.0, 8.0, 80.0, 80.0, 120.0], 200);
    let mut saturated = 0;
    for (weak, stuck, rate) in [
        (&[(0, 0.5)][..], None, 0.0),
        (&[(5, 0.3)][..], None, 0.0),
        (&[(1, 0.6), (6, 0.25)][..], None, 0.0),
        (&[(1, 0.6), (6, 0.25)][..], None, 2000.0),
        (&[(2, 0.4)][..], Some((2, 10.0)), 0.0),
        (&[(4, 0.5), (4, 0.45), (7, 0.7)][..], None, 0.0),
        (&[(3, 1e-4)][..], None, 0.0),
    ] {
        saturated += check(&rov, weak, stuck, rate, &d, none);
    }
    let hex = hexarotor();
    let d = demands([1.5, 1.5, 0.3, 4.0, 4.0, 60.0], 200);
    for weak in [&[(0, 0.5)][..], &[(2, 0.7), (5, 0.3)][..]] {
        saturated += check(&hex, weak, None, 0.0, &d, none);
    }
    let sc = spacecraft();
    let d3: Vec<SVector<f64, 3>> = d.iter().map(|x| x.fixed_rows::<3>(0) * 3.0).collect();
    saturated += check(&sc, &[(4, 0.5)], None, 0.0, &d3, none);
    assert!(
        saturated > 300,
        "{saturated} saturated allocations among them"
    );
}

/// The six-rotor hexarotor's dual stages (docs/maths.md, "Control allocation": stage 1 of a
/// square geometry) give no command until both finish: a budget spent in them answers the
/// primal stages' start, the closed form `B⁻¹w` clamped into the bounds, or the previous
/// command clamped when one is given, with status 3 and the budget's count.
#[test]
fn a_budget_spent_in_the_dual_stages_answers_the_clamped_start() {
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    let mut x = move || (rng.next_u64() as f64 / u64::MAX as f64) * 2.0 - 1.0;
    let hex = hexarotor();
    let b = hex
        .geometry()
        .effectiveness()
        .fixed_columns::<6>(0)
        .into_owned();
    let inverse = b.try_inverse().unwrap();
    let mut checked = 0;
    for i in 0..60 {
        let mut bounds = hex.bounds();
        if i % 3 == 1 {
            bounds.fail(i % 6, 4.0 * (x() + 1.0));
        }
        let d = SVector::<f64, 6>::from_fn(
            |r, _| if r < 3 { 2.0 * x() } else { 8.0 * x() } + if r == 5 { 40.0 } else { 0.0 },
        );
        let previous = Commands::<f64>::from_fn(|j, _| if j < 6 { 9.0 * x() } else { 0.0 });
        let full = hex.allocate_within(&d, &bounds);
        let clamp = |u: &SVector<f64, 6>, j: usize| u[j].max(bounds.lo[j]).min(bounds.hi[j]);
        let start = inverse * d;
        for budget in 1..full.iterations {
            let cold = hex.with_budget(budget).allocate_within(&d, &bounds);
            let warm = hex
                .with_budget(budget)
                .allocate_from(&d, &bounds, Some(&previous));
            for (a, from) in [
                (cold, start),
                (warm, previous.fixed_rows::<6>(0).into_owned()),
            ] {
                assert_eq!((a.status, a.iterations), (Status::Stopped, budget), "{a:?}");
                for j in 0..6 {
                    assert!(
                        (a.u[j] - clamp(&from, j)).abs() <= 1e-9,
                        "demand {i}, budget {budget}: {a:?}"
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 100, "{checked} stopped allocations");
}

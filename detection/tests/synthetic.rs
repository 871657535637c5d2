//! The detector on a synthetic eight-thruster ROV (docs/maths.md, "Failure detection"): the
//! body's momentum stepped exactly as the residual models it, its thrusters lagging, its
//! velocity measured with seeded noise, and commands that move within the thrusters' null
//! space (so the healthy body stays near rest). Each test can fail: a thruster's death, stuck
//! value and weakness must be found, on the right thruster, with the right kind, in time; a
//! nominal flight must raise no alarm at the stated rate, and must raise some at a rate a
//! million times higher; a gust that no single thruster explains must not be taken for one.

use detection::{Config, ConfigError, Detection, Detector, Kind, threshold};
use eqtrack_allocation::{
    Allocator, Commands, Geometry, Priority, Restoring, VehicleControl, presets,
};
use eqtrack_controller::group::{MatrixLieGroup, Se3};
use nalgebra::{DMatrix, Matrix3, SMatrix, SVector};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, Normal};

const H: f64 = 0.01;
const LAG: f64 = 0.05;

fn inertia() -> SMatrix<f64, 6, 6> {
    SMatrix::from_diagonal(&SVector::from([0.28, 0.28, 0.28, 17.0, 24.2, 26.1]))
}

fn control() -> VehicleControl<f64, 6> {
    let g = Geometry::<f64, 6>::new(&presets::rov_heavy(0.4, 0.3, 0.12, 0.22, 40.0)).unwrap();
    let a = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let none = Restoring {
        weight: 0.0,
        buoyancy: 0.0,
        centre: nalgebra::Vector3::zeros(),
    };
    VehicleControl::new(a, none, 0.0, H)
}

fn config(per_hour: f64) -> Config<f64, 6> {
    let window = 10;
    let p = threshold::per_test(per_hour, H, 8);
    Config {
        decimation: 1,
        window,
        threshold: threshold::chi2_upper(1, p),
        isolation: threshold::chi2_upper(5, 1e-6),
        margin: threshold::chi2_upper(1, 1e-3),
        relative: 0.01,
        confirm: window / 2,
        warmup: 0,
        calibration: 200,
        memory: H / 10.0,
        floor: SVector::from_element(1e-3),
        resolution: Commands::from_element(0.4),
        inertia: inertia(),
        damping_linear: SVector::zeros(),
        damping_quadratic: SVector::zeros(),
        period: H,
        time_constant: LAG,
    }
}

/// What happens to one thruster.
#[derive(Clone, Copy, Debug)]
enum Fault {
    Dead,
    Stuck(f64),
    Weak(f64),
}

/// The synthetic ROV: momentum, the thrusters' lagged outputs, and a basis of `B`'s null
/// space that the commands move in.
struct Rov {
    b: SMatrix<f64, 6, 12>,
    mu: SVector<f64, 6>,
    output: Commands<f64>,
    null: [Commands<f64>; 2],
    faults: Vec<(usize, Fault)>,
    /// How far the commands swing (1: as [`Rov::command`] says; 0: steady).
    swing: f64,
    started: bool,
}

impl Rov {
    fn new() -> Self {
        let b = *control().allocator().geometry().effectiveness();
        let bd = DMatrix::from_fn(6, 8, |i, j| b[(i, j)]);
        // the null space from Gram–Schmidt on the identity's columns against Bᵀ's span
        let bt = bd.transpose();
        let q = bt.clone().qr().q();
        let mut null = Vec::new();
        for e in 0..8 {
            let mut x = nalgebra::DVector::<f64>::zeros(8);
            x[e] = 1.0;
            for c in 0..6 {
                let col = q.column(c);
                x -= col * col.dot(&x);
            }
            for n in &null {
                let n: &nalgebra::DVector<f64> = n;
                x -= n * n.dot(&x);
            }
            if x.norm() > 1e-6 {
                null.push(x.normalize());
            }
        }
        assert_eq!(null.len(), 2);
        let to =
            |x: &nalgebra::DVector<f64>| Commands::from_fn(|j, _| if j < 8 { x[j] } else { 0.0 });
        Rov {
            b,
            mu: SVector::zeros(),
            output: Commands::zeros(),
            null: [to(&null[0]), to(&null[1])],
            faults: Vec::new(),
            swing: 1.0,
            started: false,
        }
    }

    /// The command at time `t`: 15 N on each thruster (held against a steady wrench, as an
    /// ROV holds its buoyancy) and the null space's two directions swinging about it.
    fn command(&self, t: f64) -> Commands<f64> {
        let a = 8.0 * (2.0 * std::f64::consts::PI * 0.4 * t).sin() + 2.0;
        let c = 6.0 * (2.0 * std::f64::consts::PI * 0.27 * t + 1.0).cos() - 1.0;
        self.offset() + (self.null[0] * a + self.null[1] * c) * self.swing
    }

    fn offset(&self) -> Commands<f64> {
        Commands::from_fn(|j, _| if j < 8 { 15.0 } else { 0.0 })
    }

    /// The steady wrench the offset holds.
    fn steady(&self) -> SVector<f64, 6> {
        -(self.b * self.offset())
    }

    /// One period under command `u` (lagged exactly) and a further wrench `extra`; the
    /// gyroscopic term by the trapezoid, as the residual has it.
    fn step(&mut self, u: &Commands<f64>, extra: &SVector<f64, 6>) {
        if !self.started {
            // the first command is the output at once, as the plant's actuators have it
            self.output = *u;
            self.started = true;
        }
        let d = (-H / LAG).exp();
        let mean = LAG / H * (1.0 - d);
        let mut produced = *u + (self.output - *u) * mean;
        self.output = *u + (self.output - *u) * d;
        for (j, f) in &self.faults {
            produced[*j] = match f {
                Fault::Dead => 0.0,
                Fault::Stuck(v) => *v,
                Fault::Weak(k) => produced[*j] * k,
            };
        }
        let i = inertia();
        let gyro = |mu: &SVector<f64, 6>| {
            let v = i.try_inverse().unwrap() * mu;
            Se3::ad_transpose_mul(&v, mu)
        };
        let g0 = gyro(&self.mu);
        let force = self.b * produced + extra + self.steady();
        let mut next = self.mu + (g0 + force) * H;
        for _ in 0..4 {
            next = self.mu + ((g0 + gyro(&next)) * 0.5 + force) * H;
        }
        self.mu = next;
    }

    fn velocity(&self) -> SVector<f64, 6> {
        inertia().try_inverse().unwrap() * self.mu
    }
}

/// Flies `seconds` with a fault of thruster `j` from `t_fail` (none: `None`), velocity noise
/// `sigma`, and `gust` added from `t_fail`; returns every detection with its time.
fn fly(
    seed: u64,
    per_hour: f64,
    seconds: f64,
    faults: &[(usize, Fault, f64)],
    sigma: f64,
    gust: Option<(f64, SVector<f64, 6>)>,
) -> Vec<(f64, Detection<f64>)> {
    fly_with(seed, per_hour, seconds, faults, sigma, gust, &mut |_| ())
}

/// [`fly`], handing the detector to `each` after every cycle.
fn fly_with(
    seed: u64,
    per_hour: f64,
    seconds: f64,
    faults: &[(usize, Fault, f64)],
    sigma: f64,
    gust: Option<(f64, SVector<f64, 6>)>,
    each: &mut dyn FnMut(&Detector<f64, 6>),
) -> Vec<(f64, Detection<f64>)> {
    fly_swinging(
        seed,
        config(per_hour),
        seconds,
        faults,
        sigma,
        gust,
        1.0,
        each,
    )
}

/// [`fly_with`], the commands swinging by `swing`.
#[allow(clippy::too_many_arguments)]
fn fly_swinging(
    seed: u64,
    config: Config<f64, 6>,
    seconds: f64,
    faults: &[(usize, Fault, f64)],
    sigma: f64,
    gust: Option<(f64, SVector<f64, 6>)>,
    swing: f64,
    each: &mut dyn FnMut(&Detector<f64, 6>),
) -> Vec<(f64, Detection<f64>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma.max(1e-300)).unwrap();
    let mut rov = Rov::new();
    rov.swing = swing;
    let mut control = control();
    let mut detector = Detector::new(config).unwrap();
    let r = Matrix3::identity();
    let mut found = Vec::new();
    let steps = (seconds / H).round() as usize;
    for k in 0..steps {
        let t = k as f64 * H;
        for (j, f, at) in faults {
            if (t - at).abs() < H / 2.0 {
                rov.faults.push((*j, *f));
            }
        }
        let v = rov.velocity()
            + SVector::from_fn(|_, _| noise.sample(&mut rng) * (sigma > 0.0) as u8 as f64);
        let mut announced = control;
        let d = detector.observe::<Se3, 4>(&v, &r, &mut control);
        if let Some(d) = d {
            found.push((t, d));
            // told as the detection says, at the cycle it is reported
            d.kind.tell(d.actuator, &mut announced);
        }
        // the allocator changes only in a cycle that reports a detection, as the detection
        // tells it (replay tells the allocator from the record so, bit for bit)
        assert!(
            announced == control,
            "at {t} s the allocator is not what the reports told it ({d:?})"
        );
        each(&detector);
        // the allocator holds a failed thruster at its value: the command respects the bounds
        let (lo, hi) = control.bounds();
        let u = rov
            .command(t)
            .zip_zip_map(&lo, &hi, |x, l, h| x.max(l).min(h));
        detector.commanded(&u);
        let extra = match gust {
            Some((at, w)) if t >= at => w,
            _ => SVector::zeros(),
        };
        rov.step(&u, &extra);
    }
    found
}

#[test]
fn each_dead_thruster_is_found_on_the_right_one_within_a_fifth_of_a_second() {
    let mut late = Vec::new();
    for j in 0..8 {
        for (n, at) in [3.13, 4.71, 6.02, 7.37, 8.8].into_iter().enumerate() {
            let found = fly(
                100 + n as u64,
                1e-3,
                at + 1.0,
                &[(j, Fault::Dead, at)],
                1e-3,
                None,
            );
            assert_eq!(found.len(), 1, "thruster {j} dead at {at}: {found:?}");
            let (t, d) = found[0];
            assert_eq!(d.actuator, j, "{d:?}");
            assert!(t >= at, "thruster {j}: found before it failed");
            late.push(t - at);
            if t - at > 0.15 {
                let rov = Rov::new();
                eprintln!(
                    "thruster {j} at {at}: {:.2} s, command {:.2} {d:?}",
                    t - at,
                    rov.command(at)[j]
                );
            }
            assert!(matches!(d.kind, Kind::Dead), "thruster {j}: {d:?}");
        }
    }
    late.sort_by(f64::total_cmp);
    let p95 = late[(0.95 * late.len() as f64).ceil() as usize - 1];
    eprintln!(
        "dead thrusters: latency median {:.3} s, 95 % {p95:.3} s, worst {:.3} s",
        late[late.len() / 2],
        late[late.len() - 1]
    );
    assert!(p95 <= 0.2 + 1e-9, "95 % within {p95:.3} s: {late:?}");
}

/// However long the confirmation, from one entry (named in the cycle of its one test) to the
/// whole window (one entry of the window left to project when the lead begins), and with two
/// (every projection left to the naming), a dead thruster is found on the right one, dead
/// (or stuck at 0 within the resolution), once, and a confirmation one entry longer names it
/// one entry later: the entry after the
/// last test names it (docs/maths.md, "Failure detection", paragraph "The kind, prepared ahead").
#[test]
fn the_change_point_is_prepared_ahead_however_long_the_confirmation() {
    for j in [0, 5] {
        let mut times = Vec::new();
        for confirm in [1, 2, 3, 5, 10] {
            let c = Config {
                confirm,
                ..config(1e-3)
            };
            let found = fly_swinging(
                11,
                c,
                5.0,
                &[(j, Fault::Dead, 4.0)],
                1e-3,
                None,
                1.0,
                &mut |_| (),
            );
            assert_eq!(found.len(), 1, "thruster {j}, confirm {confirm}: {found:?}");
            let (t, d) = found[0];
            assert_eq!(d.actuator, j, "confirm {confirm}: {d:?}");
            // dead, or stuck within the resolution (0.4 N) at 0: a confirmation of one
            // entry can see a change point of one entry, whose mean is its value
            assert!(
                match d.kind {
                    Kind::Dead => true,
                    Kind::Stuck(v) => v.abs() <= 0.4,
                    Kind::Weak(_) => false,
                },
                "confirm {confirm}: {d:?}"
            );
            assert!((4.0..4.2).contains(&t), "confirm {confirm}: found at {t}");
            times.push(((t - 4.0) / H).round() as i64);
        }
        // a dead thruster, whose change leads from its first test on: one entry more of
        // confirmation, one entry later
        for (w, k) in times.windows(2).zip([1, 1, 2, 5]) {
            assert_eq!(
                w[1] - w[0],
                k,
                "thruster {j}: named after {times:?} entries"
            );
        }
    }
}

#[test]
fn a_stuck_and_a_weak_thruster_are_told_apart_and_estimated() {
    for j in [1, 5] {
        let found = fly(7, 1e-3, 6.0, &[(j, Fault::Stuck(-24.0), 4.0)], 1e-3, None);
        assert!(found.iter().all(|(_, d)| d.actuator == j), "{found:?}");
        match found.last().map(|(_, d)| d.kind) {
            Some(Kind::Stuck(v)) => assert!((v + 24.0).abs() < 1.0, "{found:?}"),
            k => panic!("thruster {j} stuck at -24: {k:?}"),
        }
        // weak: while its command barely moves, it looks stuck at its present thrust, and
        // it is held there; held, it gives only 0.3 of that, which the detector sees again
        // and, with two commands to compare, names it weak
        let found = fly(8, 1e-3, 6.0, &[(j, Fault::Weak(0.3), 4.0)], 1e-3, None);
        assert!(found.iter().all(|(_, d)| d.actuator == j), "{found:?}");
        match found.last().map(|(_, d)| d.kind) {
            Some(Kind::Weak(k)) => assert!((k - 0.3).abs() < 0.05, "{found:?}"),
            k => panic!("thruster {j} weak by 0.3: {k:?} ({found:?})"),
        }
        eprintln!("thruster {j} weak by 0.3: {found:?}");
    }
    // with steady commands a weak thruster is first taken for a stuck one and held at its
    // thrust; watched for a window after, it gives 0.3 of the held command, and the two
    // commands tell it weak
    let found = fly_swinging(
        9,
        config(1e-3),
        6.0,
        &[(5, Fault::Weak(0.3), 4.0)],
        1e-3,
        None,
        0.0,
        &mut |_| (),
    );
    eprintln!("thruster 5 weak by 0.3, steady commands: {found:?}");
    assert!(
        found.len() >= 2 && found.iter().all(|(_, d)| d.actuator == 5),
        "{found:?}"
    );
    assert!(
        matches!(found[0].1.kind, Kind::Stuck(v) if (v - 4.5).abs() < 0.5),
        "{found:?}"
    );
    match found.last().map(|(_, d)| d.kind) {
        Some(Kind::Weak(k)) => assert!((k - 0.3).abs() < 0.05, "{found:?}"),
        k => panic!("{k:?} ({found:?})"),
    }
}

/// A weak thruster is told over the cycles after its naming or refinement (docs/maths.md,
/// "Failure detection", *A weak actuator told over cycles*): the allocator's reweighting
/// begun, formed two columns a cycle and put in force, in place of the test, the detection
/// reported only then, its `since` counting the wait; and the allocator changed only in that
/// cycle (the check in every flight, [`fly_swinging`]).
#[test]
fn a_weak_thruster_is_told_over_the_cycles_after_its_naming() {
    let mut testing = Vec::new();
    let found = fly_with(
        8,
        1e-3,
        6.0,
        &[(1, Fault::Weak(0.3), 4.0)],
        1e-3,
        None,
        &mut |d| testing.push(d.statistic().testing),
    );
    let weak: Vec<_> = found
        .iter()
        .filter(|(_, d)| matches!(d.kind, Kind::Weak(_)))
        .collect();
    assert!(!weak.is_empty(), "{found:?}");
    for (t, d) in weak {
        let k = (t / H).round() as usize;
        // the naming or the refinement, the reweighting begun, three steps of two columns
        // (six columns of one update) and the weights: none tests; then the report's
        let quiet = testing[..k].iter().rev().take_while(|x| !**x).count();
        eprintln!("{d:?} at {t} s after {quiet} cycles without a test");
        assert!(!testing[k]);
        if d.refined {
            // a refinement is fitted in place of a test, six cycles before it is reported
            assert_eq!(quiet, 6, "{d:?} at {t} s");
            assert_eq!(d.since, 6, "{d:?}");
        } else {
            assert!(
                quiet >= 6,
                "{quiet} cycles without a test before {d:?} at {t} s"
            );
            assert!(d.since >= 6, "{d:?}");
        }
    }
}

#[test]
fn a_second_failure_is_found_after_the_first() {
    let found = fly(
        11,
        1e-3,
        9.0,
        &[(2, Fault::Dead, 3.5), (6, Fault::Dead, 6.5)],
        1e-3,
        None,
    );
    let which: Vec<usize> = found.iter().map(|(_, d)| d.actuator).collect();
    assert_eq!(which, vec![2, 6], "{found:?}");
    assert!(found[1].0 - 6.5 <= 0.2, "{found:?}");
}

#[test]
fn nominal_flight_raises_no_alarm_at_the_stated_rate_and_some_at_a_far_higher_one() {
    // ten minutes of noisy nominal flight: at 1e-3 false alarms an hour, none; at 1e4 an
    // hour (about 3e-4 a test over 8 hypotheses), some alarms, at most the stated rate
    // (with room for chance), and still no actuator named
    let (quiet, alarms) = fly_counting(21, 1e-3, 600.0);
    assert!(
        quiet.is_empty() && alarms == 0,
        "{quiet:?}, {alarms} alarms"
    );
    let (loud, alarms) = fly_counting(21, 1e4, 600.0);
    let expected = 1e4 / 6.0;
    assert!(
        alarms > 0,
        "a rate of 1e4 an hour never raised an alarm in ten minutes"
    );
    assert!(
        f64::from(alarms) < 3.0 * expected,
        "{alarms} alarms where at most about {expected} are expected"
    );
    assert!(loud.is_empty(), "{loud:?}");
}

/// [`fly`] without faults, with the detector's alarm count.
fn fly_counting(seed: u64, per_hour: f64, seconds: f64) -> (Vec<(f64, Detection<f64>)>, u32) {
    let mut alarms = 0;
    let found = fly_with(seed, per_hour, seconds, &[], 1e-3, None, &mut |d| {
        alarms = d.alarms()
    });
    (found, alarms)
}

#[test]
fn a_gust_no_single_thruster_explains_is_not_a_failure() {
    // a step of 12 N along body x and 1 N m about z: no single column
    let gust = SVector::from([0.0, 0.0, 1.0, 12.0, 0.0, 0.0]);
    let found = fly(31, 1e-3, 6.0, &[], 1e-3, Some((3.0, gust)));
    assert!(found.is_empty(), "{found:?}");
}

#[test]
fn bad_settings_are_refused() {
    let mut c = config(1e-3);
    c.window = 0;
    assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Window);
    c.window = 33;
    assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Window);
    let mut c = config(1e-3);
    c.decimation = 0;
    assert_eq!(
        Detector::new(c).unwrap_err(),
        ConfigError::Value("decimation")
    );
    let mut c = config(1e-3);
    c.calibration = 19;
    assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Calibration);
    for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let mut c = config(1e-3);
        c.threshold = bad;
        assert_eq!(
            Detector::new(c).unwrap_err(),
            ConfigError::Value("threshold")
        );
        let mut c = config(1e-3);
        c.floor[4] = bad;
        assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Value("floor"));
    }
    for bad in [0, 11] {
        let mut c = config(1e-3);
        c.confirm = bad;
        assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Confirm);
    }
    let mut c = config(1e-3);
    c.memory = 1.5;
    assert_eq!(Detector::new(c).unwrap_err(), ConfigError::Value("memory"));
    let mut c = config(1e-3);
    c.time_constant = -0.1;
    assert_eq!(
        Detector::new(c).unwrap_err(),
        ConfigError::Value("time_constant")
    );
}

/// The detector in `f32`: a hexarotor held at rest (its rotors' wrench balanced by a steady
/// one) is quiet, and when rotor 4 dies the detector names it, dead, within a fifth of a
/// second, with entries of two periods each.
#[test]
fn in_f32_a_dead_rotor_is_found() {
    let g = Geometry::<f32, 6>::new(&presets::hexarotor(0.25_f32, 0.5, 0.016, 8.0)).unwrap();
    let a = Allocator::new(g, &[], &[], Priority::Torque).unwrap();
    let none = Restoring {
        weight: 0.0_f32,
        buoyancy: 0.0,
        centre: nalgebra::Vector3::zeros(),
    };
    let mut control = VehicleControl::new(a, none, 0.0, 0.01);
    let inertia =
        SMatrix::<f32, 6, 6>::from_diagonal(&SVector::from([0.02, 0.02, 0.04, 1.5, 1.5, 1.5]));
    let config = Config::<f32, 6> {
        decimation: 2,
        window: 10,
        threshold: threshold::chi2_upper(1, threshold::per_test(1e-3, 0.02, 6)) as f32,
        isolation: threshold::chi2_upper(5, 1e-6) as f32,
        margin: threshold::chi2_upper(1, 1e-3) as f32,
        relative: 0.01,
        confirm: 3,
        warmup: 10,
        calibration: 50,
        memory: 2e-3,
        floor: SVector::from_element(1e-3),
        resolution: Commands::from_element(0.008),
        inertia,
        damping_linear: SVector::zeros(),
        damping_quadratic: SVector::zeros(),
        period: 0.01,
        time_constant: 0.0,
    };
    let mut detector = Detector::new(config).unwrap();
    let u = Commands::<f32>::from_fn(|j, _| if j < 6 { 3.0 + 0.2 * j as f32 } else { 0.0 });
    let b = *control.allocator().geometry().effectiveness();
    let inverse = inertia.try_inverse().unwrap();
    let mut mu = SVector::<f32, 6>::zeros();
    let mut found = Vec::new();
    for k in 0..400 {
        let v = inverse * mu;
        if let Some(d) = detector.observe::<eqtrack_controller::group::Se3, 4>(
            &v,
            &Matrix3::identity(),
            &mut control,
        ) {
            found.push((k, d));
        }
        detector.commanded(&u);
        let mut real = u;
        if k >= 300 {
            real[4] = 0.0;
        }
        mu += (b * real - b * u) * 0.01;
    }
    assert!(detector.statistic().best.is_finite());
    assert!(!found.is_empty(), "nothing found");
    let (k, d) = found[0];
    assert_eq!((d.actuator, d.kind), (4, Kind::Dead), "{found:?}");
    assert!(k > 300 && k <= 320, "found at cycle {k}");
    assert!(found.iter().all(|(_, d)| d.actuator == 4), "{found:?}");
}

#[test]
fn a_kind_crosses_the_wire_as_its_code_and_estimate() {
    for k in [Kind::Dead, Kind::Stuck(-20.5), Kind::Weak(0.375)] {
        assert_eq!(Kind::from_code(k.code(), k.value()), Some(k));
    }
    assert_eq!(Kind::<f64>::Dead.value(), 0.0);
    assert_eq!(Kind::from_code(0, 1.0), None);
    assert_eq!(Kind::from_code(4, 1.0), None);
}

/// Six seconds of nominal flight in which, for 0.3 s from t = 3 s, the plant applies other
/// commands than the detector is told of, thruster 2's output missing (as a plant in safe
/// mode, allocating its own damping, may apply them); with `gaps`, the
/// detector is told of each such period at the state that ends it, as the pair's controller
/// tells it when the state's `applied` is not its command's. Its detections and alarms.
fn fly_through_a_spell(gaps: bool) -> (Vec<Detection<f64>>, u32) {
    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let noise = Normal::new(0.0, 1e-3).unwrap();
    let mut rov = Rov::new();
    let mut control = control();
    let mut detector = Detector::new(config(1e-3)).unwrap();
    let r = Matrix3::identity();
    let mut found = Vec::new();
    let mut spell_before = false;
    for k in 0..600 {
        let t = k as f64 * H;
        if gaps && spell_before {
            detector.gap();
        }
        let v = rov.velocity() + SVector::from_fn(|_, _| noise.sample(&mut rng));
        if let Some(d) = detector.observe::<Se3, 4>(&v, &r, &mut control) {
            found.push(d);
        }
        let u = rov.command(t);
        detector.commanded(&u);
        let spell = (300..330).contains(&k);
        let mut applied = u;
        if spell {
            applied[2] = 0.0;
        }
        rov.step(&applied, &SVector::zeros());
        spell_before = spell;
    }
    let alarms = detector.alarms();
    (found, alarms)
}

#[test]
fn periods_the_plant_did_not_fly_as_commanded_are_not_read_as_failures() {
    // told of them, the detector takes no residual over them nor while its lag model
    // settles: nothing found, no alarm
    let (found, alarms) = fly_through_a_spell(true);
    assert!(
        found.is_empty() && alarms == 0,
        "{found:?}, {alarms} alarms"
    );
    // not told, the thrust it believes is not there: it takes thruster 2 for failed
    let (found, alarms) = fly_through_a_spell(false);
    assert!(alarms > 0, "{found:?}, {alarms} alarms");
    assert!(found.iter().any(|d| d.actuator == 2), "{found:?}");
}

/// A detector that has flown, found two failures and learned its spread, restarted in
/// place, is the detector `Detector::new` makes from the same settings, field for field.
#[test]
fn a_restart_in_place_is_a_new_detector() {
    let mut flown = None;
    let found = fly_with(
        11,
        1e-3,
        9.0,
        &[(2, Fault::Dead, 3.5), (6, Fault::Dead, 6.5)],
        1e-3,
        None,
        &mut |d| flown = Some(d.clone()),
    );
    assert_eq!(found.len(), 2, "{found:?}");
    let mut d = flown.unwrap();
    let fresh = Detector::new(*d.config()).unwrap();
    assert_ne!(d, fresh, "a flown detector is not a fresh one");
    d.restart();
    assert_eq!(d, fresh);
}

/// `Kind::tell` of an actuator past the vehicle's (a corrupt recorded detection that replay
/// follows) changes nothing and does not panic, whatever the kind; of a weak actuator told dead,
/// it sets the factor back to 1 and holds it at 0, as `heal` then `fail` did.
#[test]
fn a_tell_past_the_actuators_changes_nothing_and_a_dead_tell_heals_the_factor() {
    let fresh = control();
    for j in [8, 11, 12, 1000, usize::MAX] {
        for kind in [Kind::Dead, Kind::Stuck(3.0), Kind::Weak(0.5)] {
            let mut c = control();
            kind.tell(j, &mut c);
            assert_eq!(c.bounds(), fresh.bounds(), "{kind:?} of {j}");
            assert_eq!(c.factors(), fresh.factors(), "{kind:?} of {j}");
        }
    }
    let mut c = control();
    Kind::Weak(0.5).tell(2, &mut c);
    assert_eq!(c.factors()[2], 0.5);
    Kind::Dead.tell(2, &mut c);
    let mut told = control();
    told.heal(2);
    told.fail(2, 0.0);
    assert_eq!(c.factors(), told.factors());
    assert_eq!(c.bounds(), told.bounds());
    assert_eq!(c.allocator(), told.allocator());
    assert_eq!(c.held(2), Some(0.0));
}

//! Per-cycle latency, one control cycle per iteration. IDs are `<what>/<group>/<scalar>`
//! (`error_frame/<group>/<scalar>/<frame>`: the law at the reference against the papers').
//!
//! `cargo bench -p benches` (full) or `cargo bench -p benches -- --quick`.

use benches::*;
use control_cycle::respond;
use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use eqtrack_controller::group::{BuiltinGroup, Se3, So3};
use eqtrack_controller::law::{eqt, so3};
use eqtrack_controller::{Law, Real, Source, Trajectory, real};
use nalgebra::{SVector, Vector3};
use std::hint::black_box;

/// The controller's whole cycle without IPC, as controller_node runs it: `respond` to the
/// state message (the reference's desired state, the law, the command), then the reference's
/// step to the next period; a fresh reference from `setup` per batch.
fn controller_cycle<T, G, R, const N: usize, const M: usize>(
    b: &mut criterion::Bencher,
    ctl: &eqtrack_controller::Controller<T, G, N, M>,
    msg: &ipc_types::StateMsg,
    setup: impl FnMut() -> R,
) where
    T: Real,
    G: BuiltinGroup<N, M>,
    R: Trajectory<T, N, M>,
{
    b.iter_batched_ref(
        setup,
        |r| {
            let cmd = respond(ctl, r, black_box(msg));
            r.advance();
            cmd
        },
        BatchSize::SmallInput,
    )
}

/// A closed-form SO(3) law.
type ClosedForm<T> = fn(&so3::So3LawInput<T>) -> Vector3<T>;

fn laws<T: Real>(c: &mut Criterion, scalar: &str) {
    let x = so3_input::<T>();
    let closed: [(&str, ClosedForm<T>); 4] = [
        ("eqt", so3::eqt),
        ("gt", so3::gt),
        ("nog", so3::nog),
        ("asym", so3::asym),
    ];
    for (name, law) in closed {
        let mut g = c.benchmark_group(name);
        g.throughput(Throughput::Elements(1));
        g.bench_function(format!("so3/{scalar}"), |b| b.iter(|| law(black_box(&x))));
        g.finish();
    }
    let mut g = c.benchmark_group("eqt_generic");
    g.throughput(Throughput::Elements(1));
    let (q, v, p, d, k, kd) = so3_generic::<T>();
    g.bench_function(format!("so3/{scalar}"), |b| {
        b.iter(|| {
            eqt::<So3, T, 3, 3>(
                black_box(&q),
                black_box(&v),
                black_box(&p),
                black_box(&d),
                &k,
                &kd,
            )
            .0
        })
    });
    let (q, v, p, d, k, kd) = se3_generic::<T>();
    g.bench_function(format!("se3/{scalar}"), |b| {
        b.iter(|| {
            eqt::<Se3, T, 4, 6>(
                black_box(&q),
                black_box(&v),
                black_box(&p),
                black_box(&d),
                &k,
                &kd,
            )
            .0
        })
    });
    g.finish();
}

/// EqT at the reference (`error_frame = Reference`, the default: the transported-error law)
/// against the papers' form (`World`), through `Controller::compute` (the finiteness checks,
/// the law, the Lyapunov function), on the states of `eqt_generic`: one group per group and
/// scalar, `error_frame/<group>/<scalar>`, with the functions `reference` and `world`.
fn error_frames<T: Real>(c: &mut Criterion, scalar: &str) {
    use eqtrack_controller::ErrorFrame;
    let frames = [
        ("reference", ErrorFrame::Reference),
        ("world", ErrorFrame::World),
    ];
    let mut g = c.benchmark_group(format!("error_frame/so3/{scalar}"));
    g.throughput(Throughput::Elements(1));
    let (q, v, _, d, ..) = so3_generic::<T>();
    for (name, frame) in frames {
        let ctl = so3_law_controller::<T>(frame);
        g.bench_function(name, |b| {
            b.iter(|| ctl.compute(black_box(&q), black_box(&v), black_box(&d)))
        });
    }
    g.finish();
    let mut g = c.benchmark_group(format!("error_frame/se3/{scalar}"));
    g.throughput(Throughput::Elements(1));
    let (q, v, _, d, ..) = se3_generic::<T>();
    for (name, frame) in frames {
        let ctl = se3_law_controller::<T>(frame);
        g.bench_function(name, |b| {
            b.iter(|| ctl.compute(black_box(&q), black_box(&v), black_box(&d)))
        });
    }
    g.finish();
}

fn steps<T: Real>(c: &mut Criterion, scalar: &str) {
    // One control period of the reference generator: 1 RKMK4 substep (a scenario's default)
    // and 10 (the seed scenario's setting).
    for (name, sub) in [("reference_step", 1), ("reference_step_10sub", 10)] {
        let mut g = c.benchmark_group(name);
        g.throughput(Throughput::Elements(1));
        g.bench_function(format!("so3/{scalar}"), |b| {
            b.iter_batched_ref(
                || seed_reference::<T>(sub),
                |r| r.advance(),
                BatchSize::SmallInput,
            )
        });
        g.bench_function(format!("se3/{scalar}"), |b| {
            b.iter_batched_ref(
                || se3_reference::<T>(sub),
                |r| r.advance(),
                BatchSize::SmallInput,
            )
        });
        g.finish();
    }

    let mut g = c.benchmark_group("plant_step");
    g.throughput(Throughput::Elements(1));
    let tau3 = Vector3::new(0.3, -0.2, 0.1).map(real::<T>);
    g.bench_function(format!("so3/{scalar}"), |b| {
        b.iter_batched_ref(
            seed_plant::<T>,
            |p| p.advance(black_box(&tau3), real(0.001), 10),
            BatchSize::SmallInput,
        )
    });
    let tau6 = SVector::<f64, 6>::new(0.3, -0.2, 0.1, 0.5, 0.0, -0.5).map(real::<T>);
    g.bench_function(format!("se3/{scalar}"), |b| {
        b.iter_batched_ref(
            se3_plant::<T>,
            |p| p.advance(black_box(&tau6), real(0.001), 10),
            BatchSize::SmallInput,
        )
    });
    g.finish();

    // The controller's whole cycle without IPC, as controller_node runs it: read the state
    // message, step the reference, run the law (checks, saturation), write the command, then
    // advance the reference to the next period — with 1 and with 10 reference substeps.
    for (name, sub) in [("cycle", 1), ("cycle_10sub", 10)] {
        let mut g = c.benchmark_group(name);
        g.throughput(Throughput::Elements(1));
        let ctl = seed_controller::<T>(Law::Eqt);
        let (q, v, ..) = so3_generic::<f64>();
        let msg = state_msg::<So3, 3, 3>(&q, &v);
        g.bench_function(format!("so3/{scalar}"), |b| {
            controller_cycle(b, &ctl, &msg, || seed_reference::<T>(sub))
        });
        let ctl = se3_controller::<T>();
        let (q, v, ..) = se3_generic::<f64>();
        let msg = state_msg::<Se3, 4, 6>(&q, &v);
        g.bench_function(format!("se3/{scalar}"), |b| {
            controller_cycle(b, &ctl, &msg, || se3_reference::<T>(sub))
        });
        g.finish();
    }
}

/// One estimator step on exact samples of a body at rest, after the filter has started (the
/// complementary filter with two directions; the equivariant filter with the same two; the
/// SE(3) pose filter with one direction, the accelerometer and a position fix).
fn estimators<T: Real>(c: &mut Criterion, scalar: &str) {
    use eqtrack_estimator::{
        ComplementaryConfig, ComplementaryFilter, EqfConfig, EquivariantFilter, PoseConfig,
        PoseFilter,
    };
    let w = [Vector3::z(), Vector3::new(1.0, 0.0, 0.2).map(real::<T>)];
    let (q, ..) = so3_generic::<T>();
    let y = [q.tr_mul(&w[0]), q.tr_mul(&w[1].normalize())];
    let gyro = Vector3::new(0.02, -0.01, 0.03).map(real::<T>);
    let f_up = q.tr_mul(&Vector3::new(0.0, 0.0, 9.81).map(real::<T>));
    let x = Vector3::new(1.0, 2.0, 3.0).map(real::<T>);
    let h = real::<T>(0.001);
    let Ok(cc) = ComplementaryConfig::new(real(2.0), real(1.0), &w, &[T::one(), T::one()]) else {
        return;
    };
    let Ok(pc) = PoseConfig::new(
        real(2.0),
        real(1.0),
        &w[1..],
        &[T::one(), T::one()],
        real(0.05),
        real(0.01),
    ) else {
        return;
    };
    let Ok(ec) = EqfConfig::new(real(0.002), real(1e-5), &w, &[real(0.01), real(0.01)]) else {
        return;
    };
    let mut g = c.benchmark_group("estimator_step");
    g.throughput(Throughput::Elements(1));
    g.bench_function(format!("so3_eqf/{scalar}"), |b| {
        b.iter_batched_ref(
            || {
                let mut f = EquivariantFilter::new(ec);
                f.step(h, &gyro, &y);
                f
            },
            |f| f.step(black_box(h), black_box(&gyro), black_box(&y)),
            BatchSize::SmallInput,
        )
    });
    g.bench_function(format!("so3/{scalar}"), |b| {
        b.iter_batched_ref(
            || {
                let mut f = ComplementaryFilter::new(cc);
                f.step(h, &gyro, &y);
                f
            },
            |f| f.step(black_box(h), black_box(&gyro), black_box(&y)),
            BatchSize::SmallInput,
        )
    });
    g.bench_function(format!("se3/{scalar}"), |b| {
        b.iter_batched_ref(
            || {
                let mut f = PoseFilter::new(pc);
                f.step(h, &gyro, &y[1..], &f_up, Some(&x));
                f
            },
            |f| {
                f.step(
                    black_box(h),
                    black_box(&gyro),
                    black_box(&y[1..]),
                    black_box(&f_up),
                    Some(&x),
                )
            },
            BatchSize::SmallInput,
        )
    });
    g.finish();
}

/// The plant side's whole cycle in the simulator with `sensors_so3`'s sensors and filter (and
/// `eqf_so3`'s, the same sensors with the equivariant filter):
/// sample the sensors from the true body, step the filter, integrate the body over one 1 ms
/// period (10 RKMK4 substeps) — against the same integration alone (the exact state).
fn plant_side(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/sensors_so3.toml");
    let Ok(s) = scenario::Scenario::from_file(std::path::Path::new(path)) else {
        return;
    };
    let Ok(body) = s.plant_body::<So3, 3, 3>() else {
        return;
    };
    let tau = Vector3::new(0.3, -0.2, 0.1);
    let mut g = c.benchmark_group("plant_side_cycle");
    g.throughput(Throughput::Elements(1));
    g.bench_function("so3/f64/truth", |b| {
        b.iter_batched_ref(
            || body,
            |p| p.advance(black_box(&tau), 0.001, 10),
            BatchSize::SmallInput,
        )
    });
    let eqf = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/eqf_so3.toml");
    let Ok(eqf) = scenario::Scenario::from_file(std::path::Path::new(eqf)) else {
        return;
    };
    for (name, s) in [("complementary", &s), ("eqf", &eqf)] {
        g.bench_function(format!("so3/f64/{name}"), |b| {
            b.iter_batched_ref(
                || {
                    let mut e = plant::estimation::Estimation::new(s, 0.001, &[])
                        .ok()
                        .flatten()
                        .expect("the scenario has sensors");
                    e.measure(0, &body, &tau);
                    (e, body, 1u64)
                },
                |(e, p, k)| {
                    let out = e.measure(*k, p, &tau);
                    p.advance(black_box(&tau), 0.001, 10);
                    *k += 1;
                    out.0
                },
                BatchSize::SmallInput,
            )
        });
    }
    g.finish();
}

fn baseline(c: &mut Criterion) {
    let x = so3_input::<f64>();
    let mut g = c.benchmark_group("plain_nalgebra_eqt");
    g.throughput(Throughput::Elements(1));
    g.bench_function("so3/f64", |b| b.iter(|| plain_nalgebra_eqt(black_box(&x))));
    g.finish();
}

/// The disturbance-rejection terms (docs/maths.md, "Disturbance rejection"): the four
/// variants' configurations (none, observer, integral, both) for the SO(3) seed body.
fn term_variants<T: Real>() -> [(&'static str, eqtrack_controller::RejectionConfig<T, 3>); 4] {
    let observer = eqtrack_controller::ObserverConfig {
        gain: Vector3::repeat(real(20.0)),
        limit: None,
        frame: eqtrack_controller::Frame::Body,
    };
    let integral = eqtrack_controller::IntegralConfig {
        ki: Vector3::repeat(real(0.5)),
        c: Vector3::repeat(real(0.2)),
        limit: Some(Vector3::repeat(real(0.5))),
        anti_windup: true,
    };
    let config = |o, i| eqtrack_controller::RejectionConfig {
        observer: o,
        integral: i,
    };
    [
        ("plain", config(None, None)),
        ("observer", config(Some(observer), None)),
        ("integral", config(None, Some(integral))),
        ("both", config(Some(observer), Some(integral))),
    ]
}

/// The law with each term (`Controller::compute_rejecting` on a running cycle; `plain`:
/// `Controller::compute`), and the controller's whole cycle with each (as the node runs it:
/// `Responder::respond` on consecutive states, then the reference's step).
fn terms<T: Real>(c: &mut Criterion, scalar: &str) {
    let ctl = seed_controller::<T>(Law::Eqt);
    let (q, v, _, d, ..) = so3_generic::<T>();
    let applied = Vector3::new(0.1, -0.2, 0.05).map(real::<T>);
    let h = real::<T>(0.001);
    let mut g = c.benchmark_group("law_terms");
    g.throughput(Throughput::Elements(1));
    for (name, config) in term_variants::<T>() {
        let Ok(mut terms) = eqtrack_controller::Rejection::new(config, None) else {
            continue;
        };
        for _ in 0..2 {
            let _ = ctl.compute_rejecting(&mut terms, &q, &v, &d, &applied, h, true);
        }
        g.bench_function(format!("so3/{name}/{scalar}"), |b| {
            b.iter(|| {
                if name == "plain" {
                    ctl.compute(black_box(&q), black_box(&v), black_box(&d))
                } else {
                    ctl.compute_rejecting(
                        &mut terms,
                        black_box(&q),
                        black_box(&v),
                        black_box(&d),
                        black_box(&applied),
                        h,
                        true,
                    )
                }
            })
        });
    }
    g.finish();
    let mut g = c.benchmark_group("cycle_terms");
    g.throughput(Throughput::Elements(1));
    let (q64, v64, ..) = so3_generic::<f64>();
    for (name, config) in term_variants::<T>() {
        let Ok(mut responder) = control_cycle::Responder::new(ctl, config) else {
            continue;
        };
        let mut reference = seed_reference::<T>(1);
        let mut msg = state_msg::<So3, 3, 3>(&q64, &v64);
        msg.applied = [0.1, -0.2, 0.05, 0.0, 0.0, 0.0];
        msg.control_period = 0.01;
        g.bench_function(format!("so3/{name}/{scalar}"), |b| {
            b.iter(|| {
                // consecutive states: the terms update every cycle
                msg.seq = reference.step_index();
                let cmd = responder.respond(&mut reference, black_box(&msg));
                reference.advance();
                cmd
            })
        });
    }
    g.finish();
}

/// One sample of a waypoint path inside a leg (`path_sample`: `Path::sample`, what the
/// controller evaluates every cycle), and the controller's whole cycle tracking it
/// (`cycle_path`: `respond` then the reference's step, as `cycle` with the feedforward
/// series): the shipped slews flown `stop` (one exponential per sample) and `through` (five
/// exponentials and adjoints, Sommer et al.'s recursion), at t = 5.5 s (inside the second leg).
fn paths(c: &mut Criterion) {
    fn group<G: BuiltinGroup<N, M>, const N: usize, const M: usize>(
        c: &mut Criterion,
        name: &str,
        file: &str,
        q: &nalgebra::SMatrix<f64, N, N>,
        v: &SVector<f64, M>,
    ) {
        let at = format!("{}/../scenarios/{file}", env!("CARGO_MANIFEST_DIR"));
        let Ok(stop) = scenario::Scenario::from_file(std::path::Path::new(&at)) else {
            return;
        };
        let mut through = stop.clone();
        if let Some(p) = through.path.as_mut() {
            p.kind = scenario::PathKind::Through;
        }
        let msg = state_msg::<G, N, M>(q, v);
        for (kind, s) in [("stop", &stop), ("through", &through)] {
            let (Some(Ok(path)), Ok(ctl)) = (s.path::<G, N, M>(), s.controller::<G, N, M>()) else {
                continue;
            };
            c.benchmark_group("path_sample")
                .bench_function(format!("{name}/{kind}/f64"), |b| {
                    b.iter(|| path.sample(black_box(5.5)))
                });
            let Ok(Source::Path(start)) = s.reference_source::<G, N, M>() else {
                continue;
            };
            let mut start = start;
            while start.time() < 5.5 {
                start.advance();
            }
            let mut g = c.benchmark_group("cycle_path");
            g.throughput(Throughput::Elements(1));
            g.bench_function(format!("{name}/{kind}/f64"), |b| {
                controller_cycle(b, &ctl, &msg, || start.clone())
            });
            g.finish();
        }
    }
    let (q, v, ..) = so3_generic::<f64>();
    group::<So3, 3, 3>(c, "so3", "slew_so3.toml", &q, &v);
    let (q, v, ..) = se3_generic::<f64>();
    group::<Se3, 4, 6>(c, "se3", "slew_se3.toml", &q, &v);
}

/// One allocation (docs/maths.md, "Control allocation"): the hexarotor (m = 6) and the ROV
/// (m = 8), a demand within reach (stages 1–3 each converge in one or two iterations) and one
/// past it (saturated: more active-set iterations).
fn allocations<T: Real>(c: &mut Criterion, scalar: &str) {
    use eqtrack_allocation::{Allocator, Geometry, Priority, presets};
    use nalgebra::SVector;
    let r = |x: f64| eqtrack_controller::real::<T>(x);
    let hexarotor = presets::hexarotor::<T>(r(0.25), r(0.5), r(0.016), r(8.0));
    let rov = presets::rov_heavy::<T>(r(0.4), r(0.3), r(0.12), r(0.22), r(40.0));
    type Case<'a, T> = (
        &'a str,
        &'a [eqtrack_allocation::Actuator<T>],
        [f64; 6],
        [f64; 6],
    );
    let cases: [Case<T>; 2] = [
        (
            "hexarotor_m6",
            &hexarotor,
            [0.1, -0.05, 0.02, 0.5, -0.3, 20.0],
            [0.5, -0.3, 1.2, 2.0, -1.0, 45.0],
        ),
        (
            "rov_m8",
            &rov,
            [1.0, -2.0, 3.0, 20.0, -10.0, 5.0],
            [10.0, -8.0, 30.0, 150.0, -90.0, 120.0],
        ),
    ];
    let mut g = c.benchmark_group("allocation");
    g.throughput(Throughput::Elements(1));
    for (name, acts, within, past) in cases {
        let Ok(geometry) = Geometry::<T, 6>::new(acts) else {
            continue;
        };
        let Ok(alloc) = Allocator::new(geometry, &[], &[], Priority::Torque) else {
            continue;
        };
        for (reach, d) in [("within", within), ("saturated", past)] {
            let demand = SVector::<T, 6>::from(d.map(r));
            g.bench_function(format!("{name}/{reach}/{scalar}"), |b| {
                b.iter(|| alloc.allocate(black_box(&demand)))
            });
        }
    }
    g.finish();
}

/// The controller's whole cycle for a vehicle, as controller_node runs it: the law
/// (`law_only`: without the vehicle, its wrench sent as is) or the law and the allocation of
/// its wrench to the actuators (`with_allocation`), on the shipped hexarotor (m = 6, 500 Hz)
/// and ROV (m = 8), from their initial state; then the reference's step. f64, as the node.
fn vehicle_cycles(c: &mut Criterion) {
    let mut g = c.benchmark_group("cycle_vehicle");
    g.throughput(Throughput::Elements(1));
    let mut steadies = Vec::new();
    for (name, file) in [
        ("hexarotor_m6", "hexarotor_eight"),
        ("rov_m8", "rov_failure"),
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenarios")
            .join(format!("{file}.toml"));
        let Ok(s) = scenario::Scenario::from_file(&path) else {
            continue;
        };
        let (Some(spec), Ok(body)) = (&s.vehicle, s.plant_body::<Se3, 4, 6>()) else {
            continue;
        };
        let Ok(law_only) = s
            .controller::<Se3, 4, 6>()
            .and_then(|c| control_cycle::Responder::new(c, s.rejection_config()))
        else {
            continue;
        };
        let Ok(vehicle) = control_cycle::ControllerVehicle::new(spec, s.control_period) else {
            continue;
        };
        let with_allocation = law_only.clone().with_vehicle(vehicle);
        // and the failsafe manager ahead of it: every cycle the span test of the actuators it
        // may still move, the tracking error against its limit, the state machine's step
        let supervised = std::fs::read_to_string(&path).ok().and_then(|text| {
            let text = format!(
                "{text}\n[failsafe]\nactuators = \"warn\"\ntracking = \"hold\"\ntracking_limit_position = 5.0\n"
            );
            let base = path.parent()?;
            let with = scenario::Scenario::from_toml_in(&text, file, file, Some(base)).ok()?;
            Some(with_allocation.clone().with_supervisor(control_cycle::Supervisor::of(&with)?))
        });
        let mut msg = state_msg::<Se3, 4, 6>(body.configuration(), &body.velocity());
        msg.control_period = s.control_period;
        if let Some(supervised) = supervised {
            steadies.push((name, s.clone(), [with_allocation.clone(), supervised], msg));
        }
        for (variant, responder) in [("law_only", law_only), ("with_allocation", with_allocation)] {
            g.bench_function(format!("{name}/{variant}"), |b| {
                b.iter_batched_ref(
                    || {
                        let r = s.reference_source::<Se3, 4, 6>().ok();
                        (r, responder.clone())
                    },
                    |(r, resp)| {
                        let r = r.as_mut()?;
                        let cmd = resp.respond(r, black_box(&msg)).ok();
                        r.advance();
                        cmd
                    },
                    BatchSize::SmallInput,
                )
            });
        }
    }
    g.finish();
    for (name, s, responders, msg) in &steadies {
        steady(c, name, s, responders, msg);
    }
}

/// The cycle of `responders` (with the allocation; then with the failsafe manager too) in
/// steady flight: one responder and one reference kept from cycle to cycle, consecutive states,
/// so the manager's span test, which runs again only after a failure is told, is not repeated
/// (`cycle_failsafe/<vehicle>/with_allocation` · `with_failsafe`).
fn steady(
    c: &mut Criterion,
    name: &str,
    s: &scenario::Scenario,
    responders: &[control_cycle::Responder<f64, Se3, 4, 6>; 2],
    msg: &ipc_types::StateMsg,
) {
    let mut g = c.benchmark_group("cycle_failsafe");
    g.throughput(Throughput::Elements(1));
    for (variant, responder) in ["with_allocation", "with_failsafe"]
        .into_iter()
        .zip(responders)
    {
        let (Ok(mut reference), mut responder) =
            (s.reference_source::<Se3, 4, 6>(), responder.clone())
        else {
            continue;
        };
        let mut msg = *msg;
        g.bench_function(format!("{name}/{variant}"), |b| {
            b.iter(|| {
                msg.seq = reference.step_index();
                let cmd = responder.respond(&mut reference, black_box(&msg)).ok();
                reference.advance();
                cmd
            })
        });
    }
    g.finish();
}

fn all(c: &mut Criterion) {
    vehicle_cycles(c);
    allocations::<f64>(c, "f64");
    allocations::<f32>(c, "f32");
    laws::<f64>(c, "f64");
    laws::<f32>(c, "f32");
    error_frames::<f64>(c, "f64");
    error_frames::<f32>(c, "f32");
    baseline(c);
    steps::<f64>(c, "f64");
    steps::<f32>(c, "f32");
    estimators::<f64>(c, "f64");
    estimators::<f32>(c, "f32");
    plant_side(c);
    terms::<f64>(c, "f64");
    terms::<f32>(c, "f32");
    paths(c);
}

criterion_group!(benches, all);
criterion_main!(benches);

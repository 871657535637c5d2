//! Instruction counts under valgrind (callgrind, via gungraun) for the same functions as the
//! criterion benches: figures that do not move with machine noise. Setup (building the
//! controller, reference, plant and state) is excluded. Opt-in:
//!
//! ```sh
//! cargo install gungraun-runner --version 0.20.0 --locked
//! cargo bench -p benches --features icount --bench icount
//! ```

use benches::*;
use control_cycle::respond;
use eqtrack_controller::group::{Se3, So3};
use eqtrack_controller::integrator::RigidBody;
use eqtrack_controller::law::so3::{self, So3LawInput};
use eqtrack_controller::law::{Desired, eqt};
use eqtrack_controller::{Controller, Law, Reference, real};
use gungraun::{library_benchmark, library_benchmark_group, main};
use ipc_types::{CommandMsg, StateMsg};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use std::hint::black_box;

/// The closed-form SO(3) laws and the generic EqT, in one scalar.
macro_rules! laws {
    ($t:ty, $eqt:ident, $gt:ident, $nog:ident, $asym:ident, $gso3:ident, $gse3:ident) => {
        #[library_benchmark]
        #[bench::eqt(so3_input::<$t>())]
        fn $eqt(x: So3LawInput<$t>) -> Vector3<$t> {
            black_box(so3::eqt(black_box(&x)))
        }
        #[library_benchmark]
        #[bench::gt(so3_input::<$t>())]
        fn $gt(x: So3LawInput<$t>) -> Vector3<$t> {
            black_box(so3::gt(black_box(&x)))
        }
        #[library_benchmark]
        #[bench::nog(so3_input::<$t>())]
        fn $nog(x: So3LawInput<$t>) -> Vector3<$t> {
            black_box(so3::nog(black_box(&x)))
        }
        #[library_benchmark]
        #[bench::asym(so3_input::<$t>())]
        fn $asym(x: So3LawInput<$t>) -> Vector3<$t> {
            black_box(so3::asym(black_box(&x)))
        }
        #[library_benchmark]
        #[bench::so3(so3_generic::<$t>())]
        fn $gso3(
            a: (
                Matrix3<$t>,
                Vector3<$t>,
                Vector3<$t>,
                Desired<$t, 3, 3>,
                Matrix3<$t>,
                Matrix3<$t>,
            ),
        ) -> Vector3<$t> {
            black_box(eqt::<So3, $t, 3, 3>(&a.0, &a.1, &a.2, &a.3, &a.4, &a.5).0)
        }
        #[library_benchmark]
        #[bench::se3(se3_generic::<$t>())]
        fn $gse3(
            a: (
                SMatrix<$t, 4, 4>,
                SVector<$t, 6>,
                SVector<$t, 6>,
                Desired<$t, 4, 6>,
                SMatrix<$t, 4, 4>,
                SMatrix<$t, 6, 6>,
            ),
        ) -> SVector<$t, 6> {
            black_box(eqt::<Se3, $t, 4, 6>(&a.0, &a.1, &a.2, &a.3, &a.4, &a.5).0)
        }
    };
}

laws!(
    f64,
    eqt_so3_f64,
    gt_so3_f64,
    nog_so3_f64,
    asym_so3_f64,
    eqt_generic_so3_f64,
    eqt_generic_se3_f64
);
laws!(
    f32,
    eqt_so3_f32,
    gt_so3_f32,
    nog_so3_f32,
    asym_so3_f32,
    eqt_generic_so3_f32,
    eqt_generic_se3_f32
);

#[library_benchmark]
#[bench::f64(so3_input::<f64>())]
fn plain_nalgebra_eqt_so3_f64(x: So3LawInput<f64>) -> Vector3<f64> {
    black_box(plain_nalgebra_eqt(black_box(&x)))
}

type So3Cycle<T> = (Controller<T, So3, 3, 3>, Reference<T, So3, 3, 3>, StateMsg);
type Se3Cycle<T> = (Controller<T, Se3, 4, 6>, Reference<T, Se3, 4, 6>, StateMsg);

fn so3_cycle<T: eqtrack_controller::Real>(substeps: usize) -> So3Cycle<T> {
    let (q, v, ..) = so3_generic::<f64>();
    (
        seed_controller::<T>(Law::Eqt),
        seed_reference::<T>(substeps),
        state_msg::<So3, 3, 3>(&q, &v),
    )
}

fn se3_cycle<T: eqtrack_controller::Real>(substeps: usize) -> Se3Cycle<T> {
    let (q, v, ..) = se3_generic::<f64>();
    (
        se3_controller::<T>(),
        se3_reference::<T>(substeps),
        state_msg::<Se3, 4, 6>(&q, &v),
    )
}

/// Reference step, plant step and the controller's whole cycle, in one scalar.
macro_rules! steps {
    ($t:ty, $rso3:ident, $rse3:ident, $pso3:ident, $pse3:ident, $cso3:ident, $cse3:ident) => {
        #[library_benchmark]
        #[bench::sub1(seed_reference::<$t>(1))]
        #[bench::sub10(seed_reference::<$t>(10))]
        fn $rso3(mut r: Reference<$t, So3, 3, 3>) -> Reference<$t, So3, 3, 3> {
            r.advance();
            black_box(r)
        }
        #[library_benchmark]
        #[bench::sub1(se3_reference::<$t>(1))]
        #[bench::sub10(se3_reference::<$t>(10))]
        fn $rse3(mut r: Reference<$t, Se3, 4, 6>) -> Reference<$t, Se3, 4, 6> {
            r.advance();
            black_box(r)
        }
        #[library_benchmark]
        #[bench::sub10(seed_plant::<$t>())]
        fn $pso3(mut p: RigidBody<$t, So3, 3, 3>) -> RigidBody<$t, So3, 3, 3> {
            p.advance(
                &Vector3::new(0.3, -0.2, 0.1).map(real::<$t>),
                real(0.001),
                10,
            );
            black_box(p)
        }
        #[library_benchmark]
        #[bench::sub10(se3_plant::<$t>())]
        fn $pse3(mut p: RigidBody<$t, Se3, 4, 6>) -> RigidBody<$t, Se3, 4, 6> {
            p.advance(
                &SVector::<f64, 6>::new(0.3, -0.2, 0.1, 0.5, 0.0, -0.5).map(real::<$t>),
                real(0.001),
                10,
            );
            black_box(p)
        }
        #[library_benchmark]
        #[bench::sub1(so3_cycle::<$t>(1))]
        #[bench::sub10(so3_cycle::<$t>(10))]
        fn $cso3(s: So3Cycle<$t>) -> (Option<CommandMsg>, Reference<$t, So3, 3, 3>) {
            let (ctl, mut r, msg) = s;
            let cmd = respond(&ctl, &mut r, black_box(&msg)).ok();
            r.advance();
            black_box((cmd, r))
        }
        #[library_benchmark]
        #[bench::sub1(se3_cycle::<$t>(1))]
        #[bench::sub10(se3_cycle::<$t>(10))]
        fn $cse3(s: Se3Cycle<$t>) -> (Option<CommandMsg>, Reference<$t, Se3, 4, 6>) {
            let (ctl, mut r, msg) = s;
            let cmd = respond(&ctl, &mut r, black_box(&msg)).ok();
            r.advance();
            black_box((cmd, r))
        }
    };
}

steps!(
    f64,
    reference_step_so3_f64,
    reference_step_se3_f64,
    plant_step_so3_f64,
    plant_step_se3_f64,
    cycle_so3_f64,
    cycle_se3_f64
);
steps!(
    f32,
    reference_step_so3_f32,
    reference_step_se3_f32,
    plant_step_so3_f32,
    plant_step_se3_f32,
    cycle_so3_f32,
    cycle_se3_f32
);

library_benchmark_group!(
    name = laws;
    benchmarks = eqt_so3_f64, eqt_so3_f32, plain_nalgebra_eqt_so3_f64, gt_so3_f64, gt_so3_f32, nog_so3_f64, nog_so3_f32,
        asym_so3_f64, asym_so3_f32, eqt_generic_so3_f64, eqt_generic_so3_f32, eqt_generic_se3_f64, eqt_generic_se3_f32
);

library_benchmark_group!(
    name = steps;
    benchmarks = reference_step_so3_f64, reference_step_so3_f32, reference_step_se3_f64, reference_step_se3_f32,
        plant_step_so3_f64, plant_step_so3_f32, plant_step_se3_f64, plant_step_se3_f32,
        cycle_so3_f64, cycle_so3_f32, cycle_se3_f64, cycle_se3_f32
);

main!(library_benchmark_groups = laws, steps);

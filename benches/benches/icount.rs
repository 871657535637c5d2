//! Instruction counts under valgrind (callgrind, via gungraun): figures that do not move with
//! machine noise. Opt-in:
//!
//! ```sh
//! cargo install gungraun-runner --version 0.20.0 --locked
//! cargo bench -p benches --features icount --bench icount
//! ```

use benches::*;
use controller::group::{Se3, So3};
use controller::law::so3::So3LawInput;
use controller::law::{Desired, eqt};
use controller::{Law, Reference};
use controller_node::respond;
use gungraun::{library_benchmark, library_benchmark_group, main};
use ipc_types::{CommandMsg, StateMsg};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use std::hint::black_box;

#[library_benchmark]
#[bench::f64(so3_input::<f64>())]
fn eqt_so3_f64(x: So3LawInput<f64>) -> Vector3<f64> {
    black_box(controller::law::so3::eqt(black_box(&x)))
}

#[library_benchmark]
#[bench::f32(so3_input::<f32>())]
fn eqt_so3_f32(x: So3LawInput<f32>) -> Vector3<f32> {
    black_box(controller::law::so3::eqt(black_box(&x)))
}

#[library_benchmark]
#[bench::f64(so3_input::<f64>())]
fn plain_nalgebra_eqt_so3_f64(x: So3LawInput<f64>) -> Vector3<f64> {
    black_box(plain_nalgebra_eqt(black_box(&x)))
}

type So3Args = (
    Matrix3<f64>,
    Vector3<f64>,
    Vector3<f64>,
    Desired<f64, 3, 3>,
    Matrix3<f64>,
    Matrix3<f64>,
);
type Se3Args = (
    SMatrix<f64, 4, 4>,
    SVector<f64, 6>,
    SVector<f64, 6>,
    Desired<f64, 4, 6>,
    SMatrix<f64, 4, 4>,
    SMatrix<f64, 6, 6>,
);

#[library_benchmark]
#[bench::f64(so3_generic::<f64>())]
fn eqt_generic_so3_f64(a: So3Args) -> Vector3<f64> {
    black_box(eqt::<So3, f64, 3, 3>(&a.0, &a.1, &a.2, &a.3, &a.4, &a.5).0)
}

#[library_benchmark]
#[bench::f64(se3_generic::<f64>())]
fn eqt_generic_se3_f64(a: Se3Args) -> SVector<f64, 6> {
    black_box(eqt::<Se3, f64, 4, 6>(&a.0, &a.1, &a.2, &a.3, &a.4, &a.5).0)
}

type CycleSetup = (
    controller::Controller<f64, So3, 3, 3>,
    Reference<f64, So3, 3, 3>,
    StateMsg,
);

fn so3_cycle_setup() -> CycleSetup {
    let (q, v, ..) = so3_generic::<f64>();
    (
        seed_controller::<f64>(Law::Eqt),
        seed_reference::<f64>(1),
        state_msg::<So3, 3, 3>(&q, &v, ipc_types::group::SO3),
    )
}

#[library_benchmark]
#[bench::f64(so3_cycle_setup())]
fn cycle_so3_f64(setup: CycleSetup) -> Option<CommandMsg> {
    let (ctl, mut r, msg) = setup;
    let cmd = respond(&ctl, &mut r, black_box(&msg), ipc_types::group::SO3).ok();
    r.advance();
    black_box(cmd)
}

library_benchmark_group!(
    name = laws;
    benchmarks = eqt_so3_f64, eqt_so3_f32, plain_nalgebra_eqt_so3_f64, eqt_generic_so3_f64, eqt_generic_se3_f64, cycle_so3_f64
);

main!(library_benchmark_groups = laws);

//! The kit on eqtrack's own groups (SO(3), SE(3), SE(2)) in both scalars, and on groups that
//! are deliberately wrong, which must fail it by the property's name.

use super::*;
use crate::group::{Se2, Se3, So3};
use nalgebra::Matrix3;
use proptest::prelude::*;

fn samples<const M: usize>(seed: u64, scale: f64) -> [SVector<f64, M>; 12] {
    core::array::from_fn(|i| sample::<M>(seed, i as u64, scale))
}

/// Samples whose rotation angle is `π − δ` (δ from 10⁻⁹ to 10⁻³), about random axes: the
/// first `rot` coordinates are the rotation vector.
fn near_cut_locus<const M: usize>(seed: u64, rot: usize) -> [SVector<f64, M>; 12] {
    core::array::from_fn(|i| {
        let mut v = sample::<M>(seed, i as u64, 1.0);
        let n = v.rows(0, rot).norm().max(1e-3);
        let angle = core::f64::consts::PI - 10f64.powi(-3 - (i as i32 % 7));
        for k in 0..rot {
            v[k] *= angle / n;
        }
        v
    })
}

/// A configuration for [`check_lyapunov`]: SPD inertia, `K` and `K_d` with off-diagonal
/// terms; on SE(3) `K = diag(K_R, k_x)`, the form its potential needs.
fn config<const N: usize, const M: usize>(seed: u64) -> ControllerConfig<f64, N, M> {
    ControllerConfig {
        law: Law::Eqt,
        error_frame: ErrorFrame::Reference,
        inertia: spd::<M>(seed, 0.5),
        k: spd::<N>(seed + 1, 0.5),
        kd: spd::<M>(seed + 2, 0.5),
        torque_limit: None,
    }
}

fn se3_config(seed: u64) -> ControllerConfig<f64, 4, 6> {
    let mut c = config::<4, 6>(seed);
    let kr = spd::<3>(seed + 3, 0.5);
    c.k = SMatrix::<f64, 4, 4>::zeros();
    c.k.fixed_view_mut::<3, 3>(0, 0).copy_from(&kr);
    c.k[(3, 3)] = 1.5;
    c
}

fn se2_config(seed: u64) -> ControllerConfig<f64, 3, 3> {
    let mut c = config::<3, 3>(seed);
    let kr = spd::<2>(seed + 3, 0.5);
    c.k = SMatrix::<f64, 3, 3>::zeros();
    c.k.fixed_view_mut::<2, 2>(0, 0).copy_from(&kr);
    c.k[(2, 2)] = 1.5;
    c
}

#[test]
fn the_whole_kit_passes_on_so3() {
    let r = check::<So3, 3, 3>(&samples::<3>(1, 1.5), &config::<3, 3>(10), 5).unwrap();
    assert!(
        r.group > 300 && r.error_dynamics >= 18 && r.lyapunov > 10_000,
        "{r:?}"
    );
}

#[test]
fn the_whole_kit_passes_on_se3() {
    let r = check::<Se3, 4, 6>(&samples::<6>(2, 1.5), &se3_config(20), 6).unwrap();
    assert!(
        r.group > 300 && r.error_dynamics >= 18 && r.lyapunov > 10_000,
        "{r:?}"
    );
}

#[test]
fn the_whole_kit_passes_on_se2() {
    let r = check::<Se2, 3, 3>(&samples::<3>(3, 1.5), &se2_config(30), 7).unwrap();
    assert!(
        r.group > 300 && r.error_dynamics >= 18 && r.lyapunov > 10_000,
        "{r:?}"
    );
}

#[test]
fn the_kit_passes_near_the_cut_locus() {
    check_group::<So3, f64, 3, 3>(&near_cut_locus::<3>(4, 3), 1e-8).unwrap();
    check_group::<Se3, f64, 4, 6>(&near_cut_locus::<6>(5, 3), 1e-8).unwrap();
    check_group::<Se2, f64, 3, 3>(&near_cut_locus::<3>(6, 1), 1e-9).unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn the_group_part_holds_on_random_samples(seed in any::<u64>(), scale in 0.0..1.8f64) {
        let run = |r: Result<usize, Failure>| r.map_err(|f| TestCaseError::fail(f.to_string()));
        run(check_group::<So3, f64, 3, 3>(&samples::<3>(seed, scale), 1e-12))?;
        run(check_group::<Se3, f64, 4, 6>(&samples::<6>(seed, scale), 1e-12))?;
        run(check_group::<Se2, f64, 3, 3>(&samples::<3>(seed, scale), 1e-12))?;
        run(check_group::<So3, f32, 3, 3>(&samples::<3>(seed, scale), 5e-6))?;
        run(check_group::<Se3, f32, 4, 6>(&samples::<6>(seed, scale), 5e-6))?;
        run(check_group::<Se2, f32, 3, 3>(&samples::<3>(seed, scale), 5e-6))?;
    }
}

/// A group that is SO(3) or SE(2) with one operation spoiled: `WRONG` 0 flips `ad`'s sign,
/// 1 stretches `exp` by 0.1 %, 2 transposes the adjoint, 3 scales the Frobenius coordinates
/// (the law's gradient) by 1.01, 4 turns `ad_transpose_mul` into `ad(v) μ`.
#[derive(Debug, Clone, Copy, Default)]
struct Spoiled<G, const WRONG: u8>(core::marker::PhantomData<G>);

impl<G: MatrixLieGroup<3, 3>, const WRONG: u8> MatrixLieGroup<3, 3> for Spoiled<G, WRONG> {
    const NAME: &'static str = "spoiled";
    fn hat<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        G::hat(v)
    }
    fn vee<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        G::vee(x)
    }
    fn exp<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        if WRONG == 1 {
            G::exp(&(v * real::<T>(1.001)))
        } else {
            G::exp(v)
        }
    }
    fn log<T: Real>(q: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        G::log(q)
    }
    fn inverse<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        G::inverse(q)
    }
    fn adjoint<T: Real>(q: &SMatrix<T, 3, 3>) -> SMatrix<T, 3, 3> {
        if WRONG == 2 {
            G::adjoint(q).transpose()
        } else {
            G::adjoint(q)
        }
    }
    fn ad<T: Real>(v: &SVector<T, 3>) -> SMatrix<T, 3, 3> {
        if WRONG == 0 { -G::ad(v) } else { G::ad(v) }
    }
    fn ad_transpose_mul<T: Real>(v: &SVector<T, 3>, mu: &SVector<T, 3>) -> SVector<T, 3> {
        if WRONG == 4 {
            G::ad(v) * mu
        } else {
            G::ad_transpose_mul(v, mu)
        }
    }
    fn frobenius_coordinates<T: Real>(x: &SMatrix<T, 3, 3>) -> SVector<T, 3> {
        let f = G::frobenius_coordinates(x);
        if WRONG == 3 { f * real::<T>(1.01) } else { f }
    }
    fn attitude<T: Real>(q: &SMatrix<T, 3, 3>) -> Option<Matrix3<T>> {
        G::attitude(q)
    }
}

fn named(r: Result<usize, Failure>) -> &'static str {
    r.unwrap_err().property
}

#[test]
fn a_wrong_group_fails_the_kit_naming_the_property() {
    let s = samples::<3>(11, 1.5);
    assert!(check_group::<So3, f64, 3, 3>(&s, 1e-12).unwrap() > 100);
    assert!(check_group::<Se2, f64, 3, 3>(&s, 1e-12).unwrap() > 100);
    for (wrong, property) in [
        (
            named(check_group::<Spoiled<So3, 0>, f64, 3, 3>(&s, 1e-12)),
            "ad against the commutator",
        ),
        (
            named(check_group::<Spoiled<Se2, 0>, f64, 3, 3>(&s, 1e-12)),
            "ad against the commutator",
        ),
        (
            named(check_group::<Spoiled<So3, 1>, f64, 3, 3>(&s, 1e-12)),
            "exp against its series",
        ),
        (
            named(check_group::<Spoiled<Se2, 1>, f64, 3, 3>(&s, 1e-12)),
            "exp against its series",
        ),
        (
            named(check_group::<Spoiled<So3, 2>, f64, 3, 3>(&s, 1e-12)),
            "Ad(a)Ad(b) = Ad(ab)",
        ),
        (
            named(check_group::<Spoiled<Se2, 2>, f64, 3, 3>(&s, 1e-12)),
            "Ad(a)Ad(b) = Ad(ab)",
        ),
        (
            named(check_group::<Spoiled<Se2, 3>, f64, 3, 3>(&s, 1e-12)),
            "the Frobenius coordinates",
        ),
        (
            named(check_group::<Spoiled<Se2, 4>, f64, 3, 3>(&s, 1e-12)),
            "ad_transpose_mul equals ad(a)ᵀ μ",
        ),
    ] {
        assert_eq!(wrong, property);
    }
    let e = check_group::<Spoiled<So3, 0>, f64, 3, 3>(&s, 1e-12).unwrap_err();
    assert!(e.to_string().contains("`ad against the commutator`"), "{e}");
}

/// The control side fails too, by name: a gradient 1 % off breaks `L̇`, and the error
/// dynamics of a group whose `ad` has the wrong sign (its momentum equation turns the other
/// way) break the theorem.
#[test]
fn a_wrong_group_fails_the_control_side_naming_the_property() {
    let c = se2_config(30);
    assert!(check_lyapunov::<Se2, 3, 3>(&c, 7).is_ok());
    assert_eq!(
        named(check_lyapunov::<Spoiled<Se2, 3>, 3, 3>(&c, 7)),
        "L̇ is the stated rate"
    );
    assert_eq!(
        named(check_lyapunov::<Spoiled<Se2, 4>, 3, 3>(&c, 7)),
        "L̇ is the stated rate"
    );
    assert!(check_error_dynamics::<Se2, 3, 3>(7).is_ok());
    assert_eq!(
        named(check_error_dynamics::<Spoiled<Se2, 2>, 3, 3>(7)),
        "the error-dynamics theorem"
    );
}
